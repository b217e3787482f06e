// CVODE integration of the element driver (BDF, dense direct solver, difference-quotient
// Jacobian): the right-hand side, the switch functions as roots, the projection onto the yield
// surface, and the run loop with its events and restarts (element_driver.hpp has the overview).
#include <cvode/cvode.h>
#include <cvode/cvode_proj.h>
#include <nvector/nvector_serial.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <cstdlib>

#include "element_driver.hpp"

namespace granflow::elementtest::detail {

namespace {

// CVodeGetReturnFlagName returns a malloc'd string the caller must free (leak found by ASan).
std::string flag_name(int flag) {
  char* name = CVodeGetReturnFlagName(flag);
  const std::string s = name ? name : "flag " + std::to_string(flag);
  std::free(name);
  return s;
}

long steps_since_init(void* mem) {
  long n = 0;
  CVodeGetNumSteps(mem, &n);
  return n;
}

}  // namespace

// Static members, so CVODE can call them with the driver as user data.
template <class Model>
struct CvodeCallbacks {
  using Driver = detail::Driver<Model>;
  static constexpr bool kF = Driver::kF;

  static int rhs(realtype t, N_Vector yv, N_Vector ydot, void* ud) {
    auto* self = static_cast<Driver*>(ud);
    ++self->rhs_evals_;
    const ElementState x = self->unpack(N_VGetArrayPointer(yv));
    double* yd = N_VGetArrayPointer(ydot);
    if (!(x.e > 0 && x.e < kVoidRatioMax) || !std::isfinite(x.s)) {  // recoverable: smaller step
      self->note_rhs_issue(t, "state " + inadmissible(x, -kInf) + "; " + state_text(x));
      return 1;
    }
    const double r = self->seg_.rate(t);
    const M3 L = self->grad_v(x, r, self->plastic_);
    ElementState d = self->rates_for(x, L, self->plastic_);
    d.sf /= self->sigma_ref_;
    d.s /= self->s_ref_;
    self->pack_raw(d, yd);
    static const char* const kRateNames[kN] = {"dsigma_f_xx/dt", "dsigma_f_yy/dt", "dsigma_f_zz/dt", "dsigma_f_xy/dt",
                                               "dsigma_f_yz/dt", "dsigma_f_xz/dt", "deps_pd/dt",     "de/dt",
                                               "dsqrt(T)/dt",    "dgamma/dt",      "deps_v/dt",      "deps_a/dt",
                                               "deps_xx/dt",     "deps_zz/dt"};
    for (int i = 0; i < kN; ++i)
      if (!std::isfinite(yd[i])) {
        self->note_rhs_issue(t, std::string("rate ") + kRateNames[i] + " = " + std::to_string(yd[i]) +
                                    " (non-finite) at " + state_text(x));
        return 1;
      }
    return 0;
  }

  static int roots(realtype t, N_Vector yv, realtype* g, void* ud) {
    auto* self = static_cast<Driver*>(ud);
    const ElementState x = self->unpack(N_VGetArrayPointer(yv));
    const double r = self->seg_.rate(t);
    const M3 L = self->grad_v(x, r, self->plastic_);
    double f, load;
    self->switch_functions(x, sym(L), f, load);
    g[0] = mean_pressure(x.sf) / self->sigma_ref_;
    // Offsets make a start exactly on a switch (f = 0 at a K0 state; load = 0 when shearing a
    // coaxial state) count as being on the safe side, so the crossing that follows is seen.
    // Elastic mode entered outside the surface (unloading_outside_) has no f crossing ahead:
    // loading again (load > 0) is its switch back to plastic.
    if (self->plastic_)
      g[1] = load / (std::fabs(load) + 1.0) + 1e-10;
    else if (self->unloading_outside_)
      g[1] = load / (std::fabs(load) + 1.0) - 1e-10;
    else
      g[1] = f - 1e-8;
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
      ElementState x = self->unpack(y);
      if (!(mean_pressure(x.sf) > fpar(self->p_).p_min)) return 0;
      const double r = self->seg_.rate(t);
      const M3 D = sym(self->stress_control() ? self->grad_v(x, r, true) : velocity_gradient(self->test_.path, r, 0.0));
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
};

template <class Model>
void Driver<Model>::run_cvode(ElementState& x, const std::vector<Segment>& segs, const std::vector<double>& out_times,
                              ResultTable& out, const ProgressCallback& progress) {
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
  // Chattering: the mode switching back and forth without progress in time (no consistent
  // mode, e.g. stress control where the law softens) is an error: 1000 switches within 1e-4 of the run.
  double chatter_t = t;
  long chatter_n = 0;
  const double chatter_span = 1e-4 * std::max(t_end - t, 1e-300);
  for (std::size_t si = 0; si < segs.size(); ++si) {
    seg_ = segs[si];
    bool restart = true;
    while (t < seg_.t1 * (1 - 1e-15) && (seg_.t1 - t) > 1e-15 * std::max(1.0, seg_.t1)) {
      if (restart) {
        const M3 L0 = grad_v(x, seg_.rate(t), false);
        plastic_ = plastic_at(x, sym(L0));
        // A plastic phase can end (load = 0) with f above the onset offset where the cone is
        // narrower than CVODE's stress tolerance (rtol sigma_ref) and q_f <= 1e-6 p_f, which
        // the projection skips. The onset root f - 1e-8 would start positive there and never
        // change sign: CVODE integrated elastically through the surface (issue 21, Fig. 4 with
        // phi_c = 1e-6 deg: q_f = 7.4e13 Pa at p_f = 1e5 Pa).
        unloading_outside_ = false;
        if (!plastic_ && kF && !cut_) {
          double f, load;
          switch_functions(x, sym(L0), f, load);
          unloading_outside_ = f - 1e-8 >= 0;
        }
        pack(x, y);
        int flag = first ? CVodeInit(c.mem, CvodeCallbacks<Model>::rhs, t, c.y) : CVodeReInit(c.mem, t, c.y);
        if (first) {
          flag |= CVodeSetUserData(c.mem, this);
          flag |= CVodeSStolerances(c.mem, test_.solver.rtol, test_.solver.atol);
          flag |= CVodeSetLinearSolver(c.mem, c.LS, c.A);
          flag |= CVodeSetMaxNumSteps(c.mem, std::min<long>(test_.solver.max_steps, 2000000000L));
          flag |= CVodeSetNoInactiveRootWarn(c.mem);
          // More than CVODE's default 10 nonlinear-solver failures in one step before giving up:
          // the narrow cone of test NarrowConeStaysOnTheSurfaceUnderCvodeAndIncremental
          // (phi_c = 1e-6 deg, nu = -0.999999) needed 11-20 step reductions after rounding-level
          // changes of the rate. A run that converges within 10 is unchanged.
          flag |= CVodeSetMaxConvFails(c.mem, 100);
          if constexpr (kF) {
            flag |= CVodeSetProjFn(c.mem, CvodeCallbacks<Model>::project);
            flag |= CVodeSetProjErrEst(c.mem, SUNFALSE);
          }
          first = false;
        } else {
          out.stats.steps += steps_since_init(c.mem);
        }
        flag |= CVodeRootInit(c.mem, (kF && !cut_) ? 2 : 0, (kF && !cut_) ? CvodeCallbacks<Model>::roots : nullptr);
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
        if (t - chatter_t > chatter_span) {
          chatter_t = t;
          chatter_n = 0;
        } else if (++chatter_n > 1000) {
          std::ostringstream os;
          os.precision(10);
          os << "element test '" << test_.name << "': the elastic/plastic mode switched 1000 times within 1e-4 of the run at t = "
             << t << " s (no consistent mode: e.g. stress control of a softening state); state: " << state_text(x);
          throw std::runtime_error(os.str());
        }
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

#define GRANFLOW_INSTANTIATE(Model)                                                                      \
  template void Driver<Model>::run_cvode(ElementState&, const std::vector<Segment>&, const std::vector<double>&, \
                                         ResultTable&, const ProgressCallback&);
GRANFLOW_ELEMENT_DRIVER_MODELS(GRANFLOW_INSTANTIATE)
#undef GRANFLOW_INSTANTIATE

}  // namespace granflow::elementtest::detail
