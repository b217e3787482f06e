// granflow mpm as a real process: killed (SIGKILL) or interrupted (SIGINT, SIGTERM) once a
// checkpoint exists, then restarted with --restart; every file of the restarted run equals
// the uninterrupted run's byte for byte. Truncated, corrupt and foreign checkpoints are
// refused with one message and touch nothing. No sleeps decide anything: the tests poll for
// the checkpoint file.
#include <gtest/gtest.h>

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "harness.hpp"

using namespace reliability;
namespace fs = std::filesystem;

namespace {


struct Work {
  fs::path dir;
  explicit Work(const std::string& name) {
    dir = fs::path(scratch_root("granflow_restart")) / name / "work";
    fs::remove_all(dir.parent_path());
    fs::create_directories(dir);
    const std::string scene = small_column_scene();
    EXPECT_EQ(scene.find("<edit target not found>"), std::string::npos) << "the CI scene changed: " << scene;
    write("scene.toml", scene);
    ::setenv("OMP_NUM_THREADS", "1", 1);  // small scene: one thread is fastest
  }
  void write(const std::string& name, const std::string& text) const {
    std::ofstream(dir / name, std::ios::binary) << text;
  }
  std::vector<std::string> args(const std::string& out, std::vector<std::string> extra = {}) const {
    std::vector<std::string> a = {"mpm", "scene.toml", "--out", out, "--no-png", "--quiet"};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  }
  Outcome run(const std::string& out, std::vector<std::string> extra = {}) const {
    return run_in(dir.string(), GRANFLOW_BINARY, args(out, extra));
  }
  // Starts a run, waits until its first checkpoint exists, sends `sig`, waits for the end.
  Outcome interrupt(const std::string& out, int sig, std::vector<std::string> extra = {}) const {
    const int pid = start_in(dir.string(), GRANFLOW_BINARY, args(out, std::move(extra)));
    const fs::path ck = dir / out / "checkpoint.bin";
    const auto t0 = std::chrono::steady_clock::now();
    while (!fs::exists(ck) && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60))
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    ::kill(pid, sig);
    return finish(pid, dir.string());
  }
  std::map<std::string, std::string> files(const std::string& out) const {
    std::map<std::string, std::string> m;
    for (const auto& e : fs::directory_iterator(dir / out)) m[e.path().filename().string()] = slurp(e.path());
    return m;
  }
};

void expect_same_files(const Work& w, const std::string& a, const std::string& b) {
  const auto fa = w.files(a), fb = w.files(b);
  std::string na, nb;
  for (const auto& [k, v] : fa) na += k + " ";
  for (const auto& [k, v] : fb) nb += k + " ";
  ASSERT_EQ(na, nb) << "file lists differ";
  EXPECT_GE(fa.size(), 9u) << na;  // 5 frames, the PVD, three CSVs
  for (const auto& [name, bytes] : fa) EXPECT_TRUE(fb.at(name) == bytes) << name << " differs";
}

// Header, then rows of `columns` fields, numbers except text_column, time not decreasing.
void expect_readable_csv(const fs::path& p, const std::string& header, size_t columns, size_t text_column = 99) {
  std::ifstream in(p);
  ASSERT_TRUE(in) << p;
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_EQ(line, header);
  double last_t = -1;
  size_t rows = 0;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    ASSERT_EQ(f.size(), columns) << p << ": " << line;
    for (size_t k = 0; k < f.size(); ++k) {
      if (k == text_column) continue;
      size_t used = 0;
      EXPECT_NO_THROW(std::stod(f[k], &used)) << line;
      EXPECT_EQ(used, f[k].size()) << line;
    }
    const double t = std::stod(f[0]);
    EXPECT_GE(t, last_t) << line;
    last_t = t;
    ++rows;
  }
  EXPECT_GE(rows, 2u) << p;
}

}  // namespace

TEST(MpmRestartProcess, KilledRunRestartsToTheSameFiles) {
  const Work w("killed");
  const Outcome ref = w.run("ref");
  ASSERT_EQ(ref.exit_code, 0) << ref.err;
  EXPECT_FALSE(fs::exists(w.dir / "ref/checkpoint.bin"));

  const Outcome k = w.interrupt("o", SIGKILL);
  ASSERT_TRUE(k.signaled && k.signal == SIGKILL) << "the run ended before it could be killed: " << k.err;
  ASSERT_TRUE(fs::exists(w.dir / "o/checkpoint.bin"));
  EXPECT_FALSE(fs::exists(w.dir / "o/frame_0004_final.vtu"));

  const Outcome r = w.run("o", {"--restart"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("restarting at t = "), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(w.dir / "o/checkpoint.bin"));  // completed
  expect_same_files(w, "ref", "o");
}

TEST(MpmRestartProcess, SigintWritesCheckpointAndSeriesThenRestarts) {
  const Work w("sigint");
  const Outcome ref = w.run("ref");
  ASSERT_EQ(ref.exit_code, 0) << ref.err;

  const Outcome i = w.interrupt("o", SIGINT);
  ASSERT_FALSE(i.signaled) << "killed by signal " << i.signal << ": " << i.err;
  EXPECT_EQ(i.exit_code, 130);
  EXPECT_NE(i.err.find("granflow: interrupted by SIGINT at t = "), std::string::npos) << i.err;
  EXPECT_NE(i.err.find("continue with: granflow mpm scene.toml --out o --restart"), std::string::npos) << i.err;
  ASSERT_TRUE(fs::exists(w.dir / "o/checkpoint.bin"));
  expect_readable_csv(w.dir / "o/runout.csv", "t,t_flow,stage,runout,height,max_speed,kinetic_energy,mean_T,max_T",
                      9);
  expect_readable_csv(w.dir / "o/tracked.csv", "t,t_flow,name,x,y,vx,vy,p,q,eps_pd,T,eta_c,K_col", 13, 2);
  for (const auto& [name, bytes] : w.files("o")) EXPECT_NE(fs::path(name).extension(), ".tmp") << name;

  const Outcome r = w.run("o", {"--restart"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same_files(w, "ref", "o");
}

TEST(MpmRestartProcess, SigtermExits143ThenRestarts) {
  const Work w("sigterm");
  const Outcome ref = w.run("ref");
  ASSERT_EQ(ref.exit_code, 0) << ref.err;
  const Outcome i = w.interrupt("o", SIGTERM);
  ASSERT_FALSE(i.signaled) << "killed by signal " << i.signal;
  EXPECT_EQ(i.exit_code, 143);
  EXPECT_NE(i.err.find("interrupted by SIGTERM"), std::string::npos) << i.err;
  // without --restart the folder is protected, and the message points at --restart
  const Outcome again = w.run("o");
  EXPECT_EQ(again.exit_code, 2);
  EXPECT_NE(again.err.find("--restart to continue from its checkpoint"), std::string::npos) << again.err;
  const Outcome r = w.run("o", {"--restart"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same_files(w, "ref", "o");
}

// A restart that is refused exits 2 with one message naming the checkpoint and leaves the
// folder exactly as it was (the checkpoint too, so a fixed scene can still use it).
TEST(MpmRestartProcess, TruncatedCorruptAndForeignCheckpointsAreRefused) {
  Work w("refused");
  // the scene reads a local copy of its parameter set, so the set can be changed too
  w.write("params.toml", slurp(fs::path(GRANFLOW_SOURCE_DIR) / "data/params/column_collapse.toml"));
  const std::string scene = edit(slurp(w.dir / "scene.toml"), "parameters = \"column_collapse\"",
                                 "parameters = \"./params.toml\"");
  w.write("scene.toml", scene);
  const Outcome k = w.interrupt("o", SIGKILL);
  ASSERT_TRUE(k.signaled) << k.err;
  const std::string good = slurp(w.dir / "o/checkpoint.bin");
  ASSERT_GT(good.size(), 1000u);
  const std::string params = slurp(w.dir / "params.toml");

  struct Bad {
    const char* what;
    std::string checkpoint, scene, params;
    const char* message;
  };
  std::string flipped = good;
  flipped[good.size() / 2] = static_cast<char>(flipped[good.size() / 2] ^ 0x20);
  const Bad cases[] = {
      {"truncated", good.substr(0, good.size() / 2), scene, params, "truncated checkpoint"},
      {"corrupt", flipped, scene, params, "checksum mismatch"},
      {"other scene", good, edit(scene, "e0 = 0.95", "e0 = 0.96"), params, "for a different scene or parameter set"},
      {"other parameter set", good, scene, edit(params, "K0 = 120", "K0 = 121"), "for a different scene or parameter set"},
  };
  for (const Bad& b : cases) {
    SCOPED_TRACE(b.what);
    ASSERT_EQ(b.scene.find("<edit target not found>"), std::string::npos);
    ASSERT_EQ(b.params.find("<edit target not found>"), std::string::npos);
    w.write("o/checkpoint.bin", b.checkpoint);
    w.write("scene.toml", b.scene);
    w.write("params.toml", b.params);
    const auto before = w.files("o");
    const Outcome r = w.run("o", {"--restart"});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("granflow: error: o/checkpoint.bin: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(b.message), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_TRUE(w.files("o") == before) << "the refused restart changed the folder";
  }
  // and with the right scene, set and checkpoint it completes
  w.write("o/checkpoint.bin", good);
  w.write("scene.toml", scene);
  w.write("params.toml", params);
  const Outcome r = w.run("o", {"--restart"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

// --set and --params are part of what a checkpoint was written for: the interrupted run says
// to repeat them, a restart without them or with other values is refused and touches nothing,
// and the restart that repeats them ends with the uninterrupted run's files.
TEST(MpmRestartProcess, RestartNeedsTheSameOverrides) {
  const Work w("overrides");
  const std::vector<std::string> sets = {"--params", "column_collapse", "--set", "frictional.K0=110", "--set",
                                         "output.series_dt=5e-3"};
  const Outcome ref = w.run("ref", sets);
  ASSERT_EQ(ref.exit_code, 0) << ref.err;

  const Outcome i = w.interrupt("o", SIGINT, sets);
  ASSERT_FALSE(i.signaled) << "killed by signal " << i.signal << ": " << i.err;
  ASSERT_EQ(i.exit_code, 130) << i.err;
  EXPECT_NE(i.err.find("continue with: granflow mpm scene.toml --out o --restart --params column_collapse --set "
                       "frictional.K0=110 --set output.series_dt=5e-3"),
            std::string::npos)
      << i.err;

  const std::vector<std::vector<std::string>> others = {
      {},                                                                        // none
      {"--set", "frictional.K0=110"},                                            // one left out
      {"--params", "column_collapse", "--set", "frictional.K0=111", "--set", "output.series_dt=5e-3"},  // other value
      {"--params", "flume", "--set", "frictional.K0=110", "--set", "output.series_dt=5e-3"},           // other set
  };
  for (const auto& other : others) {
    const auto before = w.files("o");
    std::vector<std::string> extra = other;
    extra.push_back("--restart");
    const Outcome r = w.run("o", extra);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("o/checkpoint.bin: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("for a different scene or parameter set"), std::string::npos) << r.err;
    EXPECT_TRUE(w.files("o") == before) << "the refused restart changed the folder";
  }
  std::vector<std::string> same = sets;
  same.push_back("--restart");
  const Outcome r = w.run("o", same);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same_files(w, "ref", "o");
}

// A second Ctrl-C while the interrupt's checkpoint is written (the only checkpoint of a run
// without periodic ones; the write slowed to 0.4 s a step by the fault hook) lets the write
// finish: the run stops as after one signal, leaves no temporary, and --restart ends with the
// uninterrupted run's files.
TEST(MpmRestartProcess, SecondSigintDuringTheCheckpointWriteKeepsIt) {
  Work w("second_sigint");
  w.write("scene.toml", edit(slurp(w.dir / "scene.toml"), "checkpoint_dt = 0.02", ""));
  const Outcome ref = w.run("ref");
  ASSERT_EQ(ref.exit_code, 0) << ref.err;

  ChildSetup slow;
  slow.env = {{"GRANFLOW_FAULT_FILE", "checkpoint.bin"}, {"GRANFLOW_FAULT_DELAY_MS", "400"}};
  const int pid = start_in(w.dir.string(), GRANFLOW_BINARY, w.args("o"), slow);
  auto wait_for = [&](auto&& ready) {
    const auto t0 = std::chrono::steady_clock::now();
    while (!ready() && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60))
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return ready();
  };
  // the time loop runs (its handler is installed) once the frame at t = 0 is listed
  ASSERT_TRUE(wait_for([&] { return fs::exists(w.dir / "o/frames.pvd"); }));
  ::kill(pid, SIGINT);
  const fs::path tmp = w.dir / ("o/checkpoint.bin.tmp-" + std::to_string(pid));
  const bool writing = wait_for([&] { return fs::exists(tmp); });
  ::kill(pid, SIGINT);
  const Outcome i = finish(pid, w.dir.string());
  ASSERT_TRUE(writing) << "no checkpoint write seen: " << i.err;
  ASSERT_FALSE(i.signaled) << "killed by signal " << i.signal << " during the checkpoint write";
  EXPECT_EQ(i.exit_code, 130) << i.err;
  EXPECT_NE(i.err.find("granflow: finishing the checkpoint first"), std::string::npos) << i.err;
  ASSERT_TRUE(fs::exists(w.dir / "o/checkpoint.bin"));
  for (const auto& [name, bytes] : w.files("o")) EXPECT_EQ(name.find(".tmp"), std::string::npos) << name;

  const Outcome r = w.run("o", {"--restart"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same_files(w, "ref", "o");
}

namespace {

// A run stopped after a checkpoint that lies at a stage end (--checkpoint-every 0.05, stage
// end 0.1, --stop-after 0.12), then restarted, against the same run uninterrupted: every file
// byte for byte, manifest included (issue 50: the stage frame's pressure profile was lost).
void expect_stage_end_restart_equals_uninterrupted(const std::string& name, const std::string& scene,
                                                  const std::vector<std::string>& extra) {
  Work w(name);
  w.write("scene.toml", scene);
  std::vector<std::string> opts = {"--checkpoint-every", "0.05"};
  opts.insert(opts.end(), extra.begin(), extra.end());
  const Outcome ref = w.run("ref", opts);
  ASSERT_EQ(ref.exit_code, 0) << ref.err;
  std::vector<std::string> first = opts;
  first.insert(first.end(), {"--stop-after", "0.12"});
  const Outcome a = w.run("o", first);
  ASSERT_EQ(a.exit_code, 0) << a.err;
  std::vector<std::string> again = opts;
  again.push_back("--restart");
  const Outcome r = w.run("o", again);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("restarting at t = 0.1 s"), std::string::npos) << "not a stage-end checkpoint: " << r.err;
  expect_same_files(w, "ref", "o");
}

std::string source_file(const std::string& rel) { return slurp(std::string(GRANFLOW_SOURCE_DIR) + "/" + rel); }

}  // namespace

// 2D: an obstacle (pressure profiles beside each frame), a gauge, two slabs.
TEST(MpmRestartProcess, CheckpointAtAStageEndRestartsToTheSameFiles2D) {
  std::string s = source_file("mpm/scenes/column_obstacle_ci.toml");
  s = edit(s, "duration = 0.4", "duration = 0.04");
  s = edit(s, "times = [0.05, 0.25, 0.4]", "times = [0.01, 0.04]");
  s += "\n[[gauge]]\nname = \"behind, the wall\"\nfrom = [0.22, 0.0]\nto = [0.22, 0.12]\n";
  expect_stage_end_restart_equals_uninterrupted("stage_end_2d", s, {"--devices", "2"});
}

// 3D: terrain maps and deposit series, a box obstacle, two slabs.
TEST(MpmRestartProcess, CheckpointAtAStageEndRestartsToTheSameFiles3D) {
  const std::string dir = std::string(GRANFLOW_SOURCE_DIR) + "/mpm/scenes/valley/";
  std::string s = source_file("mpm/scenes/valley_ci.toml");
  s = edit(s, "\"valley/ground.asc\"", "\"" + dir + "ground.asc\"");
  s = edit(s, "\"valley/top.asc\"", "\"" + dir + "top.asc\"");
  s = edit(s, "name = \"slide\"\nduration = 0.2", "name = \"start\"\nduration = 0.1\n[[stage]]\nname = \"on\"\nduration = 0.04");
  s = edit(s, "stage_frames = false", "stage_frames = true");
  s = edit(s, "times = [0.1, 0.2]", "times = [0.02, 0.04]");  // from the last stage's start
  s += "\n[[obstacle]]\nname = \"block\"\nkind = \"box\"\nmin = [0.70, 0.0, 0.06]\nmax = [0.76, 0.08, 0.14]\n";
  expect_stage_end_restart_equals_uninterrupted("stage_end_3d", s, {"--devices", "2"});
}
