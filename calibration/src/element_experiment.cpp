// Element-test experiments: the [experiments.test] table is an element test as `granflow element`
// reads it; the model curve is the driver's result column interpolated at the data abscissae.
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <random>
#include <sstream>

#include "granflow/calibration/experiment.hpp"
#include <granflow/io/input_error.hpp>
#include <granflow/io/toml_reader.hpp>

#if defined(GRANFLOW_HAVE_ELEMENTTEST) && __has_include(<granflow/elementtest/run.hpp>)
#include <granflow/elementtest/run.hpp>
#define GF_ELEMENT 1
#else
#define GF_ELEMENT 0
#endif

namespace granflow::calibration {

const std::vector<std::string>& element_test_outputs() {
  static const std::vector<std::string> o = {"time",  "gamma", "shear_rate", "eps_v", "eps_a", "sigma_n_f", "sigma_n_c",
                                             "sigma_n", "tau_f", "tau_c", "tau", "p_f", "q_f", "p_c", "q_c",
                                             "p", "q", "e", "T", "K_col", "eta_c", "eps_pd"};
  return o;
}

bool element_tests_available() { return GF_ELEMENT != 0; }

#if GF_ELEMENT

namespace {

// Linear interpolation of y(x) at xi; x increasing. NaN outside [x0, xn] widened by a round-off
// margin (a run to gamma = 0.2 may end at 0.19999999999).
double interpolate(const std::vector<double>& x, const std::vector<double>& y, double xi) {
  if (x.empty()) return std::numeric_limits<double>::quiet_NaN();
  const double tol = 1e-9 * std::max({std::fabs(x.front()), std::fabs(x.back()), x.back() - x.front()});
  if (xi < x.front() - tol || xi > x.back() + tol) return std::numeric_limits<double>::quiet_NaN();
  xi = std::clamp(xi, x.front(), x.back());
  std::size_t hi = std::lower_bound(x.begin(), x.end(), xi) - x.begin();
  if (hi == 0) return y[0];
  const std::size_t lo = hi - 1;
  const double w = (xi - x[lo]) / (x[hi] - x[lo]);
  return y[lo] + w * (y[hi] - y[lo]);
}

}  // namespace

namespace {

class ElementExperiment : public Experiment {
 public:
  elementtest::ElementTest test;
  std::string model_abscissa;

  Prediction predict(const io::ParameterSet& set) const override {
    Prediction out;
    elementtest::ResultTable r;
    try {
      r = elementtest::run_element_test(test, set);
    } catch (const std::exception& e) {
      out.ok = false;
      out.error = e.what();
      return out;
    }
    const auto& xm = r.column(model_abscissa);
    for (const auto& c : curves) {
      const auto& ym = r.column(c.model_output);
      // Keep the strictly increasing part of the model abscissa (a strain or time axis).
      std::vector<double> xs, ys;
      for (std::size_t i = 0; i < xm.size(); ++i)
        if (xs.empty() || xm[i] > xs.back()) {
          xs.push_back(xm[i]);
          ys.push_back(ym[i]);
        }
      std::vector<double> v(c.x.size());
      for (std::size_t i = 0; i < c.x.size(); ++i) v[i] = interpolate(xs, ys, c.x[i]);
      out.values.push_back(std::move(v));
    }
    return out;
  }
};

}  // namespace

std::vector<std::shared_ptr<const Experiment>> make_element_experiments(const std::string& name,
                                                                        const DataSelection& sel,
                                                                        io::TomlTable& test_table,
                                                                        const std::string& model_abscissa) {
  elementtest::ElementTest test = elementtest::parse_element_test(test_table);
  std::vector<std::shared_ptr<const Experiment>> out;
  for (DataGroup& g : select_data(sel, name)) {
    auto e = std::make_shared<ElementExperiment>();
    e->name = name + g.suffix;
    e->kind = "element";
    e->abscissa_quantity = sel.quantity;
    e->data_file = sel.file;
    e->test = test;
    e->model_abscissa = model_abscissa;
    e->curves = std::move(g.curves);
    out.push_back(std::move(e));
  }
  return out;
}

std::string synthesize_element_data(const DataSelection& sel, io::TomlTable& test_table,
                                    const std::string& model_abscissa, const io::ParameterSet& truth, double noise,
                                    unsigned long seed, long stride) {
  const elementtest::ElementTest test = elementtest::parse_element_test(test_table);
  const elementtest::ResultTable r = elementtest::run_element_test(test, truth);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::ostringstream out;
  out << "# synthetic data: element test with parameter set '" << truth.name << "', relative noise " << noise
      << ", seed " << seed << "\n";
  out << sel.abscissa;
  for (const auto& [col, o] : sel.targets) out << "," << col;
  out << "\n" << std::setprecision(10);
  const auto& x = r.column(model_abscissa);
  double last = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 1; i < x.size(); i += static_cast<std::size_t>(stride)) {
    if (!(x[i] > last)) continue;
    last = x[i];
    out << x[i];
    for (const auto& [col, o] : sel.targets) out << "," << r.column(o)[i] * (1.0 + noise * normal(rng));
    out << "\n";
  }
  return out.str();
}

#else

std::vector<std::shared_ptr<const Experiment>> make_element_experiments(const std::string& name, const DataSelection& sel,
                                                                        io::TomlTable& test_table,
                                                                        const std::string&) {
  test_table.fail("", "experiment '" + name + "' is an element test, but this granflow was built without the " +
                          "element-test driver (granflow_elementtest); data file " + sel.file);
}

std::string synthesize_element_data(const DataSelection& sel, io::TomlTable&, const std::string&,
                                    const io::ParameterSet&, double, unsigned long, long) {
  throw io::InputError(io::where(sel.file) + "synthetic element data need the element-test driver (not built)");
}

#endif

}  // namespace granflow::calibration
