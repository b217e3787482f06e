// Output integrity of the real granflow binary (issue 21): write failures injected at chosen
// bytes and steps (GRANFLOW_FAULT_*, granflow/io/output.hpp) and a real file-size limit, two runs
// on one folder, and stopped runs resumed. Each case checks that no partial file is named as
// complete, the previous good outputs are intact, no temporary is left and the error is clear.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <thread>

#include <granflow/io/input_error.hpp>
#include <granflow/io/run_folder.hpp>

#include "harness.hpp"

namespace reliability {
Files default_files();
}

using namespace reliability;
namespace fs = std::filesystem;

namespace {

using Env = std::vector<std::pair<std::string, std::string>>;

struct Work {
  fs::path dir;
  explicit Work(const std::string& name) {
    dir = fs::path(scratch_root("granflow_integrity")) / name / "work";
    fs::remove_all(dir.parent_path());
    fs::create_directories(dir);
    for (const auto& [file, text] : default_files()) write(file, text);
    const std::string scene = small_column_scene();
    EXPECT_EQ(scene.find("<edit target not found>"), std::string::npos) << "the CI scene changed";
    write("column.toml", scene);
    ::setenv("OMP_NUM_THREADS", "1", 1);  // small scenes: one thread is fastest
  }
  void write(const std::string& name, const std::string& text) const {
    fs::create_directories((dir / name).parent_path());
    std::ofstream(dir / name, std::ios::binary) << text;
  }
  Outcome run(std::vector<std::string> args, const Env& env = {}, long fsize = -1) const {
    ChildSetup setup;
    setup.env = env;
    setup.file_size_limit = fsize;
    return run_in(dir.string(), GRANFLOW_BINARY, args, 120.0, setup);
  }
  static std::vector<std::string> mpm(const std::string& out, std::vector<std::string> extra = {}) {
    std::vector<std::string> a = {"mpm", "column.toml", "--out", out, "--no-png", "--quiet"};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  }
  static std::vector<std::string> calibrate(std::vector<std::string> extra = {}) {
    std::vector<std::string> a = {"calibrate", "job.toml", "--out", "fit", "--no-plot", "--quiet", "--evaluate"};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  }
  // name -> bytes of every regular file below `sub` (relative names).
  std::map<std::string, std::string> files(const std::string& sub = "") const {
    std::map<std::string, std::string> m;
    const fs::path root = dir / sub;
    if (!fs::exists(root)) return m;
    for (const auto& e : fs::recursive_directory_iterator(root))
      if (e.is_regular_file()) m[fs::relative(e.path(), root).string()] = slurp(e.path().string());
    return m;
  }
  std::set<std::string> names(const std::string& sub = "") const {
    std::set<std::string> s;
    for (const auto& e : fs::directory_iterator(dir / sub)) s.insert(e.path().filename().string());
    return s;
  }
};

// The one message line (after "granflow: error: ").
std::string error_line(const Outcome& o) {
  std::string last;
  std::istringstream is(o.err);
  for (std::string l; std::getline(is, l);)
    if (l.rfind("granflow: error: ", 0) == 0) last = l;
  return last;
}

void expect_no_temporaries(const Work& w) {
  for (const auto& e : fs::recursive_directory_iterator(w.dir)) {
    const std::string n = e.path().filename().string();
    EXPECT_FALSE(std::regex_search(n, std::regex(R"(\.(tmp|old)(-[0-9]+)?$)"))) << "left over: " << e.path();
  }
}

// frames.pvd is a whole index and every frame it lists is a whole VTU file.
void expect_consistent_frames(const Work& w, const std::string& out) {
  const std::string pvd = slurp((w.dir / out / "frames.pvd").string());
  ASSERT_FALSE(pvd.empty()) << out << "/frames.pvd is missing or empty";
  EXPECT_EQ(pvd.substr(pvd.size() - 11), "</VTKFile>\n") << pvd;
  const std::regex file_re("file=\"([^\"]+)\"");
  int listed = 0;
  for (std::sregex_iterator it(pvd.begin(), pvd.end(), file_re), end; it != end; ++it, ++listed) {
    const std::string vtu = slurp((w.dir / out / (*it)[1].str()).string());
    ASSERT_GE(vtu.size(), 11u) << (*it)[1];
    EXPECT_EQ(vtu.substr(vtu.size() - 11), "</VTKFile>\n") << (*it)[1];
  }
  EXPECT_GE(listed, 1);
}

void expect_same(const std::map<std::string, std::string>& a, const std::map<std::string, std::string>& b) {
  std::string na, nb;
  for (const auto& [k, v] : a) na += k + " ";
  for (const auto& [k, v] : b) nb += k + " ";
  ASSERT_EQ(na, nb);
  for (const auto& [k, v] : a) EXPECT_TRUE(b.at(k) == v) << k << " differs";
}

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

}  // namespace

// ---- element: one result file -------------------------------------------------------------

TEST(IntegrityElement, FullDiskKeepsThePreviousResult) {
  const Work w("element_full_disk");
  ASSERT_EQ(w.run({"element", "t.toml", "--out", "out.csv"}).exit_code, 0);
  const auto before = w.files();
  const std::size_t size = before.at("out.csv").size();
  for (std::size_t n : {std::size_t(0), std::size_t(1), size / 2, size - 1}) {
    SCOPED_TRACE(n);
    const Outcome o = w.run({"element", "t.toml", "--out", "out.csv", "--force"}, {{"GRANFLOW_FAULT_BYTES", std::to_string(n)}});
    EXPECT_EQ(o.exit_code, 2) << o.err;
    EXPECT_EQ(error_line(o), "granflow: error: out.csv: cannot write: No space left on device (the file system is full: "
                             "free space there, or write elsewhere); the file keeps its previous content");
    EXPECT_FALSE(has(o.out, "wrote")) << o.out;
    EXPECT_TRUE(w.files() == before);
  }
  // a late error from close (NFS, quotas) is caught too; EIO is not the user's to fix: exit 1
  const Outcome o = w.run({"element", "t.toml", "--out", "out.csv", "--force"},
                          {{"GRANFLOW_FAULT_AT", "close"}, {"GRANFLOW_FAULT_ERRNO", "EIO"}});
  EXPECT_EQ(o.exit_code, 1) << o.err;
  EXPECT_TRUE(has(error_line(o), "out.csv: cannot write: Input/output error")) << o.err;
  EXPECT_TRUE(w.files() == before);
}

// A real OS failure, no injection: a file-size limit of 400 bytes (the result has 633; the
// message, on stderr, must fit too) gives EFBIG.
TEST(IntegrityElement, FileSizeLimitGivesAClearErrorAndNoFile) {
  const Work w("element_fsize");
  const auto before = w.files();
  const Outcome o = w.run({"element", "t.toml", "--out", "out.csv"}, {}, 400);
  EXPECT_FALSE(o.signaled) << "signal " << o.signal;
  EXPECT_EQ(o.exit_code, 2) << o.err;
  EXPECT_TRUE(has(error_line(o), "out.csv: cannot write: File too large (the file exceeds the size limit, see ulimit -f); "
                                 "nothing was written"))
      << o.err;
  EXPECT_TRUE(w.files() == before);
}

// ---- calibrate: a staged folder ---------------------------------------------------------

TEST(IntegrityCalibrate, FullDiskAtAnyPointKeepsThePreviousResults) {
  const Work w("calibrate_full_disk");
  const Outcome first = w.run(Work::calibrate());
  ASSERT_EQ(first.exit_code, 0) << first.err;
  EXPECT_TRUE(granflow::io::verify_manifest((w.dir / "fit").string()).empty());
  const auto before = w.files();
  std::size_t total = 0;
  for (const auto& [name, bytes] : w.files("fit")) total += bytes.size();
  for (std::size_t n : {std::size_t(0), std::size_t(40), std::size_t(300), total / 4, total / 2, total - 1}) {
    SCOPED_TRACE(n);
    const Outcome o = w.run(Work::calibrate({"--force"}), {{"GRANFLOW_FAULT_BYTES", std::to_string(n)}});
    EXPECT_EQ(o.exit_code, 2) << o.err;
    const std::string m = error_line(o);
    EXPECT_TRUE(has(m, ": cannot write") && has(m, "No space left on device")) << o.err;
    if (n > 0) {
      EXPECT_TRUE(std::regex_search(m, std::regex(R"(error: fit/[a-z_0-9]+\.(csv|txt|toml|manifest): cannot write)"))) << m;
      EXPECT_TRUE(has(m, "; fit keeps its previous results")) << m;
    } else {
      EXPECT_TRUE(has(m, "fit.lock: cannot write the lock file")) << m;  // not even the lock fits
    }
    EXPECT_FALSE(has(o.err, "calibrate: wrote")) << o.err;
    EXPECT_TRUE(w.files() == before) << "the previous results changed, or something was left";
    expect_no_temporaries(w);
  }
  // a first run that fails leaves no folder at all
  fs::remove_all(w.dir / "fit");
  const Outcome o = w.run(Work::calibrate(), {{"GRANFLOW_FAULT_BYTES", std::to_string(total / 2)}});
  EXPECT_EQ(o.exit_code, 2) << o.err;
  EXPECT_TRUE(has(error_line(o), "; no fit was made")) << o.err;
  EXPECT_FALSE(fs::exists(w.dir / "fit"));
  expect_no_temporaries(w);
  EXPECT_FALSE(fs::exists(w.dir / "fit.lock"));
}

TEST(IntegrityCalibrate, SynthesizeRefusesExistingDataWithoutForce) {
  const Work w("calibrate_synthesize");
  w.write("syn.toml",
          "params = \"frictional_element\"\n[[experiments]]\nname = \"uss\"\nkind = \"element\"\ndata = \"uss.csv\"\n"
          "abscissa = \"gamma\"\nquantity = \"strain\"\ntargets = { tau = \"tau\" }\n[experiments.test]\n"
          "path = \"undrained_simple_shear\"\nmodel = \"frictional\"\nprogramme = \"constant\"\nrate = 0.01\n"
          "duration = 1.0\ne0 = 0.85\nsigma_v0 = 100e3\nsolver = \"cvode\"\n");
  const std::vector<std::string> args = {"calibrate", "syn.toml", "--synthesize", "frictional_element"};
  Outcome o = w.run(args);
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const std::string made = slurp((w.dir / "uss.csv").string());
  ASSERT_TRUE(has(made, "gamma,tau\n")) << made;
  w.write("uss.csv", "gamma,tau\n0.01,1\n");  // measured data, say
  o = w.run(args);
  EXPECT_EQ(o.exit_code, 2) << o.err;
  EXPECT_TRUE(has(error_line(o), "'experiments[0].data': uss.csv exists; pass --force to replace it")) << o.err;
  EXPECT_EQ(slurp((w.dir / "uss.csv").string()), "gamma,tau\n0.01,1\n");
  std::vector<std::string> forced = args;
  forced.push_back("--force");
  o = w.run(forced);
  EXPECT_EQ(o.exit_code, 0) << o.err;
  EXPECT_EQ(slurp((w.dir / "uss.csv").string()), made);
  expect_no_temporaries(w);
}

// ---- mpm: a run folder ------------------------------------------------------------------

// A frame that does not fit on the disk mid-run: the index and the frames before stay whole,
// the last checkpoint is kept, the message says where the run stopped and how to continue; the
// restart then gives the files of an uninterrupted run, byte for byte.
TEST(IntegrityMpm, FullDiskMidRunKeepsCheckpointAndRestartsToTheSameFiles) {
  const Work w("mpm_full_disk");
  const Outcome ref = w.run(Work::mpm("ref"));
  ASSERT_EQ(ref.exit_code, 0) << ref.err;
  EXPECT_TRUE(granflow::io::verify_manifest((w.dir / "ref").string()).empty());
  for (const char* target : {"frame_0003.vtu", "frames.pvd", "runout.csv"}) {
    SCOPED_TRACE(target);
    fs::remove_all(w.dir / "o");
    // the frame fails in its first KB, the index on its third rewrite, the series a few
    // checkpoints in
    const std::string t = target;
    const std::string budget = t == "frame_0003.vtu" ? "1000" : t == "frames.pvd" ? "600" : "9000";
    const Outcome o = w.run(Work::mpm("o"), {{"GRANFLOW_FAULT_FILE", target}, {"GRANFLOW_FAULT_BYTES", budget}});
    ASSERT_EQ(o.exit_code, 2) << o.err;
    const std::string m = error_line(o);
    EXPECT_TRUE(has(m, "error: o/" + std::string(target) + ": cannot write: No space left on device")) << m;
    EXPECT_TRUE(has(m, "; the run stopped at t = ")) << m;
    EXPECT_TRUE(std::regex_search(m, std::regex(R"(its checkpoint of t = [0-9.]+ s \(o/checkpoint.bin\) is intact)"))) << m;
    EXPECT_TRUE(has(m, "when that is fixed, continue with: granflow mpm column.toml --out o --restart")) << m;
    expect_no_temporaries(w);
    expect_consistent_frames(w, "o");
    const auto names = w.names("o");
    EXPECT_TRUE(names.count("checkpoint.bin"));
    EXPECT_FALSE(names.count("granflow.manifest"));
    EXPECT_FALSE(names.count("granflow.lock"));
    const Outcome r = w.run(Work::mpm("o", {"--restart"}));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    expect_same(w.files("ref"), w.files("o"));
  }
}

// Without a checkpoint the outputs so far stay, marked by the lock file; --force takes them over.
TEST(IntegrityMpm, FullDiskBeforeAnyCheckpointThenForce) {
  const Work w("mpm_full_disk_no_checkpoint");
  const Outcome o = w.run(Work::mpm("o", {"--checkpoint-every", "10"}),
                          {{"GRANFLOW_FAULT_FILE", "frame_0002.vtu"}, {"GRANFLOW_FAULT_ERRNO", "EDQUOT"}});
  ASSERT_EQ(o.exit_code, 2) << o.err;
  const std::string m = error_line(o);
  EXPECT_TRUE(has(m, "o/frame_0002.vtu: cannot write: Disk quota exceeded (the disk quota is used up); nothing was written"))
      << m;
  EXPECT_TRUE(has(m, "no checkpoint had been written; when that is fixed, run it again with --force")) << m;
  expect_no_temporaries(w);
  expect_consistent_frames(w, "o");
  EXPECT_TRUE(w.names("o").count("granflow.lock"));
  Outcome again = w.run(Work::mpm("o"));
  EXPECT_EQ(again.exit_code, 2);
  EXPECT_TRUE(has(again.err, "exists and is not empty; use --force")) << again.err;
  again = w.run(Work::mpm("o", {"--force"}));
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_TRUE(has(again.err, "granflow: note: o/granflow.lock: took over the lock of pid ")) << again.err;
  EXPECT_TRUE(granflow::io::verify_manifest((w.dir / "o").string()).empty());
  EXPECT_FALSE(w.names("o").count("granflow.lock"));
}

// A rename that fails with EIO (not the user's to fix: exit 1) leaves the index as it was.
TEST(IntegrityMpm, FailedRenameKeepsTheIndex) {
  const Work w("mpm_rename");
  const Outcome o = w.run(Work::mpm("o"), {{"GRANFLOW_FAULT_FILE", "frame_0002.vtu"}, {"GRANFLOW_FAULT_AT", "rename"},
                                           {"GRANFLOW_FAULT_ERRNO", "EIO"}});
  EXPECT_EQ(o.exit_code, 1) << o.err;
  EXPECT_TRUE(has(error_line(o), "o/frame_0002.vtu: cannot replace: Input/output error")) << o.err;
  expect_no_temporaries(w);
  expect_consistent_frames(w, "o");
  EXPECT_FALSE(has(slurp((w.dir / "o/frames.pvd").string()), "frame_0002"));
}

// Frames are written on a thread of their own (issue 49): a frame that fails there (here its
// fsync) stops the run at the next frame or checkpoint with the same message, rc 2; the frames
// before it, the index listing just them and the checkpoint before it are intact, and the
// restart gives the files of an uninterrupted run.
TEST(IntegrityMpm, FrameFailingInTheWriterThreadStopsTheRunAndKeepsWhatCameBefore) {
  const Work w("mpm_writer_thread");
  const Outcome ref = w.run(Work::mpm("ref"));
  ASSERT_EQ(ref.exit_code, 0) << ref.err;
  const Outcome o = w.run(Work::mpm("o"), {{"GRANFLOW_FAULT_FILE", "frame_0002.vtu"}, {"GRANFLOW_FAULT_AT", "sync"}});
  ASSERT_EQ(o.exit_code, 2) << o.err;
  const std::string m = error_line(o);
  EXPECT_TRUE(has(m, "error: o/frame_0002.vtu: cannot write: No space left on device")) << m;
  EXPECT_TRUE(has(m, "; nothing was written; the run stopped at t = ")) << m;
  // frame_0002 is at t = 0.09; the checkpoint of 0.10 waits for it, and is not written
  EXPECT_TRUE(has(m, "its checkpoint of t = 0.08 s (o/checkpoint.bin) is intact")) << m;
  expect_no_temporaries(w);
  expect_consistent_frames(w, "o");
  const auto names = w.names("o");
  EXPECT_FALSE(names.count("frame_0002.vtu"));
  EXPECT_FALSE(names.count("granflow.manifest"));
  const auto before = w.files("ref"), now = w.files("o");
  for (const char* f : {"frame_0000.vtu", "frame_0001_consolidation.vtu"}) EXPECT_TRUE(now.at(f) == before.at(f)) << f;
  const std::string pvd = now.at("frames.pvd");
  EXPECT_TRUE(has(pvd, "frame_0001_consolidation.vtu") && !has(pvd, "frame_0002")) << pvd;
  const Outcome r = w.run(Work::mpm("o", {"--restart"}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same(w.files("ref"), w.files("o"));
  EXPECT_TRUE(granflow::io::verify_manifest((w.dir / "o").string()).empty());
}

// A slow disk under the frames (every step of their writes waits): the loop hands frames over
// faster than they are written, waits where two are pending, and the files are those of a run
// on a fast disk, the manifest right.
TEST(IntegrityMpm, SlowFrameWritesGiveTheSameFiles) {
  const Work w("mpm_slow_frames");
  const Outcome ref = w.run(Work::mpm("ref"));
  ASSERT_EQ(ref.exit_code, 0) << ref.err;
  const Outcome o = w.run(Work::mpm("o"), {{"GRANFLOW_FAULT_FILE", "/frame_"}, {"GRANFLOW_FAULT_DELAY_MS", "40"}});
  ASSERT_EQ(o.exit_code, 0) << o.err;
  expect_same(w.files("ref"), w.files("o"));
  EXPECT_TRUE(granflow::io::verify_manifest((w.dir / "o").string()).empty());
}

// Another run holds the folder: refused with the owner named, --force and --restart included,
// and the folder is left as it was.
TEST(IntegrityMpm, ASecondRunOnTheFolderIsRefused) {
  const Work w("mpm_locked");
  ASSERT_EQ(w.run(Work::mpm("o")).exit_code, 0);
  const auto before = w.files("o");
  {
    granflow::io::OutputLock held((w.dir / "o/granflow.lock").string(), "test");
    for (const auto& extra : std::vector<std::vector<std::string>>{{}, {"--force"}, {"--restart"}}) {
      const Outcome o = w.run(Work::mpm("o", extra));
      EXPECT_EQ(o.exit_code, 2) << o.err;
      EXPECT_TRUE(has(error_line(o), "output folder 'o' is in use by another granflow run (pid " +
                                         std::to_string(::getpid()) + " on host "))
          << o.err;
    }
    const Outcome c = [&] {
      granflow::io::OutputLock fit((w.dir / "fit.lock").string(), "test");
      return w.run(Work::calibrate({"--force"}));
    }();
    EXPECT_EQ(c.exit_code, 2) << c.err;
    EXPECT_TRUE(has(error_line(c), "output folder 'fit' is in use by another granflow run (pid ")) << c.err;
  }
  fs::remove(w.dir / "o/granflow.lock");
  expect_same(before, w.files("o"));
}

// Two --force runs started together on one folder: one runs, the other is refused naming it
// (or, if the first was already done, runs after it); the folder is one run's, whole.
TEST(IntegrityMpm, TwoForceRunsStartedTogether) {
  const Work w("mpm_two_at_once");
  ASSERT_EQ(w.run(Work::mpm("o")).exit_code, 0);
  ChildSetup a, b;
  a.tag = "_a";
  b.tag = "_b";
  const int pa = start_in(w.dir.string(), GRANFLOW_BINARY, Work::mpm("o", {"--force"}), a);
  const int pb = start_in(w.dir.string(), GRANFLOW_BINARY, Work::mpm("o", {"--force"}), b);
  const Outcome oa = finish(pa, w.dir.string(), 120, a.tag), ob = finish(pb, w.dir.string(), 120, b.tag);
  ASSERT_FALSE(oa.signaled || ob.signaled);
  EXPECT_TRUE(oa.exit_code == 0 || ob.exit_code == 0) << oa.err << ob.err;
  for (const auto* o : {&oa, &ob})
    if (o->exit_code != 0) {
      EXPECT_EQ(o->exit_code, 2) << o->err;
      const int other = o == &oa ? pb : pa;
      EXPECT_TRUE(has(error_line(*o), "is in use by another granflow run (pid " + std::to_string(other) + " ")) << o->err;
    }
  EXPECT_TRUE(granflow::io::verify_manifest((w.dir / "o").string()).empty());
  EXPECT_FALSE(w.names("o").count("granflow.lock"));
  expect_no_temporaries(w);
}

// --stop-after: the folder says 'stopped' and keeps its checkpoint; --restart removes what was
// written after the checkpoint (the stopped run's _final frame among them) and completes the run
// to the files of one uninterrupted run.
TEST(IntegrityMpm, StoppedRunResumesToTheFilesOfOneRun) {
  const Work w("mpm_stopped");
  const Outcome ref = w.run(Work::mpm("ref"));
  ASSERT_EQ(ref.exit_code, 0) << ref.err;
  const Outcome s = w.run(Work::mpm("o", {"--stop-after", "0.3"}));
  ASSERT_EQ(s.exit_code, 0) << s.err;
  const auto stopped = w.names("o");
  EXPECT_TRUE(stopped.count("checkpoint.bin"));
  EXPECT_TRUE(std::any_of(stopped.begin(), stopped.end(), [](const std::string& n) { return has(n, "_final.vtu"); }));
  const granflow::io::Manifest mf = granflow::io::read_manifest((w.dir / "o").string());
  EXPECT_TRUE(has(mf.status, "stopped at t = 0.3 s (--stop-after)")) << mf.status;
  EXPECT_TRUE(granflow::io::verify_manifest((w.dir / "o").string()).empty());
  const Outcome r = w.run(Work::mpm("o", {"--restart"}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same(w.files("ref"), w.files("o"));
  // a completed run has nothing to continue
  const Outcome again = w.run(Work::mpm("o", {"--restart"}));
  EXPECT_EQ(again.exit_code, 2);
  EXPECT_TRUE(has(error_line(again), "o/checkpoint.bin: no checkpoint to restart from")) << again.err;
  expect_same(w.files("ref"), w.files("o"));
}

TEST(IntegrityMpm, ReadOnlyFolderIsAClearError) {
  if (::geteuid() == 0) GTEST_SKIP() << "root writes into read-only folders";
  const Work w("mpm_read_only");
  fs::create_directories(w.dir / "ro");
  fs::permissions(w.dir / "ro", fs::perms::owner_read | fs::perms::owner_exec);
  const Outcome o = w.run(Work::mpm("ro/o"));
  fs::permissions(w.dir / "ro", fs::perms::owner_all);
  EXPECT_EQ(o.exit_code, 2) << o.err;
  EXPECT_TRUE(has(error_line(o), "ro/o: cannot create the folder: Permission denied")) << o.err;
  EXPECT_TRUE(fs::is_empty(w.dir / "ro"));
}
