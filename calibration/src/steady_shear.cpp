// Steady simple-shear flow curves from the closed forms of MODEL.md 5.3:
//   T = (K_eta/K_Gamma) d^2 gd^2,  p = rho_p V_s p* T,  tau = rho_p K_eta^{3/2}/K_Gamma^{1/2} d^2 gd^2.
#include <cmath>
#include <limits>

#include <granflow/constitutive.hpp>

#include "granflow/calibration/experiment.hpp"
#include <granflow/io/input_error.hpp>

namespace granflow::calibration {

namespace {

class SteadyShearExperiment : public Experiment {
 public:
  SteadyShearSpec spec;
  bool abscissa_is_rate = false;
  double eps_n = -1, mu_p = -1;  // from the data columns; < 0: from the parameter set

  std::string data_parameters() const override {
    std::string s;
    if (eps_n >= 0) s += "eps_n = " + std::to_string(eps_n);
    if (mu_p >= 0) s += std::string(s.empty() ? "" : ", ") + "mu_p = " + std::to_string(mu_p);
    return s;
  }

  double data_friction() const override { return mu_p >= 0 ? mu_p : std::numeric_limits<double>::quiet_NaN(); }
  double data_restitution() const override { return eps_n >= 0 ? eps_n : std::numeric_limits<double>::quiet_NaN(); }

  Prediction predict(const io::ParameterSet& set) const override {
    Prediction out;
    if (!set.collisional) {
      out.ok = false;
      out.error = "the parameter set has no [collisional] table";
      return out;
    }
    CollisionalParams<double> c = *set.collisional;
    if (eps_n >= 0) c.eps_n = eps_n;
    if (mu_p >= 0) c.mu_p = mu_p;
    // a fit may try constants a parameter file would refuse (V_m >= V_sd(mu_p), V_sd_inf > V_sd)
    if (!(c.V_m < jamming_fraction(c)) || !(effective_restitution(c) > -1) || (c.jamming_friction && !(c.V_m < c.V_sd_inf && c.V_sd_inf <= c.V_sd))) {
      out.ok = false;
      out.error = "V_m must lie below V_sd(mu_p), and V_sd_inf below V_sd";
      return out;
    }
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (const auto& curve : curves) {
      std::vector<double> v(curve.x.size(), nan);
      for (std::size_t i = 0; i < curve.x.size(); ++i) {
        const double Vs = abscissa_is_rate ? spec.solid_fraction : curve.x[i];
        const double rate = abscissa_is_rate ? curve.x[i] : spec.shear_rate;
        const KineticCoefficients<double> kc = kinetic_coefficients(c, Vs);
        if (kc.clamped) continue;  // at or above V_sd the closed forms do not exist: NaN -> penalty
        const SteadyShear<double> ss = steady_simple_shear(c, kc, rate);
        const double stress_unit = spec.dimensionless ? c.rho_p * c.d * c.d * rate * rate : 1.0;
        const double T_unit = spec.dimensionless ? c.d * c.d * rate * rate : 1.0;
        const std::string& o = curve.model_output;
        v[i] = o == "p" ? ss.p / stress_unit : o == "tau" ? ss.tau / stress_unit : o == "T" ? ss.T / T_unit : ss.mu;
      }
      out.values.push_back(std::move(v));
    }
    return out;
  }
};

}  // namespace

const std::vector<std::string>& steady_shear_outputs() {
  static const std::vector<std::string> o = {"p", "tau", "T", "mu"};
  return o;
}

std::vector<std::shared_ptr<const Experiment>> make_steady_shear_experiments(const std::string& name,
                                                                               const DataSelection& sel_in,
                                                                               const SteadyShearSpec& spec) {
  DataSelection sel = sel_in;
  int i_eps = -1, i_mu = -1;
  if (!spec.restitution_column.empty()) {
    i_eps = static_cast<int>(sel.extra_columns.size());
    sel.extra_columns.push_back(spec.restitution_column);
  }
  if (!spec.friction_column.empty()) {
    i_mu = static_cast<int>(sel.extra_columns.size());
    sel.extra_columns.push_back(spec.friction_column);
  }
  std::vector<std::shared_ptr<const Experiment>> out;
  for (DataGroup& g : select_data(sel, name)) {
    auto e = std::make_shared<SteadyShearExperiment>();
    e->name = name + g.suffix;
    e->kind = "steady_shear";
    e->abscissa_quantity = sel.quantity;
    e->data_file = sel.file;
    e->spec = spec;
    e->abscissa_is_rate = sel.quantity == "shear_rate";
    if (i_eps >= 0) {
      e->eps_n = g.extra[i_eps];
      if (!(e->eps_n >= 0 && e->eps_n <= 1))
        throw io::InputError(io::where(sel.file) + "column '" + spec.restitution_column + "' gives restitution " +
                             std::to_string(e->eps_n) + " outside [0, 1] in curve '" + e->name + "'");
    }
    if (i_mu >= 0) {
      e->mu_p = g.extra[i_mu];
      if (!(e->mu_p >= 0))
        throw io::InputError(io::where(sel.file) + "column '" + spec.friction_column + "' gives a negative friction in curve '" +
                             e->name + "'");
    }
    e->curves = std::move(g.curves);
    out.push_back(std::move(e));
  }
  return out;
}

}  // namespace granflow::calibration
