// Stand-in for the lab-CSV readers of `granflow calibrate` (not on this branch yet): reads the
// named columns of a CSV with granflow::io::read_csv_columns exactly as a command would, and
// reports errors the way granflow's main() does ("granflow: error: ...", exit 2). The
// bad-input suite drives it as a subprocess; when calibrate lands, its lab-CSV cases switch to
// `granflow calibrate` and this program can go.
//
//   granflow_csv_probe FILE COLUMNS [ABSCISSA]
//     COLUMNS   comma-separated column names, e.g. "strain,q"
//     ABSCISSA  a column that must increase strictly (the curve's abscissa)
#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <granflow/io/csv_table.hpp>
#include <granflow/io/input_error.hpp>

int main(int argc, char** argv) {
  if (argc < 3 || argc > 4) {
    std::cerr << "usage: granflow_csv_probe FILE COLUMNS [ABSCISSA]\n";
    return 64;
  }
  std::vector<std::string> names;
  std::stringstream ss(argv[2]);
  for (std::string n; std::getline(ss, n, ',');) names.push_back(n);
  try {
    const granflow::io::CsvColumns t = granflow::io::read_csv_columns(argv[1], names);
    if (argc == 4) granflow::io::require_strictly_increasing(t, argv[3]);
    std::printf("%zu rows\n", t.rows());
  } catch (const granflow::io::InputError& e) {
    std::cerr << "granflow: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "granflow: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
