// Spans of steps (Runner::advance_span and the driver's use of them) and the particle order
// of the CUDA backend (binning.hpp: sort keys, slot bookkeeping, warp runs and the P2G tile),
// checked on the CPU with the functions the kernels use.
#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <granflow/mpm/binning.hpp>
#include <granflow/mpm/driver.hpp>

#include "one_thread.hpp"
#include "tiny_column.hpp"

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

// The tiny column with short stages.
Scene tiny_column() {
  Scene sc = test::tiny_column(ModelKind::PhaseTransition);
  sc.stages[0].duration = 0.02;
  sc.stages[1].duration = 0.06;
  sc.output.times = {0.03};
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

// ---- particle order (binning.hpp) ----------------------------------------------------------

TEST(MpmBinning, SortKeysAreDistinctBoundedAndWalkStrips) {
  {
    const int nodes[2] = {13, 10};
    std::set<std::uint64_t> seen;
    for (int y = 0; y < nodes[1]; ++y)
      for (int x = 0; x < nodes[0]; ++x) {
        const int b[2] = {x, y};
        const std::uint64_t k = sort_key<2>(b, nodes);
        EXPECT_LT(k, sort_key_bound<2>(nodes));
        EXPECT_TRUE(seen.insert(k).second);
        if (x > 0) {  // along x inside a strip: the keys increase
          const int a[2] = {x - 1, y};
          EXPECT_LT(sort_key<2>(a, nodes), k);
        }
        if (y % kSortStrip != 0) {  // the row below in the same strip comes just before
          const int a[2] = {x, y - 1};
          EXPECT_EQ(sort_key<2>(a, nodes) + 1, k);
        }
      }
    const int out[2] = {-3, 99};  // clamped onto the grid
    const int in[2] = {0, 9};
    EXPECT_EQ(sort_key<2>(out, nodes), sort_key<2>(in, nodes));
  }
  {
    const int nodes[3] = {7, 6, 9};
    std::set<std::uint64_t> seen;
    for (int z = 0; z < nodes[2]; ++z)
      for (int y = 0; y < nodes[1]; ++y)
        for (int x = 0; x < nodes[0]; ++x) {
          const int b[3] = {x, y, z};
          const std::uint64_t k = sort_key<3>(b, nodes);
          EXPECT_LT(k, sort_key_bound<3>(nodes));
          EXPECT_TRUE(seen.insert(k).second);
        }
  }
}

TEST(MpmBinning, RunEndLane) {
  // runs: lanes 0-2, 3, 4-30, 31
  const std::uint32_t heads = 1u | (1u << 3) | (1u << 4) | (1u << 31);
  EXPECT_EQ(run_end_lane(heads, 0), 3);
  EXPECT_EQ(run_end_lane(heads, 2), 3);
  EXPECT_EQ(run_end_lane(heads, 3), 4);
  EXPECT_EQ(run_end_lane(heads, 4), 31);
  EXPECT_EQ(run_end_lane(heads, 30), 31);
  EXPECT_EQ(run_end_lane(heads, 31), 32);
  EXPECT_EQ(run_end_lane(1u, 0), 32);
  EXPECT_EQ(run_end_lane(~0u, 17), 18);
}

namespace {

using FR = FrictionalModel<double>;
using Lay = ParticleLayout<2, false>;

// A jittered 2D block of particles in a field-major buffer with the P2G inputs set.
struct Particles {
  std::vector<double> a;
  long n = 0;
  ParticleView<double> view() { return ParticleView<double>{a.data(), n}; }
};

Particles make_particles(const SceneSetup& su, std::mt19937& rng) {
  Particles p;
  p.n = su.particles.n;
  p.a.assign(static_cast<size_t>(Lay::N) * p.n, 0.0);
  auto pv = p.view();
  std::uniform_real_distribution<double> u(-1, 1);
  for (long i = 0; i < p.n; ++i) {
    for (int d = 0; d < 2; ++d) {
      pv.f(Lay::X + d, i) = su.particles.x[d * p.n + i] + 0.4 * su.spacing * u(rng);
      pv.f(Lay::V + d, i) = u(rng);
    }
    pv.f(Lay::M, i) = su.particles.m[i];
    for (int c = 0; c < 6; ++c) pv.f(Lay::SIG + c, i) = 100 * u(rng);
    for (int f = Lay::L; f < Lay::N; ++f) pv.f(f, i) = u(rng);
    pv.f(Lay::E, i) = 0.6 + 0.1 * u(rng);
  }
  return p;
}

template <class Shape>
std::vector<std::uint64_t> keys_of(ParticleView<double> pv, const GridDesc<2, double>& g) {
  std::vector<std::uint64_t> k(pv.n);
  for (long i = 0; i < pv.n; ++i) {
    double xi[2];
    int base[2];
    particle_base<2, double, Shape, false>(pv, i, g, xi, base);
    k[i] = sort_key<2>(base, g.nodes);
  }
  return k;
}

// One reorder as the CUDA backend does it: stable sort of the slots by key, gather.
template <class Shape>
void reorder(Particles& p, std::vector<std::uint32_t>& ids, const GridDesc<2, double>& g) {
  const std::vector<std::uint64_t> k = keys_of<Shape>(p.view(), g);
  std::vector<std::uint32_t> perm(p.n);
  std::iota(perm.begin(), perm.end(), 0u);
  std::stable_sort(perm.begin(), perm.end(), [&](std::uint32_t a, std::uint32_t b) { return k[a] < k[b]; });
  Particles q = p;
  std::vector<std::uint32_t> ids_new(p.n);
  for (long i = 0; i < p.n; ++i) {
    gather_slot(p.view(), q.view(), Lay::N, i, perm[i]);
    ids_new[i] = ids[perm[i]];
  }
  p = q;
  ids = ids_new;
}

struct TileStats {
  long blocks = 0, tiled = 0, runs = 0, lanes = 0;
  double box_nodes = 0;
};

// Host emulation of p2g_kernel<kP2GTile> (blocks of 128, warps of 32) with the kernel's
// helpers: block box, warp runs with the segmented shuffle sum, tile, flush; blocks whose box
// exceeds `cap` scatter the runs' sums directly.
template <class Shape>
TileStats tile_p2g(ParticleView<double> pv, const StepParams<2, double, FR>& sp, std::vector<double>& grid, long cap) {
  constexpr int K = Shape::K, NC = 5, B = 128;
  const long nn = sp.grid.n_nodes;
  TileStats st;
  std::vector<double> tile(NC * cap);
  for (long b0 = 0; b0 < pv.n; b0 += B) {
    P2GParticle<2, double> q[B];
    int base[B][2];
    long key[B];
    bool valid[B];
    int lo[2] = {INT_MAX, INT_MAX}, hi[2] = {INT_MIN, INT_MIN};
    for (int t = 0; t < B; ++t) {
      const long p = b0 + t;
      valid[t] = p < pv.n;
      base[t][0] = base[t][1] = 0;
      key[t] = -1 - t;
      if (!valid[t]) continue;
      q[t] = p2g_load<2, double, FR>(pv, p, sp);
      stencil_base<2, double, Shape>(q[t].xi, sp.grid, base[t]);
      key[t] = sp.grid.linear(base[t]);
      for (int d = 0; d < 2; ++d) {
        lo[d] = std::min(lo[d], base[t][d]);
        hi[d] = std::max(hi[d], base[t][d]);
      }
    }
    TileBox<2, K> box;
    box.set(lo, hi);
    const long nt = box.size(cap);
    ++st.blocks;
    if (nt >= 0) {
      ++st.tiled;
      st.box_nodes += nt;
      std::fill(tile.begin(), tile.end(), 0.0);
    }
    for (int w = 0; w < B / 32; ++w) {
      const int l0 = 32 * w;
      std::uint32_t heads = 0;
      for (int l = 0; l < 32; ++l)
        if (l == 0 || key[l0 + l - 1] != key[l0 + l]) heads |= 1u << l;
      int run_end[32], max_len = 0;
      for (int l = 0; l < 32; ++l) {
        run_end[l] = run_end_lane(heads, l);
        max_len = std::max(max_len, run_end[l] - l);
        if (valid[l0 + l]) {
          ++st.lanes;
          st.runs += (heads >> l) & 1u;
        }
      }
      for (int k = 0; k < stencil_size<2, K>(); ++k) {
        double c[32][NC];
        int I[32][2];
        for (int l = 0; l < 32; ++l) {
          stencil_node<2, K>(base[l0 + l], k, I[l]);
          if (valid[l0 + l])
            p2g_contribution<2, double, Shape>(q[l0 + l], I[l], sp.grid.inv_h, c[l]);
          else
            std::fill(c[l], c[l] + NC, 0.0);
        }
        for (int o = 1; o < max_len; o <<= 1) {  // __shfl_down_sync: every lane reads the old values
          double old[32][NC];
          std::copy(&c[0][0], &c[0][0] + 32 * NC, &old[0][0]);
          for (int l = 0; l < 32; ++l)
            for (int f = 0; f < NC; ++f)
              if (l + o < run_end[l]) c[l][f] += old[l + o][f];
        }
        for (int l = 0; l < 32; ++l) {
          if (!((heads >> l) & 1u) || !valid[l0 + l]) continue;
          if (nt >= 0) {
            const int j = box.local(I[l]);
            EXPECT_TRUE(j >= 0 && j < nt);
            for (int f = 0; f < NC; ++f) tile[f * cap + j] += c[l][f];
          } else {
            const long n = sp.grid.linear(I[l]);
            for (int f = 0; f < NC; ++f) grid[f * nn + n] += c[l][f];
          }
        }
      }
    }
    if (nt >= 0)
      for (int j = 0; j < nt; ++j) {
        int I[2];
        box.node(j, I);
        const long n = sp.grid.linear(I);
        for (int f = 0; f < NC; ++f)
          if (tile[f * cap + j] != 0.0) grid[f * nn + n] += tile[f * cap + j];
      }
  }
  return st;
}

template <class Shape>
std::vector<double> scatter_p2g(ParticleView<double> pv, const StepParams<2, double, FR>& sp) {
  const long nn = sp.grid.n_nodes;
  std::vector<double> g(5 * nn, 0.0);
  for (long p = 0; p < pv.n; ++p) {
    const P2GParticle<2, double> q = p2g_load<2, double, FR>(pv, p, sp);
    int base[2];
    stencil_base<2, double, Shape>(q.xi, sp.grid, base);
    for (int k = 0; k < stencil_size<2, Shape::K>(); ++k) {
      int I[2];
      stencil_node<2, Shape::K>(base, k, I);
      double c[5];
      p2g_contribution<2, double, Shape>(q, I, sp.grid.inv_h, c);
      for (int f = 0; f < 5; ++f) g[f * nn + sp.grid.linear(I)] += c[f];
    }
  }
  return g;
}

StepParams<2, double, FR> p2g_params(const SceneSetup& su) {
  StepParams<2, double, FR> sp{};
  sp.grid = test::grid_of(su);
  sp.rho_p = su.scene.material.params.c.rho_p;
  return sp;
}

}  // namespace

TEST(MpmBinning, ReorderKeepsOriginalIdsAndRoundTrips) {
  const SceneSetup su = make_setup(small_column_scene(ModelKind::Frictional, ShapeKind::QuadraticBSpline));
  std::mt19937 rng(11);
  Particles p = make_particles(su, rng);
  const Particles orig = p;  // records by original index
  const GridDesc<2, double> g = p2g_params(su).grid;
  std::vector<std::uint32_t> ids(p.n);
  std::iota(ids.begin(), ids.end(), 0u);
  std::vector<double> expect = orig.a;  // expected record of each original index, moved below
  std::uniform_real_distribution<double> u(-1, 1);
  for (int round = 0; round < 3; ++round) {
    // move the particles (in their current slots), as steps do between sorts
    auto pv = p.view();
    for (long i = 0; i < p.n; ++i)
      for (int d = 0; d < 2; ++d) {
        const double dx = 0.7 * su.scene.h * u(rng);
        pv.f(Lay::X + d, i) += dx;
        expect[(Lay::X + d) * p.n + ids[i]] += dx;
      }
    reorder<QuadraticShape>(p, ids, g);
    const std::vector<std::uint64_t> k = keys_of<QuadraticShape>(p.view(), g);
    EXPECT_TRUE(std::is_sorted(k.begin(), k.end())) << "round " << round;
    // ids is a permutation; inv finds each original index; unpermuted fields are the records
    std::vector<std::uint32_t> inv(p.n, ~0u);
    for (long i = 0; i < p.n; ++i) inv[ids[i]] = static_cast<std::uint32_t>(i);
    for (long j = 0; j < p.n; ++j) ASSERT_NE(inv[j], ~0u);
    std::vector<double> out(p.a.size());
    for (long i = 0; i < p.n; ++i)
      for (int f = 0; f < Lay::N; ++f) out[f * p.n + ids[i]] = p.a[f * p.n + i];
    EXPECT_EQ(out, expect) << "round " << round;
    for (long j = 0; j < p.n; j += 97)
      for (int f = 0; f < Lay::N; ++f) EXPECT_EQ(p.a[f * p.n + inv[j]], expect[f * p.n + j]);
  }
}

TEST(MpmBinning, TileP2GEqualsScatterAndSortedBlocksFitTheTile) {
  // the 4 mm column (5,000 points), jittered. Sorted, the blocks of 128 fit the tile (a box of
  // about 10 x 6 nodes) except where one strip of the sort key ends and the next begins (one
  // block in 6 here, one in 25 at 1 mm); runs of the warps hold 3 to 4 particles.
  const SceneSetup su = make_setup(column_scene(0.004, 4e-5, ModelKind::Frictional, ShapeKind::QuadraticBSpline, 0.1));
  std::mt19937 rng(5);
  Particles p = make_particles(su, rng);
  const StepParams<2, double, FR> sp = p2g_params(su);
  const std::vector<double> ref = scatter_p2g<QuadraticShape>(p.view(), sp);
  double scale[5] = {};
  for (int f = 0; f < 5; ++f)
    for (long n = 0; n < su.n_nodes; ++n) scale[f] = std::max(scale[f], std::fabs(ref[f * su.n_nodes + n]));
  std::vector<std::uint32_t> ids(p.n);
  std::iota(ids.begin(), ids.end(), 0u);
  for (const bool sorted : {false, true}) {
    if (sorted) reorder<QuadraticShape>(p, ids, sp.grid);
    std::vector<double> grid(5 * su.n_nodes, 0.0);
    const TileStats st = tile_p2g<QuadraticShape>(p.view(), sp, grid, 512);
    double err = 0;
    for (int f = 0; f < 5; ++f)
      for (long n = 0; n < su.n_nodes; ++n)
        err = std::max(err, std::fabs(grid[f * su.n_nodes + n] - ref[f * su.n_nodes + n]) / scale[f]);
    EXPECT_LT(err, 1e-12) << (sorted ? "sorted" : "unsorted");
    std::printf("%s: %ld blocks, %ld in the tile (mean box %.0f nodes), %.2f particles per warp run\n",
                sorted ? "sorted" : "seeding order", st.blocks, st.tiled, st.tiled ? st.box_nodes / st.tiled : 0.0,
                double(st.lanes) / double(st.runs));
    if (sorted) {
      EXPECT_GE(st.tiled, 0.8 * st.blocks);
      EXPECT_LT(st.box_nodes / st.tiled, 120.0);
      EXPECT_GT(double(st.lanes) / double(st.runs), 3.0);
    }
  }
}

// The CUDA options' command-line spellings (granflow mpm / bench mpm): every
// value the help lists is taken, anything else is refused and leaves the options as they were.
TEST(CudaOptions, CommandLineSpellingsAreTakenOrRefusedWithoutSideEffects) {
  CudaOptions o;
  EXPECT_EQ(o.g2p_split, CudaOptions::Split::Auto);
  EXPECT_TRUE(set_cuda_option(o, "g2p-split", "on"));
  EXPECT_EQ(o.g2p_split, CudaOptions::Split::On);
  EXPECT_TRUE(set_cuda_option(o, "g2p-split", "off"));
  EXPECT_EQ(o.g2p_split, CudaOptions::Split::Off);
  EXPECT_TRUE(set_cuda_option(o, "g2p-split", "auto"));
  EXPECT_EQ(o.g2p_split, CudaOptions::Split::Auto);
  EXPECT_NE(describe(o).find("g2p split auto"), std::string::npos);
  EXPECT_TRUE(set_cuda_option(o, "p2g", "tile"));
  EXPECT_EQ(o.p2g, CudaOptions::P2G::Tile);
  EXPECT_TRUE(set_cuda_option(o, "sort", "0"));
  EXPECT_EQ(o.sort_every, 0);
  EXPECT_TRUE(set_cuda_option(o, "g2p-block", "64"));
  EXPECT_EQ(o.g2p_block, 64);
  EXPECT_FALSE(o.update_stats);
  EXPECT_TRUE(set_cuda_option(o, "update-stats", "on"));
  EXPECT_TRUE(o.update_stats);
  EXPECT_NE(describe(o).find("update stats on"), std::string::npos);

  const CudaOptions before = o;
  for (const auto& [name, value] : std::vector<std::pair<std::string, std::string>>{
           {"g2p-split", "maybe"}, {"update-stats", "yes please"}, {"g2p-block", "100"}, {"g2p-block", "512"}, {"sort", "-1"}, {"sort", "8x"},
           {"p2g", "shared"}, {"graphs", "yes please"}, {"graph-steps", "0"}, {"g2p-splits", "on"}}) {
    EXPECT_FALSE(set_cuda_option(o, name, value)) << name << " " << value;
    EXPECT_EQ(describe(o), describe(before)) << name << " " << value << " changed the options";
  }
}

// time.stop_at_rest's window on hand-made rows: the peak is the last stage's (rows at t >= t_from),
// the window is the trailing run below ratio x peak, and it must span the hold.
TEST(MpmRest, RestSinceFindsTheTrailingQuietWindow) {
  std::vector<SeriesRow> rows;
  auto add = [&](double t, double ke) {
    SeriesRow r{t, t, 0, Measures{}};
    r.m.kinetic_energy = ke;
    rows.push_back(r);
  };
  add(0.0, 50);  // an earlier stage's motion: not the peak of the flow
  add(0.1, 0);
  add(0.2, 10);  // the flow's peak
  add(0.3, 2);
  add(0.4, 0.009);  // below 1e-3 x 10 from here
  add(0.5, 0.005);
  add(0.6, 0.002);
  EXPECT_DOUBLE_EQ(rest_since(rows, rows.size(), 0.1, 1e-3, 0.2), 0.4);
  EXPECT_EQ(rest_since(rows, rows.size(), 0.1, 1e-3, 0.25), -1);  // the window spans 0.2 s only
  EXPECT_EQ(rest_since(rows, rows.size() - 1, 0.1, 1e-3, 0.2), -1);  // the last row not settled yet
  // the earlier stage's 50 taken as the peak would open the window at 0.4; the flow's 10 does not
  EXPECT_EQ(rest_since(rows, rows.size(), 0.1, 5e-4, 0.1), -1);
  EXPECT_DOUBLE_EQ(rest_since(rows, rows.size(), 0.0, 5e-4, 0.1), 0.4);
  add(0.7, 0.5);  // moving again: the window closes
  EXPECT_EQ(rest_since(rows, rows.size(), 0.1, 1e-3, 0.1), -1);
  EXPECT_EQ(rest_since({}, 0, 0.0, 1e-3, 0.1), -1);
}

// A run that stops at rest is the full run up to that time, bit for bit, ends well before the
// scene's end, and its run-out is that of the pile the full run leaves (within a point spacing).
TEST(MpmRest, StopAtRestEndsTheRunOnceThePileIsStill) {
  Scene sc = test::tiny_column(ModelKind::Frictional);
  sc.stages[1].duration = 0.8;
  const SceneSetup full_su = make_setup(sc);
  sc.stop_at_rest = 2e-3;  // this coarse pile creeps at about 1e-3 of the peak energy from 0.5 s on
  sc.rest_hold = 0.05;
  const SceneSetup rest_su = make_setup(sc);
  RunOptions o;
  o.progress = false;
  auto a = make_cpu_runner(full_su);
  auto b = make_cpu_runner(rest_su);
  const RunSummary full = run(full_su, *a, o), rest = run(rest_su, *b, o);
  ASSERT_TRUE(full.ok && rest.ok);
  EXPECT_LT(full.at_rest_since, 0);
  ASSERT_GE(rest.at_rest_since, 0);
  const double t_release = sc.stages[0].duration, t_total = sc.duration();
  EXPECT_GT(rest.at_rest_since, t_release);
  EXPECT_LT(rest.t_end, t_total - 0.2) << "at rest from " << rest.at_rest_since;
  EXPECT_NEAR(rest.t_end - rest.at_rest_since, sc.rest_hold + sc.output.series_dt, 1.5 * sc.output.series_dt);
  ASSERT_LE(rest.series.size(), full.series.size());
  double peak = 0;
  for (size_t i = 0; i < rest.series.size(); ++i) {
    EXPECT_EQ(rest.series[i].t, full.series[i].t);
    EXPECT_EQ(rest.series[i].m.runout, full.series[i].m.runout) << "row " << i;
    EXPECT_EQ(rest.series[i].m.kinetic_energy, full.series[i].m.kinetic_energy) << "row " << i;
    if (rest.series[i].t >= t_release) peak = std::max(peak, rest.series[i].m.kinetic_energy);
  }
  EXPECT_LT(rest.final.kinetic_energy, sc.stop_at_rest * peak);
  const double spacing = sc.h / sc.ppc_axis;
  EXPECT_NEAR(rest.final.runout, full.final.runout, spacing);
  EXPECT_NEAR(rest.final.height, full.final.height, spacing);
}
