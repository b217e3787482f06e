// Regressions for what the fuzzers found in granflow's own readers (docs/reliability.md).
// The inputs themselves are also in tests/fuzz/corpus and replayed by fuzz_corpus_* tests.
#include <gtest/gtest.h>

#include <string>

#include <granflow/io/input_error.hpp>
#include "test_file_text.hpp"
#include <granflow/io/parameter_set.hpp>

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

// fuzz_element_test: rate_min = 5e-324, rate_max = 1000 overflowed rate_max / rate_min to inf
// and converted inf to int (undefined behaviour). Now computed in logarithms, bounded, and a
// range narrower than one step still gives its two end rates.
TEST(FuzzFindings, SweepRangeIsComputedInLogarithms) {
  const std::string head = "[test]\nprogramme = \"sweep\"\n";
  const auto t = elementtest::parse_test_file_text(head + "rate_min = 1e-300\nrate_max = 1e300\nrates_per_decade = 2\n",
                                                   "t.toml");
  ASSERT_EQ(t.test.programme.sweep_rates.size(), 1201u);
  EXPECT_EQ(t.test.programme.sweep_rates.front(), 1e-300);
  EXPECT_EQ(t.test.programme.sweep_rates.back(), 1e300);
  EXPECT_NEAR(t.test.programme.sweep_rates[600], 1.0, 1e-12);
  const auto narrow = elementtest::parse_test_file_text(head + "rate_min = 1\nrate_max = 1.0000000000000002\n", "t.toml");
  ASSERT_EQ(narrow.test.programme.sweep_rates.size(), 2u);
  for (double r : narrow.test.programme.sweep_rates) EXPECT_TRUE(r >= 1.0 && r <= 1.0000000000000002);
  EXPECT_THROW(elementtest::parse_test_file_text(head + "rate_min = 5e-324\nrate_max = 1000\nrates_per_decade = 1000\n",
                                                 "t.toml"),
               io::InputError);
}
