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
#if GF_ELEMENT
  return elementtest::result_column_names();
#else
  static const std::vector<std::string> o = {"time",  "gamma", "shear_rate", "eps_v", "eps_a", "sigma_n_f", "sigma_n_c",
                                             "sigma_n", "tau_f", "tau_c", "tau", "p_f", "q_f", "p_c", "q_c",
                                             "p", "q", "e", "T", "K_col", "eta_c", "eps_pd",
                                             "sigma_xx", "sigma_zz", "eps_xx", "eps_zz", "q_axial"};
  return o;
#endif
}

bool element_tests_available() { return GF_ELEMENT != 0; }

#if GF_ELEMENT

namespace {

// Linear interpolation of y(x) at xi; x increasing. NaN outside [x0, xn] widened by a round-off
// margin (a run to gamma = 0.2 may end at 0.19999999999).
double interpolate(const std::vector<double>& x, const std::vector<double>& y, double xi, double slack = 0.0) {
  if (x.empty()) return std::numeric_limits<double>::quiet_NaN();
  const double tol = std::max(1e-9 * std::max({std::fabs(x.front()), std::fabs(x.back()), x.back() - x.front()}), slack);
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

// The model curve on the data abscissae. Reversing curves: the model's abscissa is cut into
// monotonic runs with the data's tolerance and data run k is interpolated on model run k.
std::vector<double> model_on_curve(const Curve& c, const std::vector<double>& xm, const std::vector<double>& ym) {
  const std::vector<int> mb = c.branch.empty() ? std::vector<int>(xm.size(), 0) : abscissa_branches(xm, c.reversal_tolerance);
  const int runs = mb.empty() ? 0 : mb.back() + 1;
  // Per run: the part that extends the run's extreme, as an increasing axis (x negated on decreasing runs).
  std::vector<std::vector<double>> xs(runs), ys(runs);
  std::vector<double> sign(runs, 1.0);
  for (int k = 0; k < runs && !c.branch.empty(); ++k) {
    const auto first = std::find(mb.begin(), mb.end(), k) - mb.begin();
    const auto end = std::find(mb.begin(), mb.end(), k + 1) - mb.begin();
    if (xm[end - 1] < xm[first]) sign[k] = -1.0;
  }
  for (std::size_t i = 0; i < xm.size(); ++i) {
    const int k = mb[i];
    const double xi = sign[k] * xm[i];
    if (xs[k].empty() || xi > xs[k].back()) {
      xs[k].push_back(xi);
      ys[k].push_back(ym[i]);
    }
  }
  std::vector<double> v(c.x.size(), std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i = 0; i < c.x.size(); ++i) {
    const int k = c.branch.empty() ? 0 : c.branch[i];
    // A run's ends are turning points the model reaches only to its solver tolerance (a stress-
    // controlled reversal within ~1e-6 of the stress): 1e-5 of the run's span counts as reached.
    const double slack = c.branch.empty() || xs[k].empty() ? 0.0 : 1e-5 * (xs[k].back() - xs[k].front());
    if (k < runs) v[i] = interpolate(xs[k], ys[k], sign[k] * c.x[i], slack);
  }
  return v;
}

class ElementExperiment : public Experiment {
 public:
  elementtest::ElementTest test;
  std::string model_abscissa;

  double initial_void_ratio() const override { return test.initial.e0; }
  std::string loading_path() const override {
    switch (test.path) {
      case elementtest::LoadingPath::UndrainedSimpleShear: return "undrained_simple_shear";
      case elementtest::LoadingPath::SimpleShearConstantNormal: return "simple_shear_constant_normal";
      case elementtest::LoadingPath::DrainedTriaxial: return "drained_triaxial";
      case elementtest::LoadingPath::UndrainedTriaxial: return "undrained_triaxial";
      case elementtest::LoadingPath::Oedometric: return "oedometric";
      case elementtest::LoadingPath::Isotropic: return "isotropic";
    }
    return "";
  }

  Prediction predict(const io::ParameterSet& set) const override {
    Prediction out;
    elementtest::ResultTable r;
    try {
      const auto e0 = set.test_e0.find(base_name);  // a per-test free e0
      if (e0 == set.test_e0.end()) {
        r = elementtest::run_element_test(test, set);
      } else {
        elementtest::ElementTest t = test;
        t.initial.e0 = e0->second;
        r = elementtest::run_element_test(t, set);
      }
    } catch (const std::exception& e) {
      out.ok = false;
      out.error = e.what();
      return out;
    }
    const auto& xm = r.column(model_abscissa);
    for (const auto& c : curves) out.values.push_back(model_on_curve(c, xm, r.column(c.model_output)));
    return out;
  }
};

}  // namespace

std::vector<std::shared_ptr<const Experiment>> make_element_experiments(const std::string& name,
                                                                        const DataSelection& sel,
                                                                        io::TomlTable& test_table,
                                                                        const std::string& model_abscissa) {
  elementtest::ElementTest test = elementtest::parse_element_test(test_table);
  // A data programme follows the experiment's own data file unless the test names another.
  if (test.programme.kind == elementtest::ProgrammeKind::Data && test.programme.data_control.empty())
    elementtest::load_programme_data(test, sel.file);
  std::vector<std::shared_ptr<const Experiment>> out;
  for (DataGroup& g : select_data(sel, name)) {
    auto e = std::make_shared<ElementExperiment>();
    e->name = name + g.suffix;
    e->base_name = name;
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
