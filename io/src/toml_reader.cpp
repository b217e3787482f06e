#include <granflow/io/toml_reader.hpp>

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace granflow::io {

std::string where(const std::string& file, long line, long column) {
  std::ostringstream os;
  os << file;
  if (line > 0) {
    os << ':' << line;
    if (column > 0) os << ':' << column;
  }
  os << ": ";
  return os.str();
}

namespace {
void default_warning_sink(const std::string& line) { std::fprintf(stderr, "granflow: warning: %s\n", line.c_str()); }
void (*g_warning_sink)(const std::string&) = default_warning_sink;
}  // namespace

void warn(const std::string& line) { g_warning_sink(line); }
void set_warning_sink(void (*sink)(const std::string&)) { g_warning_sink = sink ? sink : default_warning_sink; }

bool Bounds::contains(double v) const {
  if (!std::isfinite(v)) return false;
  const bool lo_ok = lo_open ? v > lo : v >= lo;
  const bool hi_ok = hi_open ? v < hi : v <= hi;
  return lo_ok && hi_ok;
}

std::string Bounds::describe() const {
  std::ostringstream os;
  const bool lo_inf = std::isinf(lo), hi_inf = std::isinf(hi);
  if (lo_inf && hi_inf) return "a finite number";
  if (hi_inf) {
    os << (lo_open ? "> " : ">= ") << lo;
  } else if (lo_inf) {
    os << (hi_open ? "< " : "<= ") << hi;
  } else {
    os << "in " << (lo_open ? '(' : '[') << lo << ", " << hi << (hi_open ? ')' : ']');
  }
  return os.str();
}

TomlTable::TomlTable(const toml::table& table, std::string file, std::string prefix)
    : table_(&table), file_(std::move(file)), prefix_(std::move(prefix)) {}

toml::table TomlTable::parse_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec))
    throw InputError(where(path) + "not a regular file (a TOML file is expected here)");
  std::ifstream in(path);
  if (!in) throw InputError(where(path) + "cannot open file (" + std::strerror(errno) + ")");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_text(text.str(), path);
}

toml::table TomlTable::parse_text(const std::string& text, const std::string& name) {
  try {
    return toml::parse(std::string_view(text), std::string_view(name));
  } catch (const toml::parse_error& err) {
    const auto& b = err.source().begin;
    throw InputError(where(name, static_cast<long>(b.line), static_cast<long>(b.column)) + "TOML syntax error: " +
                     std::string(err.description()));
  }
}

// The node with a position for n: n itself, else the table holding it (nullptr: none known).
const toml::node* TomlTable::located(const toml::node* n) const {
  if (n && n->source().begin) return n;
  return table_->source().begin ? table_ : nullptr;
}

// A node put in from elsewhere (a command-line --set over a scene file) carries that origin
// as its source path: messages name it instead of a line of the file.
bool TomlTable::foreign(const toml::node* n) const { return n->source().path && *n->source().path != file_; }

std::string TomlTable::position(const toml::node* n) const {
  const toml::node* at = located(n);
  if (!at) return where(file_);
  if (foreign(at)) return where(file_) + *at->source().path + ": ";
  return where(file_, at->source().begin.line, at == n ? at->source().begin.column : 0);
}

long TomlTable::line(const std::string& key) const {
  const toml::node* at = located(key.empty() ? nullptr : table_->get(key));
  return at && !foreign(at) ? static_cast<long>(at->source().begin.line) : 0;
}

void TomlTable::fail(const std::string& key, const std::string& message) const {
  throw InputError(position(table_->get(key)) + "'" + dotted(key) + "': " + message);
}

bool TomlTable::has(const std::string& key) const { return table_->contains(key); }

const toml::node* TomlTable::node(const std::string& key) {
  used_.insert(key);
  return table_->get(key);
}

namespace {
std::string type_name(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::table: return "a table";
    case toml::node_type::array: return "an array";
    case toml::node_type::string: return "a string";
    case toml::node_type::integer: return "an integer";
    case toml::node_type::floating_point: return "a number";
    case toml::node_type::boolean: return "a boolean";
    default: return "a date/time";
  }
}
// Edits (insert, delete, substitute, swap two neighbours) from a to b: "rnage" is one from "range".
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

}  // namespace

void TomlTable::fail_missing(const std::string& key, const std::string& what) const {
  std::string close;
  const std::size_t max_dist = std::max<std::size_t>(1, key.size() / 3);
  for (const auto& [k, v] : *table_) {
    const std::string present(k.str());
    if (!used_.count(present) && edit_distance(present, key) <= max_dist)
      close += (close.empty() ? "'" : ", '") + dotted(present) + "'";
  }
  const std::string hint = close.empty() ? "" : " (similar keys present: " + close + "; a typo?)";
  fail(key, "required key is missing (" + what + ")" + hint);
}

std::optional<double> TomlTable::optional_number(const std::string& key, Bounds b) {
  const toml::node* n = node(key);
  if (!n) return std::nullopt;
  if (!n->is_number()) fail(key, "expected a number, got " + type_name(*n));
  const double v = n->is_integer() ? static_cast<double>(n->as_integer()->get()) : n->as_floating_point()->get();
  if (!std::isfinite(v)) fail(key, "must be finite, got " + std::to_string(v));
  if (!b.contains(v)) {
    std::ostringstream os;
    os << "must be " << b.describe() << ", got " << v;
    fail(key, os.str());
  }
  return v;
}

double TomlTable::number(const std::string& key, Bounds b) {
  auto v = optional_number(key, b);
  if (!v) fail_missing(key, b.describe());
  return *v;
}

double TomlTable::number_or(const std::string& key, double fallback, Bounds b) {
  return optional_number(key, b).value_or(fallback);
}

long TomlTable::integer_or(const std::string& key, long fallback, long lo, long hi) {
  const toml::node* n = node(key);
  if (!n) return fallback;
  if (!n->is_integer()) fail(key, "expected an integer, got " + type_name(*n));
  const long v = static_cast<long>(n->as_integer()->get());
  if (v < lo || v > hi)
    fail(key, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + std::to_string(v));
  return v;
}

long TomlTable::integer(const std::string& key, long lo, long hi) {
  if (!has(key)) fail_missing(key, "an integer");
  return integer_or(key, 0, lo, hi);
}

std::string TomlTable::string_or(const std::string& key, const std::string& fallback) {
  const toml::node* n = node(key);
  if (!n) return fallback;
  if (!n->is_string()) fail(key, "expected a string, got " + type_name(*n));
  return n->as_string()->get();
}

std::string TomlTable::string(const std::string& key) {
  if (!has(key)) fail_missing(key, "a string");
  return string_or(key, "");
}

std::string TomlTable::choice(const std::string& key, const std::vector<std::string>& allowed,
                              const std::string& fallback) {
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + ("'" + a + "'");
  if (fallback.empty() && !has(key)) fail_missing(key, "one of " + list);  // no default: required
  const std::string v = string_or(key, fallback);
  for (const auto& a : allowed)
    if (a == v) return v;
  fail(key, "must be one of " + list + ", got '" + v + "'");
}

bool TomlTable::boolean_or(const std::string& key, bool fallback) {
  const toml::node* n = node(key);
  if (!n) return fallback;
  if (!n->is_boolean()) fail(key, "expected true or false, got " + type_name(*n));
  return n->as_boolean()->get();
}

std::vector<double> TomlTable::numbers(const std::string& key, Bounds b, bool allow_scalar) {
  const toml::node* n = node(key);
  if (!n) fail_missing(key, "an array of numbers");
  std::vector<double> out;
  auto check = [&](const toml::node& v) {
    if (!v.is_number()) fail(key, "expected numbers, got " + type_name(v));
    const double x = v.is_integer() ? static_cast<double>(v.as_integer()->get()) : v.as_floating_point()->get();
    if (!b.contains(x)) {
      std::ostringstream os;
      os << "every value must be " << b.describe() << ", got " << x;
      fail(key, os.str());
    }
    out.push_back(x);
  };
  if (n->is_array()) {
    for (const auto& v : *n->as_array()) check(v);
    if (out.empty()) fail(key, "array is empty");
  } else if (allow_scalar) {
    check(*n);
  } else {
    fail(key, "expected an array of numbers, got " + type_name(*n));
  }
  return out;
}

std::vector<std::string> TomlTable::strings(const std::string& key, bool allow_scalar) {
  const toml::node* n = node(key);
  if (!n) fail(key, "required key is missing (an array of strings)");
  std::vector<std::string> out;
  if (n->is_string() && allow_scalar) return {n->as_string()->get()};
  if (!n->is_array()) fail(key, "expected an array of strings, got " + type_name(*n));
  for (const auto& v : *n->as_array()) {
    if (!v.is_string()) fail(key, "expected strings, got " + type_name(v));
    out.push_back(v.as_string()->get());
  }
  if (out.empty()) fail(key, "array is empty");
  return out;
}

TomlTable TomlTable::table(const std::string& key) {
  auto t = optional_table(key);
  if (!t) fail(key, "required table [" + dotted(key) + "] is missing");
  return *t;
}

std::optional<TomlTable> TomlTable::optional_table(const std::string& key) {
  const toml::node* n = node(key);
  if (!n) return std::nullopt;
  if (!n->is_table()) fail(key, "expected a table, got " + type_name(*n));
  return TomlTable(*n->as_table(), file_, dotted(key));
}

std::vector<TomlTable> TomlTable::array_of_tables(const std::string& key) {
  const toml::node* n = node(key);
  std::vector<TomlTable> out;
  if (!n) return out;
  if (!n->is_array_of_tables()) fail(key, "expected an array of tables ([[" + dotted(key) + "]])");
  int i = 0;
  for (const auto& t : *n->as_array()) out.emplace_back(*t.as_table(), file_, dotted(key) + "[" + std::to_string(i++) + "]");
  return out;
}

void TomlTable::finish() const {
  for (const auto& [k, v] : *table_) {
    const std::string key(k.str());
    if (used_.count(key)) continue;
    std::string allowed;
    for (const auto& u : used_) allowed += (allowed.empty() ? "" : ", ") + u;
    throw InputError(position(&v) + "unknown key '" + dotted(key) + "'" +
                     (allowed.empty() ? std::string() : " (allowed here: " + allowed + ")"));
  }
}

}  // namespace granflow::io
