// Element-test driver: the state of one material point as an ODE system in time.
//
//   y = [sigma_f (xx yy zz xy yz xz) / sigma_ref, eps_pd, e, s / s_ref, gamma, eps_v, eps_a]
//
// dsigma_f/dt = frictional_rate (library, unchanged) + W sigma_f - sigma_f W   (Jaumann, MODEL 3.1)
// deps_pd/dt  = plastic multiplier rate (library)
// de/dt       = (1 + e) tr D                                                   (MODEL 3.7)
// ds/dt       = sqrt_temperature_rate(temperature_balance(...), s)              (MODEL 5.2)
//
// The right-hand side is piecewise smooth. The driver is a hybrid system: a mode flag (elastic or
// plastic) is held fixed between events and CVODE's root finding locates the switches (yield
// onset f = 0 in elastic mode; the loading indicator n:C:D - h dGm/de de = 0 in plastic mode) and
// the tension cut-off p_f = 0, after which sigma_f stays 0 (MODEL 3.2 A5, 3.6 "Switches").
// Rate-programme breakpoints (end of the hold phase, table nodes, jumps) are stop times with a
// restart, so no step straddles a kink.
#include <cvode/cvode.h>
#include <cvode/cvode_proj.h>
#include <nvector/nvector_serial.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <time.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>

#include <granflow/constitutive.hpp>

#include "granflow/elementtest/run.hpp"
#include "guards.hpp"

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

namespace {

using M3 = Mat3<double>;
constexpr LodeShape kLode = LodeShape::SmoothMohrCoulomb;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kN = 12;  // ODE size

double cpu_now() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

// ---- parameter access per model ---------------------------------------------------------
const FrictionalParams<double>& fpar(const FrictionalParams<double>& p) { return p; }
const FrictionalParams<double>& fpar(const PhaseTransitionParams<double>& p) { return p.f; }
const CollisionalParams<double>& cpar(const CollisionalParams<double>& p) { return p; }
const CollisionalParams<double>& cpar(const PhaseTransitionParams<double>& p) { return p.c; }

// ---- element state -------------------------------------------------------------------------
struct X {
  M3 sf = M3::Zero();
  double eps_pd = 0, e = 0, s = 0;
  double gamma = 0, eps_v = 0, eps_a = 0;
};

// Model-state conversions (the incremental update works on the library's own State types).
FrictionalState<double> to_state(const X& x, const FrictionalModel<double>*) { return {x.sf, x.eps_pd, x.e}; }
CollisionalState<double> to_state(const X& x, const CollisionalModel<double>*) { return {x.e, x.s}; }
PhaseTransitionModel<double>::State to_state(const X& x, const PhaseTransitionModel<double>*) {
  PhaseTransitionModel<double>::State st;
  st.sigma_f = x.sf;
  st.eps_pd = x.eps_pd;
  st.e = x.e;
  st.s = x.s;
  return st;
}
void from_state(X& x, const FrictionalState<double>& st) {
  x.sf = st.sigma;
  x.eps_pd = st.eps_pd;
  x.e = st.e;
}
void from_state(X& x, const CollisionalState<double>& st) {
  x.e = st.e;
  x.s = st.s;
}
void from_state(X& x, const PhaseTransitionModel<double>::State& st) {
  x.sf = st.sigma_f;
  x.eps_pd = st.eps_pd;
  x.e = st.e;
  x.s = st.s;
}

// ---- rate programme as segments -------------------------------------------------------
struct Segment {
  double t0, t1, r0, r1;
  double rate(double t) const { return t1 > t0 ? r0 + (r1 - r0) * (t - t0) / (t1 - t0) : r0; }
};

std::vector<Segment> segments_of(const RateProgramme& g) {
  std::vector<Segment> s;
  switch (g.kind) {
    case ProgrammeKind::Constant:
    case ProgrammeKind::Sweep:
      s.push_back({0.0, g.duration, g.rate, g.rate});
      break;
    case ProgrammeKind::Acceleration:
      if (g.hold > 0) s.push_back({0.0, g.hold, g.rate, g.rate});
      s.push_back({g.hold, g.duration, g.rate, g.rate + g.acceleration * (g.duration - g.hold)});
      break;
    case ProgrammeKind::Table:
      for (std::size_t i = 0; i + 1 < g.table_time.size(); ++i) {
        const double a = g.table_time[i], b = std::min(g.table_time[i + 1], g.duration);
        if (!(b > a)) continue;
        const double rb = g.table_rate[i] + (g.table_rate[i + 1] - g.table_rate[i]) * (b - a) /
                                                (g.table_time[i + 1] - g.table_time[i]);
        s.push_back({a, b, g.table_rate[i], rb});
        if (b >= g.duration) break;
      }
      break;
  }
  return s;
}

bool is_shear(LoadingPath p) {
  return p == LoadingPath::UndrainedSimpleShear || p == LoadingPath::SimpleShearConstantNormal;
}
bool is_mixed(LoadingPath p) {
  return p == LoadingPath::SimpleShearConstantNormal || p == LoadingPath::DrainedTriaxial;
}
// Stress component held constant under mixed control: yy (shear box) or xx (= zz, triaxial cell).
int controlled_index(LoadingPath p) { return p == LoadingPath::SimpleShearConstantNormal ? 1 : 0; }

// Velocity gradient for control rate r and (mixed control) the unknown normal strain rate u.
M3 velocity_gradient(LoadingPath p, double r, double u) {
  M3 L = M3::Zero();
  switch (p) {
    case LoadingPath::UndrainedSimpleShear: L(0, 1) = r; break;
    case LoadingPath::SimpleShearConstantNormal: L(0, 1) = r; L(1, 1) = u; break;
    case LoadingPath::DrainedTriaxial: L(1, 1) = -r; L(0, 0) = L(2, 2) = u; break;
    case LoadingPath::UndrainedTriaxial: L(1, 1) = -r; L(0, 0) = L(2, 2) = 0.5 * r; break;
    case LoadingPath::Oedometric: L(1, 1) = -r; break;
    case LoadingPath::Isotropic: L = -r * M3::Identity(); break;
  }
  return L;
}

std::string state_text(const X& x) {
  std::ostringstream os;
  os.precision(6);
  os << "p_f = " << mean_pressure(x.sf) << " Pa, q_f = " << deviatoric_q(x.sf) << " Pa, e = " << x.e
     << ", T = " << x.s * x.s << " m2/s2, eps_pd = " << x.eps_pd << ", gamma = " << x.gamma;
  return os.str();
}

// ---- numerical guards (guards.hpp) ------------------------------------------------------------
std::string inadmissible(const X& x, double p_floor, double s_floor = 0.0) {
  return detail::inadmissible_state(x.sf, x.eps_pd, x.e, x.s, x.gamma, x.eps_v, x.eps_a, p_floor, s_floor);
}
using detail::update_flags_text;

// ---- the driver, one model ------------------------------------------------------------------
template <class Model>
class Driver {
 public:
  using P = typename Model::Params;
  static constexpr bool kF = Model::kFrictional, kC = Model::kCollisional;

  Driver(const ElementTest& t, const P& p, const io::ParameterSet& set) : test_(t), p_(p), set_(set) {
    sigma_ref_ = std::max(t.initial.sigma_v0, 1.0);
    if constexpr (kC) s_ref_ = cpar(p_).d * 1.0;
  }

  X initial_state() const {
    X x;
    x.e = test_.initial.e0;
    double T0 = test_.initial.T0 >= 0 ? test_.initial.T0 : set_.T0.value_or(1e-15);
    x.s = std::sqrt(T0);
    if constexpr (kF) {
      const auto& f = fpar(p_);
      const double k0 = test_.initial.k0 > 0 ? test_.initial.k0 : 1.0 - std::sin(f.phi_c);
      const double sv = test_.initial.sigma_v0;
      x.sf = M3::Zero();
      x.sf(0, 0) = x.sf(2, 2) = -k0 * sv;
      x.sf(1, 1) = -sv;
      x.eps_pd = initial_plastic_strain<kLode>(f, x.sf, x.e);
      if (!(x.eps_pd >= 0)) {
        std::ostringstream os;
        os << io::where(test_.file) << "initial stress (sigma_v0 = " << sv << " Pa, k0 = " << k0
           << ") lies outside the yield surface (stress ratio >= g M_p at e0 = " << x.e << ")";
        throw io::InputError(os.str());
      }
    }
    return x;
  }

  // ---- rates -----------------------------------------------------------------------------
  struct Rates {
    X dx;
    M3 L;
  };

  // Rates for a given velocity gradient; `plastic` selects the mode (ftol_load = +-inf).
  X rates_for(const X& x, const M3& L, bool plastic) const {
    X d;
    const M3 D = sym(L), W = skew(L);
    if constexpr (kF) {
      if (!cut_) {
        const FrictionalRate<double> fr =
            frictional_rate<kLode>(fpar(p_), x.sf, x.eps_pd, x.e, D, plastic ? kInf : -kInf);
        d.sf = fr.dsigma + W * x.sf - x.sf * W;
        d.eps_pd = fr.deps_pd;
      }
    }
    d.e = (1.0 + x.e) * trace(D);
    if constexpr (kC) {
      const auto& c = cpar(p_);
      const KineticCoefficients<double> kc = kinetic_coefficients(c, 1.0 / (1.0 + x.e));
      d.s = sqrt_temperature_rate(temperature_balance(c, kc, D), x.s);
    }
    d.gamma = is_shear(test_.path) ? L(0, 1) : D(0, 0) - D(1, 1);
    d.eps_v = -trace(D);
    d.eps_a = -D(1, 1);
    return d;
  }

  // "Controlled" normal stress: sigma_f,ii - p_c (the viscous normal stress of the collisional
  // part is not controlled: it would make the mixed control an index-2 DAE in D).
  double controlled_stress(const X& x) const {
    const int i = controlled_index(test_.path);
    double v = 0;
    if constexpr (kF) v += x.sf(i, i);
    if constexpr (kC) {
      const auto& c = cpar(p_);
      const KineticCoefficients<double> kc = kinetic_coefficients(c, 1.0 / (1.0 + x.e));
      v -= collisional_transport(c, kc, x.s).p;
    }
    return v;
  }

  double controlled_rate(const X& x, const X& d) const {
    const int i = controlled_index(test_.path);
    double v = 0;
    if constexpr (kF) v += d.sf(i, i);
    if constexpr (kC) {
      // d(-p_c)/dt = -rho_p [ d(V_s p*)/de de/dt s^2 + V_s p* 2 s ds/dt ]
      const auto& c = cpar(p_);
      auto vp = [&](double e) {
        const KineticCoefficients<double> kc = kinetic_coefficients(c, 1.0 / (1.0 + e));
        return kc.Vs * kc.p_star;
      };
      const double h = 1e-7 * (1.0 + x.e);
      const double dvp = (vp(x.e + h) - vp(x.e - h)) / (2 * h);
      v -= c.rho_p * (dvp * d.e * x.s * x.s + vp(x.e) * 2.0 * x.s * d.s);
    }
    return v;
  }

  // Solves the mixed control for u (secant on a piecewise-linear function); returns L.
  M3 solve_mixed(const X& x, double r, bool plastic) const {
    auto g = [&](double u) { return controlled_rate(x, rates_for(x, velocity_gradient(test_.path, r, u), plastic)); };
    double u0 = 0, g0 = g(u0);
    double u1 = -0.5 * r - 1e-12, g1 = g(u1);
    const double tol = 1e-12 * (std::fabs(g0) + std::fabs(g1)) + 1e-300;
    for (int it = 0; it < 40 && std::fabs(g1) > tol; ++it) {
      if (g1 == g0) break;
      const double u2 = u1 - g1 * (u1 - u0) / (g1 - g0);
      u0 = u1; g0 = g1;
      u1 = u2; g1 = g(u1);
    }
    return velocity_gradient(test_.path, r, u1);
  }

  M3 grad_v(const X& x, double r, bool plastic) const {
    return is_mixed(test_.path) ? solve_mixed(x, r, plastic) : velocity_gradient(test_.path, r, 0.0);
  }

  // Loading indicator and yield function at x for D (the frictional_rate's plastic test).
  void switch_functions(const X& x, const M3& D, double& f, double& load) const {
    if constexpr (kF) {
      const auto& fp = fpar(p_);
      const YieldState<double> y = yield_state<kLode>(fp, x.sf, x.eps_pd, x.e, D);
      f = y.f;
      const double de = (1.0 + x.e) * trace(D);
      load = ddot(y.n, apply_elastic(y.C, D)) - y.h * y.dGm_de * de;
    } else {
      f = -1;
      load = -1;
    }
  }

  bool plastic_at(const X& x, const M3& D) const {
    if constexpr (!kF) return false;
    if (cut_) return false;
    double f, load;
    switch_functions(x, D, f, load);
    return f >= -1e-6 && load >= 0;
  }

  // ---- output row -----------------------------------------------------------------------
  void record(ResultTable& out, double t, double r, const X& x, const M3& L) const {
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
                          x.s * x.s, collisional_share(deviatoric_q(sc), deviatoric_q(sf)), eta, x.eps_pd};
    (void)r;
    for (int i = 0; i < 22; ++i)
      if (!std::isfinite(row[i])) {
        std::ostringstream os;
        os.precision(10);
        os << "element test '" << test_.name << "': output '" << out.names[i] << "' = " << row[i]
           << " is not finite at t = " << t << " s; state: " << state_text(x);
        throw std::runtime_error(os.str());
      }
    for (int i = 0; i < 22; ++i) out.columns[i].push_back(row[i]);
  }

  // ---- packing -----------------------------------------------------------------------------
  void pack(const X& x, double* y) const {
    y[0] = x.sf(0, 0) / sigma_ref_; y[1] = x.sf(1, 1) / sigma_ref_; y[2] = x.sf(2, 2) / sigma_ref_;
    y[3] = x.sf(0, 1) / sigma_ref_; y[4] = x.sf(1, 2) / sigma_ref_; y[5] = x.sf(0, 2) / sigma_ref_;
    y[6] = x.eps_pd; y[7] = x.e; y[8] = x.s / s_ref_;
    y[9] = x.gamma; y[10] = x.eps_v; y[11] = x.eps_a;
  }
  X unpack(const double* y) const {
    X x;
    x.sf(0, 0) = y[0] * sigma_ref_; x.sf(1, 1) = y[1] * sigma_ref_; x.sf(2, 2) = y[2] * sigma_ref_;
    x.sf(0, 1) = x.sf(1, 0) = y[3] * sigma_ref_;
    x.sf(1, 2) = x.sf(2, 1) = y[4] * sigma_ref_;
    x.sf(0, 2) = x.sf(2, 0) = y[5] * sigma_ref_;
    x.eps_pd = y[6]; x.e = y[7]; x.s = y[8] * s_ref_;
    x.gamma = y[9]; x.eps_v = y[10]; x.eps_a = y[11];
    return x;
  }

  // ---- CVODE callbacks ---------------------------------------------------------------------
  static int rhs(realtype t, N_Vector yv, N_Vector ydot, void* ud) {
    auto* self = static_cast<Driver*>(ud);
    ++self->rhs_evals_;
    const X x = self->unpack(N_VGetArrayPointer(yv));
    double* yd = N_VGetArrayPointer(ydot);
    if (!(x.e > 0 && x.e < kVoidRatioMax) || !std::isfinite(x.s)) {  // recoverable: smaller step
      self->note_rhs_issue(t, "state " + inadmissible(x, -kInf) + "; " + state_text(x));
      return 1;
    }
    const double r = self->seg_.rate(t);
    const M3 L = self->grad_v(x, r, self->plastic_);
    X d = self->rates_for(x, L, self->plastic_);
    d.sf /= self->sigma_ref_;
    d.s /= self->s_ref_;
    self->pack_raw(d, yd);
    static const char* const kRateNames[kN] = {"dsigma_f_xx/dt", "dsigma_f_yy/dt", "dsigma_f_zz/dt", "dsigma_f_xy/dt",
                                               "dsigma_f_yz/dt", "dsigma_f_xz/dt", "deps_pd/dt",     "de/dt",
                                               "dsqrt(T)/dt",    "dgamma/dt",      "deps_v/dt",      "deps_a/dt"};
    for (int i = 0; i < kN; ++i)
      if (!std::isfinite(yd[i])) {
        self->note_rhs_issue(t, std::string("rate ") + kRateNames[i] + " = " + std::to_string(yd[i]) +
                                    " (non-finite) at " + state_text(x));
        return 1;
      }
    return 0;
  }
  void pack_raw(const X& d, double* y) const {
    y[0] = d.sf(0, 0); y[1] = d.sf(1, 1); y[2] = d.sf(2, 2);
    y[3] = d.sf(0, 1); y[4] = d.sf(1, 2); y[5] = d.sf(0, 2);
    y[6] = d.eps_pd; y[7] = d.e; y[8] = d.s;
    y[9] = d.gamma; y[10] = d.eps_v; y[11] = d.eps_a;
  }

  static int roots(realtype t, N_Vector yv, realtype* g, void* ud) {
    auto* self = static_cast<Driver*>(ud);
    const X x = self->unpack(N_VGetArrayPointer(yv));
    const double r = self->seg_.rate(t);
    const M3 L = self->grad_v(x, r, self->plastic_);
    double f, load;
    self->switch_functions(x, sym(L), f, load);
    g[0] = mean_pressure(x.sf) / self->sigma_ref_;
    // Offsets make a start exactly on a switch (f = 0 at a K0 state; load = 0 when shearing a
    // coaxial state) count as being on the safe side, so the crossing that follows is seen.
    g[1] = self->plastic_ ? load / (std::fabs(load) + 1.0) + 1e-10 : f - 1e-8;
    return 0;
  }

  // Projection onto the yield surface in plastic mode (CVODE's constrained-ODE projection).
  // The rate form keeps f constant only along the exact flow; BDF steps near the cone vertex
  // (eps_pd ~ 0, where H' = M_p / k_p is huge) leave f off zero by up to 7e-4 (Table 1,
  // e0 = 0.80, 100 kPa) and it then stays there, which changes the path (the dip of p_f ends
  // at zero instead of ~12 kPa). The correction below is the Newton step of the library's own
  // drift correction (the one the incremental update applies after each substep).
  static int project(realtype t, N_Vector yv, N_Vector corr, realtype, N_Vector, void* ud) {
    auto* self = static_cast<Driver*>(ud);
    double* c = N_VGetArrayPointer(corr);
    for (int i = 0; i < kN; ++i) c[i] = 0;
    if constexpr (kF) {
      if (!self->plastic_ || self->cut_) return 0;
      const double* y = N_VGetArrayPointer(yv);
      X x = self->unpack(y);
      if (!(mean_pressure(x.sf) > fpar(self->p_).p_min)) return 0;
      const M3 D = sym(velocity_gradient(self->test_.path, self->seg_.rate(t), 0.0));
      // Consistent (closest-point in the energy norm) correction along C^e m, the first branch
      // of the library's detail::correct_drift, applied unconditionally: correct_drift only
      // acts when |f| > ftol = 1e-9, and that switch made CVODE's step collapse at rtol 1e-10.
      // Not at the cone vertex (q_f ~ 0), where the deviatoric direction is undefined: there the
      // correction is ill-conditioned and made CVODE fail at t ~ 3e-15 s (Fig. 6, rtol 1e-12).
      if (!(deviatoric_q(x.sf) > 1e-6 * mean_pressure(x.sf))) return 0;
      for (int it = 0; it < 2; ++it) {
        const YieldState<double> yv = yield_state<kLode>(fpar(self->p_), x.sf, x.eps_pd, x.e, D);
        const M3 Cm = apply_elastic(yv.C, yv.m);
        const double denom = ddot(yv.n, Cm) + yv.Gm * yv.dh;
        if (!(denom > 0) || !std::isfinite(yv.f)) return 0;
        const double dL = yv.f / denom;
        x.sf -= dL * Cm;
        x.eps_pd += dL;
      }
      double yp[kN];
      self->pack(x, yp);
      for (int i = 0; i < 7; ++i) {
        if (!std::isfinite(yp[i])) {
          return 1;
        }
        c[i] = yp[i] - y[i];
      }
    }
    return 0;
  }

  // ---- runs ----------------------------------------------------------------------------------
  // Integrates from x over the given segments, recording rows at out_times (which must lie in
  // [segments.front().t0, segments.back().t1]).
  void run(X& x, const std::vector<Segment>& segs, const std::vector<double>& out_times, ResultTable& out,
           const ProgressCallback& progress) {
    if (test_.solver.kind == SolverKind::Cvode)
      run_cvode(x, segs, out_times, out, progress);
    else
      run_incremental(x, segs, out_times, out, progress);
  }

  void run_cvode(X& x, const std::vector<Segment>& segs, const std::vector<double>& out_times, ResultTable& out,
                 const ProgressCallback& progress) {
    struct Ctx {
      SUNContext ctx = nullptr;
      void* mem = nullptr;
      N_Vector y = nullptr;
      SUNMatrix A = nullptr;
      SUNLinearSolver LS = nullptr;
      ~Ctx() {
        if (LS) SUNLinSolFree(LS);
        if (A) SUNMatDestroy(A);
        if (y) N_VDestroy(y);
        if (mem) CVodeFree(&mem);
        if (ctx) SUNContext_Free(&ctx);
      }
    } c;
    if (SUNContext_Create(nullptr, &c.ctx) != 0) throw std::runtime_error("SUNContext_Create failed");
    c.y = N_VNew_Serial(kN, c.ctx);
    c.mem = CVodeCreate(CV_BDF, c.ctx);
    c.A = SUNDenseMatrix(kN, kN, c.ctx);
    c.LS = SUNLinSol_Dense(c.y, c.A, c.ctx);
    if (!c.y || !c.mem || !c.A || !c.LS) throw std::runtime_error("CVODE: allocation failed");
    CVodeSetErrHandlerFn(c.mem, [](int, const char*, const char*, char*, void*) {}, nullptr);  // errors thrown below
    double* y = N_VGetArrayPointer(c.y);

    double t = segs.front().t0;
    std::size_t k = 0;
    const double t_end = segs.back().t1;
    while (k < out_times.size() && out_times[k] <= t) {
      seg_ = segs.front();
      record(out, t, seg_.rate(t), x, grad_v(x, seg_.rate(t), plastic_));
      ++k;
    }
    bool first = true;
    double last_progress = 0;
    for (std::size_t si = 0; si < segs.size(); ++si) {
      seg_ = segs[si];
      bool restart = true;
      while (t < seg_.t1 * (1 - 1e-15) && (seg_.t1 - t) > 1e-15 * std::max(1.0, seg_.t1)) {
        if (restart) {
          const M3 L0 = grad_v(x, seg_.rate(t), false);
          plastic_ = plastic_at(x, sym(L0));
          pack(x, y);
          int flag = first ? CVodeInit(c.mem, rhs, t, c.y) : CVodeReInit(c.mem, t, c.y);
          if (first) {
            flag |= CVodeSetUserData(c.mem, this);
            flag |= CVodeSStolerances(c.mem, test_.solver.rtol, test_.solver.atol);
            flag |= CVodeSetLinearSolver(c.mem, c.LS, c.A);
            flag |= CVodeSetMaxNumSteps(c.mem, std::min<long>(test_.solver.max_steps, 2000000000L));
            flag |= CVodeSetNoInactiveRootWarn(c.mem);
            if constexpr (kF) {
              flag |= CVodeSetProjFn(c.mem, project);
              flag |= CVodeSetProjErrEst(c.mem, SUNFALSE);
            }
            first = false;
          } else {
            out.stats.steps += steps_since_init(c.mem);
          }
          flag |= CVodeRootInit(c.mem, (kF && !cut_) ? 2 : 0, (kF && !cut_) ? roots : nullptr);
          if (flag != 0) throw std::runtime_error("CVODE: set-up failed");
          restart = false;
        }
        const double t_next = (k < out_times.size() && out_times[k] < seg_.t1) ? out_times[k] : seg_.t1;
        CVodeSetStopTime(c.mem, t_next);
        double tret = t;
        const int flag = CVode(c.mem, t_next, c.y, &tret, CV_NORMAL);
        t = tret;
        x = unpack(y);
        if (flag < 0) {
          std::ostringstream os;
          os.precision(10);
          os << "CVODE failed (" << flag_name(flag) << ") at t = " << t << " s in test '"
             << test_.name << "': " << state_text(x);
          if (!rhs_issue_.empty() &&
              (flag == CV_RHSFUNC_FAIL || flag == CV_REPTD_RHSFUNC_ERR || flag == CV_FIRST_RHSFUNC_ERR ||
               flag == CV_UNREC_RHSFUNC_ERR || flag == CV_CONV_FAILURE || flag == CV_ERR_FAILURE))
            os << "; last rejected right-hand side: " << rhs_issue_;
          if (flag == CV_TOO_MUCH_WORK)
            os << " (more than test.max_steps = " << test_.solver.max_steps << " steps to the next output; raise it or loosen rtol)";
          throw std::runtime_error(os.str());
        }
        check_state(x, t, "CVODE");
        if (flag == CV_ROOT_RETURN) {
          ++out.stats.events;
          if (out.stats.events > 100000) throw std::runtime_error("element test: more than 100000 switch events (chattering) at t = " + std::to_string(t));
          int found[2] = {0, 0};
          CVodeGetRootInfo(c.mem, found);
          if (found[0] != 0 && mean_pressure(x.sf) <= 1e-6 * sigma_ref_) {
            cut_ = true;  // tension cut-off: the skeleton carries no stress from here on
            x.sf = M3::Zero();
            out.stats.tension_cutoff = true;
            out.stats.cutoff_time = t;
          }
          restart = true;
        }
        while (k < out_times.size() && out_times[k] <= t * (1 + 1e-14) + 1e-300) {
          record(out, out_times[k], seg_.rate(t), x, grad_v(x, seg_.rate(t), plastic_));
          ++k;
        }
        if (progress && t_end > 0 && t / t_end - last_progress > 0.02) {
          last_progress = t / t_end;
          progress(last_progress);
        }
      }
      // a kink or jump of the programme: restart
    }
    out.stats.steps += steps_since_init(c.mem);
    out.stats.rhs_evals = rhs_evals_;
    while (k < out_times.size()) {  // rounding at the very end
      record(out, out_times[k], seg_.rate(t), x, grad_v(x, seg_.rate(t), plastic_));
      ++k;
    }
  }

  // CVodeGetReturnFlagName returns a malloc'd string the caller must free (leak found by ASan).
  static std::string flag_name(int flag) {
    char* name = CVodeGetReturnFlagName(flag);
    const std::string s = name ? name : "flag " + std::to_string(flag);
    std::free(name);
    return s;
  }

  static long steps_since_init(void* mem) {
    long n = 0;
    CVodeGetNumSteps(mem, &n);
    return n;
  }

  // The MPM's update at a fixed step dt (shortened only to land on outputs and breakpoints).
  void run_incremental(X& x, const std::vector<Segment>& segs, const std::vector<double>& out_times,
                       ResultTable& out, const ProgressCallback& progress) {
    const double dt = test_.solver.dt;
    double t = segs.front().t0;
    const double t_end = segs.back().t1;
    std::size_t k = 0;
    auto st = to_state(x, static_cast<const Model*>(nullptr));
    M3 stress = M3::Zero();
    M3 L_last = velocity_gradient(test_.path, segs.front().rate(t), 0.0);
    seg_ = segs.front();
    while (k < out_times.size() && out_times[k] <= t) {
      record(out, t, seg_.rate(t), x, grad_v(x, seg_.rate(t), plastic_at(x, sym(L_last))));
      ++k;
    }
    double last_progress = 0;
    long steps = 0;
    const double target = is_mixed(test_.path) ? controlled_stress(x) : 0.0;
    for (const Segment& sg : segs) {
      seg_ = sg;
      while (sg.t1 - t > 1e-12 * dt) {
        double h = std::min(dt, sg.t1 - t);
        if (k < out_times.size() && out_times[k] > t && out_times[k] - t < h) h = out_times[k] - t;
        if (sg.t1 - t - h < 1e-9 * dt) h = sg.t1 - t;
        const double r = sg.rate(t + 0.5 * h);
        if (++steps > test_.solver.max_steps)
          throw std::runtime_error("incremental update: more than test.max_steps = " +
                                   std::to_string(test_.solver.max_steps) + " steps, at t = " + std::to_string(t) +
                                   " s of " + std::to_string(t_end) + " s (raise max_steps or dt)");
        auto try_step = [&](double u, decltype(st)& trial) {
          trial = st;
          const M3 L = velocity_gradient(test_.path, r, u);
          ++rhs_evals_;
          return std::make_pair(Model::update(p_, trial, L, h, stress), L);
        };
        decltype(st) trial = st;
        UpdateInfo inf;
        M3 L;
        if (!is_mixed(test_.path)) {
          std::tie(inf, L) = try_step(0.0, trial);
        } else {
          // secant on u so that the controlled stress after the step equals its initial value
          auto resid = [&](double u) {
            auto pr = try_step(u, trial);
            X xt = x;
            from_state(xt, trial);
            inf = pr.first;
            L = pr.second;
            return inf.ok() ? controlled_stress(xt) - target : std::numeric_limits<double>::quiet_NaN();
          };
          double u0 = 0, g0 = resid(u0);
          double u1 = -0.5 * r - 1e-12, g1 = resid(u1);
          for (int it = 0; it < 40 && std::isfinite(g1) && std::fabs(g1) > 1e-10 * sigma_ref_; ++it) {
            if (g1 == g0) break;
            const double u2 = u1 - g1 * (u1 - u0) / (g1 - g0);
            u0 = u1; g0 = g1;
            u1 = u2; g1 = resid(u1);
          }
        }
        if (!inf.ok()) {
          std::ostringstream os;
          os.precision(10);
          os << "incremental update failed (" << update_flags_text(inf.flags) << ") at t = " << t << " s, dt = " << h
             << " in test '" << test_.name << "': " << state_text(x);
          throw std::runtime_error(os.str());
        }
        if (inf.flags & info::kTensionCutoff) {
          if (!out.stats.tension_cutoff) out.stats.cutoff_time = t + h;
          out.stats.tension_cutoff = true;
        }
        st = trial;
        from_state(x, st);
        const M3 D = sym(L);
        x.gamma += h * (is_shear(test_.path) ? L(0, 1) : D(0, 0) - D(1, 1));
        x.eps_v += -h * trace(D);
        x.eps_a += -h * D(1, 1);
        t += h;
        L_last = L;
        check_state(x, t, "incremental update");
        while (k < out_times.size() && out_times[k] <= t + 1e-12 * dt) {
          // Outputs use D at the output time (the step itself used the midpoint rate, which
          // makes the temperature update second order for a varying rate).
          record(out, out_times[k], r, x,
                 is_mixed(test_.path) ? L : velocity_gradient(test_.path, sg.rate(t), 0.0));
          ++k;
        }
        if (progress && t / t_end - last_progress > 0.02) {
          last_progress = t / t_end;
          progress(last_progress);
        }
      }
    }
    out.stats.steps += steps;
    out.stats.rhs_evals = rhs_evals_;
    while (k < out_times.size()) {
      record(out, out_times[k], seg_.rate(t), x, L_last);
      ++k;
    }
  }

  void reset_mode() { cut_ = false; plastic_ = false; }

  // Throws when x is non-finite or inadmissible, naming the time, the quantity and its value.
  void check_state(const X& x, double t, const char* solver) const {
    const double floor = (kF && !cut_) ? -std::max(1e-3 * sigma_ref_, 1e-6) : -kInf;
    const double s_floor = -10.0 * test_.solver.atol * s_ref_;
    const std::string issue = inadmissible(x, floor, s_floor);
    if (issue.empty()) return;
    std::ostringstream os;
    os.precision(10);
    os << "element test '" << test_.name << "': " << solver << " reached an inadmissible state at t = " << t
       << " s: " << issue << "; state: " << state_text(x);
    throw std::runtime_error(os.str());
  }

  void note_rhs_issue(double t, const std::string& what) {
    std::ostringstream os;
    os.precision(10);
    os << "t = " << t << " s: " << what;
    rhs_issue_ = os.str();
  }

 private:
  const ElementTest& test_;
  const P& p_;
  const io::ParameterSet& set_;
  double sigma_ref_ = 1, s_ref_ = 1;
  Segment seg_{0, 1, 0, 0};
  bool plastic_ = false;
  bool cut_ = false;
  long rhs_evals_ = 0;
  std::string rhs_issue_;  // why the right-hand side last returned a recoverable error
};

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
ResultTable run_model(const ElementTest& test, const typename Model::Params& p, const io::ParameterSet& set,
                      const ProgressCallback& progress) {
  ResultTable out;
  out.names = result_column_names();
  out.columns.assign(out.names.size(), {});
  const double c0 = cpu_now();
  const RateProgramme& g = test.programme;
  if (g.kind != ProgrammeKind::Sweep) {
    const std::vector<Segment> segs = segments_of(g);
    if (segs.empty()) throw io::InputError(io::where(test.file) + "the rate programme has no time span");
    Driver<Model> drv(test, p, set);
    X x = drv.initial_state();
    drv.run(x, segs, output_times(test.output, segs.front().t0, segs.back().t1), out, progress);
  } else {
    if (g.sweep_rates.empty()) throw io::InputError(io::where(test.file) + "the sweep has no rates");
    ResultTable one;
    one.names = out.names;
    std::size_t i = 0;
    for (double r : g.sweep_rates) {
      if (!(r > 0)) throw io::InputError(io::where(test.file) + "sweep rates must be > 0");
      one.columns.assign(out.names.size(), {});
      Driver<Model> drv(test, p, set);
      X x = drv.initial_state();
      const Segment s{0.0, g.sweep_strain / r, r, r};
      drv.run(x, {s}, {s.t1}, one, {});
      for (std::size_t c = 0; c < out.columns.size(); ++c) out.columns[c].push_back(one.columns[c].back());
      out.stats.rhs_evals += one.stats.rhs_evals;
      out.stats.steps += one.stats.steps;
      out.stats.events += one.stats.events;
      out.stats.vs_clamped += one.stats.vs_clamped;
      out.stats.tension_cutoff = out.stats.tension_cutoff || one.stats.tension_cutoff;
      one.stats = RunStats{};
      if (progress) progress(double(++i) / g.sweep_rates.size());
    }
  }
  out.stats.cpu_seconds = cpu_now() - c0;
  return out;
}

void check_test(const ElementTest& t) {
  const std::string w = io::where(t.file);
  const auto& g = t.programme;
  if (g.kind != ProgrammeKind::Sweep && !(g.duration > 0)) throw io::InputError(w + "duration must be > 0");
  if (g.kind == ProgrammeKind::Sweep && !(g.sweep_strain > 0)) throw io::InputError(w + "sweep_strain must be > 0");
  if (t.solver.kind == SolverKind::Cvode && !(t.solver.rtol > 0 && t.solver.atol > 0))
    throw io::InputError(w + "rtol and atol must be > 0");
  if (t.solver.kind == SolverKind::Incremental && !(t.solver.dt > 0)) throw io::InputError(w + "dt must be > 0");
  if (!(t.initial.sigma_v0 > 0)) throw io::InputError(w + "sigma_v0 must be > 0");
  if (g.rate < 0) throw io::InputError(w + "rate must be >= 0");
}

}  // namespace

ResultTable run_element_test(const ElementTest& test, const io::ParameterSet& set, const ProgressCallback& progress) {
  check_test(test);
  {
    // The test's e0 against the set's V_sd: the message names the test file (where e0 is set).
    io::ParameterSet named = set;
    if (!test.file.empty()) named.file = test.file;
    io::check_initial_void_ratio(named, test.initial.e0,
                                 "'test.e0'" + (set.file.empty() ? std::string() : " (V_sd from " + set.file + ")"));
  }
  ModelChoice m = test.model;
  if (m == ModelChoice::Auto)
    m = set.has_frictional() && set.has_collisional() ? ModelChoice::PhaseTransition
        : set.has_frictional()                        ? ModelChoice::Frictional
                                                      : ModelChoice::Collisional;
  const std::string w = io::where(test.file.empty() ? set.file : test.file);
  switch (m) {
    case ModelChoice::Frictional:
      if (!set.has_frictional()) throw io::InputError(w + "model 'frictional' needs a [frictional] table in " + set.file);
      return run_model<FrictionalModel<double>>(test, *set.frictional, set, progress);
    case ModelChoice::Collisional:
      if (!set.has_collisional())
        throw io::InputError(w + "model 'collisional' needs a [collisional] table in " + set.file);
      return run_model<CollisionalModel<double>>(test, *set.collisional, set, progress);
    default: {
      const PhaseTransitionParams<double> p = set.phase_transition();
      return run_model<PhaseTransitionModel<double>>(test, p, set, progress);
    }
  }
  throw io::InputError(w + "unsupported model choice");
}

}  // namespace granflow::elementtest
