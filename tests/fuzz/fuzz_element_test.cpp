// libFuzzer target: element-test file text -> parse_test_file_text (strict [test] parsing,
// rate tables, sweeps). The file "lives" in a folder that does not exist, so a relative
// rate_file cannot reach real files. Any exception other than io::InputError is a bug.
#include <cstdint>
#include <string>

#include <granflow/io/input_error.hpp>
#include "toml_known_ub.hpp"
#include "test_file_text.hpp"

using namespace granflow;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (hits_known_toml_ub(data, size)) return 0;  // toml++ 3.3.0 bug, see toml_known_ub.hpp
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    (void)elementtest::parse_test_file_text(text, "/nonexistent-granflow-fuzz/fuzz.toml");
  } catch (const io::InputError&) {
  }
  return 0;
}
