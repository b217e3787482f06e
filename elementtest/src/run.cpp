// Element-test driver (stub: the integration comes in the next commit).
#include <sstream>
#include <stdexcept>

#include "granflow/elementtest/run.hpp"

namespace granflow::elementtest {

const std::vector<std::string>& result_column_names() {
  static const std::vector<std::string> names = {
      "time", "gamma", "shear_rate", "eps_v", "eps_a", "sigma_n_f", "sigma_n_c", "sigma_n", "tau_f", "tau_c", "tau",
      "p_f",  "q_f",   "p_c",        "q_c",   "p",     "q",         "e",         "T",       "K_col", "eta_c", "eps_pd"};
  return names;
}

const std::vector<double>& ResultTable::column(const std::string& name) const {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return columns[i];
  std::string known;
  for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
  throw io::InputError("element-test result has no column '" + name + "' (columns: " + known + ")");
}

std::string ResultTable::to_csv() const {
  std::ostringstream os;
  os.precision(10);
  for (std::size_t i = 0; i < names.size(); ++i) os << (i ? "," : "") << names[i];
  os << "\n";
  for (std::size_t r = 0; r < rows(); ++r) {
    for (std::size_t i = 0; i < names.size(); ++i) os << (i ? "," : "") << columns[i][r];
    os << "\n";
  }
  return os.str();
}

ResultTable run_element_test(const ElementTest&, const io::ParameterSet&, const ProgressCallback&) {
  throw std::runtime_error("run_element_test: not implemented yet");
}

}  // namespace granflow::elementtest
