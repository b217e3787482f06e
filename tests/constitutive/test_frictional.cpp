// Frictional part (MODEL.md 3): reference values typed from MODEL.md or recomputed here by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <algorithm>

#include "reference.hpp"

using namespace granflow;
using granflow::test::kDeg;
constexpr auto SMC = LodeShape::SmoothMohrCoulomb;
constexpr auto CIRC = LodeShape::Circular;

namespace {

double M_of(double phi) { return 6 * std::sin(phi) / (3 - std::sin(phi)); }

// Independent transcription of Eq. (13).
double K_eq13(const FrictionalParams<double>& m, double p, double e) {
  return m.K0 * m.p_at * (2.97 - e) * (2.97 - e) / (1 + e) * std::pow(p / m.p_at, m.n);
}

FrictionalState<double> state(const Mat3<double>& sigma, double eps, double e) {
  FrictionalState<double> s;
  s.sigma = sigma;
  s.eps_pd = eps;
  s.e = e;
  return s;
}

}  // namespace

TEST(Frictional, DerivedConstantsOfTheParameterTables) {  // MODEL.md 7, derived constants
  EXPECT_NEAR(M_of(30 * kDeg), 1.20000, 5e-6);
  EXPECT_NEAR(M_of(23 * kDeg), 0.89848, 5e-6);
  EXPECT_NEAR(M_of(19.8 * kDeg), 0.76371, 5e-6);
  EXPECT_NEAR(M_of(38 * kDeg), 1.54926, 5e-6);
  EXPECT_DOUBLE_EQ(stress_ratio_of_angle(std::sin(30 * kDeg)), M_of(30 * kDeg));
}

TEST(Frictional, StateDependentAnglesMatchTheWorkedExample) {
  // MODEL.md 7: Table 1, e = 0.80, p = 100 kPa.
  const auto m = test::table1();
  const auto y = yield_state<CIRC>(m, test::isotropic(100e3), 0.0, 0.80, Mat3<double>::Zero());
  EXPECT_NEAR(y.e_c, 0.9168, 5e-5);
  EXPECT_NEAR(y.Gm, 1.3523, 5e-5);  // g = 1: Gm = M_p
  const double M_pt = y.Dg / m.A_d + y.r;
  EXPECT_NEAR(M_pt, 1.0586, 5e-5);
  EXPECT_NEAR(y.C.K, 3.944e7, 0.001e7);
  EXPECT_NEAR(y.C.G, 2.716e7, 0.001e7);
}

TEST(Frictional, CriticalPressureOfConstantVolumeShear) {
  // MODEL.md 6.4: e_c(p_cs) = e, values 1629, 824.1, 237.5 kPa for Table 1.
  const auto m = test::table1();
  const double expected[] = {1629e3, 824.1e3, 237.5e3};
  const double e0[] = {0.80, 0.85, 0.90};
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(critical_void_ratio(m, expected[i]), e0[i], 2e-4) << "e0 = " << e0[i];
  }
  EXPECT_NEAR(critical_void_ratio(test::table3_collapse().f, 12.82e3), 0.95, 2e-4);
}

TEST(Frictional, TangentModuliFollowEq13) {
  auto m = test::table1();
  for (double p : {1e3, 50e3, 100e3, 400e3}) {
    for (double e : {0.6, 0.8, 0.95}) {
      // Opened cone (eps_pd >> k_p) and an isotropic state: small increments stay elastic.
      auto s = state(test::isotropic(p), 0.05, e);
      const double dev = 1e-10;
      Mat3<double> deps = Mat3<double>::Zero();
      deps.diagonal().setConstant(-dev / 3);  // volumetric compression dev
      const auto inf = frictional_increment<SMC>(m, s, deps);
      ASSERT_TRUE(inf.ok());
      const double K = (mean_pressure(s.sigma) - p) / dev;
      EXPECT_NEAR(K / K_eq13(m, p, e), 1.0, 1e-6) << "p = " << p << " e = " << e;

      auto s2 = state(test::isotropic(p), 0.05, e);
      Mat3<double> dg = Mat3<double>::Zero();
      dg(0, 1) = dg(1, 0) = 0.5e-10;  // engineering shear strain 1e-10
      frictional_increment<SMC>(m, s2, dg);
      const double G = s2.sigma(0, 1) / 1e-10;
      const double G_expected = 3 * K_eq13(m, p, e) * (1 - 2 * m.nu) / (2 * (1 + m.nu));
      EXPECT_NEAR(G / G_expected, 1.0, 1e-6);
    }
  }
}

TEST(Frictional, LodeFactorIsOneInCompressionAndCInExtension) {
  const double sphi = std::sin(30 * kDeg);
  const double c = (3 - sphi) / (3 + sphi);
  EXPECT_NEAR(lode_factor<SMC>(1.0, sphi).g, 1.0, 1e-14);
  EXPECT_NEAR(lode_factor<SMC>(-1.0, sphi).g, c, 1e-14);
  // Triaxial compression of a tension-positive stress gives sin(3 theta) = +1.
  Mat3<double> s = test::isotropic(100e3);
  s(2, 2) -= 60e3;
  const auto inv = stress_invariants(s, Mat3<double>::Zero());
  EXPECT_NEAR(inv.x, 1.0, 1e-12);
  s = test::isotropic(100e3);
  s(2, 2) += 60e3;
  EXPECT_NEAR(stress_invariants(s, Mat3<double>::Zero()).x, -1.0, 1e-12);
  // Derivatives against central differences.
  const double h = 1e-6;
  for (double x : {-0.7, 0.0, 0.4}) {
    const auto L = lode_factor<SMC>(x, sphi);
    EXPECT_NEAR(L.dg_dx, (lode_factor<SMC>(x + h, sphi).g - lode_factor<SMC>(x - h, sphi).g) / (2 * h), 1e-8);
    EXPECT_NEAR(L.dg_dsin, (lode_factor<SMC>(x, sphi + h).g - lode_factor<SMC>(x, sphi - h).g) / (2 * h), 1e-8);
  }
}

TEST(Frictional, YieldGradientMatchesFiniteDifferences) {
  // n = df/dsigma at fixed e, eps_pd, including the p-dependence of e_c and the Lode angle.
  const auto m = test::table1();
  Mat3<double> sig;
  sig << -120e3, 15e3, 4e3, 15e3, -90e3, -7e3, 4e3, -7e3, -60e3;
  const double eps = 0.004, e = 0.83;
  const auto y = yield_state<SMC>(m, sig, eps, e, Mat3<double>::Zero());
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) {
      const double h = 1.0;  // Pa
      Mat3<double> d = Mat3<double>::Zero();
      d(i, j) += h / (i == j ? 1 : 2);
      d(j, i) += i == j ? 0 : h / 2;
      const double fd = (yield_function<SMC>(m, Mat3<double>(sig + d), eps, e) -
                         yield_function<SMC>(m, Mat3<double>(sig - d), eps, e)) / (2 * h);
      // the symmetric perturbation of (i,j) and (j,i) measures n_ij for a symmetric n
      EXPECT_NEAR(y.n(i, j), fd, 1e-9 + 1e-5 * std::fabs(fd)) << i << j;
    }
  // d Gm / d e at fixed p
  const double he = 1e-6;
  const auto yp = yield_state<SMC>(m, sig, eps, e + he, Mat3<double>::Zero());
  const auto ym = yield_state<SMC>(m, sig, eps, e - he, Mat3<double>::Zero());
  EXPECT_NEAR(y.dGm_de, (yp.Gm - ym.Gm) / (2 * he), 1e-6 * std::fabs(y.dGm_de) + 1e-9);
}

TEST(Frictional, RateFormKeepsTheStateOnTheSurface) {
  // Consistency (MODEL.md 3.6 rate form): one explicit rate step of size h leaves f = O(h^2).
  {
    const auto m = test::table1();
    auto s = state(test::isotropic(100e3), 0.0, 0.82);
    Mat3<double> deps = Mat3<double>::Zero();
    deps(0, 1) = deps(1, 0) = 2e-4;
    deps(2, 2) = 1e-4;  // some volume change so the de term matters
    for (int k = 0; k < 10; ++k) frictional_increment<SMC>(m, s, deps);  // load onto the surface
    auto df = [&](double h) {
      const Mat3<double> d = h * deps;
      const auto r = frictional_rate<SMC>(m, s.sigma, s.eps_pd, s.e, d, 1e-6);
      EXPECT_TRUE(r.plastic);
      const double e1 = s.e + (1 + s.e) * trace(d);
      return yield_function<SMC>(m, Mat3<double>(s.sigma + r.dsigma), s.eps_pd + r.deps_pd, e1) -
             yield_function<SMC>(m, s.sigma, s.eps_pd, s.e);
    };
    const double ratio = df(1e-2) / df(1e-3);
    EXPECT_GT(ratio, 60.0);  // second order: 100; a missing consistency term gives ~10
  }
}

TEST(Frictional, UpdateEndsOnTheYieldSurfaceWhenCrossingIt) {
  const auto m = test::table1();
  for (double dgam : {1e-5, 1e-4, 1e-3, 1e-2}) {
    // Start inside an opened surface so the increment crosses it part-way.
    auto s = state(test::isotropic(100e3), 0.002, 0.85);
    ASSERT_LT(yield_function<SMC>(m, s.sigma, s.eps_pd, s.e), -0.1);
    Mat3<double> deps = Mat3<double>::Zero();
    deps(0, 1) = deps(1, 0) = 0.5 * dgam;
    deps(0, 0) = -0.2 * dgam;
    int plastic_steps = 0;
    const int steps = std::max(20, static_cast<int>(0.01 / dgam));
    for (int k = 0; k < steps; ++k) {
      const double eps_before = s.eps_pd;
      const auto inf = frictional_increment<SMC>(m, s, deps);
      ASSERT_TRUE(inf.ok());
      const double f = yield_function<SMC>(m, s.sigma, s.eps_pd, s.e);
      EXPECT_LE(f, 10 * m.ftol) << "dgamma = " << dgam << " step " << k;
      if (s.eps_pd > eps_before) {
        ++plastic_steps;
        EXPECT_NEAR(f, 0.0, 10 * m.ftol) << "plastic step must end on the surface";
      }
    }
    EXPECT_GT(plastic_steps, 0) << dgam;
  }
}

TEST(Frictional, InitialPlasticStrainPutsAGeostaticStateOnTheSurface) {
  const auto m = test::table3_collapse().f;
  const double K0 = 1 - std::sin(m.phi_c);
  Mat3<double> sig = Mat3<double>::Zero();
  sig(1, 1) = -5e3;
  sig(0, 0) = sig(2, 2) = -K0 * 5e3;
  const double eps0 = initial_plastic_strain<SMC>(m, sig, 0.95);
  ASSERT_GT(eps0, 0.0);
  EXPECT_NEAR(yield_function<SMC>(m, sig, eps0, 0.95), 0.0, 1e-12);
  // A stress ratio above the peak is reported as inadmissible.
  sig(0, 0) = sig(2, 2) = -0.05 * 5e3;
  EXPECT_LT(initial_plastic_strain<SMC>(m, sig, 0.95), 0.0);
}

namespace {

struct TriaxialResult {
  double q_over_p, e, e_c, p, e_min, r_at_e_min, Mpt_at_e_min;
};

// Drained triaxial compression at constant lateral stress, driven with the incremental update.
// The lateral strain increment of each step is found by the secant method.
TriaxialResult drained_triaxial(double e0, double p0, double axial_strain, double step) {
  const auto m = test::table1();
  auto s = state(test::isotropic(p0), 0.0, e0);
  TriaxialResult out{};
  out.e_min = e0;
  const int n = static_cast<int>(axial_strain / step);
  double x_prev = 0.3 * step;
  for (int k = 0; k < n; ++k) {
    auto lateral_residual = [&](double x, FrictionalState<double>& trial) {
      trial = s;
      Mat3<double> d = Mat3<double>::Zero();
      d(2, 2) = -step;  // axial compression
      d(0, 0) = d(1, 1) = x;
      frictional_increment<CIRC>(m, trial, d);
      return trial.sigma(0, 0) + p0;
    };
    FrictionalState<double> t0, t1;
    double x0 = x_prev, x1 = x_prev * 1.01 + 1e-9;
    double r0 = lateral_residual(x0, t0), r1 = lateral_residual(x1, t1);
    for (int it = 0; it < 50 && std::fabs(r1) > 1e-6 * p0; ++it) {
      const double x2 = x1 - r1 * (x1 - x0) / (r1 - r0);
      x0 = x1; r0 = r1;
      x1 = x2; r1 = lateral_residual(x1, t1);
    }
    s = t1;
    x_prev = x1;
    if (s.e < out.e_min) {
      out.e_min = s.e;
      const auto y = yield_state<CIRC>(m, s.sigma, s.eps_pd, s.e, Mat3<double>::Zero());
      out.r_at_e_min = y.r;
      out.Mpt_at_e_min = y.Dg / m.A_d + y.r;
    }
  }
  const double p = mean_pressure(s.sigma);
  out.q_over_p = deviatoric_q(s.sigma) / p;
  out.e = s.e;
  out.e_c = critical_void_ratio(m, p);
  out.p = p;
  return out;
}

}  // namespace

TEST(Frictional, DrainedTriaxialReachesTheCriticalState) {
  // MODEL.md 6.4: q/p -> M (g = 1 in compression) and e -> e_c(p); dense dilates, loose contracts.
  const double M = M_of(30 * kDeg);
  const auto dense = drained_triaxial(0.80, 100e3, 1.5, 2e-4);
  const auto loose = drained_triaxial(0.95, 100e3, 1.5, 2e-4);
  for (const auto& r : {dense, loose}) {
    EXPECT_NEAR(r.q_over_p, M, 0.01 * M);
    EXPECT_NEAR(r.e, r.e_c, 0.01);
    EXPECT_NEAR(r.p, 100e3 / (1 - M / 3), 2e3);  // drained path: p = p0 + q/3
  }
  EXPECT_GT(dense.e, 0.80);  // dilated overall
  EXPECT_LT(loose.e, 0.95);  // contracted
  // The dense sample first contracts; it turns to dilation where q/p crosses M_pt.
  EXPECT_LT(dense.e_min, 0.80);
  EXPECT_NEAR(dense.r_at_e_min, dense.Mpt_at_e_min, 0.05 * dense.Mpt_at_e_min);
}

TEST(Frictional, LooseUndrainedShearLiquefiesWithoutNaN) {
  // Table 3 element test, e0 = 0.99 > e_ref, 500 Pa: the frictional stress vanishes near
  // gamma = 0.004 (MODEL.md 8) and stays zero, without a NaN.
  const auto m = test::table3_element().f;
  auto s = state(test::isotropic(500), 0.0, 0.99);
  const Mat3<double> L = test::simple_shear(10.0);
  const double dt = 1e-6;
  double gamma_liquefied = -1;
  bool had_stress_at_1e3 = false;
  for (int k = 1; k <= 10000; ++k) {  // gamma up to 0.1
    const auto inf = frictional_update<SMC>(m, s, L, dt);
    ASSERT_TRUE(inf.ok());
    ASSERT_TRUE(all_finite(s.sigma));
    const double gamma = k * dt * 10.0;
    if (std::fabs(gamma - 1e-3) < 5e-6) had_stress_at_1e3 = mean_pressure(s.sigma) > 10.0;
    if (gamma_liquefied < 0 && mean_pressure(s.sigma) <= 0.0) gamma_liquefied = gamma;
  }
  EXPECT_TRUE(had_stress_at_1e3);
  EXPECT_GT(gamma_liquefied, 0.001);
  EXPECT_LT(gamma_liquefied, 0.008);
  EXPECT_EQ(s.sigma.norm(), 0.0);
}

TEST(Frictional, TensionCutOffAndRestartFromZeroStress) {
  const auto m = test::table1();
  auto s = state(test::isotropic(10.0), 0.01, 0.85);
  Mat3<double> ext = Mat3<double>::Zero();
  ext.diagonal().setConstant(1e-3);  // opening
  auto inf = frictional_increment<SMC>(m, s, ext);
  EXPECT_TRUE(inf.ok());
  EXPECT_TRUE(inf.flags & info::kTensionCutoff);
  EXPECT_EQ(s.sigma.norm(), 0.0);
  // Pure shear of a stress-free skeleton creates no stress.
  Mat3<double> shear = Mat3<double>::Zero();
  shear(0, 1) = shear(1, 0) = 1e-3;
  inf = frictional_increment<SMC>(m, s, shear);
  EXPECT_TRUE(inf.ok());
  EXPECT_EQ(s.sigma.norm(), 0.0);
  // Compression restarts it, on or inside the (apex-rounded) surface.
  Mat3<double> comp = Mat3<double>::Zero();
  comp.diagonal().setConstant(-1e-5);
  comp(0, 1) = comp(1, 0) = 1e-5;
  inf = frictional_increment<SMC>(m, s, comp);
  EXPECT_TRUE(inf.ok());
  EXPECT_GT(mean_pressure(s.sigma), 0.0);
  EXPECT_LE(yield_function<SMC>(m, s.sigma, s.eps_pd, s.e), 10 * m.ftol);
}

TEST(Frictional, InadmissibleVoidRatioIsReportedNotPropagated) {
  const auto m = test::table1();
  auto s = state(test::isotropic(100e3), 0.01, 2.99);
  const Mat3<double> before = s.sigma;
  const auto inf = frictional_increment<SMC>(m, s, Mat3<double>::Zero());
  EXPECT_FALSE(inf.ok());
  EXPECT_TRUE(inf.flags & info::kInadmissible);
  EXPECT_EQ(s.sigma, before);
}

TEST(Frictional, SubsteppingConvergesWithTolerance) {
  // The error of the incremental update against a tight-tolerance reference falls with stol.
  auto run = [](double stol) {
    auto m = test::table1();
    m.stol = stol;
    m.max_substeps = 1000000;
    auto s = state(test::isotropic(100e3), 0.0, 0.85);
    Mat3<double> d = Mat3<double>::Zero();
    d(0, 1) = d(1, 0) = 5e-4;
    for (int k = 0; k < 40; ++k) frictional_increment<SMC>(m, s, d);
    return s.sigma;
  };
  const Mat3<double> ref = run(1e-10);
  const double e1 = (run(1e-3) - ref).norm() / ref.norm();
  const double e2 = (run(1e-5) - ref).norm() / ref.norm();
  EXPECT_LT(e2, e1);
  EXPECT_LT(e2, 1e-3);
}

TEST(Frictional, PureSpinRotatesStressAndKeepsInvariants) {
  const auto m = test::table1();
  Mat3<double> sig;
  sig << -120e3, 15e3, 0, 15e3, -90e3, 0, 0, 0, -60e3;
  auto s = state(sig, 0.05, 0.85);
  const double omega = 2.0, dt = 1e-3;
  Mat3<double> L = Mat3<double>::Zero();
  L(0, 1) = -omega;
  L(1, 0) = omega;  // rigid rotation about z at rate omega
  const int n = 500;
  for (int k = 0; k < n; ++k) ASSERT_TRUE(frictional_update<SMC>(m, s, L, dt).ok());
  EXPECT_NEAR(mean_pressure(s.sigma), mean_pressure(sig), 1e-9 * 1e5);
  EXPECT_NEAR(deviatoric_q(s.sigma), deviatoric_q(sig), 1e-9 * 1e5);
  EXPECT_NEAR(det3(s.sigma), det3(sig), 1e-9 * std::fabs(det3(sig)));
  // Against the exact rotation by omega t (Hughes-Winget is second order in omega dt).
  const double a = omega * n * dt;
  Mat3<double> R;
  R << std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a), 0, 0, 0, 1;
  const Mat3<double> exact = R * sig * R.transpose();
  EXPECT_LT((s.sigma - exact).norm() / sig.norm(), 1e-5);
  // No stress from nothing.
  auto z = state(Mat3<double>::Zero(), 0.0, 0.85);
  ASSERT_TRUE(frictional_update<SMC>(m, z, L, dt).ok());
  EXPECT_EQ(z.sigma.norm(), 0.0);
}

TEST(Frictional, ReturnMapEndsOnTheSurfaceAndConvergesToTheRateSolution) {
  // Backward Euler is first order: against a tight explicit reference over the same total strain,
  // halving the increment halves the error.
  const auto m = test::table1();
  auto run = [&](int steps, bool implicit) {
    auto s = state(test::isotropic(100e3), 0.0, 0.85);
    Mat3<double> d = Mat3<double>::Zero();
    d(0, 1) = d(1, 0) = 0.5 * 0.02 / steps;  // gamma = 0.02 in `steps` increments
    d(2, 2) = 1e-3 / steps;
    auto mm = m;
    mm.stol = 1e-10;
    mm.max_substeps = 1000000;
    for (int k = 0; k < steps; ++k) {
      const auto inf = implicit ? frictional_return_map<SMC>(m, s, d) : frictional_increment<SMC>(mm, s, d);
      EXPECT_TRUE(inf.ok());
      EXPECT_FALSE(inf.flags & info::kReturnUnconverged);
      if (implicit) EXPECT_NEAR(yield_function<SMC>(m, s.sigma, s.eps_pd, s.e), 0.0, 1e-8);
    }
    return s.sigma;
  };
  const Mat3<double> ref = run(4000, false);
  const double e1 = (run(50, true) - ref).norm() / ref.norm();
  const double e2 = (run(100, true) - ref).norm() / ref.norm();
  const double e3 = (run(200, true) - ref).norm() / ref.norm();
  const double order = std::log2(e2 / e3);
  EXPECT_NEAR(std::log2(e1 / e2), 1.0, 0.2);
  EXPECT_NEAR(order, 1.0, 0.2);
  EXPECT_LT(e3, 0.1);  // 200 increments of 1e-4 through the steep pressure dip: 6 %
}

TEST(Frictional, ConeRatioIsTheLodeFactorTimesTheStressRatio) {
  // cone_ratio (the return map's and yield_state's g M with three divisions) against the
  // separate functions of sin(phi), and its derivatives against central differences.
  for (double tan_phi : {0.2, 0.36, 0.7, 1.5}) {
    const double sn = sin_of_tan(tan_phi);
    for (double x : {-1.0, -0.4, 0.0, 0.8, 1.0}) {
      const ConeRatio<double> c = cone_ratio<SMC>(x, tan_phi);
      const LodeFactor<double> g = lode_factor<SMC>(x, sn);
      const double M = stress_ratio_of_angle(sn);
      EXPECT_NEAR(c.gM, g.g * M, 1e-14 * M) << tan_phi << " " << x;
      EXPECT_NEAR(c.dgM_dx, g.dg_dx * M, 1e-13 * M) << tan_phi << " " << x;
      const double h = 1e-6 * tan_phi;
      const double fd = (cone_ratio<SMC>(x, tan_phi + h).gM - cone_ratio<SMC>(x, tan_phi - h).gM) / (2 * h);
      EXPECT_NEAR(c.dgM_dtan, fd, 1e-7 * std::fabs(fd)) << tan_phi << " " << x;
      if (std::fabs(x) < 1) {
        const double hx = 1e-6;
        const double fx = (cone_ratio<SMC>(x + hx, tan_phi).gM - cone_ratio<SMC>(x - hx, tan_phi).gM) / (2 * hx);
        EXPECT_NEAR(c.dgM_dx, fx, 1e-7 * M) << tan_phi << " " << x;
      }
    }
    const ConeRatio<double> circ = cone_ratio<LodeShape::Circular>(0.3, tan_phi);
    EXPECT_NEAR(circ.gM, stress_ratio_of_angle(sn), 1e-14);
    EXPECT_EQ(circ.dgM_dx, 0.0);
    const double h = 1e-6 * tan_phi;
    EXPECT_NEAR(circ.dgM_dtan,
                (stress_ratio_of_angle(sin_of_tan(tan_phi + h)) - stress_ratio_of_angle(sin_of_tan(tan_phi - h))) / (2 * h),
                1e-7 * circ.dgM_dtan);
  }
}

TEST(Frictional, ReturnMapJacobianMatchesCentralDifferences) {
  // The Newton iteration of the return map uses the analytic Jacobian of its residual in
  // (p, dLambda); central differences of the residual itself are the independent reference.
  for (const auto& m : {test::table1(), test::table3_collapse().f}) {
    for (double e1 : {0.70, 0.85, 0.97}) {
      for (double x : {-0.9, 0.0, 0.7}) {
        const detail::ReturnMapResidual<SMC, double> res{m, 80e3, 60e3, x, 4e7, 3e7, 0.02, e1};
        for (double p : {50.0, 5e3, 70e3}) {
          for (double dL : {0.0, 1e-4, 1e-3}) {
            const auto v = res(p, dL);
            const double hp = 1e-6 * p, hl = 1e-7;
            const auto pp = res(p + hp, dL), pm = res(p - hp, dL);
            // central in dLambda, or the second-order one-sided formula at dLambda = 0
            const auto l1 = res(p, dL + hl), l2 = res(p, dL + 2 * hl), lm = res(p, dL > 0 ? dL - hl : dL);
            const double dR1_dL = dL > 0 ? (l1.R1 - lm.R1) / (2 * hl) : (-3 * v.R1 + 4 * l1.R1 - l2.R1) / (2 * hl);
            const double dR2_dL = dL > 0 ? (l1.R2 - lm.R2) / (2 * hl) : (-3 * v.R2 + 4 * l1.R2 - l2.R2) / (2 * hl);
            auto near = [](double a, double b) { return std::fabs(a - b) <= 1e-5 * std::fabs(b) + 1e-9; };
            EXPECT_TRUE(near(v.dR1_dp, (pp.R1 - pm.R1) / (2 * hp))) << p << " " << dL << " " << v.dR1_dp;
            EXPECT_TRUE(near(v.dR2_dp, (pp.R2 - pm.R2) / (2 * hp))) << p << " " << dL << " " << v.dR2_dp;
            EXPECT_TRUE(near(v.dR1_dL, dR1_dL)) << p << " " << dL << " " << v.dR1_dL;
            EXPECT_TRUE(near(v.dR2_dL, dR2_dL)) << p << " " << dL << " " << v.dR2_dL;
          }
        }
      }
    }
  }
}

TEST(Frictional, ReturnMapHandlesLargeIncrementsAtLowPressure) {
  // Free-surface situation: 2 G deps is hundreds of times p. The return converges in a few
  // iterations (no fallback), ends on the surface or at the cut-off, never NaN.
  const auto m = test::table3_collapse().f;
  int iterations = 0, cases = 0;
  for (double p0 : {2.0, 20.0, 200.0}) {
    for (double g : {1e-4, 1e-3, 1e-2}) {
      for (double vol : {-1e-3, 0.0, 1e-4}) {
        auto s = state(test::isotropic(p0), 0.01, 0.95);
        Mat3<double> d = Mat3<double>::Zero();
        d(0, 1) = d(1, 0) = 0.5 * g;
        d.diagonal().setConstant(vol / 3);
        const auto inf = frictional_return_map<SMC>(m, s, d);
        ASSERT_TRUE(inf.ok());
        EXPECT_FALSE(inf.flags & info::kReturnUnconverged) << p0 << " " << g << " " << vol;
        ASSERT_TRUE(all_finite(s.sigma));
        if (!(inf.flags & info::kTensionCutoff)) {
          EXPECT_LE(yield_function<SMC>(m, s.sigma, s.eps_pd, s.e), 1e-8);
        }
        iterations += inf.substeps;
        ++cases;
      }
    }
  }
  EXPECT_LT(iterations, 15 * cases);
}

TEST(Frictional, ReturnMapBuildsPressureFromZeroStressInSmallIncrements) {
  // A stress-free skeleton (the MPM column before consolidation, a point restarting after the
  // cut-off) compressed oedometrically: 0.2 % vertical strain in N increments. The return map
  // must converge to the rate solution as N grows (first order), never pass through the
  // cut-off on the way. Before the fix, converged returns below 2 p_min were taken for a stall
  // at the floor about half of the time and reset to zero: sigma_yy was 0.3 Pa at N = 1000 and
  // 0.04 Pa at N = 100000 instead of 3.9 kPa.
  const auto m = test::table3_collapse().f;
  auto run = [&](int steps, bool implicit) {
    auto s = state(Mat3<double>::Zero(), 0.0, 0.95);
    Mat3<double> d = Mat3<double>::Zero();
    d(1, 1) = -2e-3 / steps;
    auto mm = m;
    mm.stol = 1e-10;
    mm.max_substeps = 1000000;
    int cutoffs = 0;
    for (int k = 0; k < steps; ++k) {
      const auto inf = implicit ? frictional_return_map<SMC>(m, s, d) : frictional_increment<SMC>(mm, s, d);
      EXPECT_TRUE(inf.ok());
      cutoffs += (inf.flags & info::kTensionCutoff) != 0;
    }
    EXPECT_EQ(cutoffs, 0) << steps << (implicit ? " implicit" : " explicit");
    return -s.sigma(1, 1);
  };
  const double ref = run(2000, false);
  EXPECT_GT(ref, 3000.0);
  double prev = 1e300;
  for (int n : {100, 1000, 10000}) {
    const double err = std::fabs(run(n, true) - ref) / ref;
    EXPECT_LT(err, 2.0 / n) << n;  // first order: 0.6 %, 0.09 %, 0.008 %
    EXPECT_LT(err, prev) << n;
    prev = err;
  }
}

TEST(Frictional, ReturnMapCostIsBoundedNearZeroPressure) {
  // Random low-pressure states (0.1 Pa to 100 Pa, around the floor p_min = 1 Pa; the free
  // surface of a flow) under shear and volumetric increments up to 1 %: every return converges
  // without the explicit fallback, ends on the yield surface or at the cut-off, and costs a
  // bounded number of residual evaluations. Newton steps across the kink at p_min used to creep
  // (step halving every iteration): up to 1,084 evaluations, 46 fallbacks in 400,000 such cases;
  // a GPU warp waits for its slowest point. With the yield residual in ratio form (q / p - ...)
  // the mean was 3.8 evaluations; in the p-form 2.9.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  long evaluations = 0, cases = 0;
  int worst = 0;
  for (double phi : {19.8, 38.0}) {
    auto m = test::table3_collapse().f;
    m.phi_c = phi * kDeg;
    for (int k = 0; k < 20000; ++k) {
      const double p0 = std::pow(10.0, -1 + 3 * u(rng)), q0 = 1.2 * p0 * u(rng);
      Mat3<double> sigma = test::isotropic(p0);
      sigma(0, 0) -= q0 / 3;
      sigma(1, 1) += q0 / 3;
      auto s = state(sigma, std::pow(10.0, -4 + 4 * u(rng)), 0.8 + 0.4 * u(rng));
      const double g = std::pow(10.0, -6 + 4 * u(rng));
      Mat3<double> d = Mat3<double>::Zero();
      d(0, 1) = d(1, 0) = g * (u(rng) - 0.5);
      d(0, 0) = g * (u(rng) - 0.5);
      d(1, 1) = g * (u(rng) - 0.5);
      const auto inf = frictional_return_map<SMC>(m, s, d);
      ASSERT_TRUE(inf.ok());
      ASSERT_FALSE(inf.flags & info::kReturnUnconverged) << "case " << k << ", phi_c " << phi;
      ASSERT_TRUE(all_finite(s.sigma));
      if (!(inf.flags & info::kTensionCutoff)) {
        ASSERT_GE(mean_pressure(s.sigma), 0.0);
        ASSERT_LE(yield_function<SMC>(m, s.sigma, s.eps_pd, s.e), 1e-8) << "case " << k << ", phi_c " << phi;
      }
      evaluations += inf.substeps;
      worst = std::max(worst, inf.substeps);
      ++cases;
    }
  }
  EXPECT_LE(worst, 80);
  EXPECT_LT(evaluations, 3.3 * cases);
}

// The cost record of each return (what issue 37 measures on the GPU): an update inside the yield
// surface is one evaluation and no return; a return counts its halving trials among its
// evaluations; the bracketed return is reached only through the floored one. In the random
// low-pressure states above both hand-overs occur.
TEST(Frictional, ReturnMapReportsWhatItDid) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  long plastic = 0, floored = 0, halved = 0, cases = 0;
  auto m = test::table3_collapse().f;
  for (int k = 0; k < 20000; ++k) {
    const double p0 = std::pow(10.0, -1 + 3 * u(rng)), q0 = 1.2 * p0 * u(rng);
    Mat3<double> sigma = test::isotropic(p0);
    sigma(0, 0) -= q0 / 3;
    sigma(1, 1) += q0 / 3;
    auto s = state(sigma, std::pow(10.0, -4 + 4 * u(rng)), 0.8 + 0.4 * u(rng));
    const double g = std::pow(10.0, -6 + 4 * u(rng));
    Mat3<double> d = Mat3<double>::Zero();
    d(0, 1) = d(1, 0) = g * (u(rng) - 0.5);
    d(0, 0) = g * (u(rng) - 0.5);
    d(1, 1) = g * (u(rng) - 0.5);
    const auto inf = frictional_return_map<SMC>(m, s, d);
    ASSERT_TRUE(inf.ok());
    ++cases;
    if (!(inf.flags & info::kPlasticReturn)) {
      EXPECT_EQ(inf.substeps, 1) << "case " << k;
      EXPECT_EQ(inf.halvings, 0) << "case " << k;
      EXPECT_FALSE(inf.flags & (info::kFlooredReturn | info::kBracketedReturn)) << "case " << k;
      continue;
    }
    ++plastic;
    EXPECT_LE(inf.halvings, inf.substeps - 1) << "case " << k;
    if (inf.flags & info::kBracketedReturn) EXPECT_TRUE(inf.flags & info::kFlooredReturn) << "case " << k;
    floored += (inf.flags & info::kFlooredReturn) != 0;
    halved += inf.halvings > 0;
  }
  EXPECT_GT(plastic, cases / 5);
  EXPECT_LT(plastic, cases);
  EXPECT_GT(floored, 0);
  EXPECT_GT(halved, 0);
  std::printf("random low-pressure returns: %ld of %ld plastic, %ld with halvings, %ld floored\n", plastic, cases,
              halved, floored);
}

TEST(Frictional, UpdateWithSpinIsSecondOrderInTheStep) {
  // Undrained simple shear (spin = strain rate) with the substepping tight enough that the
  // splitting of rotation and straining dominates: Strang splitting gives order 2.
  auto m = test::table1();
  m.stol = 1e-10;
  m.max_substeps = 1000000;
  auto run = [&](int steps) {
    auto s = state(test::isotropic(100e3), 0.01, 0.80);
    const double duration = 0.05, dt = duration / steps;  // gamma = 0.5 at rate 10 1/s
    for (int k = 0; k < steps; ++k)
      EXPECT_TRUE((frictional_update<SMC, StressIntegrator::ExplicitSubstep>(m, s, test::simple_shear(10.0), dt).ok()));
    return s.sigma;
  };
  const Mat3<double> ref = run(1600);
  const double e1 = (run(50) - ref).norm(), e2 = (run(100) - ref).norm(), e3 = (run(200) - ref).norm();
  RecordProperty("orders", std::to_string(std::log2(e1 / e2)) + " " + std::to_string(std::log2(e2 / e3)));
  EXPECT_NEAR(std::log2(e1 / e2), 2.0, 0.2);
  EXPECT_NEAR(std::log2(e2 / e3), 2.0, 0.2);
}
