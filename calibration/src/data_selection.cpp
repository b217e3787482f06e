// Rows of a data file -> curves: filter, split into groups, abscissa window, duplicates, order.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include "granflow/calibration/experiment.hpp"
#include <granflow/io/csv_table.hpp>
#include <granflow/io/input_error.hpp>

namespace granflow::calibration {

namespace {

bool same_value(double a, double b) { return std::fabs(a - b) <= 1e-9 * std::max(1.0, std::fabs(b)); }

std::string format_value(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// A requested column missing from the header: name the header's line and what the job asked for
// (the CSV reader names only the file for this case).
void check_header(const std::string& path, const std::vector<std::string>& names, const std::string& experiment) {
  std::ifstream in(path);
  if (!in) throw io::InputError(io::where(path) + "cannot open the data file of experiment '" + experiment + "'");
  const io::CsvHeaderLine header = io::find_csv_header(in);  // a byte-order mark skipped
  if (header.line == 0)
    throw io::InputError(io::where(path) + "empty file: no header line (data of experiment '" + experiment + "')");
  const std::string& line = header.text;
  std::vector<std::string> cols;
  std::stringstream ss(line);
  std::string c;
  while (std::getline(ss, c, ',')) {
    const auto a = c.find_first_not_of(" \t\""), b = c.find_last_not_of(" \t\"");
    cols.push_back(a == std::string::npos ? "" : c.substr(a, b - a + 1));
  }
  for (const auto& want : names)
    if (std::find(cols.begin(), cols.end(), want) == cols.end())
      throw io::InputError(io::where(path, header.line) + "experiment '" + experiment + "' needs column '" + want +
                           "', which the header '" + line + "' does not have" +
                           (line.find(';') != std::string::npos || line.find('\t') != std::string::npos
                                ? " (the delimiter must be a comma)"
                                : ""));
}

}  // namespace

std::vector<int> abscissa_branches(const std::vector<double>& x, double tolerance) {
  std::vector<int> b(x.size(), 0);
  int branch = 0, dir = 0;
  double ext = x.empty() ? 0.0 : x.front();  // extreme of the current run
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double d = x[i] - ext;
    if (dir == 0) {
      if (std::fabs(d) > tolerance) dir = d > 0 ? 1 : -1;
      if (dir != 0 || i == 0) ext = x[i];
    } else if (dir * d > 0) {
      ext = x[i];
    } else if (-dir * d > tolerance) {  // moved back beyond the tolerance: a new run from here
      ++branch;
      dir = -dir;
      ext = x[i];
    }
    b[i] = branch;
  }
  return b;
}

double Experiment::x_max() const {
  double m = -1e300;
  for (const auto& c : curves)
    for (double x : c.x) m = std::max(m, x);
  return m;
}

std::vector<DataGroup> select_data(const DataSelection& sel, const std::string& experiment_name) {
  // Columns to read: abscissa, targets, filter, split, extra (each once, in that order).
  std::vector<std::string> names;
  auto add = [&](const std::string& n) {
    if (std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
  };
  add(sel.abscissa);
  for (const auto& [col, out] : sel.targets) add(col);
  for (const auto& [col, v] : sel.filter) add(col);
  for (const auto& col : sel.split_by) add(col);
  for (const auto& col : sel.extra_columns) add(col);
  check_header(sel.file, names, experiment_name);
  const io::CsvColumns table = io::read_csv_columns(sel.file, names);
  const auto& x = table.column(sel.abscissa);
  // strains are fractions: a column in per cent gets a warning, a stray huge value an error
  auto strain_output = [](const std::string& o) { return o.rfind("eps_", 0) == 0 || o == "gamma"; };
  const bool strain_abscissa = strain_output(sel.model_abscissa);
  if (strain_abscissa) io::check_strain_column(table, sel.abscissa);
  for (const auto& [col, out] : sel.targets)
    if (strain_output(out) && !(strain_abscissa && col == sel.abscissa)) io::check_strain_column(table, col);

  // Filter and group rows (groups keep first-appearance order).
  std::vector<std::vector<double>> keys;
  std::vector<std::vector<std::size_t>> rows;
  for (std::size_t r = 0; r < table.rows(); ++r) {
    bool keep = x[r] >= sel.x_lo && x[r] <= sel.x_hi;
    for (const auto& [col, v] : sel.filter) keep = keep && same_value(table.column(col)[r], v);
    if (!keep) continue;
    std::vector<double> key;
    for (const auto& col : sel.split_by) key.push_back(table.column(col)[r]);
    std::size_t g = 0;
    while (g < keys.size() && !std::equal(key.begin(), key.end(), keys[g].begin(), same_value)) ++g;
    if (g == keys.size()) {
      keys.push_back(key);
      rows.emplace_back();
    }
    rows[g].push_back(r);
  }
  if (rows.empty()) {
    std::ostringstream os;
    os << "experiment '" << experiment_name << "': no data row passes the filter";
    for (const auto& [col, v] : sel.filter) os << " " << col << " = " << v;
    if (sel.x_lo > -1e300 || sel.x_hi < 1e300) os << " within the range [" << sel.x_lo << ", " << sel.x_hi << "] of '" << sel.abscissa << "'";
    throw io::InputError(io::where(sel.file) + os.str());
  }

  std::vector<DataGroup> groups;
  for (std::size_t g = 0; g < rows.size(); ++g) {
    DataGroup grp;
    if (!sel.split_by.empty()) {
      grp.suffix = "[";
      for (std::size_t k = 0; k < sel.split_by.size(); ++k)
        grp.suffix += (k ? "," : "") + sel.split_by[k] + "=" + format_value(keys[g][k]);
      grp.suffix += "]";
    }
    const auto& rr = rows[g];
    for (const auto& col : sel.extra_columns) {
      const auto& c = table.column(col);
      for (std::size_t r : rr)
        if (!same_value(c[r], c[rr.front()]))
          throw io::InputError(io::where(sel.file, table.lines[r]) + "column '" + col + "' must be constant within curve '" +
                               experiment_name + grp.suffix + "' (it sets a model parameter); split the data with " +
                               "'split_by' or 'filter'");
      grp.extra.push_back(c[rr.front()]);
    }
    // Abscissa order; equal abscissae (repeated measurements) only with duplicates = "average".
    for (std::size_t k = 1; k < rr.size() && !sel.reverses; ++k) {
      const double a = x[rr[k - 1]], b = x[rr[k]];
      if (b > a || (b == a && sel.average_duplicates)) continue;
      std::ostringstream os;
      os << "column '" << sel.abscissa << "' must increase strictly within curve '" << experiment_name << grp.suffix
         << "' (abscissa), but " << b << " follows " << a;
      if (b == a) os << " (repeated value: set duplicates = \"average\" to average repeated points)";
      throw io::InputError(io::where(sel.file, table.lines[rr[k]]) + os.str());
    }
    for (std::size_t t = 0; t < sel.targets.size(); ++t) {
      Curve c;
      c.experiment = experiment_name + grp.suffix;
      c.data_column = sel.targets[t].first;
      c.model_output = sel.targets[t].second;
      c.abscissa = sel.abscissa;
      c.file = sel.file;
      c.weight = sel.weight * sel.target_weights[t];
      if (t < sel.target_sd.size()) c.sd = sel.target_sd[t];
      const auto& y = table.column(c.data_column);
      for (std::size_t k = 0; k < rr.size();) {
        std::size_t m = k + 1;
        double sum = y[rr[k]];
        while (m < rr.size() && x[rr[m]] == x[rr[k]] && sel.average_duplicates) sum += y[rr[m++]];
        c.x.push_back(x[rr[k]]);
        c.y.push_back(sum / static_cast<double>(m - k));
        c.lines.push_back(table.lines[rr[k]]);
        k = m;
      }
      if (sel.reverses) {
        c.branch = abscissa_branches(c.x, sel.reversal_tolerance);
        c.reversal_tolerance = sel.reversal_tolerance;
      }
      grp.curves.push_back(std::move(c));
    }
    groups.push_back(std::move(grp));
  }
  return groups;
}

}  // namespace granflow::calibration
