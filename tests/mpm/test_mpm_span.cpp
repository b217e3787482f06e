// Spans of steps (Runner::advance_span and the driver's use of them), checked on the CPU twin.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include <granflow/mpm/driver.hpp>

#include "one_thread.hpp"

using namespace granflow;
using namespace granflow::mpm;

namespace {

void expect_same_state(const HostParticles& a, const HostParticles& b, const std::string& what) {
  EXPECT_EQ(a.x, b.x) << what;
  EXPECT_EQ(a.v, b.v) << what;
  EXPECT_EQ(a.sig, b.sig) << what;
  EXPECT_EQ(a.sigf, b.sigf) << what;
  EXPECT_EQ(a.L, b.L) << what;
  EXPECT_EQ(a.eps, b.eps) << what;
  EXPECT_EQ(a.e, b.e) << what;
  EXPECT_EQ(a.s, b.s) << what;
}

// The CI column on a 20 mm grid (200 points), short stages.
Scene tiny_column() {
  Scene sc = small_column_scene(ModelKind::PhaseTransition);
  sc.h = 0.02;
  sc.dt = 2e-4;
  sc.size = {0.60, 0.16};
  sc.stages[0].duration = 0.02;
  sc.stages[1].duration = 0.06;
  sc.output.times = {0.03};
  sc.output.series_dt = 0.01;
  return sc;
}

}  // namespace

TEST(MpmSpan, AdvanceEqualsRepeatedStepBitwise) {
  for (const bool vol_avg : {false, true}) {
    Scene sc = small_column_scene(ModelKind::PhaseTransition);
    sc.volumetric_averaging = vol_avg;
    const SceneSetup su = make_setup(sc);
    auto a = make_cpu_runner(su);
    auto b = make_cpu_runner(su);
    a->set_stage(1, 0.0, 0.99);
    b->set_stage(1, 0.0, 0.99);
    for (int s = 0; s < 25; ++s) ASSERT_TRUE(a->step(5e-5, false).ok);
    const StepResult r = b->advance(25, 5e-5);
    ASSERT_TRUE(r.ok);
    EXPECT_EQ(r.steps, 25);
    HostParticles ha, hb;
    a->download(ha);
    b->download(hb);
    expect_same_state(ha, hb, vol_avg ? "fixed, vol_avg" : "fixed");

    // adaptive span landing on t_land, against the same rules applied by hand
    Span sp;
    sp.max_steps = 30;
    sp.t = 0.01;
    sp.dt = 1e-5;
    sp.adaptive = true;
    sp.dt_max = 5e-5;
    sp.t_land = 0.01 + 7.3e-4;
    const SpanResult sr = b->advance_span(sp);
    double t = sp.t, dt = sp.dt;
    long steps = 0;
    for (; steps < sp.max_steps; ++steps) {
      const double h = span_step_size(t, dt, sp.t_land);
      const StepResult st = a->step(h, true);
      ASSERT_TRUE(st.ok);
      t += h;
      dt = span_next_dt(st.dt_limit, sp.dt_max);
    }
    ASSERT_TRUE(sr.ok);
    EXPECT_EQ(sr.steps, steps);
    EXPECT_EQ(sr.t, t);
    EXPECT_EQ(sr.dt, dt);
    a->download(ha);
    b->download(hb);
    expect_same_state(ha, hb, "adaptive");
  }
}

TEST(MpmSpan, SpanStopsAtTUntilAndLandsOnTLand) {
  const SceneSetup su = make_setup(small_column_scene(ModelKind::Frictional));
  auto r = make_cpu_runner(su);
  Span sp;
  sp.max_steps = 1000;
  sp.dt = 1e-4;
  sp.t_land = 1.05e-3;  // 10 steps of 1e-4, then one of 5e-5 lands on it
  sp.t_until = 1.05e-3 - 1e-12;
  const SpanResult s = r->advance_span(sp);
  ASSERT_TRUE(s.ok);
  EXPECT_EQ(s.steps, 11);
  EXPECT_NEAR(s.t, 1.05e-3, 1e-18);
  EXPECT_NEAR(s.h_last, 5e-5, 1e-15);
  EXPECT_EQ(s.dt, 1e-4);  // fixed step: unchanged for the next span
}

// The driver queues spans between its events; with one step per span it is the old
// step-by-step loop. Both give the same steps, samples, frames and final state, bitwise.
TEST(MpmSpan, RunInSpansEqualsRunStepByStep) {
  struct Case {
    const char* name;
    bool adaptive;
    double stop_after;
  };
  for (const Case c : {Case{"fixed", false, -1.0}, Case{"adaptive", true, -1.0}, Case{"stop-after", false, 0.047}}) {
    Scene sc = tiny_column();
    sc.adaptive = c.adaptive;
    const SceneSetup su = make_setup(sc);
    RunSummary s[2];
    HostParticles hp[2];
    for (int k = 0; k < 2; ++k) {
      auto r = make_cpu_runner(su);
      RunOptions o;
      o.progress = false;
      o.stop_after = c.stop_after;
      o.max_span = k == 0 ? 1 : 10000;
      s[k] = run(su, *r, o);
      ASSERT_TRUE(s[k].ok) << s[k].message;
      r->download(hp[k]);
    }
    EXPECT_EQ(s[0].steps, s[1].steps) << c.name;
    EXPECT_EQ(s[0].t_end, s[1].t_end) << c.name;
    ASSERT_EQ(s[0].series.size(), s[1].series.size()) << c.name;
    for (size_t i = 0; i < s[0].series.size(); ++i) {
      EXPECT_EQ(s[0].series[i].t, s[1].series[i].t) << c.name;
      EXPECT_EQ(s[0].series[i].m.runout, s[1].series[i].m.runout) << c.name;
      EXPECT_EQ(s[0].series[i].m.kinetic_energy, s[1].series[i].m.kinetic_energy) << c.name;
    }
    ASSERT_EQ(s[0].tracks.size(), s[1].tracks.size()) << c.name;
    for (size_t i = 0; i < s[0].tracks.size(); ++i) {
      EXPECT_EQ(s[0].tracks[i].x, s[1].tracks[i].x) << c.name;
      EXPECT_EQ(s[0].tracks[i].p, s[1].tracks[i].p) << c.name;
    }
    expect_same_state(hp[0], hp[1], c.name);
    if (c.stop_after > 0) EXPECT_LT(s[1].t_end, 0.047 + sc.dt);
  }
}

TEST(MpmSpan, FailureInASpanIsReportedAsStepByStep) {
  // a block without walls falls out of the grid: same particle, step, time and message
  Scene sc = tiny_column();
  sc.walls.clear();
  for (auto& st : sc.stages) st.gate.reset();
  sc.stages[1].duration = 0.5;
  const SceneSetup su = make_setup(sc);
  RunSummary s[2];
  for (int k = 0; k < 2; ++k) {
    auto r = make_cpu_runner(su);
    RunOptions o;
    o.progress = false;
    o.max_span = k == 0 ? 1 : 10000;
    s[k] = run(su, *r, o);
  }
  ASSERT_FALSE(s[0].ok);
  ASSERT_FALSE(s[1].ok);
  EXPECT_EQ(s[0].message, s[1].message);
  EXPECT_EQ(s[0].steps, s[1].steps);
  EXPECT_NE(s[1].message.find("left the grid"), std::string::npos) << s[1].message;
}
