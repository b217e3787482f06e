// The element driver's incremental solver: the MPM's own update (Model::update) at a fixed step,
// so that update can be measured against the CVODE solution of the same test.
#include <tuple>
#include <utility>

#include "element_driver.hpp"

namespace granflow::elementtest::detail {

namespace {

// SolverSettings::material_update on the model's state (x supplies what the model lacks).
template <class Model>
UpdateInfo external_update(const MaterialUpdate& update, const ElementState& x, typename Model::State& st,
                           const M3& L, double dt, M3& stress) {
  ElementState xs = x;
  from_state(xs, st);
  PointState ps;
  std::array<double, 9> l{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      ps.sigma_f[3 * i + j] = xs.sf(i, j);
      l[3 * i + j] = L(i, j);
    }
  ps.eps_pd = xs.eps_pd;
  ps.e = xs.e;
  ps.s = xs.s;
  UpdateInfo inf;
  inf.flags = update(ps, l, dt);
  if (!inf.ok()) return inf;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      xs.sf(i, j) = ps.sigma_f[3 * i + j];
      stress(i, j) = ps.stress[3 * i + j];
    }
  xs.eps_pd = ps.eps_pd;
  xs.e = ps.e;
  xs.s = ps.s;
  st = to_state(xs, static_cast<const Model*>(nullptr));
  return inf;
}

}  // namespace

// Steps of dt, shortened only to land on outputs and breakpoints.
template <class Model>
void Driver<Model>::run_incremental(ElementState& x, const std::vector<Segment>& segs,
                                    const std::vector<double>& out_times, ResultTable& out,
                                    const ProgressCallback& progress) {
  const double dt = test_.solver.dt;
  double t = segs.front().t0;
  const double t_end = segs.back().t1;
  std::size_t k = 0;
  auto st = to_state(x, static_cast<const Model*>(nullptr));
  M3 stress = M3::Zero();
  M3 L_last = L_of(segs.front().rate(t), 0.0);
  seg_ = segs.front();
  while (k < out_times.size() && out_times[k] <= t) {
    record(out, t, seg_.rate(t), x, grad_v(x, seg_.rate(t), plastic_at(x, sym(L_last))));
    ++k;
  }
  double last_progress = 0;
  long steps = 0;
  double target = mixed() ? controlled_stress(x) : 0.0;  // moves with the programme under stress control
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
        const M3 L = L_of(r, u);
        ++rhs_evals_;
        if (test_.solver.material_update) return std::make_pair(external_update<Model>(test_.solver.material_update, x, trial, L, h, stress), L);
        return std::make_pair(Model::update(p_, trial, L, h, stress), L);
      };
      decltype(st) trial = st;
      UpdateInfo inf;
      M3 L;
      if (!mixed()) {
        std::tie(inf, L) = try_step(0.0, trial);
      } else {
        // secant on u so that the controlled stress after the step equals its target (its
        // initial value, or under stress control the programme's stress at t + h; the rate is
        // constant within a Data segment, so h r is exact)
        const double step_target = target + h * controlled_target_rate(r);
        auto resid = [&](double u) {
          auto pr = try_step(u, trial);
          ElementState xt = x;
          from_state(xt, trial);
          inf = pr.first;
          L = pr.second;
          return inf.ok() ? controlled_stress(xt) - step_target : std::numeric_limits<double>::quiet_NaN();
        };
        double u0 = 0, u1 = -0.5 * r - 1e-12;
        if (stress_control()) {  // start from the tangent's strain rate (r is a stress rate here)
          u0 = solve_mixed(x, r, plastic_at(x, sym(L_last)))(1, 1);
          u1 = u0 * (1 + 1e-3) + (r > 0 ? -1e-12 : 1e-12);
        }
        double g0 = resid(u0), g1 = resid(u1);
        for (int it = 0; it < 40 && std::isfinite(g1) && std::fabs(g1) > 1e-10 * sigma_ref_; ++it) {
          if (g1 == g0) break;
          const double u2 = u1 - g1 * (u1 - u0) / (g1 - g0);
          u0 = u1; g0 = g1;
          u1 = u2; g1 = resid(u1);
        }
        target = step_target;
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
      x.eps_xx += -h * D(0, 0);
      x.eps_zz += -h * D(2, 2);
      t += h;
      L_last = L;
      check_state(x, t, "incremental update");
      while (k < out_times.size() && out_times[k] <= t + 1e-12 * dt) {
        // Outputs use D at the output time (the step itself used the midpoint rate, which
        // makes the temperature update second order for a varying rate).
        record(out, out_times[k], r, x,
               mixed() ? L : L_of(sg.rate(t), 0.0));
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

#define GRANFLOW_INSTANTIATE(Model)                                                                 \
  template void Driver<Model>::run_incremental(ElementState&, const std::vector<Segment>&,             \
                                               const std::vector<double>&, ResultTable&, const ProgressCallback&);
GRANFLOW_ELEMENT_DRIVER_MODELS(GRANFLOW_INSTANTIATE)
#undef GRANFLOW_INSTANTIATE

}  // namespace granflow::elementtest::detail
