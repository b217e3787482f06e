// Element-test driver: the state of one material point as an ODE system in time.
//
//   y = [sigma_f (xx yy zz xy yz xz) / sigma_ref, eps_pd, e, s / s_ref, gamma, eps_v, eps_a, eps_xx, eps_zz]
//
// dsigma_f/dt = frictional_rate (library, unchanged) + W sigma_f - sigma_f W   (Jaumann, MODEL 3.1)
// deps_pd/dt  = plastic multiplier rate (library)
// de/dt       = (1 + e) tr D                                                   (MODEL 3.7)
// ds/dt       = sqrt_temperature_rate(temperature_balance(...), s)              (MODEL 5.2)
//
// The right-hand side is piecewise smooth. The driver is a hybrid system: a mode flag (elastic or
// plastic) is held fixed between events and CVODE's root finding locates the switches (yield
// onset f = 0 in elastic mode, or loading again where elastic mode began outside the surface;
// the loading indicator n:C:D - h dGm/de de = 0 in plastic mode) and the tension cut-off p_f = 0,
// after which sigma_f stays 0 (MODEL 3.2 A5, 3.6 "Switches").
// Rate-programme breakpoints (end of the hold phase, table nodes, jumps) are stop times with a
// restart, so no step straddles a kink.
//
// Driver<Model> holds the point's rates, switch functions and guards (this header); its members
// are defined by responsibility in loading_paths.cpp (mixed control), cvode_integration.cpp,
// incremental_solver.cpp and output_rows.cpp, each instantiated there for the three models.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <granflow/constitutive.hpp>

#include "granflow/elementtest/run.hpp"
#include "guards.hpp"
#include "loading_paths.hpp"
#include "rate_programme.hpp"

namespace granflow::elementtest::detail {

using M3 = Mat3<double>;
inline constexpr LodeShape kLode = LodeShape::SmoothMohrCoulomb;
inline constexpr double kInf = std::numeric_limits<double>::infinity();
inline constexpr int kN = 14;  // ODE size

// ---- parameter access per model ---------------------------------------------------------
inline const FrictionalParams<double>& fpar(const FrictionalParams<double>& p) { return p; }
inline const FrictionalParams<double>& fpar(const PhaseTransitionParams<double>& p) { return p.f; }
inline const CollisionalParams<double>& cpar(const CollisionalParams<double>& p) { return p; }
inline const CollisionalParams<double>& cpar(const PhaseTransitionParams<double>& p) { return p.c; }

// ---- element state -------------------------------------------------------------------------
struct ElementState {
  M3 sf = M3::Zero();
  double eps_pd = 0, e = 0, s = 0;
  double gamma = 0, eps_v = 0, eps_a = 0;
  double eps_xx = 0, eps_zz = 0;  // lateral strains, compression positive (radial on axial paths)
};

// Model-state conversions (the incremental update works on the library's own State types).
inline FrictionalState<double> to_state(const ElementState& x, const FrictionalModel<double>*) {
  return {x.sf, x.eps_pd, x.e};
}
inline CollisionalState<double> to_state(const ElementState& x, const CollisionalModel<double>*) { return {x.e, x.s}; }
inline PhaseTransitionModel<double>::State to_state(const ElementState& x, const PhaseTransitionModel<double>*) {
  PhaseTransitionModel<double>::State st;
  st.sigma_f = x.sf;
  st.eps_pd = x.eps_pd;
  st.e = x.e;
  st.s = x.s;
  return st;
}
inline void from_state(ElementState& x, const FrictionalState<double>& st) {
  x.sf = st.sigma;
  x.eps_pd = st.eps_pd;
  x.e = st.e;
}
inline void from_state(ElementState& x, const CollisionalState<double>& st) {
  x.e = st.e;
  x.s = st.s;
}
inline void from_state(ElementState& x, const PhaseTransitionModel<double>::State& st) {
  x.sf = st.sigma_f;
  x.eps_pd = st.eps_pd;
  x.e = st.e;
  x.s = st.s;
}

inline std::string state_text(const ElementState& x) {
  std::ostringstream os;
  os.precision(6);
  os << "p_f = " << mean_pressure(x.sf) << " Pa, q_f = " << deviatoric_q(x.sf) << " Pa, e = " << x.e
     << ", T = " << x.s * x.s << " m2/s2, eps_pd = " << x.eps_pd << ", gamma = " << x.gamma;
  return os.str();
}

// ---- numerical guards (guards.hpp) ------------------------------------------------------------
inline std::string inadmissible(const ElementState& x, double p_floor, double s_floor = 0.0) {
  return inadmissible_state(x.sf, x.eps_pd, x.e, x.s, x.gamma, x.eps_v, x.eps_a, p_floor, s_floor);
}

// The CVODE right-hand side, root and projection functions (cvode_integration.cpp).
template <class Model>
struct CvodeCallbacks;

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

  ElementState initial_state() const {
    ElementState x;
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
  // Rates for a given velocity gradient; `plastic` selects the mode (ftol_load = +-inf).
  ElementState rates_for(const ElementState& x, const M3& L, bool plastic) const {
    ElementState d;
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
      d.s = sqrt_temperature_rate(temperature_balance(c, kc, D, x.s), x.s);
    }
    d.gamma = is_shear(test_.path) ? L(0, 1) : D(0, 0) - D(1, 1);
    d.eps_v = -trace(D);
    d.eps_a = -D(1, 1);
    d.eps_xx = -D(0, 0);
    d.eps_zz = -D(2, 2);
    return d;
  }

  // Stress control (a Data programme with control = "stress", oedometric): the axial strain rate
  // is the unknown of the mixed control and the programme rate r is d sigma_a/dt.
  bool stress_control() const {
    return test_.programme.kind == ProgrammeKind::Data && test_.programme.control == Control::Stress;
  }
  bool mixed() const { return is_mixed(test_.path) || stress_control(); }
  // Velocity gradient for control rate r and mixed-control unknown u.
  M3 L_of(double r, double u) const {
    if (stress_control()) {
      M3 L = M3::Zero();
      L(1, 1) = u;
      return L;
    }
    return velocity_gradient(test_.path, r, u);
  }
  // Rate of the controlled stress the mixed control must produce (0: held constant).
  double controlled_target_rate(double r) const { return stress_control() ? -r : 0.0; }

  // Mixed control (loading_paths.cpp).
  double controlled_stress(const ElementState& x) const;
  double controlled_rate(const ElementState& x, const ElementState& d) const;
  M3 solve_mixed(const ElementState& x, double r, bool plastic) const;
  M3 grad_v(const ElementState& x, double r, bool plastic) const;

  // Loading indicator and yield function at x for D (the frictional_rate's plastic test).
  void switch_functions(const ElementState& x, const M3& D, double& f, double& load) const {
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

  bool plastic_at(const ElementState& x, const M3& D) const {
    if constexpr (!kF) return false;
    if (cut_) return false;
    double f, load;
    switch_functions(x, D, f, load);
    return f >= -1e-6 && load >= 0;
  }

  // ---- output row (output_rows.cpp) ------------------------------------------------------
  void record(ResultTable& out, double t, double r, const ElementState& x, const M3& L) const;

  // ---- packing -----------------------------------------------------------------------------
  void pack(const ElementState& x, double* y) const {
    y[0] = x.sf(0, 0) / sigma_ref_; y[1] = x.sf(1, 1) / sigma_ref_; y[2] = x.sf(2, 2) / sigma_ref_;
    y[3] = x.sf(0, 1) / sigma_ref_; y[4] = x.sf(1, 2) / sigma_ref_; y[5] = x.sf(0, 2) / sigma_ref_;
    y[6] = x.eps_pd; y[7] = x.e; y[8] = x.s / s_ref_;
    y[9] = x.gamma; y[10] = x.eps_v; y[11] = x.eps_a;
    y[12] = x.eps_xx; y[13] = x.eps_zz;
  }
  ElementState unpack(const double* y) const {
    ElementState x;
    x.sf(0, 0) = y[0] * sigma_ref_; x.sf(1, 1) = y[1] * sigma_ref_; x.sf(2, 2) = y[2] * sigma_ref_;
    x.sf(0, 1) = x.sf(1, 0) = y[3] * sigma_ref_;
    x.sf(1, 2) = x.sf(2, 1) = y[4] * sigma_ref_;
    x.sf(0, 2) = x.sf(2, 0) = y[5] * sigma_ref_;
    x.eps_pd = y[6]; x.e = y[7]; x.s = y[8] * s_ref_;
    x.gamma = y[9]; x.eps_v = y[10]; x.eps_a = y[11];
    x.eps_xx = y[12]; x.eps_zz = y[13];
    return x;
  }
  void pack_raw(const ElementState& d, double* y) const {
    y[0] = d.sf(0, 0); y[1] = d.sf(1, 1); y[2] = d.sf(2, 2);
    y[3] = d.sf(0, 1); y[4] = d.sf(1, 2); y[5] = d.sf(0, 2);
    y[6] = d.eps_pd; y[7] = d.e; y[8] = d.s;
    y[9] = d.gamma; y[10] = d.eps_v; y[11] = d.eps_a;
    y[12] = d.eps_xx; y[13] = d.eps_zz;
  }

  // ---- runs ----------------------------------------------------------------------------------
  // Integrates from x over the given segments, recording rows at out_times (which must lie in
  // [segments.front().t0, segments.back().t1]).
  void run(ElementState& x, const std::vector<Segment>& segs, const std::vector<double>& out_times,
           ResultTable& out, const ProgressCallback& progress) {
    if (test_.solver.kind == SolverKind::Cvode)
      run_cvode(x, segs, out_times, out, progress);
    else
      run_incremental(x, segs, out_times, out, progress);
  }

  // CVODE with events and restarts (cvode_integration.cpp).
  void run_cvode(ElementState& x, const std::vector<Segment>& segs, const std::vector<double>& out_times,
                 ResultTable& out, const ProgressCallback& progress);

  // The MPM's update at a fixed step dt (incremental_solver.cpp).
  void run_incremental(ElementState& x, const std::vector<Segment>& segs, const std::vector<double>& out_times,
                       ResultTable& out, const ProgressCallback& progress);

  // Throws when x is non-finite or inadmissible, naming the time, the quantity and its value.
  void check_state(const ElementState& x, double t, const char* solver) const {
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
  friend struct CvodeCallbacks<Model>;

  const ElementTest& test_;
  const P& p_;
  const io::ParameterSet& set_;
  double sigma_ref_ = 1, s_ref_ = 1;
  Segment seg_{0, 1, 0, 0};
  bool plastic_ = false;
  bool unloading_outside_ = false;  // elastic mode entered with f above the onset offset (load < 0)
  bool cut_ = false;
  long rhs_evals_ = 0;
  std::string rhs_issue_;  // why the right-hand side last returned a recoverable error
};

// Every source file defining members of Driver instantiates them for these models.
#define GRANFLOW_ELEMENT_DRIVER_MODELS(M) \
  M(FrictionalModel<double>)              \
  M(CollisionalModel<double>)             \
  M(PhaseTransitionModel<double>)

}  // namespace granflow::elementtest::detail
