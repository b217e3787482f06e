// The parallel sum of Eq. (1) and the diagnostics the figures plot.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <type_traits>

#include "random_states.hpp"
#include "reference.hpp"

using namespace granflow;
using PT = PhaseTransitionModel<double>;
using FO = FrictionalModel<double>;
using CO = CollisionalModel<double>;

TEST(PhaseTransition, FrictionalOnlyCarriesNoTemperature) {
  static_assert(!FO::kCollisional && FO::kFrictional);
  static_assert(CO::kCollisional && !CO::kFrictional);
  static_assert(sizeof(FO::State) < sizeof(PT::State));
  SUCCEED();
}

TEST(PhaseTransition, TotalStressIsTheSumOfTheParts) {
  const auto p = test::table3_collapse();
  PT::State pt;
  pt.sigma_f = test::isotropic(2000);
  pt.e = 0.95;
  pt.s = std::sqrt(1e-4);
  pt.eps_pd = 0.01;
  FO::State fo{pt.sigma_f, pt.eps_pd, pt.e};
  CO::State co{pt.e, pt.s};
  Mat3<double> L = test::simple_shear(5.0);
  L(1, 1) = -0.3;  // slight compaction
  const double dt = 1e-4;
  Mat3<double> s_pt, s_fo, s_co;
  ASSERT_TRUE(PT::update(p, pt, L, dt, s_pt).ok());
  ASSERT_TRUE(FO::update(p.f, fo, L, dt, s_fo).ok());
  ASSERT_TRUE(CO::update(p.c, co, L, dt, s_co).ok());
  EXPECT_LT((s_pt - (s_fo + s_co)).norm(), 1e-12 * s_pt.norm());
  EXPECT_DOUBLE_EQ(pt.e, fo.e);
  EXPECT_DOUBLE_EQ(pt.e, co.e);
  EXPECT_DOUBLE_EQ(pt.s, co.s);

  const auto d = PT::diagnostics(p, pt, sym(L));
  EXPECT_NEAR(d.p_f, mean_pressure(s_fo), 1e-9);
  EXPECT_NEAR(d.q_c, deviatoric_q(s_co), 1e-9 * (1 + d.q_c));
  EXPECT_NEAR(d.K_col, d.q_c / (d.q_c + d.q_f), 1e-15);
  EXPECT_NEAR(d.T, pt.s * pt.s, 1e-18);
  EXPECT_GT(d.eta_c, 0.0);
}

TEST(PhaseTransition, CollisionalShareGrowsWithShearRate) {
  // Liquefied skeleton aside, a fast-sheared element is collisional, a slow one frictional.
  const auto p = test::table3_collapse();
  auto share = [&](double rate) {
    PT::State st;
    st.sigma_f = test::isotropic(5000);
    st.e = 0.80;  // dense: the skeleton dilates and keeps its strength
    st.s = std::sqrt(1e-15);
    Mat3<double> sig;
    const double gamma_end = 0.05, dt = gamma_end / rate / 2000;
    for (int k = 0; k < 2000; ++k) EXPECT_TRUE(PT::update(p, st, test::simple_shear(rate), dt, sig).ok());
    return PT::diagnostics(p, st, sym(test::simple_shear(rate))).K_col;
  };
  const double slow = share(0.01), fast = share(1000.0);
  EXPECT_LT(slow, 0.01);
  EXPECT_GT(fast, slow);
}

TEST(PhaseTransition, PureSpinLeavesInvariantsAndCreatesNoStress) {
  const auto p = test::table3_collapse();
  PT::State st;
  st.sigma_f << -3000, 400, 0, 400, -2000, 0, 0, 0, -1500;
  st.eps_pd = 0.2;
  st.e = 0.95;
  st.s = 0.0;
  ASSERT_LT(yield_function<LodeShape::SmoothMohrCoulomb>(p.f, st.sigma_f, st.eps_pd, st.e), 0.0);
  const Mat3<double> s0 = st.sigma_f;
  Mat3<double> W = Mat3<double>::Zero();
  W(0, 1) = -3.0;
  W(1, 0) = 3.0;
  Mat3<double> sig;
  for (int k = 0; k < 100; ++k) ASSERT_TRUE(PT::update(p, st, W, 1e-3, sig).ok());
  EXPECT_NEAR(mean_pressure(sig), mean_pressure(s0), 1e-9);
  EXPECT_NEAR(deviatoric_q(sig), deviatoric_q(s0), 1e-9);
  EXPECT_EQ(st.s, 0.0);  // no deformation, no temperature
  PT::State zero;
  zero.e = 0.95;
  ASSERT_TRUE(PT::update(p, zero, W, 1e-3, sig).ok());
  EXPECT_EQ(sig.norm(), 0.0);
}

TEST(PhaseTransition, FailedUpdateLeavesTheStateUntouched) {
  const auto p = test::table3_collapse();
  PT::State st;
  st.sigma_f = test::isotropic(1000);
  st.e = 2.969;
  st.s = 0.1;
  const PT::State before = st;
  Mat3<double> L = Mat3<double>::Zero();
  L.diagonal().setConstant(10.0);  // strong expansion: e leaves its admissible range
  Mat3<double> sig = Mat3<double>::Zero();
  const auto inf = PT::update(p, st, L, 1e-2, sig);
  EXPECT_FALSE(inf.ok());
  EXPECT_EQ(st.e, before.e);
  EXPECT_EQ(st.s, before.s);
  EXPECT_EQ(st.sigma_f, before.sigma_f);
  st.s = -1.0;  // inadmissible temperature
  EXPECT_FALSE(PT::update(p, st, Mat3<double>::Zero(), 1e-3, sig).ok());
}

// A NaN or infinite input, or a negative eps_pd, is refused before the update starts by every
// model and integrator (state_check.hpp): it used to pass, a NaN stress as a tension cut-off.
template <class S>
void expect_refused(const char* what) {
  using M = Mat3<S>;
  const PhaseTransitionParams<S> p = params_cast<S>(test::table3_collapse());
  const S nan = std::numeric_limits<S>::quiet_NaN(), inf = std::numeric_limits<S>::infinity();
  struct Fault {
    const char* name;
    int field;  // 0 sigma_f(i, j), 1 eps_pd, 2 s
    int i, j;
    S value;
  };
  const Fault faults[] = {{"sigma_f(0,0) nan", 0, 0, 0, nan}, {"sigma_f(1,2) inf", 0, 1, 2, inf},
                          {"sigma_f(2,2) -inf", 0, 2, 2, -inf}, {"eps_pd nan", 1, 0, 0, nan},
                          {"eps_pd inf", 1, 0, 0, inf},         {"eps_pd < 0", 1, 0, 0, S(-1e-3)},
                          {"s nan", 2, 0, 0, nan},              {"s inf", 2, 0, 0, inf}};
  const M L = test::simple_shear(10.0).template cast<S>();
  const S dt = S(1e-4);
  for (const Fault& f : faults) {
    SCOPED_TRACE(std::string(what) + ": " + f.name);
    PhaseTransitionState<S> st;
    st.sigma_f = -S(500) * M::Identity();
    st.e = S(0.95);
    st.s = S(1e-3);
    if (f.field == 0) st.sigma_f(f.i, f.j) = f.value;
    if (f.field == 1) st.eps_pd = f.value;
    if (f.field == 2) st.s = f.value;
    M sig = M::Zero();
    auto untouched = [](const auto& a, const auto& b) { return std::memcmp(&a, &b, sizeof a) == 0; };
    auto refused = [](UpdateInfo i) { return !i.ok() && (i.flags & info::kInadmissible); };
    auto pt = st;
    EXPECT_TRUE(refused(PhaseTransitionModel<S>::update(p, pt, L, dt, sig)));
    EXPECT_TRUE(untouched(pt, st));
    EXPECT_TRUE(refused(PhaseTransitionModel<S>::template update<UpdatePart::ElasticOnly>(p, pt, L, dt, sig)));
    EXPECT_TRUE(untouched(pt, st));
    if (f.field == 2) {
      CollisionalState<S> co{st.e, st.s}, co0 = co;
      EXPECT_TRUE(refused(CollisionalModel<S>::update(p.c, co, L, dt, sig)));
      EXPECT_TRUE(untouched(co, co0));
      continue;
    }
    const FrictionalState<S> fs0{st.sigma_f, st.eps_pd, st.e};
    auto fs = fs0;
    EXPECT_TRUE(refused(FrictionalModel<S>::update(p.f, fs, L, dt, sig)));
    EXPECT_TRUE(untouched(fs, fs0));
    EXPECT_TRUE(refused(
        FrictionalModel<S, LodeShape::SmoothMohrCoulomb, StressIntegrator::ExplicitSubstep>::update(p.f, fs, L, dt, sig)));
    EXPECT_TRUE(refused(FrictionalModel<S, LodeShape::SmoothMohrCoulomb, StressIntegrator::Hybrid>::update(p.f, fs, L, dt, sig)));
    EXPECT_TRUE(untouched(fs, fs0));
  }
}

TEST(PhaseTransition, NonFiniteOrInadmissibleInputStateIsRefused) {
  expect_refused<double>("double");
  expect_refused<float>("float");
}

// The GPU's split G2P (UpdatePart::ElasticOnly, then Full on the deferred points) must give the
// fused update's result bit for bit: an elastic step is the Full step, a deferred one leaves the
// state as it was, and exactly the steps whose return map runs are deferred.
TEST(PhaseTransition, ElasticOnlyUpdateIsTheFullUpdateOrDefersPlasticSteps) {
  const auto p = test::table3_collapse();
  const auto cases = test::random_cases(20000, -1.0, 0x5eedull);
  auto same = [](const PT::State& a, const PT::State& b) {
    return a.sigma_f == b.sigma_f && a.e == b.e && a.eps_pd == b.eps_pd && a.s == b.s;
  };
  int deferred = 0, elastic = 0;
  for (const auto& c : cases) {
    PT::State full = c.st, part = c.st;
    Mat3<double> s_full = Mat3<double>::Constant(-7.0), s_part = Mat3<double>::Constant(-7.0);
    const UpdateInfo fi = PT::update(p, full, c.L, c.dt, s_full);
    const UpdateInfo pi = PT::update<UpdatePart::ElasticOnly>(p, part, c.L, c.dt, s_part);
    // the return map changes eps_pd (dLambda > 0) unless the step is elastic or a cut-off
    const bool plastic = fi.ok() && full.eps_pd != c.st.eps_pd;
    if (pi.deferred()) {
      ++deferred;
      EXPECT_FALSE(pi.ok());
      EXPECT_TRUE(same(part, c.st)) << "a deferred update changed the state";
      EXPECT_EQ(s_part, Mat3<double>::Constant(-7.0)) << "a deferred update wrote a stress";
      EXPECT_TRUE(plastic || !fi.ok() || (fi.flags & info::kTensionCutoff)) << "an elastic step was deferred";
    } else {
      ++elastic;
      EXPECT_FALSE(plastic) << "a plastic step was not deferred";
      EXPECT_EQ(pi.flags, fi.flags);
      EXPECT_TRUE(same(part, full));
      if (fi.ok()) EXPECT_EQ(s_part, s_full);
    }
  }
  // the random set holds both kinds in numbers
  EXPECT_GT(deferred, 2000);
  EXPECT_GT(elastic, 2000);
}
