// libFuzzer target: CSV text -> parse_csv_columns (libfccp) and require_strictly_increasing.
// The first byte picks the requested columns (a rate table, a lab curve, one column); the
// rest is the file. Any exception other than io::InputError is a bug.
#include <cstdint>
#include <string>
#include <vector>

#include <granflow/io/csv_table.hpp>
#include <granflow/io/input_error.hpp>

using namespace granflow;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  static const std::vector<std::vector<std::string>> kColumns = {
      {"time", "rate"}, {"strain", "q", "p"}, {"x"}, {"a", "b", "c", "d", "e", "f", "g", "h", "i", "j", "k", "l"}};
  const auto& names = kColumns[data[0] % kColumns.size()];
  const std::string text(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    const io::CsvColumns t = io::parse_csv_columns(text, "fuzz.csv", names);
    io::require_strictly_increasing(t, names.front());
  } catch (const io::InputError&) {
  }
  return 0;
}
