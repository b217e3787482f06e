// Strict reading of TOML tables: every key is checked for type and range, missing required keys
// and unknown keys (typos) are errors naming file, line and dotted key.
#pragma once

#include <limits>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <toml++/toml.h>

#include <granflow/io/input_error.hpp>

namespace granflow::io {

// Closed or open interval used to validate a number.
struct Bounds {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false, hi_open = false;
  static Bounds positive() { return {0.0, std::numeric_limits<double>::infinity(), true, false}; }
  static Bounds non_negative() { return {0.0, std::numeric_limits<double>::infinity(), false, false}; }
  static Bounds closed(double a, double b) { return {a, b, false, false}; }
  static Bounds open(double a, double b) { return {a, b, true, true}; }
  static Bounds any() { return {}; }
  bool contains(double v) const;
  std::string describe() const;
};

class TomlTable {
 public:
  TomlTable(const toml::table& table, std::string file, std::string prefix = "");

  // Parses a whole file; syntax errors carry the file's line and column.
  static toml::table parse_file(const std::string& path);
  // Parses TOML text; `name` stands for the file in messages.
  static toml::table parse_text(const std::string& text, const std::string& name);

  bool has(const std::string& key) const;
  double number(const std::string& key, Bounds b = Bounds::any());
  std::optional<double> optional_number(const std::string& key, Bounds b = Bounds::any());
  double number_or(const std::string& key, double fallback, Bounds b = Bounds::any());
  long integer(const std::string& key, long lo, long hi);
  long integer_or(const std::string& key, long fallback, long lo, long hi);
  std::string string(const std::string& key);
  std::string string_or(const std::string& key, const std::string& fallback);
  std::string choice(const std::string& key, const std::vector<std::string>& allowed, const std::string& fallback);
  bool boolean_or(const std::string& key, bool fallback);
  std::vector<double> numbers(const std::string& key, Bounds b = Bounds::any(), bool allow_scalar = true);
  std::vector<std::string> strings(const std::string& key, bool allow_scalar = true);
  TomlTable table(const std::string& key);
  std::optional<TomlTable> optional_table(const std::string& key);
  std::vector<TomlTable> array_of_tables(const std::string& key);

  // Call once every key was read: any key not asked for is a typo or an unsupported option.
  void finish() const;

  [[noreturn]] void fail(const std::string& key, const std::string& message) const;
  [[noreturn]] void fail_missing(const std::string& key, const std::string& what) const;
  // Line of key, or of this table when key is empty or absent (0: unknown, or not from the file).
  long line(const std::string& key = "") const;
  std::string dotted(const std::string& key) const { return prefix_.empty() ? key : prefix_ + "." + key; }
  const std::string& file() const { return file_; }
  const toml::table& raw() const { return *table_; }

 private:
  const toml::node* node(const std::string& key);
  std::string position(const toml::node* n) const;
  const toml::node* located(const toml::node* n) const;
  bool foreign(const toml::node* n) const;

  const toml::table* table_;
  std::string file_;
  std::string prefix_;
  std::set<std::string> used_;
};

}  // namespace granflow::io
