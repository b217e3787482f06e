// Regressions for what the fuzzers found in granflow's own readers (docs/reliability.md).
// The inputs themselves are also in tests/fuzz/corpus and replayed by fuzz_corpus_* tests.
#include <gtest/gtest.h>

#include <string>

#include "io/input_error.hpp"
#include "io/parameter_set.hpp"

using namespace granflow;

namespace {
const std::string kCollisional =
    "[collisional]\nrho_p = 2650\nd = 0.002\nV_sd = 0.6\nV_m = 0.5\neps_n = 0.9\nmu_p = 0.5\n";
}

// fuzz_parameter_set: a name or source holding an escaped newline or control character was
// written raw by format_parameter_set, so the written set could not be read back.
TEST(FuzzFindings, FormattedSetWithControlCharactersReadsBack) {
  const io::ParameterSet s = io::parse_parameter_set_text(
      "name = \"a\\nb\\u0001c\\\"d\\\\e\\u007F\"\nsource = \"x\\ty\"\n" + kCollisional, "in.toml");
  const io::ParameterSet back = io::parse_parameter_set_text(io::format_parameter_set(s), "out.toml");
  EXPECT_EQ(back.name, s.name);
  EXPECT_EQ(back.source, s.source);
  EXPECT_EQ(back.collisional->V_sd, s.collisional->V_sd);
}

// fuzz_parameter_set: e_sd = 5e-324 (> 0, so accepted) gave V_sd = 1/(1 + e_sd) = 1 exactly;
// the set loaded but, written with V_sd = 1, could not be read back. Now refused at e_sd.
TEST(FuzzFindings, TinyEsdThatRoundsVsdToOneIsRefused) {
  std::string text = kCollisional;
  text.replace(text.find("V_sd = 0.6"), 10, "e_sd = 5e-324");
  try {
    io::parse_parameter_set_text(text, "in.toml");
    FAIL() << "accepted";
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'collisional.e_sd'"), std::string::npos) << e.what();
  }
  text.replace(text.find("e_sd = 5e-324"), 13, "e_sd = 1e-12");  // small but V_sd < 1: fine
  const io::ParameterSet s = io::parse_parameter_set_text(text, "in.toml");
  EXPECT_NO_THROW(io::parse_parameter_set_text(io::format_parameter_set(s), "out.toml"));
}
