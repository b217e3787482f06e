// Output rows of the element driver: the result table (columns, CSV text), the output times,
// and Driver::record, which turns a state into one row and refuses a non-finite one.
#include "output_rows.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "element_driver.hpp"

namespace granflow::elementtest {

const std::vector<std::string>& result_column_names() {
  static const std::vector<std::string> names = {
      "time", "gamma", "shear_rate", "eps_v", "eps_a", "sigma_n_f", "sigma_n_c", "sigma_n", "tau_f", "tau_c", "tau",
      "p_f",  "q_f",   "p_c",        "q_c",   "p",     "q",         "e",         "T",       "K_col", "eta_c", "eps_pd",
      "sigma_xx", "sigma_zz", "eps_xx", "eps_zz", "q_axial"};
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

namespace detail {

std::vector<double> output_times(const OutputSettings& o, double t0, double t1) {
  std::vector<double> ts;
  const int n = std::max(2, o.points);
  for (int i = 0; i < n; ++i) {
    const double f = double(i) / (n - 1);
    if (o.log_spacing)
      ts.push_back(i == 0 ? t0 : t0 + (t1 - t0) * std::pow(1e-4, 1.0 - double(i - 1) / (n - 2)));
    else
      ts.push_back(t0 + f * (t1 - t0));
  }
  ts.back() = t1;
  return ts;
}

template <class Model>
void Driver<Model>::record(ResultTable& out, double t, double r, const ElementState& x, const M3& L) const {
  const M3 D = sym(L);
  M3 sc = M3::Zero();
  const auto st = to_state(x, static_cast<const Model*>(nullptr));
  const Diagnostics<double> dg = Model::diagnostics(p_, st, D);
  double eta = 0;
  if constexpr (kC) {
    const auto& c = cpar(p_);
    const KineticCoefficients<double> kc = kinetic_coefficients(c, 1.0 / (1.0 + x.e));
    const CollisionalTransport<double> tr = collisional_transport(c, kc, x.s);
    sc = collisional_stress(tr, D);
    eta = tr.eta;
    if (kc.clamped) ++out.stats.vs_clamped;
  }
  const M3 sf = kF ? x.sf : M3::Zero();
  const M3 s = sf + sc;
  const bool shear = is_shear(test_.path);
  auto tau_of = [&](const M3& a) { return shear ? a(0, 1) : 0.5 * (a(0, 0) - a(1, 1)); };
  const double rate_gamma = shear ? L(0, 1) : D(0, 0) - D(1, 1);
  const double row[] = {t,        x.gamma,        rate_gamma,          x.eps_v,     x.eps_a,       -sf(1, 1),
                        -sc(1, 1), -s(1, 1),      tau_of(sf),          tau_of(sc),  tau_of(s),     dg.p_f,
                        dg.q_f,   mean_pressure(sc), deviatoric_q(sc), mean_pressure(s), deviatoric_q(s), x.e,
                        x.s * x.s, collisional_share(deviatoric_q(sc), deviatoric_q(sf)), eta, x.eps_pd,
                        -s(0, 0),  -s(2, 2),      x.eps_xx,            x.eps_zz,    s(0, 0) - s(1, 1)};
  constexpr int kColumns = sizeof(row) / sizeof(row[0]);
  static_assert(kColumns == 27, "row and result_column_names() must match");
  for (int i = 0; i < kColumns; ++i)
    if (!std::isfinite(row[i])) {
      std::ostringstream os;
      os.precision(10);
      os << "element test '" << test_.name << "': output '" << out.names[i] << "' = " << row[i]
         << " is not finite at t = " << t << " s; state: " << state_text(x);
      throw std::runtime_error(os.str());
    }
  if constexpr (kF) {
    // Results checked before they are reported: the frictional stress on or inside the yield
    // surface (guards.hpp), whichever solver produced it.
    const std::string outside = outside_yield_surface<kLode>(fpar(p_), x.sf, x.eps_pd, x.e);
    if (!outside.empty()) {
      std::ostringstream os;
      os.precision(10);
      os << "element test '" << test_.name << "': the "
         << (test_.solver.kind == SolverKind::Cvode ? "CVODE" : "incremental update") << " result ";
      if (test_.programme.kind == ProgrammeKind::Sweep)
        os << "for the sweep rate " << r << " 1/s";
      else
        os << "of output row " << out.rows() + 1;
      os << " (t = " << t << " s) is refused: " << outside << "; state: " << state_text(x);
      throw std::runtime_error(os.str());
    }
  }
  for (int i = 0; i < kColumns; ++i) out.columns[i].push_back(row[i]);
}

#define GRANFLOW_INSTANTIATE(Model) \
  template void Driver<Model>::record(ResultTable&, double, double, const ElementState&, const M3&) const;
GRANFLOW_ELEMENT_DRIVER_MODELS(GRANFLOW_INSTANTIATE)
#undef GRANFLOW_INSTANTIATE

}  // namespace detail
}  // namespace granflow::elementtest
