// libFuzzer target: parameter-set TOML text -> parse_parameter_set_text.
// Any exception other than io::InputError, any sanitizer report, and any set that loads but
// does not survive format_parameter_set -> load again is a bug.
// A line "#set section.key=value" in the input is also applied with apply_override.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <granflow/io/input_error.hpp>
#include "toml_known_ub.hpp"
#include <granflow/io/parameter_set.hpp>

using namespace granflow;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (hits_known_toml_ub(data, size)) return 0;  // toml++ 3.3.0 bug, see toml_known_ub.hpp
  const std::string text(reinterpret_cast<const char*>(data), size);
  io::ParameterSet set;
  try {
    set = io::parse_parameter_set_text(text, "fuzz.toml");
  } catch (const io::InputError&) {
    return 0;
  }
  // Round trip (calibration writes its results with format_parameter_set).
  const std::string again = io::format_parameter_set(set);
  try {
    (void)io::parse_parameter_set_text(again, "roundtrip.toml");
  } catch (const io::InputError& e) {
    std::fprintf(stderr, "round trip failed: %s\n--- input ---\n%s\n--- formatted ---\n%s\n", e.what(), text.c_str(),
                 again.c_str());
    std::abort();
  }
  const auto at = text.find("#set ");
  if (at != std::string::npos) {
    const auto end = text.find('\n', at);
    const std::string assignment = text.substr(at + 5, end == std::string::npos ? std::string::npos : end - at - 5);
    try {
      io::apply_override(set, assignment);
    } catch (const io::InputError&) {
    }
  }
  return 0;
}
