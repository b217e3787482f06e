// Sampled CPU-twin runs of the MPM tests: a set-up's stages in spans, a callback per span, and
// the mean velocity of the material along a direction.
#pragma once

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include <granflow/mpm/kernels.hpp>
#include <granflow/mpm/runner.hpp>

namespace granflow::mpm::test {

// Runs the stages of a set-up in spans of `every` seconds (the spans carry the time, as the
// driver's do) and hands each state to `sample(frame, t, stage)`.
template <class F>
void run_sampled(const SceneSetup& su, double every, F&& sample) {
  auto r = make_cpu_runner(su);
  const long per = std::lround(every / su.scene.dt);
  Span span;
  span.dt = su.scene.dt;
  double t_end = 0;
  Frame fr;
  for (size_t si = 0; si < su.scene.stages.size(); ++si) {
    const Stage& st = su.scene.stages[si];
    r->set_stage(static_cast<int>(si), st.damping, st.flip.value_or(su.scene.flip));
    t_end += st.duration;
    while (span.t < t_end - 1e-9) {
      span.max_steps = per;
      const SpanResult res = r->advance_span(span);
      EXPECT_TRUE(res.ok) << "particle " << res.particle << ": " << status_field(res.status);
      if (!res.ok) return;
      span.t = res.t;
      r->frame(fr, false);
      sample(fr, res.t, static_cast<int>(si));
    }
  }
}

// Mean velocity of the material along `dir`, every `every` seconds through the stages.
struct Motion {
  std::vector<double> t, v;
  std::vector<Frame> stage_end;  // the state at the end of each stage
  Frame last;
};

inline Motion mean_motion(const SceneSetup& su, const std::vector<double>& dir, double every) {
  const std::vector<double>& m = su.particles.m;
  double M = 0;
  for (double x : m) M += x;
  Motion out;
  double t_end = su.scene.stages[0].duration;
  size_t stage = 0;
  run_sampled(su, every, [&](const Frame& f, double t, int si) {
    double p = 0;
    for (long i = 0; i < f.n; ++i)
      for (int d = 0; d < f.dim; ++d) p += m[i] * f.v[d * f.n + i] * dir[d];
    out.t.push_back(t);
    out.v.push_back(p / M);
    out.last = f;
    if (static_cast<size_t>(si) == stage && t >= t_end - 1e-9) {
      out.stage_end.push_back(f);
      if (++stage < su.scene.stages.size()) t_end += su.scene.stages[stage].duration;
    }
  });
  return out;
}

// Least-squares slope of v(t) over t0 <= t <= t1.
inline double fitted_rate(const Motion& mo, double t0, double t1) {
  double st = 0, sv = 0, stt = 0, stv = 0, n = 0;
  for (size_t k = 0; k < mo.t.size(); ++k) {
    if (mo.t[k] < t0 - 1e-9 || mo.t[k] > t1 + 1e-9) continue;
    st += mo.t[k];
    sv += mo.v[k];
    stt += mo.t[k] * mo.t[k];
    stv += mo.t[k] * mo.v[k];
    n += 1;
  }
  return (n * stv - st * sv) / (n * stt - st * st);
}

}  // namespace granflow::mpm::test
