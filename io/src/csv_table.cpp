#include <granflow/io/csv_table.hpp>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <tuple>
#include <utility>

#include <libfccp/csv.h>

#include <granflow/io/input_error.hpp>

namespace granflow::io {

namespace {

using Comment = ::io::single_line_comment<'#'>;
template <unsigned N>
using Reader = ::io::CSVReader<N, ::io::trim_chars<' ', '\t', '\r'>, ::io::double_quote_escape<',', '"'>,
                               ::io::throw_on_overflow, Comment>;

// The CSV's header for messages: a file on disk (text == nullptr) or text in memory named `path`.
std::string header_of(const std::string& path, const std::string* text) {
  std::ifstream file;
  std::istringstream mem;
  std::istream* in = &mem;
  if (text) {
    mem.str(*text);
  } else {
    file.open(path);
    in = &file;
  }
  const std::string line = find_csv_header(*in).text;
  return line.size() > 200 ? line.substr(0, 200) + "..." : line;
}

std::string list_of(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ",") + n;
  return s;
}

[[noreturn]] void rethrow_fccp(const std::string& path, const ::io::error::base& err, const std::string* text,
                               const std::vector<std::string>& names) {
  std::string msg = err.what();
  if (dynamic_cast<const ::io::error::header_missing*>(&err))
    msg = "the file is empty: expected a header line naming the columns (" + list_of(names) + ") and data rows";
  if (dynamic_cast<const ::io::error::missing_column_in_header*>(&err)) {
    const std::string header = header_of(path, text);
    msg += " Header found: '" + header + "'";
    if (header.find(';') != std::string::npos || header.find('\t') != std::string::npos)
      msg += " (the delimiter must be a comma)";
  }
  if (auto* fl = dynamic_cast<const ::io::error::with_file_line*>(&err); fl && fl->file_line > 0)
    throw InputError(where(path, fl->file_line) + msg);
  throw InputError(where(path) + msg);
}

double parse_cell(const char* cell, const std::string& path, long line, const std::string& column) {
  if (!cell || !*cell) throw InputError(where(path, line) + "column '" + column + "': empty cell");
  char* end = nullptr;
  const double v = std::strtod(cell, &end);
  if (end == cell || *end != '\0')
    throw InputError(where(path, line) + "column '" + column + "': '" + cell + "' is not a number");
  // Overflow gives +-inf. strtod's ERANGE is no test: it also flags underflow, i.e. every
  // subnormal (1e-310) and every value that rounds to 0 (1e-400), finite numbers all.
  if (!std::isfinite(v))
    throw InputError(where(path, line) + "column '" + column + "': '" + cell + "' is not a finite number");
  return v;
}

template <unsigned N>
std::unique_ptr<Reader<N>> open_reader(const std::string& path, const std::string* text) {
  if (text) return std::make_unique<Reader<N>>(path, text->data(), text->data() + text->size());
  return std::make_unique<Reader<N>>(path);
}

template <unsigned N, std::size_t... I>
CsvColumns read_fixed(const std::string& path, const std::string* text, const std::vector<std::string>& names,
                      std::index_sequence<I...>) {
  CsvColumns out;
  out.file = path;
  out.names = names;
  out.columns.assign(N, {});
  try {
    std::unique_ptr<Reader<N>> rp = open_reader<N>(path, text);
    Reader<N>& reader = *rp;
    reader.read_header(::io::ignore_extra_column, names[I]...);
    std::array<char*, N> cells{};
    while (reader.read_row(std::get<I>(cells)...)) {
      const long line = static_cast<long>(reader.get_file_line());
      for (unsigned c = 0; c < N; ++c) out.columns[c].push_back(parse_cell(cells[c], path, line, names[c]));
      out.lines.push_back(line);
    }
  } catch (const ::io::error::base& err) {
    rethrow_fccp(path, err, text, names);
  }
  if (out.lines.empty()) throw InputError(where(path) + "no data rows after the header");
  return out;
}

template <unsigned N>
CsvColumns dispatch(const std::string& path, const std::string* text, const std::vector<std::string>& names) {
  if constexpr (N > 16) {
    throw InputError(where(path) + "at most 16 columns can be read at once");
  } else {
    if (names.size() == N) return read_fixed<N>(path, text, names, std::make_index_sequence<N>{});
    return dispatch<N + 1>(path, text, names);
  }
}

void check_names(const std::string& path, const std::vector<std::string>& names) {
  if (names.empty()) throw InputError(where(path) + "no columns requested");
  for (std::size_t i = 0; i < names.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (names[i] == names[j]) throw InputError(where(path) + "column '" + names[i] + "' requested twice");
}

void check_regular_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec))
    throw InputError(where(path) + "not a regular file (a CSV file is expected here)");
}

}  // namespace

CsvHeaderLine find_csv_header(std::istream& in) {
  std::string line;
  for (long n = 1; std::getline(in, line); ++n) {
    if (n == 1 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);  // UTF-8 byte-order mark
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!line.empty() && line[0] != '#') return {n, line};
  }
  return {};
}

const std::vector<double>& CsvColumns::column(const std::string& name) const {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return columns[i];
  throw InputError(where(file) + "column '" + name + "' was not read");
}

CsvColumns read_csv_columns(const std::string& path, const std::vector<std::string>& names) {
  check_names(path, names);
  check_regular_file(path);
  {
    std::ifstream probe(path);
    if (!probe) throw InputError(where(path) + "cannot open file (" + std::strerror(errno) + ")");
  }
  return dispatch<1>(path, nullptr, names);
}

CsvColumns parse_csv_columns(const std::string& text, const std::string& name, const std::vector<std::string>& names) {
  check_names(name, names);
  return dispatch<1>(name, &text, names);
}

std::vector<std::string> read_csv_text_column(const std::string& path, const std::string& name) {
  std::vector<std::string> out;
  check_regular_file(path);
  try {
    Reader<1> reader(path);
    reader.read_header(::io::ignore_extra_column, name);
    std::string cell;
    while (reader.read_row(cell)) out.push_back(cell);
  } catch (const ::io::error::base& err) {
    rethrow_fccp(path, err, nullptr, {name});
  }
  return out;
}

void require_strictly_increasing(const CsvColumns& t, const std::string& name) {
  const auto& c = t.column(name);
  for (std::size_t i = 1; i < c.size(); ++i)
    if (!(c[i] > c[i - 1])) {
      std::ostringstream os;
      os << "column '" << name << "' must increase strictly (abscissa), but " << c[i] << " follows " << c[i - 1];
      throw InputError(where(t.file, t.lines[i]) + os.str());
    }
}

void check_strain_column(const CsvColumns& t, const std::string& name) {
  const auto& c = t.column(name);
  std::size_t top = 0;
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (std::fabs(c[i]) > kMaxStrainPerCent) {
      std::ostringstream os;
      os << "column '" << name << "': " << c[i] << " is not a strain (a fraction, nor one in per cent): a stray value?";
      throw InputError(where(t.file, t.lines[i]) + os.str());
    }
    if (std::fabs(c[i]) > std::fabs(c[top])) top = i;
  }
  if (!c.empty() && std::fabs(c[top]) > 1) {
    std::ostringstream os;
    os << "column '" << name << "' reaches " << c[top]
       << ": strains are fractions (0.26 for 26 %); is the column in per cent? then divide it by 100";
    warn(where(t.file, t.lines[top]) + os.str());
  }
}

}  // namespace granflow::io
