// The output layer: atomic checked writes under injected failures at every byte and step, a
// real file-size limit, locks, manifests, run folders and staged folders.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <granflow/io/input_error.hpp>
#include <granflow/io/output.hpp>
#include <granflow/io/run_folder.hpp>
#include <granflow/io/sha256.hpp>

using namespace granflow;
namespace fs = std::filesystem;

namespace {

struct Scratch {
  fs::path dir;
  Scratch() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir = fs::temp_directory_path() /
          ("granflow_output_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    fs::permissions(dir, fs::perms::owner_all, fs::perm_options::add, ec);
    fs::remove_all(dir, ec);
  }
  std::string path(const std::string& name) const { return (dir / name).string(); }
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

std::vector<std::string> listing(const fs::path& dir) {
  std::vector<std::string> v;
  for (const auto& e : fs::directory_iterator(dir)) v.push_back(e.path().filename().string());
  std::sort(v.begin(), v.end());
  return v;
}

// Installs a hook for the scope of a test.
struct Fault {
  explicit Fault(io::WriteFault f) { io::set_write_fault(std::move(f)); }
  ~Fault() { io::set_write_fault({}); }
};

// Fails the matching step with `err` once `budget` bytes have been written (Write), or at once.
io::WriteFault fail_at(io::WriteStep at, std::size_t budget = 0, int err = ENOSPC) {
  auto used = std::make_shared<std::size_t>(0);
  return [=](const std::string&, io::WriteStep step, std::size_t& bytes) -> int {
    if (step != at) return 0;
    if (step != io::WriteStep::Write) return err;
    const std::size_t left = budget - *used;
    if (left == 0) return err;
    if (bytes > left) bytes = left;
    *used += bytes;
    return 0;
  };
}

// The digest coreutils' sha256sum gives (another program than the one under test).
std::string sha256sum(const std::string& path) {
  FILE* p = ::popen(("sha256sum '" + path + "'").c_str(), "r");
  if (!p) return "popen failed";
  char digest[65] = {};
  const bool read = std::fscanf(p, "%64s", digest) == 1;
  return ::pclose(p) == 0 && read ? digest : "sha256sum failed";
}

// Bytes no text compresses to a pattern: a linear congruential sequence.
std::string noise(std::size_t n, std::uint32_t x = 12345) {
  std::string bytes(n, '\0');
  for (char& c : bytes) {
    x = x * 1664525u + 1013904223u;
    c = static_cast<char>(x >> 24);
  }
  return bytes;
}

std::string big_text(std::size_t n) {
  std::string s;
  for (std::size_t i = 0; s.size() < n; ++i) s += std::to_string(i) + ",";
  s.resize(n);
  return s;
}

}  // namespace

// The known digests through the CPU's SHA extensions (where it has them) and the portable code.
TEST(Sha256, KnownDigests) {
  for (const bool extensions : {true, false}) {
    io::sha256_allow_cpu_extensions(extensions);
    SCOPED_TRACE(io::sha256_cpu_extensions() ? "SHA extensions" : "portable");
    EXPECT_EQ(io::sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    EXPECT_EQ(io::sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    EXPECT_EQ(io::sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
              "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
    io::Sha256 pieces;  // the same bytes fed in odd pieces
    const std::string a(1000000, 'a');
    for (std::size_t at = 0; at < a.size(); at += 4099) pieces.update(std::string_view(a).substr(at, 4099));
    EXPECT_EQ(pieces.hex(), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
  }
  io::sha256_allow_cpu_extensions(true);
}

// Both paths agree on every length around the block size and on a few MB of noise.
TEST(Sha256, CpuExtensionsAndPortableCodeAgree) {
  const std::string bytes = noise(3 * 1024 * 1024 + 5);
  for (std::size_t n : {std::size_t(0), std::size_t(1), std::size_t(55), std::size_t(56), std::size_t(63),
                        std::size_t(64), std::size_t(65), std::size_t(127), std::size_t(128), std::size_t(1000),
                        bytes.size()}) {
    const std::string_view v = std::string_view(bytes).substr(0, n);
    io::sha256_allow_cpu_extensions(false);
    const std::string portable = io::sha256_hex(v);
    io::sha256_allow_cpu_extensions(true);
    EXPECT_EQ(io::sha256_hex(v), portable) << n << " bytes";
  }
  if (!io::sha256_cpu_extensions()) GTEST_SKIP() << "no SHA extensions on this CPU: only the portable code ran";
}

TEST(OutputFile, WritesThroughATemporaryAndLeavesNoneBehind) {
  Scratch s;
  io::write_file(s.path("a.csv"), "x,y\n1,2\n");
  EXPECT_EQ(slurp(s.path("a.csv")), "x,y\n1,2\n");
  {
    io::AtomicFile f(s.path("a.csv"), io::Durability::Buffered);
    f.stream() << "x,y\n" << 3 << "," << 4.5 << "\n";
    EXPECT_EQ(slurp(s.path("a.csv")), "x,y\n1,2\n") << "visible before commit";
    f.commit();
  }
  EXPECT_EQ(slurp(s.path("a.csv")), "x,y\n3,4.5\n");
  {
    io::AtomicFile f(s.path("b.csv"));
    f.stream() << "never committed\n";
  }
  EXPECT_EQ(listing(s.dir), std::vector<std::string>{"a.csv"});
}

// A failure at any byte of a file leaves the previous file and no temporary; the message names
// the file and the OS reason.
TEST(OutputFile, FailureAtEveryByteKeepsThePreviousFile) {
  Scratch s;
  const std::string target = s.path("frames.pvd");
  io::write_file(target, "previous good index\n");
  const std::string text = big_text(70000) + "\n";  // more than the 64 KiB buffer
  for (std::size_t n : {std::size_t(0), std::size_t(1), std::size_t(4095), std::size_t(65535), std::size_t(65536),
                        std::size_t(65537), text.size() - 1}) {
    SCOPED_TRACE(n);
    Fault f(fail_at(io::WriteStep::Write, n));
    try {
      io::write_file(target, text);
      FAIL() << "no error";
    } catch (const io::OutputError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(target + ": cannot write: No space left on device"), std::string::npos) << m;
      EXPECT_NE(m.find("keeps its previous content"), std::string::npos) << m;
      EXPECT_TRUE(e.user_fixable());
    }
    EXPECT_EQ(slurp(target), "previous good index\n");
    EXPECT_EQ(listing(s.dir), std::vector<std::string>{"frames.pvd"});
  }
  Fault f(fail_at(io::WriteStep::Write, text.size()));  // exactly enough room
  io::write_file(target, text);
  EXPECT_EQ(slurp(target), text);
}

TEST(OutputFile, FailureAtOpenSyncCloseAndRename) {
  Scratch s;
  const std::string target = s.path("c.csv");
  for (auto step : {io::WriteStep::Open, io::WriteStep::Sync, io::WriteStep::Close, io::WriteStep::Rename}) {
    for (int err : {EIO, EDQUOT}) {
      Fault f(fail_at(step, 0, err));
      EXPECT_THROW(io::write_file(target, "new\n"), io::OutputError);
      try {
        io::write_file(target, "new\n");
      } catch (const io::OutputError& e) {
        EXPECT_EQ(e.os_error(), err);
        EXPECT_EQ(e.user_fixable(), err == EDQUOT);
        EXPECT_NE(std::string(e.what()).find("nothing was written"), std::string::npos) << e.what();
      }
      EXPECT_TRUE(listing(s.dir).empty());
    }
  }
  // Buffered skips the sync
  Fault f(fail_at(io::WriteStep::Sync));
  io::write_file(target, "new\n", io::Durability::Buffered);
  EXPECT_EQ(slurp(target), "new\n");
}

// A real OS failure without root: a file-size limit (RLIMIT_FSIZE, SIGXFSZ ignored) gives EFBIG.
TEST(OutputFile, FileSizeLimitGivesAClearError) {
  Scratch s;
  const std::string target = s.path("series.csv");
  io::write_file(target, "old\n");
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    rlimit r{1000, 1000};
    ::setrlimit(RLIMIT_FSIZE, &r);
    try {
      io::write_file(target, big_text(5000));
    } catch (const io::OutputError& e) {
      const std::string m = e.what();
      const bool good = e.os_error() == EFBIG && m.find(target + ": cannot write: File too large") == 0 &&
                        m.find("ulimit -f") != std::string::npos;
      ::_exit(good ? 0 : 3);
    }
    ::_exit(4);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_EQ(slurp(target), "old\n");
  EXPECT_EQ(listing(s.dir), std::vector<std::string>{"series.csv"});
}

TEST(OutputFile, ReadOnlyFolderIsAUserError) {
  if (::geteuid() == 0) GTEST_SKIP() << "root writes into read-only folders";
  Scratch s;
  fs::create_directories(s.path("ro"));
  fs::permissions(s.path("ro"), fs::perms::owner_read | fs::perms::owner_exec);
  try {
    io::write_file(s.path("ro/a.csv"), "x\n");
    FAIL() << "no error";
  } catch (const io::OutputError& e) {
    EXPECT_TRUE(e.user_fixable());
    EXPECT_NE(std::string(e.what()).find("ro/a.csv: cannot write: Permission denied"), std::string::npos) << e.what();
  }
}

TEST(OutputFile, TemporaryNames) {
  EXPECT_TRUE(io::is_temporary_name("frames.pvd.tmp"));
  EXPECT_TRUE(io::is_temporary_name("frames.pvd.tmp-1234"));
  EXPECT_TRUE(io::is_temporary_name(fs::path(io::temporary_name("/x/runout.csv")).filename().string()));
  EXPECT_FALSE(io::is_temporary_name("frames.pvd"));
  EXPECT_FALSE(io::is_temporary_name("a.tmp-x"));
  EXPECT_FALSE(io::is_temporary_name(".tmp"));
}

TEST(OutputFolder, AFileInTheWayIsNamed) {
  Scratch s;
  io::write_file(s.path("f"), "a file\n");
  try {
    io::make_folder(s.path("f/sub"));
    FAIL();
  } catch (const io::OutputError& e) {
    EXPECT_NE(std::string(e.what()).find(s.path("f") + ": is a file, not a folder"), std::string::npos) << e.what();
    EXPECT_TRUE(e.user_fixable());
  }
  EXPECT_TRUE(io::make_folder(s.path("new/deeper")));
  EXPECT_FALSE(io::make_folder(s.path("new/deeper")));
}

TEST(OutputLock, SecondOwnerIsRefusedWithTheFirstNamed) {
  Scratch s;
  const std::string lock = s.path("granflow.lock");
  io::OutputLock a(lock, "output folder 'o'");
  EXPECT_TRUE(a.took_over().empty());
  try {
    io::OutputLock b(lock, "output folder 'o'");
    FAIL() << "two owners";
  } catch (const io::InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("output folder 'o' is in use by another granflow run (pid " + std::to_string(::getpid())),
              std::string::npos)
        << m;
    EXPECT_NE(m.find("lock file " + lock), std::string::npos) << m;
  }
  a.release();
  EXPECT_FALSE(fs::exists(lock));
  io::OutputLock c(lock, "output folder 'o'");
  EXPECT_TRUE(c.took_over().empty());
}

TEST(OutputLock, StaleLockOfAGoneProcessIsTakenOver) {
  Scratch s;
  const std::string lock = s.path("granflow.lock");
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ::waitpid(child, nullptr, 0);  // a pid that is gone
  char host[256] = {};
  ::gethostname(host, sizeof host - 1);
  std::ofstream(lock) << "granflow lock\npid " << child << "\nhost " << host << "\n";
  {
    io::OutputLock l(lock, "output folder 'o'");
    EXPECT_EQ(l.took_over(), "pid " + std::to_string(child) + " on host " + host);
    EXPECT_EQ(io::lock_owner(lock), "pid " + std::to_string(::getpid()) + " on host " + host);
  }
  // another host's lock is not taken: its run cannot be checked from here
  std::ofstream(lock) << "granflow lock\npid 1\nhost elsewhere-" << host << "\n";
  try {
    io::OutputLock l(lock, "output folder 'o'");
    FAIL();
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("locked by pid 1 on host elsewhere-"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("remove that file"), std::string::npos) << e.what();
  }
}

TEST(Manifest, ListsEveryFileWithSizeAndChecksumAndFindsChanges) {
  Scratch s;
  io::write_file(s.path("a.csv"), "abc");
  io::write_file(s.path("b.vtu"), "");
  std::ofstream(s.path("c.csv.tmp-77")) << "left over";
  fs::create_directories(s.path("png"));
  io::write_file(s.path("png/runout.png"), "png");
  io::write_manifest(s.dir.string(), "complete");
  const io::Manifest m = io::read_manifest(s.dir.string());
  EXPECT_EQ(m.status, "complete");
  ASSERT_EQ(m.files.size(), 3u);
  EXPECT_EQ(m.files[2].name, "png/runout.png");
  EXPECT_EQ(m.files[0].name, "a.csv");
  EXPECT_EQ(m.files[0].size, 3u);
  EXPECT_EQ(m.files[0].sha256, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_TRUE(io::verify_manifest(s.dir.string()).empty());
  std::ofstream(s.path("a.csv")) << "abd";
  std::ofstream(s.path("d.csv")) << "new";
  fs::remove(s.path("b.vtu"));
  const auto p = io::verify_manifest(s.dir.string());
  ASSERT_EQ(p.size(), 3u);
  EXPECT_EQ(p[0], "a.csv: checksum differs");
  EXPECT_EQ(p[1], "b.vtu: missing");
  EXPECT_EQ(p[2], "d.csv: not in the manifest");
}

// A file of several hashing buffers (1 MiB each) and one byte more: listed with its size on disk
// and the SHA-256 of all of it, computed here by another program (coreutils' sha256sum); a change
// of its last byte is found.
TEST(Manifest, LargeFileIsListedWithItsWholeSizeAndDigest) {
  Scratch s;
  const std::size_t size = 3 * 1024 * 1024 + 1;
  std::string bytes(size, '\0');
  std::uint32_t x = 12345;
  for (char& c : bytes) {
    x = x * 1664525u + 1013904223u;
    c = static_cast<char>(x >> 24);
  }
  io::write_file(s.path("big.vtu"), bytes);
  io::write_manifest(s.dir.string(), "complete");
  const io::Manifest m = io::read_manifest(s.dir.string());
  ASSERT_EQ(m.files.size(), 1u);
  EXPECT_EQ(m.files[0].size, fs::file_size(s.path("big.vtu")));
  EXPECT_EQ(m.files[0].size, size);
  FILE* p = ::popen(("sha256sum '" + s.path("big.vtu") + "'").c_str(), "r");
  ASSERT_NE(p, nullptr);
  char digest[65] = {};
  const bool read = std::fscanf(p, "%64s", digest) == 1;
  ASSERT_EQ(::pclose(p), 0) << "sha256sum failed";
  ASSERT_TRUE(read);
  EXPECT_EQ(m.files[0].sha256, digest);
  EXPECT_TRUE(io::verify_manifest(s.dir.string()).empty());
  bytes.back() = static_cast<char>(bytes.back() ^ 1);
  std::ofstream(s.path("big.vtu"), std::ios::binary) << bytes;
  const auto changed = io::verify_manifest(s.dir.string());
  ASSERT_EQ(changed.size(), 1u);
  EXPECT_EQ(changed[0], "big.vtu: checksum differs");
}

// commit() records the digest of the bytes as they went out, pieces through the stream's buffer
// and pieces past it alike; it is the file's (sha256sum), and the manifest lists it without
// reading the file back or syncing it again.
TEST(Manifest, CommittedFileIsListedWithTheDigestComputedAsItWasWritten) {
  Scratch s;
  const std::string bytes = noise(3 * 1024 * 1024 + 7);
  {
    io::AtomicFile f(s.path("frame.vtu"), io::Durability::Sync);
    f.write(std::string_view(bytes).substr(0, 100));                  // buffered
    f.write(std::string_view(bytes).substr(100, 2 * 1024 * 1024));    // past the buffer
    f.stream() << std::string_view(bytes).substr(100 + 2 * 1024 * 1024);
    f.commit();
  }
  const auto c = io::committed_file(s.path("frame.vtu"));
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(c->sha256, sha256sum(s.path("frame.vtu")));
  EXPECT_EQ(c->size, bytes.size());
  EXPECT_TRUE(c->synced);
  EXPECT_TRUE(io::committed_file(s.dir.string() + "/./frame.vtu").has_value()) << "another spelling of the path";
  io::write_file(s.path("index.pvd"), "index\n", io::Durability::Buffered);
  EXPECT_FALSE(io::committed_file(s.path("index.pvd"))->synced);
  std::vector<std::string> synced;  // the manifest syncs the Buffered file only, and itself
  Fault f([&](const std::string& path, io::WriteStep step, std::size_t&) {
    if (step == io::WriteStep::Sync) synced.push_back(fs::path(path).filename().string());
    return 0;
  });
  io::write_manifest(s.dir.string(), "complete");
  EXPECT_EQ(synced, (std::vector<std::string>{"index.pvd", "granflow.manifest"}));
  const io::Manifest m = io::read_manifest(s.dir.string());
  ASSERT_EQ(m.files.size(), 2u);
  EXPECT_EQ(m.files[0].name, "frame.vtu");
  EXPECT_EQ(m.files[0].sha256, sha256sum(s.path("frame.vtu")));
  EXPECT_EQ(m.files[0].size, bytes.size());
  EXPECT_EQ(m.files[1].sha256, io::sha256_hex("index\n"));
  EXPECT_TRUE(io::verify_manifest(s.dir.string()).empty());
}

// A file changed after its commit, its size kept (a byte overwritten in place) or not, or
// replaced by another program, is read back and hashed again: the manifest has its new digest.
TEST(Manifest, FileChangedAfterItsCommitIsHashedAgain) {
  Scratch s;
  for (const char* name : {"same_size.csv", "appended.csv", "replaced.csv"}) io::write_file(s.path(name), noise(5000));
  for (const char* name : {"same_size.csv", "appended.csv", "replaced.csv"})
    ASSERT_TRUE(io::committed_file(s.path(name)).has_value()) << name;
  {
    std::fstream same(s.path("same_size.csv"), std::ios::in | std::ios::out | std::ios::binary);
    same.seekp(2500);
    same.put('\x7f');
  }
  std::ofstream(s.path("appended.csv"), std::ios::app | std::ios::binary) << "x";
  std::ofstream(s.path("other"), std::ios::binary) << noise(5000, 99);
  fs::rename(s.path("other"), s.path("replaced.csv"));
  std::vector<std::string> synced;
  Fault f([&](const std::string& path, io::WriteStep step, std::size_t&) {
    if (step == io::WriteStep::Sync) synced.push_back(fs::path(path).filename().string());
    return 0;
  });
  io::write_manifest(s.dir.string(), "complete");
  EXPECT_EQ(synced.size(), 4u) << "each file read back and synced, then the manifest";
  for (const io::ManifestEntry& e : io::read_manifest(s.dir.string()).files) {
    SCOPED_TRACE(e.name);
    EXPECT_FALSE(io::committed_file(s.path(e.name)).has_value());
    EXPECT_EQ(e.sha256, sha256sum(s.path(e.name)));
    EXPECT_EQ(e.size, fs::file_size(s.path(e.name)));
  }
  EXPECT_TRUE(io::verify_manifest(s.dir.string()).empty());
}

TEST(RunFolder, FreshCreatesAndLocksThenCompletes) {
  Scratch s;
  const std::string d = s.path("run");
  {
    io::RunFolder f(d, io::FolderUse::Fresh, "checkpoint.bin");
    EXPECT_TRUE(fs::exists(d + "/granflow.lock"));
    EXPECT_THROW(io::RunFolder(d, io::FolderUse::Force, "checkpoint.bin"), io::InputError);  // --force too
    io::write_file(d + "/runout.csv", "t\n0\n");
    fs::create_directories(d + "/png");
    io::write_file(d + "/png/runout.png", "png");
    f.complete("complete");
  }
  EXPECT_EQ(listing(d), (std::vector<std::string>{"granflow.manifest", "png", "runout.csv"}));
  EXPECT_TRUE(io::verify_manifest(d).empty());
  // fresh refuses it, leaving it as it was
  try {
    io::RunFolder f(d, io::FolderUse::Fresh, "checkpoint.bin");
    FAIL();
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("exists and is not empty; use --force"), std::string::npos);
  }
  EXPECT_EQ(listing(d), (std::vector<std::string>{"granflow.manifest", "png", "runout.csv"}));
  {  // force empties it
    io::RunFolder f(d, io::FolderUse::Force, "checkpoint.bin");
    EXPECT_EQ(listing(d), std::vector<std::string>{"granflow.lock"});
  }
  EXPECT_TRUE(fs::exists(d)) << "the folder existed before";
  EXPECT_TRUE(listing(d).empty());
}

TEST(RunFolder, ForceRefusesWhatGranflowDidNotWrite) {
  Scratch s;
  std::ofstream(s.path("notes.txt")) << "mine\n";
  try {
    io::RunFolder f(s.dir.string(), io::FolderUse::Force, "checkpoint.bin");
    FAIL();
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("is not a granflow run folder"), std::string::npos) << e.what();
  }
  EXPECT_EQ(listing(s.dir), std::vector<std::string>{"notes.txt"});
  try {
    io::RunFolder f(s.path("notes.txt"), io::FolderUse::Force, "checkpoint.bin");
    FAIL();
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("notes.txt: is a file, not a folder"), std::string::npos) << e.what();
  }
  EXPECT_EQ(slurp(s.path("notes.txt")), "mine\n");
}

TEST(RunFolder, UnfinishedOutputsKeepTheLockFileAsMarker) {
  Scratch s;
  const std::string d = s.path("run");
  {
    io::RunFolder f(d, io::FolderUse::Fresh, "checkpoint.bin");
    io::write_file(d + "/frame_0000.vtu", "x");
  }  // an error ended the run: no manifest, no checkpoint
  EXPECT_EQ(listing(d), (std::vector<std::string>{"frame_0000.vtu", "granflow.lock"}));
  {
    io::RunFolder f(d, io::FolderUse::Force, "checkpoint.bin");  // recognised, taken over
    EXPECT_EQ(listing(d), std::vector<std::string>{"granflow.lock"});
  }
  EXPECT_FALSE(fs::exists(d + "/granflow.lock"));
  {  // nothing written to a folder it made: the folder goes too
    io::RunFolder f(s.path("empty"), io::FolderUse::Fresh, "checkpoint.bin");
  }
  EXPECT_FALSE(fs::exists(s.path("empty")));
}

TEST(RunFolder, RestartKeepsOnlyTheCheckpointsFiles) {
  Scratch s;
  const std::string d = s.path("run");
  EXPECT_THROW(io::RunFolder(d, io::FolderUse::Restart, "checkpoint.bin"), io::InputError);
  EXPECT_FALSE(fs::exists(d));
  fs::create_directories(d);
  for (const char* n : {"checkpoint.bin", "frames.pvd", "frame_0000.vtu", "frame_0001_final.vtu", "granflow.manifest",
                        "profile_final.csv", "runout.csv.tmp-12"})
    std::ofstream(d + "/" + n) << n;
  fs::create_directories(d + "/png");
  std::ofstream(d + "/png/runout.png") << "snapshot of the stopped run";
  {
    io::RunFolder f(d, io::FolderUse::Restart, "checkpoint.bin");
    f.keep_only({"checkpoint.bin", "frames.pvd", "frame_0000.vtu"});
  }
  EXPECT_EQ(listing(d), (std::vector<std::string>{"checkpoint.bin", "frame_0000.vtu", "frames.pvd"}));
}

TEST(StagedFolder, SwapsInTheNewFolderAndRefusesForeignOnes) {
  Scratch s;
  const std::string d = s.path("fit");
  {
    io::StagedFolder f(d, false);
    EXPECT_TRUE(fs::exists(d + ".lock"));
    EXPECT_THROW(io::StagedFolder(d, true), io::InputError);  // locked
    io::write_file(f.staging() + "/report.txt", "one\n");
    f.commit("complete");
  }
  EXPECT_EQ(listing(s.dir), std::vector<std::string>{"fit"});
  EXPECT_EQ(listing(d), (std::vector<std::string>{"granflow.manifest", "report.txt"}));
  EXPECT_THROW(io::StagedFolder(d, false), io::InputError);
  {  // --force: a failure before the commit leaves the old results
    io::StagedFolder f(d, true);
    io::write_file(f.staging() + "/report.txt", "two\n");
  }
  EXPECT_EQ(slurp(d + "/report.txt"), "one\n");
  EXPECT_EQ(listing(s.dir), std::vector<std::string>{"fit"});
  {  // ... and at the swap too
    io::StagedFolder f(d, true);
    io::write_file(f.staging() + "/report.txt", "two\n");
    Fault fault(fail_at(io::WriteStep::Rename, 0, EIO));
    EXPECT_THROW(f.commit("complete"), io::OutputError);
  }
  EXPECT_EQ(slurp(d + "/report.txt"), "one\n");
  EXPECT_EQ(listing(s.dir), std::vector<std::string>{"fit"});
  {
    io::StagedFolder f(d, true);
    io::write_file(f.staging() + "/report.txt", "two\n");
    f.commit("complete");
  }
  EXPECT_EQ(slurp(d + "/report.txt"), "two\n");
  EXPECT_EQ(listing(s.dir), std::vector<std::string>{"fit"});
  // not granflow's: refused, untouched
  fs::create_directories(s.path("mine"));
  std::ofstream(s.path("mine/data.csv")) << "x\n";
  EXPECT_THROW(io::StagedFolder(s.path("mine"), true), io::InputError);
  EXPECT_EQ(slurp(s.path("mine/data.csv")), "x\n");
  std::ofstream(s.path("file")) << "x\n";
  EXPECT_THROW(io::StagedFolder(s.path("file"), true), io::InputError);
  EXPECT_EQ(slurp(s.path("file")), "x\n");
}

TEST(StagedFolder, RemovesTheStagingFolderOfADeadRun) {
  Scratch s;
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ::waitpid(child, nullptr, 0);
  const std::string left = s.path("fit.tmp-" + std::to_string(child));
  fs::create_directories(left);
  std::ofstream(left + "/correlation.csv") << "";
  std::vector<std::string> notes;
  static std::vector<std::string>* sink = nullptr;
  sink = &notes;
  io::set_note_sink([](const std::string& l) { sink->push_back(l); });
  {
    io::StagedFolder f(s.path("fit"), false);
  }
  io::set_note_sink(nullptr);
  EXPECT_FALSE(fs::exists(left));
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("did not finish"), std::string::npos) << notes[0];
  EXPECT_TRUE(listing(s.dir).empty());
}

// Every path through the layer, failures and refusals included, closes what it opened.
TEST(OutputFile, NoDescriptorIsLeaked) {
  auto open_fds = [] {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator("/proc/self/fd")) ++n;
    return n;
  };
  if (!fs::exists("/proc/self/fd")) GTEST_SKIP() << "no /proc";
  Scratch s;
  const std::size_t before = open_fds();
  for (auto step : {io::WriteStep::Open, io::WriteStep::Write, io::WriteStep::Sync, io::WriteStep::Close,
                    io::WriteStep::Rename}) {
    Fault f(fail_at(step, 10));
    EXPECT_THROW(io::write_file(s.path("a.csv"), big_text(100)), io::OutputError);
    EXPECT_THROW(io::write_manifest(s.dir.string(), "complete"), io::OutputError);
  }
  io::write_file(s.path("a.csv"), "x\n");
  io::write_manifest(s.dir.string(), "complete");
  EXPECT_TRUE(io::verify_manifest(s.dir.string()).empty());
  {
    io::RunFolder held(s.path("run"), io::FolderUse::Fresh, "checkpoint.bin");
    EXPECT_THROW(io::RunFolder(s.path("run"), io::FolderUse::Force, "checkpoint.bin"), io::InputError);
    Fault f(fail_at(io::WriteStep::Write));
    EXPECT_THROW(io::OutputLock(s.path("other.lock"), "x"), io::OutputError);
  }
  EXPECT_EQ(open_fds(), before);
}
