// Ensembles on the CPU twin: members advanced together equal their single runs bit for bit
// (same step sequence: fixed dt), a failing member is retired without disturbing the others,
// and set-ups that differ in more than an ensemble may vary are refused.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/ensemble.hpp>

#include "tiny_column.hpp"

namespace granflow::mpm {
namespace {

// Four members of the tiny column: the scene, phi_c + 2 deg, e0 - 0.03, and Coulomb friction
// (mu 0.3) on the first wall instead of its hold (a stage block with a contact table).
std::vector<Scene> four_members(ModelKind model, ShapeKind shape) {
  std::vector<Scene> s(4, test::tiny_column(model, shape));
  for (Scene& sc : s) {
    sc.stages[0].duration = 0.02;
    sc.stages[1].duration = 0.06;
    sc.output.times = {0.03, 0.06};
    sc.output.series_dt = 0.01;
    sc.cap_to_stable = false;  // ensembles run time.dt as given; so do the single runs compared with them
  }
  s[1].material.params.f.phi_c += 2 * M_PI / 180;
  s[2].material.e0 -= 0.03;
  s[3].walls[0].mu = 0.3;
  return s;
}

std::vector<SceneSetup> setups(const std::vector<Scene>& scenes) {
  std::vector<SceneSetup> out;
  for (const Scene& s : scenes) out.push_back(make_setup(s));
  return out;
}

RunOptions quiet() {
  RunOptions o;
  o.progress = false;
  return o;
}

EnsembleOptions quiet_ensemble() {
  EnsembleOptions o;
  o.progress = false;
  return o;
}

// Member k's particle state in the ensemble's final state.
HostParticles member_state(const HostParticles& all, int k, long n) {
  HostParticles h;
  h.n = n;
  h.dim = all.dim;
  auto slice = [&](const std::vector<double>& in, int comps, std::vector<double>& out) {
    out.resize(comps * n);
    for (int c = 0; c < comps; ++c)
      std::copy(in.begin() + c * all.n + k * n, in.begin() + c * all.n + (k + 1) * n, out.begin() + c * n);
  };
  slice(all.x, all.dim, h.x);
  slice(all.v, all.dim, h.v);
  slice(all.sig, 6, h.sig);
  slice(all.e, 1, h.e);
  slice(all.s, 1, h.s);
  return h;
}

void expect_bitwise(const std::vector<double>& a, const std::vector<double>& b, const char* what, int k) {
  ASSERT_EQ(a.size(), b.size()) << what << " member " << k;
  EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(double))) << what << " of member " << k
                                                                            << " differs from its single run";
}

void expect_members_equal_single_runs(ModelKind model, ShapeKind shape) {
  const std::vector<Scene> scenes = four_members(model, shape);
  const std::vector<SceneSetup> ms = setups(scenes);
  const SceneSetup su = make_ensemble_setup(ms);
  auto er = make_cpu_runner(su);
  const EnsembleSummary es = run_ensemble(su, ms, *er, quiet_ensemble());
  HostParticles all;
  er->download(all);
  const long n = ms[0].particles.n;
  for (int k = 0; k < 4; ++k) {
    auto r = make_cpu_runner(ms[k]);
    const RunSummary rs = run(ms[k], *r, quiet());
    ASSERT_TRUE(rs.ok) << rs.message;
    const MemberSummary& m = es.members[k];
    ASSERT_TRUE(m.ok) << m.message;
    EXPECT_EQ(rs.steps, m.steps);
    ASSERT_EQ(rs.series.size(), m.series.size()) << "member " << k;
    for (size_t i = 0; i < rs.series.size(); ++i) {
      EXPECT_EQ(rs.series[i].t, m.series[i].t);
      EXPECT_EQ(rs.series[i].m.runout, m.series[i].m.runout) << "member " << k << " sample " << i;
      EXPECT_EQ(rs.series[i].m.kinetic_energy, m.series[i].m.kinetic_energy) << "member " << k << " sample " << i;
    }
    // the tracked points: member k's own particles, sample by sample as in its single run
    ASSERT_FALSE(rs.tracks.empty());
    ASSERT_EQ(rs.tracks.size(), m.tracks.size()) << "member " << k;
    for (size_t i = 0; i < rs.tracks.size(); ++i) {
      const TrackRow &a = rs.tracks[i], &b = m.tracks[i];
      EXPECT_TRUE(a.t == b.t && a.t_flow == b.t_flow && a.track == b.track && a.x == b.x && a.y == b.y &&
                  a.vx == b.vx && a.vy == b.vy && a.p == b.p && a.q == b.q && a.eps_pd == b.eps_pd && a.T == b.T &&
                  a.eta_c == b.eta_c && a.K_col == b.K_col)
          << "member " << k << " tracked row " << i << " (point " << a.track << ", t = " << a.t << ")";
    }
    HostParticles single;
    r->download(single);
    const HostParticles mine = member_state(all, k, n);
    expect_bitwise(single.x, mine.x, "position", k);
    expect_bitwise(single.v, mine.v, "velocity", k);
    expect_bitwise(single.sig, mine.sig, "stress", k);
    expect_bitwise(single.e, mine.e, "void ratio", k);
    expect_bitwise(single.s, mine.s, "sqrt T", k);
  }
  // the members differ from each other (the varied values reach the kernels), their tracks too
  for (int k = 1; k < 4; ++k) {
    EXPECT_NE(es.members[0].final.kinetic_energy, es.members[k].final.kinetic_energy) << "member " << k;
    EXPECT_NE(es.members[0].tracks.back().y, es.members[k].tracks.back().y) << "member " << k;
  }
}

TEST(MpmEnsemble, FourMembersEqualTheirSingleRunsBitForBit) {
  expect_members_equal_single_runs(ModelKind::PhaseTransition, ShapeKind::Linear);
}

TEST(MpmEnsemble, FrictionalQuadraticMembersEqualTheirSingleRuns) {
  expect_members_equal_single_runs(ModelKind::Frictional, ShapeKind::QuadraticBSpline);
}

TEST(MpmEnsemble, AFailingMemberIsRetiredAndTheOthersFinishUndisturbed) {
  const std::vector<Scene> scenes = four_members(ModelKind::PhaseTransition, ShapeKind::Linear);
  std::vector<SceneSetup> ms = setups(scenes);
  // member 2 is thrown upwards at 400 m/s: its points leave the grid within a few steps
  const long n = ms[2].particles.n;
  for (long i = 0; i < n; ++i) ms[2].particles.v[n + i] = 400.0;
  const SceneSetup su = make_ensemble_setup(ms);
  auto er = make_cpu_runner(su);
  const EnsembleSummary es = run_ensemble(su, ms, *er, quiet_ensemble());
  EXPECT_FALSE(es.members[2].ok);
  EXPECT_NE(es.members[2].message.find("position"), std::string::npos) << es.members[2].message;
  EXPECT_LT(es.members[2].steps, 20);
  HostParticles all;
  er->download(all);
  for (int k : {0, 1, 3}) {
    ASSERT_TRUE(es.members[k].ok) << es.members[k].message;
    auto r = make_cpu_runner(ms[k]);
    const RunSummary rs = run(ms[k], *r, quiet());
    EXPECT_EQ(rs.final.runout, es.members[k].final.runout) << "member " << k;
    HostParticles single;
    r->download(single);
    const HostParticles mine = member_state(all, k, n);
    expect_bitwise(single.x, mine.x, "position", k);
    expect_bitwise(single.sig, mine.sig, "stress", k);
  }
}

TEST(MpmEnsemble, MembersMayNotDifferInGridParticlesOrTimeStepping) {
  const Scene base = test::tiny_column(ModelKind::PhaseTransition);
  auto refused = [&](Scene other, const std::string& key) {
    try {
      make_ensemble_setup({make_setup(base), make_setup(other)});
      ADD_FAILURE() << "accepted a member differing in " << key;
    } catch (const SceneError& e) {
      EXPECT_EQ(e.key(), key) << e.what();
      EXPECT_NE(std::string(e.what()).find("member 1"), std::string::npos) << e.what();
    }
  };
  Scene s = base;
  s.size[0] += 0.04;
  refused(s, "grid");
  s = base;
  s.dt = 1e-4;
  refused(s, "time");
  s = base;
  s.material.model = ModelKind::Frictional;
  refused(s, "material.model");
  s = base;
  s.stages[1].duration = 0.2;
  refused(s, "stage");
  EXPECT_THROW(make_ensemble_setup({}), SceneError);
}

}  // namespace
}  // namespace granflow::mpm
