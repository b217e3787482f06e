// Reading numeric columns from CSV files (lab data, DEM data, rate programmes) with the
// fast C++ CSV parser (libfccp). Columns are selected by header name; a missing column, a
// non-numeric or non-finite cell, an empty file or a wrong delimiter is an InputError that
// names the file, the line and the column. A UTF-8 byte-order mark before the header is
// skipped; subnormal numbers (1e-310) are numbers like any other.
#pragma once

#include <istream>
#include <string>
#include <vector>

namespace granflow::io {

struct CsvColumns {
  std::string file;
  std::vector<std::string> names;            // as requested
  std::vector<std::vector<double>> columns;  // columns[i][row]
  std::vector<long> lines;                   // file line of each row

  const std::vector<double>& column(const std::string& name) const;
  std::size_t rows() const { return lines.size(); }
};

// Reads the named columns (at most 16; other columns are ignored; '#' starts a comment line).
CsvColumns read_csv_columns(const std::string& path, const std::vector<std::string>& names);

// The same for CSV text held in memory; `name` stands for the file in messages (fuzzing, tests).
CsvColumns parse_csv_columns(const std::string& text, const std::string& name, const std::vector<std::string>& names);

// Reads one text column (e.g. a label used to split a file into curves).
std::vector<std::string> read_csv_text_column(const std::string& path, const std::string& name);

// The header: the first line that is neither empty nor a '#' comment, without a UTF-8 byte-order
// mark at the start of the text or a trailing '\r'. line: its number from 1; 0 when there is none.
struct CsvHeaderLine {
  long line = 0;
  std::string text;
};
CsvHeaderLine find_csv_header(std::istream& in);

// Errors unless the column increases strictly (abscissae of a curve).
void require_strictly_increasing(const CsvColumns& t, const std::string& name);

// A column of strains (fractions): a value above 1 in magnitude gets a warning (io::warn) naming
// the file, the line of the largest and the column (per cent?); one above kMaxStrainPerCent is an
// InputError (no strain, in per cent or not).
inline constexpr double kMaxStrainPerCent = 100.0;
void check_strain_column(const CsvColumns& t, const std::string& name);

}  // namespace granflow::io
