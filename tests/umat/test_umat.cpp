// The UMAT through its Abaqus ABI (umat_), driven by the element driver's incremental solver
// with the increments it gives the library's Model::update, against that direct call.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <granflow/constitutive.hpp>
#include <granflow/elementtest/run.hpp>
#include <granflow/io/parameter_set.hpp>
#include <granflow/umat.h>

namespace {

using namespace granflow;
namespace et = granflow::elementtest;
using M3 = Mat3<double>;

constexpr int kVoigt[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}};

// PROPS of a parameter set in the order of docs/umat.md.
std::vector<double> props_of(const io::ParameterSet& s, double e0, bool phase_transition) {
  const auto& f = *s.frictional;
  std::vector<double> p = {phase_transition ? 2.0 : 1.0, f.K0, f.nu, f.n, f.phi_c * 180.0 / M_PI, f.e_ref,
                           f.lambda_c, f.xi, f.A_d, f.k_p, f.n_p, f.n_d, f.p_at, e0};
  if (phase_transition) {
    const auto& c = *s.collisional;
    p.insert(p.end(), {c.rho_p, c.d, c.V_sd, c.V_m, c.eps_n, c.mu_p, s.T0.value_or(0.0)});
  }
  return p;
}

// Plays Abaqus for the element driver: hands the UMAT the stress already rotated by DROT (the
// Hughes-Winget rotation of the whole step) and keeps the UMAT's stored collisional stress, as
// STATEV would carry it, between calls.
struct AbaqusHost {
  std::vector<double> props;
  int ntens = 6;
  std::array<double, 6> sigma_c{};  // STATEV(8:13) of the last call
  long calls = 0;

  std::uint32_t operator()(et::PointState& ps, const std::array<double, 9>& l, double dt) {
    M3 sf, L;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        sf(i, j) = ps.sigma_f[3 * i + j];
        L(i, j) = l[3 * i + j];
      }
    const M3 R = hughes_winget_rotation(skew(L), dt);
    M3 sc = M3::Zero();
    for (int k = 0; k < 6; ++k) sc(kVoigt[k][0], kVoigt[k][1]) = sc(kVoigt[k][1], kVoigt[k][0]) = sigma_c[k];
    const M3 sig = R * (sf + sc) * R.transpose();
    const M3 deps = sym(L) * dt;
    double stress[6], dstran[6], stran[6] = {}, drot[9], ddsdde[36], statev[GRANFLOW_UMAT_NSTATV] = {};
    for (int k = 0; k < ntens; ++k) {
      stress[k] = sig(kVoigt[k][0], kVoigt[k][1]);
      dstran[k] = (k < 3 ? 1.0 : 2.0) * deps(kVoigt[k][0], kVoigt[k][1]);  // engineering shear
    }
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) drot[3 * j + i] = R(i, j);
    statev[0] = ps.e;
    statev[1] = ps.eps_pd;
    statev[2] = ps.s * ps.s;
    std::copy(sigma_c.begin(), sigma_c.end(), statev + 7);
    double sse = 0, spd = 0, scd = 0, rpl = 0, ddsddt[6], drplde[6], drpldt = 0, time[2] = {0, 0}, temp = 0,
           dtemp = 0, predef[1] = {0}, dpred[1] = {0}, coords[3] = {0, 0, 0}, pnewdt = 1, celent = 1, f0[9] = {},
           f1[9] = {};
    const int ndi = 3, nshr = ntens - 3, nstatv = GRANFLOW_UMAT_NSTATV, nprops = int(props.size()), noel = 1,
              npt = 1, layer = 1, kspt = 1, jstep[4] = {1, 0, 0, 0}, kinc = 1;
    const char cmname[80] = "ELEMENT-DRIVER";
    umat_(stress, statev, ddsdde, &sse, &spd, &scd, &rpl, ddsddt, drplde, &drpldt, stran, dstran, time, &dt, &temp,
          &dtemp, predef, dpred, cmname, &ndi, &nshr, &ntens, &nstatv, props.data(), &nprops, coords, drot, &pnewdt,
          &celent, f0, f1, &noel, &npt, &layer, &kspt, jstep, &kinc, sizeof cmname);
    ++calls;
    if (pnewdt < 1) return info::kNonFinite;
    std::copy(statev + 7, statev + 13, sigma_c.begin());
    M3 total = M3::Zero();
    for (int k = 0; k < ntens; ++k) total(kVoigt[k][0], kVoigt[k][1]) = total(kVoigt[k][1], kVoigt[k][0]) = stress[k];
    for (int k = 0; k < 6; ++k) sc(kVoigt[k][0], kVoigt[k][1]) = sc(kVoigt[k][1], kVoigt[k][0]) = sigma_c[k];
    const M3 f = total - sc;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        ps.sigma_f[3 * i + j] = f(i, j);
        ps.stress[3 * i + j] = total(i, j);
      }
    ps.e = statev[0];
    ps.eps_pd = statev[1];
    ps.s = std::sqrt(statev[2]);
    return static_cast<std::uint32_t>(statev[3]);
  }
};

bool is_stress_column(const std::string& n) {
  for (const char* s : {"sigma_n_f", "sigma_n_c", "sigma_n", "tau_f", "tau_c", "tau", "p_f", "q_f", "p_c", "q_c", "p",
                        "q", "sigma_xx", "sigma_zz", "q_axial"})
    if (n == s) return true;
  return false;
}

// Largest difference over all output columns, each relative to its column's largest magnitude;
// with stress_scale > 0 the stress columns relative to that instead.
double column_difference(const et::ResultTable& a, const et::ResultTable& b, std::string* worst = nullptr,
                         double stress_scale = 0) {
  EXPECT_EQ(a.rows(), b.rows());
  double d = 0;
  for (std::size_t c = 0; c < a.names.size(); ++c) {
    double scale = 0, diff = 0;
    for (std::size_t r = 0; r < a.rows(); ++r) {
      scale = std::max(scale, std::fabs(a.columns[c][r]));
      diff = std::max(diff, std::fabs(a.columns[c][r] - b.columns[c][r]));
    }
    if (stress_scale > 0 && is_stress_column(a.names[c])) scale = stress_scale;
    if (scale > 0 && diff / scale > d) {
      d = diff / scale;
      if (worst) *worst = a.names[c];
    }
  }
  return d;
}

struct Case {
  const char* name;
  et::LoadingPath path;
  bool phase_transition;
};

et::ElementTest axial_test(const Case& c) {
  et::ElementTest t;
  t.name = c.name;
  t.path = c.path;
  t.model = c.phase_transition ? et::ModelChoice::PhaseTransition : et::ModelChoice::Frictional;
  t.programme.rate = 1.0;
  t.programme.duration = 0.05;  // 5 % axial strain
  t.initial.e0 = c.phase_transition ? 0.99 : 0.80;
  t.initial.sigma_v0 = c.phase_transition ? 500.0 : 100e3;
  t.initial.k0 = -1;  // 1 - sin phi_c
  t.solver.kind = et::SolverKind::Incremental;
  t.solver.dt = 1e-4;
  t.output.points = 51;
  return t;
}

// Paths without spin: the UMAT reproduces the direct call (the rotations are the identity).
TEST(Umat, ReproducesTheLibraryOnPathsWithoutSpin) {
  const Case cases[] = {{"drained triaxial, frictional", et::LoadingPath::DrainedTriaxial, false},
                        {"undrained triaxial, frictional", et::LoadingPath::UndrainedTriaxial, false},
                        {"oedometric, frictional", et::LoadingPath::Oedometric, false},
                        {"drained triaxial, phase transition", et::LoadingPath::DrainedTriaxial, true},
                        {"undrained triaxial, phase transition", et::LoadingPath::UndrainedTriaxial, true},
                        {"oedometric, phase transition", et::LoadingPath::Oedometric, true}};
  for (const Case& c : cases) {
    const io::ParameterSet set = io::load_parameter_set(c.phase_transition ? "element_test" : "frictional_element");
    et::ElementTest t = axial_test(c);
    const et::ResultTable direct = et::run_element_test(t, set);
    for (int ntens : {4, 6}) {
      AbaqusHost host{props_of(set, t.initial.e0, c.phase_transition), ntens};
      t.solver.material_update = std::ref(host);
      const et::ResultTable via_umat = et::run_element_test(t, set);
      t.solver.material_update = nullptr;
      std::string worst;
      const double d = column_difference(direct, via_umat, &worst);
      std::printf("%-38s NTENS %d: %ld UMAT calls, largest relative difference %.2e (%s)\n", c.name, ntens,
                  host.calls, d, worst.c_str());
      EXPECT_GT(host.calls, 400) << c.name;
      EXPECT_LE(d, 1e-10) << c.name << ", NTENS " << ntens << ", column " << worst;
      // the test moved the point: q changed by much more than the tolerance
      const auto& q = direct.column("q");
      EXPECT_GT(std::fabs(q.back() - q.front()), 0.05 * std::fabs(q.front()) + 1.0) << c.name;
    }
  }
}

// Simple shear has spin: Abaqus rotates the whole step before the UMAT (DROT), the library by half
// steps around its material increment. Both are consistent; they differ by O(dt) over a test.
// Stated bound: stresses differ by at most twice the rotation angle of one step,
// 2 W dt = gamma_dot_max dt (a rotation by theta moves up to 2 theta |tau| between the normal
// stresses), times the test's stress scale S (the largest |p| or |q|); other columns by as much
// relative to their own largest value. Where the difference is above round-off it must halve with dt (first
// order: ratio 1.6-2.5), which shows it is the rotation scheme's and nothing else.
TEST(Umat, SimpleShearWithinTheRotationSchemeBound) {
  for (const char* file : {"fig4_e080.toml", "fig6_e099.toml"}) {
    et::TestFile tf = et::load_test_file(io::data_directory() + "/tests/" + file);
    io::ParameterSet set = io::load_parameter_set(tf.params);
    et::ElementTest& t = tf.test;
    const bool pt = set.has_collisional() && t.model != et::ModelChoice::Frictional;
    t.solver.kind = et::SolverKind::Incremental;
    const double rate_max = t.programme.rate + t.programme.acceleration * (t.programme.duration - t.programme.hold);
    double diff[2];
    const double dts[2] = {pt ? 1e-4 : 1e-3, pt ? 5e-5 : 5e-4};
    for (int k = 0; k < 2; ++k) {
      t.solver.dt = dts[k];
      t.solver.material_update = nullptr;
      const et::ResultTable direct = et::run_element_test(t, set);
      AbaqusHost host{props_of(set, t.initial.e0, pt), 4};
      t.solver.material_update = std::ref(host);
      const et::ResultTable via_umat = et::run_element_test(t, set);
      double S = 0;
      for (const char* c : {"p", "q"})
        for (double v : direct.column(c)) S = std::max(S, std::fabs(v));
      std::string worst;
      diff[k] = column_difference(direct, via_umat, &worst, S);
      const double bound = rate_max * dts[k];
      std::printf("%s dt %.0e: largest difference %.3e (%s; stresses relative to S = %.4g Pa), bound gamma_dot_max dt = %.3e\n",
                  file, dts[k], diff[k], worst.c_str(), S, bound);
      EXPECT_LE(diff[k], bound) << file << " dt " << dts[k];
    }
    if (diff[0] > 1e-12) {
      const double ratio = diff[0] / diff[1];
      std::printf("%s: ratio of the differences at dt and dt/2 = %.3f\n", file, ratio);
      EXPECT_GT(ratio, 1.6) << file;
      EXPECT_LT(ratio, 2.5) << file;
    } else {  // Fig. 6: p_f reaches 0 within 0.5 ms; without a frictional stress there is nothing to rotate
      std::printf("%s: the schemes agree to round-off (the frictional stress vanishes early)\n", file);
    }
  }
}

// The tangent predicts the stress of a nearby increment: DDSDDE d within 1 % of the change for a
// perturbation d of 1e-6, on an elastic and on a plastic (loading) increment of both NTENS.
TEST(Umat, TangentPredictsNearbyIncrements) {
  const io::ParameterSet set = io::load_parameter_set("frictional_element");
  const std::vector<double> props = props_of(set, 0.80, false);
  for (int ntens : {4, 6}) {
    for (double shear : {0.0, 2e-3}) {  // 0: isotropic compression (elastic); 2e-3: yields
      auto call = [&](const std::array<double, 6>& dstran, double* stress, double* ddsdde, double& pnewdt) {
        double statev[GRANFLOW_UMAT_NSTATV] = {}, stran[6] = {}, drot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
        double sse = 0, spd = 0, scd = 0, rpl = 0, ddsddt[6], drplde[6], drpldt = 0, time[2] = {0, 0}, dt = 1,
               temp = 0, dtemp = 0, predef[1] = {0}, dpred[1] = {0}, coords[3] = {0, 0, 0}, celent = 1, f0[9] = {},
               f1[9] = {};
        const int ndi = 3, nshr = ntens - 3, nstatv = GRANFLOW_UMAT_NSTATV, nprops = int(props.size()), one = 1,
                  jstep[4] = {1, 0, 0, 0};
        for (int k = 0; k < 6; ++k) stress[k] = k < 3 ? -100e3 : 0.0;
        pnewdt = 1;
        umat_(stress, statev, ddsdde, &sse, &spd, &scd, &rpl, ddsddt, drplde, &drpldt, stran, dstran.data(), time,
              &dt, &temp, &dtemp, predef, dpred, "T", &ndi, &nshr, &ntens, &nstatv, props.data(), &nprops, coords,
              drot, &pnewdt, &celent, f0, f1, &one, &one, &one, &one, jstep, &one, 1);
        return statev[1];
      };
      std::array<double, 6> d0 = {-1e-4, -1e-4, -1e-4, shear, 0, 0};
      double s0[6], D[36], pn;
      const double eps_pd0 = call(d0, s0, D, pn);
      ASSERT_EQ(pn, 1.0);
      for (int j = 0; j < ntens; ++j) {
        std::array<double, 6> d1 = d0;
        d1[j] += 1e-6;
        double s1[6], D1[36];
        call(d1, s1, D1, pn);
        double largest = 0;  // of the column's changes
        for (int i = 0; i < ntens; ++i) largest = std::max(largest, std::fabs(s1[i] - s0[i]));
        ASSERT_GT(largest, 1.0);  // 1e-6 of strain against moduli of order 1e7 Pa
        for (int i = 0; i < ntens; ++i) {
          const double change = s1[i] - s0[i], predicted = D[j * ntens + i] * 1e-6;
          EXPECT_NEAR(predicted, change, 1e-2 * largest)
              << "NTENS " << ntens << " shear " << shear << " DDSDDE(" << i + 1 << "," << j + 1 << ")";
        }
      }
      if (shear > 0) EXPECT_GT(eps_pd0, 0) << "the sheared increment should be plastic";
    }
  }
}

// Bad input: PNEWDT reduced, STRESS and STATEV untouched, a message naming the property.
TEST(Umat, BadInputIsRejectedWithItsName) {
  const io::ParameterSet set = io::load_parameter_set("element_test");
  struct Bad {
    int index;  // 0-based PROPS index changed
    double value;
    const char* expect;
  };
  const Bad bads[] = {{4, 95.0, "PROPS(5)"}, {2, 0.7, "PROPS(3)"}, {13, 3.5, "PROPS(14) e0"},
                      {16, 1.5, "PROPS(17)"}, {20, -1.0, "PROPS(21) T0"}, {0, 3.0, "PROPS(1) model"}};
  for (const Bad& b : bads) {
    std::vector<double> props = props_of(set, 0.99, true);
    props[b.index] = b.value;
    double stress[6] = {-500, -500, -500, 0, 0, 0}, statev[GRANFLOW_UMAT_NSTATV] = {}, ddsdde[36], stran[6] = {},
           dstran[6] = {0, -1e-4, 0, 0, 0, 0}, drot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    double sse = 0, spd = 0, scd = 0, rpl = 0, ddsddt[6], drplde[6], drpldt = 0, time[2] = {0, 0}, dt = 1e-3, temp = 0,
           dtemp = 0, predef[1] = {0}, dpred[1] = {0}, coords[3] = {0, 0, 0}, pnewdt = 1, celent = 1, f0[9] = {},
           f1[9] = {};
    const int ndi = 3, nshr = 3, ntens = 6, nstatv = GRANFLOW_UMAT_NSTATV, nprops = int(props.size()), one = 1,
              jstep[4] = {1, 0, 0, 0};
    umat_(stress, statev, ddsdde, &sse, &spd, &scd, &rpl, ddsddt, drplde, &drpldt, stran, dstran, time, &dt, &temp,
          &dtemp, predef, dpred, "BEADS   ", &ndi, &nshr, &ntens, &nstatv, props.data(), &nprops, coords, drot, &pnewdt,
          &celent, f0, f1, &one, &one, &one, &one, jstep, &one, 8);
    const std::string msg = granflow_umat_last_error();
    EXPECT_LT(pnewdt, 1.0) << b.expect;
    EXPECT_NE(msg.find(b.expect), std::string::npos) << msg;
    EXPECT_NE(msg.find("material BEADS,"), std::string::npos) << msg;
    EXPECT_EQ(stress[1], -500.0);
    EXPECT_EQ(statev[0], 0.0);
  }
  // A bad state or increment on entry (NaN or inf, eps_pd or T < 0, DTIME < 0, an initial
  // tension), each against a started point that is accepted as it stands (the first row).
  const std::vector<double> pt = props_of(set, 0.99, true);
  const double nan = std::nan(""), inf = HUGE_VAL;
  struct BadEntry {
    const char* expect;  // nullptr: the good control
    int stress_k = -1, statev_k = -1, dstran_k = -1;  // 0-based index changed, or -1
    double value = 0, dt = 1e-3;
    bool first = false;  // STATEV all zero: the first increment
  };
  const BadEntry entries[] = {
      {nullptr},
      {"STRESS(1) = nan is not finite", 0, -1, -1, nan},
      {"STRESS(5) = inf is not finite", 4, -1, -1, inf},
      {"STATEV(2) = nan is not finite", -1, 1, -1, nan},
      {"STATEV(2) eps_pd = -0.01 on entry: must be >= 0", -1, 1, -1, -0.01},
      {"STATEV(1) e = 3.5 on entry: must be in (0, 2.97)", -1, 0, -1, 3.5},
      {"STATEV(3) T = -1 on entry: must be >= 0", -1, 2, -1, -1.0},
      {"STATEV(3) = inf is not finite", -1, 2, -1, inf},
      {"STATEV(9) = nan is not finite", -1, 8, -1, nan},
      {"DSTRAN(4) = nan is not finite", -1, -1, 3, nan},
      {"DTIME = -0.001: must be finite and >= 0", -1, -1, -1, 0, -1e-3},
      {"DTIME = nan: must be finite and >= 0", -1, -1, -1, 0, nan},
      {"(p_f = -100000 Pa, q_f = 0 Pa) lies outside the yield surface at e0 = 0.99 (a tension: p_f < 0)", 0, -1,
       -1, 100e3, 1e-3, true},
  };
  for (const BadEntry& b : entries) {
    SCOPED_TRACE(b.expect ? b.expect : "the good control");
    double stress[6] = {-500, -500, -500, 0, 0, 0}, statev[GRANFLOW_UMAT_NSTATV] = {0.99, 0.001, 1e-6},
           ddsdde[36], stran[6] = {}, dstran[6] = {0, -1e-4, 0, 0, 0, 0}, drot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    if (b.first) std::fill(statev, statev + GRANFLOW_UMAT_NSTATV, 0.0);
    if (b.first) std::fill(stress, stress + 3, b.value);
    if (b.stress_k >= 0 && !b.first) stress[b.stress_k] = b.value;
    if (b.statev_k >= 0) statev[b.statev_k] = b.value;
    if (b.dstran_k >= 0) dstran[b.dstran_k] = b.value;
    double stress0[6], statev0[GRANFLOW_UMAT_NSTATV];
    std::copy(stress, stress + 6, stress0);
    std::copy(statev, statev + GRANFLOW_UMAT_NSTATV, statev0);
    double sse = 0, spd = 0, scd = 0, rpl = 0, ddsddt[6], drplde[6], drpldt = 0, time[2] = {0, 0}, dt = b.dt,
           temp = 0, dtemp = 0, predef[1] = {0}, dpred[1] = {0}, coords[3] = {0, 0, 0}, pnewdt = 1, celent = 1,
           f0[9] = {}, f1[9] = {};
    const int ndi = 3, nshr = 3, ntens = 6, nstatv = GRANFLOW_UMAT_NSTATV, nprops = int(pt.size()), one = 1,
              jstep[4] = {1, 0, 0, 0};
    umat_(stress, statev, ddsdde, &sse, &spd, &scd, &rpl, ddsddt, drplde, &drpldt, stran, dstran, time, &dt, &temp,
          &dtemp, predef, dpred, "BEADS   ", &ndi, &nshr, &ntens, &nstatv, pt.data(), &nprops, coords, drot, &pnewdt,
          &celent, f0, f1, &one, &one, &one, &one, jstep, &one, 8);
    const std::string msg = granflow_umat_last_error();
    if (!b.expect) {
      EXPECT_EQ(pnewdt, 1.0) << msg;
      EXPECT_EQ(msg, "");
      continue;
    }
    EXPECT_LT(pnewdt, 1.0);
    EXPECT_NE(msg.find(b.expect), std::string::npos) << msg;
    EXPECT_NE(msg.find("material BEADS,"), std::string::npos) << msg;
    // as they came, NaN included
    EXPECT_EQ(std::memcmp(stress, stress0, sizeof stress), 0);
    EXPECT_EQ(std::memcmp(statev, statev0, sizeof statev), 0);
  }
  // NSTATV too small and plane stress (NTENS 3)
  std::vector<double> props = props_of(set, 0.99, true);
  for (auto [ntens, nshr, nstatv, expect] : {std::tuple{6, 3, 12, "NSTATV = 12"}, std::tuple{3, 1, 13, "NTENS = 3"}}) {
    double stress[6] = {}, statev[13] = {}, ddsdde[36], stran[6] = {}, dstran[6] = {}, drot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    double z = 0, ddsddt[6], drplde[6], time[2] = {0, 0}, dt = 1e-3, predef[1] = {0}, coords[3] = {}, pnewdt = 1,
           f0[9] = {};
    const int ndi = ntens == 3 ? 2 : 3, nprops = int(props.size()), one = 1, jstep[4] = {1, 0, 0, 0};
    umat_(stress, statev, ddsdde, &z, &z, &z, &z, ddsddt, drplde, &z, stran, dstran, time, &dt, &z, &z, predef, predef,
          "X", &ndi, &nshr, &ntens, &nstatv, props.data(), &nprops, coords, drot, &pnewdt, &z, f0, f0, &one, &one,
          &one, &one, jstep, &one, 1);
    EXPECT_LT(pnewdt, 1.0);
    EXPECT_NE(std::string(granflow_umat_last_error()).find(expect), std::string::npos) << granflow_umat_last_error();
  }
}

}  // namespace
