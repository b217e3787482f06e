// Checkpoints in-process: the binary format round trip, refusal of truncated, corrupt and
// foreign files, Runner::upload, and runs interrupted at chosen steps that resume bitwise.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <sstream>

#include <granflow/io/output.hpp>
#include <granflow/mpm/checkpoint.hpp>
#include <granflow/mpm/driver.hpp>

#include "forwarding_runner.hpp"
#include "one_thread.hpp"

using namespace granflow;
using namespace granflow::mpm;
namespace fs = std::filesystem;

namespace {

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

// A checkpoint with every field set to something distinct (odd doubles included).
Checkpoint sample_checkpoint(long n, int dim) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1e3, 1e3);
  auto fill = [&](std::vector<double>& v, size_t k) {
    v.resize(k);
    for (double& x : v) x = u(rng);
  };
  Checkpoint c;
  c.scene_hash = 0x0123456789abcdefull;
  HostParticles& p = c.particles;
  p.n = n;
  p.dim = dim;
  fill(p.x, dim * n);
  fill(p.v, dim * n);
  fill(p.m, n);
  fill(p.sig, 6 * n);
  fill(p.sigf, 6 * n);
  fill(p.L, dim * dim * n);
  fill(p.eps, n);
  fill(p.e, n);
  fill(p.s, n);
  if (n > 2) {
    p.v[0] = -0.0;
    p.v[1] = 5e-324;
    p.v[2] = 1.7976931348623157e308;
  }
  LoopState& s = c.loop;
  s.t = 0.1 + 1e-17;
  s.step = 12345;
  s.dt = 2e-4 / 3;
  s.stage = 1;
  s.t_stage_end = 0.3;
  s.next_sample = 0.11;
  s.next_out = 2;
  s.frame_no = 4;
  s.pvd = {{0.0, "frame_0000.vtu"}, {0.05, "frame_0001_consolidation.vtu"}};
  for (int k = 0; k < 3; ++k)
    s.series.push_back({0.01 * k, 0.01 * k - 0.05, k % 2, {u(rng), u(rng), u(rng), u(rng), u(rng), u(rng)}});
  for (size_t k = 0; k < 4; ++k)
    s.tracks.push_back({0.02 * k, 0.02 * k - 0.05, k % 3, u(rng), u(rng), u(rng), u(rng), u(rng), u(rng), u(rng),
                        u(rng), u(rng), u(rng)});
  for (size_t k = 0; k < 2; ++k)  // gauge rows (format version 4)
    s.gauges.push_back({0.01 * k, 0.01 * k - 0.05, k, u(rng), u(rng), u(rng), u(rng), u(rng), static_cast<long>(7 + k)});
  for (int k = 0; k < 2 * 3; ++k)  // two materials' measures per series row (format version 4)
    s.material_series.push_back({u(rng), u(rng), u(rng), u(rng), u(rng), u(rng)});
  s.last_good.n = n;
  s.last_good.dim = dim;
  fill(s.last_good.x, dim * n);
  fill(s.last_good.v, dim * n);
  fill(s.last_good.T, n);
  s.last_good_t = 0.09;
  s.consolidation = {true, 0.006, 1201.9, 1201.0};
  s.stats = {1000, 2670, 1, 311, 2, 3};
  s.wall_s = 12.5;
  auto sums = [&] {
    ForceSums f;
    for (double* x : {&f.impulse[0], &f.impulse[1], &f.impulse[2], &f.normal, &f.tangential, &f.moment[0],
                      &f.moment[1], &f.moment[2], &f.max_force, &f.time})
      *x = u(rng);
    f.steps = 17;
    return f;
  };
  for (int k = 0; k < 3; ++k) s.forces.rows.push_back({0.01 * k, 0.01 * k - 0.05, k % 2, k - 1, sums()});
  for (BoundaryForces* f : {&s.forces.pending, &s.forces.last}) {  // the last sample's (format version 5)
    f->parts = {sums(), sums()};
    f->boundaries = {sums()};
    fill(f->node_impulse, 2 * dim);
  }
  if (n > 0 && dim == 3) {  // a terrain run's maps (format version 2)
    s.maps.max_speed = {0.5, 1.25, 0.0};
    s.maps.max_depth = {0.01, 0.2, 0.0};
    s.maps.deposit = {{0.0, -0.1, 0.0064, 3.84e-4, 0.08}, {0.01, -0.09, 0.0048, 3.8e-4, 0.09}};
    s.maps.deposit[1].ground_points = 3;
    s.maps.deposit[1].ground_depth = 2e-3;
    s.maps.deposit[1].edge_radius = 0.21;  // format version 7
    s.maps.deposit[1].edge_axes = 0.23;
    s.maps.deposit[1].edge_diagonals = 0.19;
  }
  return c;
}

std::string error_of(std::string_view bytes) {
  try {
    decode_checkpoint(bytes);
  } catch (const CheckpointError& e) {
    return e.what();
  }
  return "";
}

std::map<std::string, std::string> files_in(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) {
    std::ifstream in(e.path(), std::ios::binary);
    std::ostringstream os;
    os << in.rdbuf();
    out[e.path().filename().string()] = os.str();
  }
  return out;
}

// This process's scratch folder; removed at exit when every test passed.
const fs::path kScratch = fs::temp_directory_path() / ("granflow_ckpt_" + std::to_string(::getpid()));

class ScratchCleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    if (!::testing::UnitTest::GetInstance()->Failed()) fs::remove_all(kScratch, ec);
  }
};
const auto* const kCleanup = ::testing::AddGlobalTestEnvironment(new ScratchCleanup);

fs::path scratch(const std::string& name) {
  const fs::path p = kScratch / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

// Forwards to a runner and raises the interrupt flag after a given number of steps: a
// signal arriving at a chosen step, deterministically.
class InterruptAfter final : public test::ForwardingRunner {
 public:
  InterruptAfter(Runner& r, long steps, volatile std::sig_atomic_t& flag)
      : ForwardingRunner(r), left_(steps), flag_(flag) {}
  StepResult step(double dt, bool lim) override {
    const StepResult s = ForwardingRunner::step(dt, lim);
    if (--left_ == 0) flag_ = SIGINT;
    return s;
  }
  // The driver sees the flag at the end of a span: end the span at the chosen step.
  SpanResult advance_span(const Span& s) override {
    Span t = s;
    if (left_ > 0 && left_ < t.max_steps) t.max_steps = left_;
    return Runner::advance_span(t);
  }

 private:
  long left_;
  volatile std::sig_atomic_t& flag_;
};

// The CI column on a 20 mm grid, short: 0.02 s consolidation + 0.04 s collapse.
Scene short_column(ModelKind model, bool adaptive) {
  Scene sc = small_column_scene(model);
  sc.h = 0.02;
  sc.dt = 2e-4;
  sc.adaptive = adaptive;
  sc.size = {0.60, 0.16};
  sc.stages[0].duration = 0.02;
  sc.stages[1].duration = 0.04;
  sc.output.times = {0.01, 0.03};
  sc.output.series_dt = 0.004;
  return sc;
}

RunSummary run_to(const SceneSetup& su, Runner& r, const fs::path& out, const volatile std::sig_atomic_t* flag,
                  const Checkpoint* resume = nullptr, double checkpoint_dt = 0.01) {
  RunOptions opt;
  opt.out_dir = out.string();
  opt.progress = false;
  opt.checkpoint_dt = checkpoint_dt;
  opt.scene_hash = 7;
  opt.interrupt = flag;
  opt.resume = resume;
  return run(su, r, opt);
}

}  // namespace

TEST(MpmCheckpoint, EncodeDecodeRoundTripIsExact) {
  const Checkpoint empty = sample_checkpoint(0, 2);  // empty arrays (UBSan: memcpy of null)
  EXPECT_EQ(encode_checkpoint(decode_checkpoint(encode_checkpoint(empty))), encode_checkpoint(empty));
  for (const int dim : {2, 3}) {
    const Checkpoint c = sample_checkpoint(5, dim);
    const std::string bytes = encode_checkpoint(c);
    const Checkpoint d = decode_checkpoint(bytes);
    EXPECT_EQ(encode_checkpoint(d), bytes);  // every field written comes back
    EXPECT_EQ(d.scene_hash, c.scene_hash);
    EXPECT_EQ(d.particles.n, 5);
    EXPECT_EQ(d.particles.dim, dim);
    EXPECT_TRUE(same_bits(d.particles.v, c.particles.v));
    EXPECT_TRUE(same_bits(d.particles.s, c.particles.s));
    EXPECT_TRUE(std::signbit(d.particles.v[0]));
    EXPECT_EQ(d.loop.step, 12345);
    EXPECT_EQ(d.loop.dt, c.loop.dt);
    EXPECT_EQ(d.loop.pvd, c.loop.pvd);
    ASSERT_EQ(d.loop.tracks.size(), 4u);
    EXPECT_EQ(d.loop.tracks[3].track, 0u);
    EXPECT_EQ(d.loop.tracks[2].K_col, c.loop.tracks[2].K_col);
    EXPECT_EQ(d.loop.series[2].m.max_T, c.loop.series[2].m.max_T);
    ASSERT_EQ(d.loop.material_series.size(), 6u);
    EXPECT_EQ(d.loop.material_series[5].max_T, c.loop.material_series[5].max_T);
    ASSERT_EQ(d.loop.gauges.size(), 2u);
    EXPECT_EQ(d.loop.gauges[1].gauge, 1u);
    EXPECT_EQ(d.loop.gauges[1].mass_flux, c.loop.gauges[1].mass_flux);
    EXPECT_EQ(d.loop.gauges[1].points, 8);
    EXPECT_TRUE(same_bits(d.loop.last_good.T, c.loop.last_good.T));
    EXPECT_EQ(d.loop.stats.tension_cutoff, 311);
    EXPECT_TRUE(d.loop.consolidation.done);
  }
}

TEST(MpmCheckpoint, EveryTruncationAndEveryFlippedByteIsRefused) {
  const std::string bytes = encode_checkpoint(sample_checkpoint(3, 2));
  for (size_t len = 0; len < bytes.size(); ++len) {
    const std::string e = error_of(std::string_view(bytes).substr(0, len));
    ASSERT_FALSE(e.empty()) << "accepted a file cut at " << len << " of " << bytes.size() << " bytes";
    if (len >= 40) EXPECT_NE(e.find("truncated checkpoint"), std::string::npos) << e;
  }
  for (size_t at = 0; at < bytes.size(); ++at) {
    std::string b = bytes;
    b[at] = static_cast<char>(b[at] ^ 0x01);
    ASSERT_FALSE(error_of(b).empty()) << "accepted a flipped bit at byte " << at;
  }
  std::string b = bytes;
  b[8] = 9;  // version
  EXPECT_NE(error_of(b).find("format version 9"), std::string::npos) << error_of(b);
  EXPECT_NE(error_of("t,x\n0,1\n").find("not a granflow MPM checkpoint"), std::string::npos);
  EXPECT_NE(error_of(bytes + "x").find("truncated"), std::string::npos);  // trailing bytes: size differs too
  b = bytes;
  b[bytes.size() / 2] ^= 0x10;
  EXPECT_NE(error_of(b).find("checksum mismatch"), std::string::npos) << error_of(b);
}

TEST(MpmCheckpoint, WriteReplacesAtomicallyAndLeavesNoTemporary) {
  const fs::path dir = scratch("write");
  const std::string path = (dir / kCheckpointFile).string();
  Checkpoint c = sample_checkpoint(4, 2);
  write_checkpoint(path, c);
  c.loop.step = 99;
  write_checkpoint(path, c);
  EXPECT_EQ(read_checkpoint(path).loop.step, 99);
  EXPECT_EQ(files_in(dir).size(), 1u);
  // a disk that fills up half way through the next one: the previous checkpoint stays
  const std::size_t half = encode_checkpoint(c).size() / 2;
  auto used = std::make_shared<std::size_t>(0);
  io::set_write_fault([=](const std::string&, io::WriteStep step, std::size_t& bytes) {
    if (step != io::WriteStep::Write) return 0;
    if (*used >= half) return ENOSPC;
    bytes = std::min(bytes, half - *used);
    *used += bytes;
    return 0;
  });
  c.loop.step = 100;
  EXPECT_THROW(write_checkpoint(path, c), io::OutputError);
  io::set_write_fault({});
  EXPECT_EQ(read_checkpoint(path).loop.step, 99);
  EXPECT_EQ(files_in(dir).size(), 1u);
}

TEST(MpmCheckpoint, RefusesAnotherSceneOrASetUpItDoesNotFit) {
  const SceneSetup su = make_setup(short_column(ModelKind::Frictional, false));
  Checkpoint c = sample_checkpoint(su.particles.n, 2);
  c.loop.stage = 0;
  c.loop.t = 0.01;
  c.loop.next_out = 0;
  for (auto& r : c.loop.tracks) r.track = 0;
  const std::vector<GaugeRow> gauges = c.loop.gauges;  // rows of gauges this scene does not have
  c.loop.gauges.clear();
  c.loop.material_series.clear();  // measures of two materials: the scene has one
  const ForcesState forces = c.loop.forces;  // of boundaries this scene does not measure
  c.loop.forces = {};
  c.scene_hash = 7;
  EXPECT_NO_THROW(check_checkpoint(c, su, 7));
  for (int which = 0; which < 2; ++which) {
    Checkpoint f = c;
    if (which == 0)
      f.loop.forces.rows = forces.rows;
    else
      f.loop.forces.last = forces.last;
    try {
      check_checkpoint(f, su, 7);
      FAIL() << "accepted a checkpoint with force sums of boundaries the scene does not have";
    } catch (const CheckpointError& e) {
      EXPECT_NE(std::string(e.what()).find(which == 0 ? "force row of boundary" : "last force sample of 2 parts"),
                std::string::npos)
          << e.what();
    }
  }
  Checkpoint g = c;
  g.loop.gauges = gauges;
  try {
    check_checkpoint(g, su, 7);
    FAIL() << "accepted a checkpoint with rows of a gauge the scene does not have";
  } catch (const CheckpointError& e) {
    EXPECT_NE(std::string(e.what()).find("gauge 0"), std::string::npos) << e.what();
  }
  try {
    check_checkpoint(c, su, 8);
    FAIL() << "accepted another scene's checkpoint";
  } catch (const CheckpointError& e) {
    EXPECT_NE(std::string(e.what()).find("different scene or parameter set"), std::string::npos) << e.what();
  }
  Checkpoint m = c;  // maps, but the scene has no terrain
  m.loop.maps.max_speed = m.loop.maps.max_depth = {1.0};
  try {
    check_checkpoint(m, su, 7);
    FAIL() << "accepted a checkpoint with maps the scene does not have";
  } catch (const CheckpointError& e) {
    EXPECT_NE(std::string(e.what()).find("maps of 1 terrain cells, the scene's footprint covers 0"), std::string::npos)
        << e.what();
  }
  Checkpoint d = sample_checkpoint(su.particles.n + 1, 2);
  d.scene_hash = 7;
  try {
    check_checkpoint(d, su, 7);
    FAIL() << "accepted a checkpoint with another particle count";
  } catch (const CheckpointError& e) {
    EXPECT_NE(std::string(e.what()).find("does not fit the scene"), std::string::npos) << e.what();
  }
}

// A state downloaded from one runner and uploaded into a fresh one continues identically.
TEST(MpmCheckpoint, UploadedStateContinuesBitwise) {
  for (const bool variant : {false, true}) {
    Scene sc = short_column(variant ? ModelKind::Frictional : ModelKind::PhaseTransition, false);
    if (variant) {
      sc.shape = ShapeKind::QuadraticBSpline;
      sc.volumetric_averaging = true;
    }
    const SceneSetup su = make_setup(sc);
    auto a = make_cpu_runner(su);
    a->set_stage(1, 0.0, 0.99);
    for (int s = 0; s < 20; ++s) ASSERT_TRUE(a->step(2e-4, false).ok);
    HostParticles mid;
    a->download(mid);
    auto b = make_cpu_runner(su);
    b->upload(mid);
    b->set_stage(1, 0.0, 0.99);
    for (int s = 0; s < 20; ++s) {
      ASSERT_TRUE(a->step(2e-4, true).ok);
      ASSERT_TRUE(b->step(2e-4, true).ok);
    }
    HostParticles ea, eb;
    a->download(ea);
    b->download(eb);
    for (auto f : {&HostParticles::x, &HostParticles::v, &HostParticles::sig, &HostParticles::sigf, &HostParticles::L,
                   &HostParticles::eps, &HostParticles::e, &HostParticles::s})
      EXPECT_TRUE(same_bits(ea.*f, eb.*f)) << "variant " << variant;
    HostParticles wrong = mid;
    wrong.n -= 1;
    EXPECT_THROW(b->upload(wrong), std::invalid_argument);
  }
}

// Runs stopped by the interrupt flag at chosen steps (after a sample, on a stage end, before
// a frame, ...), resumed from their checkpoint: every output file equals the uninterrupted
// run's, and so do the summary's series, step count and statistics.
TEST(MpmRestart, InterruptedRunsResumeBitwise) {
  for (const bool adaptive : {false, true}) {
    const SceneSetup su = make_setup(short_column(ModelKind::PhaseTransition, adaptive));
    const fs::path ref = scratch(adaptive ? "ref_adaptive" : "ref");
    auto r0 = make_cpu_runner(su);
    const RunSummary s0 = run_to(su, *r0, ref, nullptr);
    ASSERT_TRUE(s0.ok) << s0.message;
    ASSERT_FALSE(fs::exists(ref / kCheckpointFile));
    const auto want = files_in(ref);
    ASSERT_GE(want.size(), 8u);
    {  // checkpoints change nothing in the run
      const fs::path plain = scratch("plain");
      auto rp = make_cpu_runner(su);
      ASSERT_TRUE(run_to(su, *rp, plain, nullptr, nullptr, 0.0).ok);
      EXPECT_TRUE(files_in(plain) == want);
    }
    for (const long k : {1L, 20L, 50L, 100L, 101L, s0.steps - 1}) {
      SCOPED_TRACE("adaptive " + std::to_string(adaptive) + ", interrupted after step " + std::to_string(k));
      const fs::path out = scratch("k" + std::to_string(k));
      volatile std::sig_atomic_t flag = 0;
      auto r1 = make_cpu_runner(su);
      InterruptAfter ir(*r1, k, flag);
      const RunSummary s1 = run_to(su, ir, out, &flag);
      ASSERT_EQ(s1.interrupted, SIGINT);
      EXPECT_EQ(s1.steps, k);
      ASSERT_TRUE(fs::exists(out / kCheckpointFile));
      EXPECT_FALSE(fs::exists(out / "profile_final.csv"));
      const Checkpoint c = read_checkpoint((out / kCheckpointFile).string());
      EXPECT_NO_THROW(check_checkpoint(c, su, 7));
      EXPECT_EQ(c.loop.step, k);
      auto r2 = make_cpu_runner(su);  // a fresh process would start from the set-up too
      const RunSummary s2 = run_to(su, *r2, out, nullptr, &c);
      ASSERT_TRUE(s2.ok) << s2.message;
      EXPECT_EQ(s2.interrupted, 0);
      EXPECT_EQ(s2.steps, s0.steps);
      EXPECT_EQ(s2.t_end, s0.t_end);
      EXPECT_EQ(s2.stats.updates, s0.stats.updates);
      EXPECT_EQ(s2.stats.substeps, s0.stats.substeps);
      EXPECT_EQ(s2.series.size(), s0.series.size());
      EXPECT_EQ(s2.final.runout, s0.final.runout);
      EXPECT_EQ(s2.consolidation.base_sigma_v, s0.consolidation.base_sigma_v);
      EXPECT_FALSE(fs::exists(out / kCheckpointFile));  // completed: nothing left to continue
      const auto got = files_in(out);
      ASSERT_EQ(got.size(), want.size());
      for (const auto& [name, bytes] : want) {
        ASSERT_TRUE(got.count(name)) << name;
        EXPECT_TRUE(got.at(name) == bytes) << name << " differs";
      }
    }
  }
}

// Interrupted twice: the checkpoint a resumed run writes is as good as the first.
TEST(MpmRestart, ChainedRestartsResumeBitwise) {
  const SceneSetup su = make_setup(short_column(ModelKind::Frictional, false));
  const fs::path ref = scratch("chain_ref"), out = scratch("chain");
  auto r0 = make_cpu_runner(su);
  const RunSummary s0 = run_to(su, *r0, ref, nullptr);
  ASSERT_TRUE(s0.ok) << s0.message;
  volatile std::sig_atomic_t flag = 0;
  auto r1 = make_cpu_runner(su);
  InterruptAfter i1(*r1, 70, flag);
  ASSERT_EQ(run_to(su, i1, out, &flag).interrupted, SIGINT);
  const Checkpoint c1 = read_checkpoint((out / kCheckpointFile).string());
  flag = 0;
  auto r2 = make_cpu_runner(su);
  InterruptAfter i2(*r2, 90, flag);
  ASSERT_EQ(run_to(su, i2, out, &flag, &c1).interrupted, SIGINT);
  const Checkpoint c2 = read_checkpoint((out / kCheckpointFile).string());
  EXPECT_EQ(c2.loop.step, 160);
  EXPECT_GT(c2.loop.stats.updates, c1.loop.stats.updates);
  auto r3 = make_cpu_runner(su);
  const RunSummary s3 = run_to(su, *r3, out, nullptr, &c2);
  ASSERT_TRUE(s3.ok) << s3.message;
  EXPECT_EQ(s3.stats.updates, s0.stats.updates);
  EXPECT_EQ(files_in(out), files_in(ref));
}

// A run stopped early by --stop-after keeps its last checkpoint (the scene is not done); one
// that finishes the scene removes it.
TEST(MpmRestart, StopAfterKeepsTheCheckpoint) {
  const SceneSetup su = make_setup(short_column(ModelKind::Frictional, false));
  const fs::path out = scratch("stop_after");
  auto r = make_cpu_runner(su);
  RunOptions opt;
  opt.out_dir = out.string();
  opt.progress = false;
  opt.checkpoint_dt = 0.01;
  opt.stop_after = 0.035;
  ASSERT_TRUE(run(su, *r, opt).ok);
  ASSERT_TRUE(fs::exists(out / kCheckpointFile));
  const Checkpoint c = read_checkpoint((out / kCheckpointFile).string());
  EXPECT_NEAR(c.loop.t, 0.03, 1e-9);
  auto r2 = make_cpu_runner(su);
  opt.stop_after = -1;
  opt.resume = &c;
  const RunSummary s = run(su, *r2, opt);
  ASSERT_TRUE(s.ok) << s.message;
  EXPECT_NEAR(s.t_end, 0.06, 1e-12);
  EXPECT_FALSE(fs::exists(out / kCheckpointFile));
}
