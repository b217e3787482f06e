#include "harness.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

namespace reliability {

const char* const kAbsent = "\x02<absent>";
static const char* const kEditMissing = "\x01<edit target not found>: ";

std::string edit(const std::string& base, const std::string& from, const std::string& to) {
  const auto at = base.find(from);
  if (at == std::string::npos) return kEditMissing + from;
  return base.substr(0, at) + to + base.substr(at + from.size());
}

std::string drop_line(const std::string& base, const std::string& line_start) {
  const auto at = base.find("\n" + line_start);
  if (at == std::string::npos) return kEditMissing + line_start;
  const auto end = base.find('\n', at + 1);
  return base.substr(0, at) + (end == std::string::npos ? "\n" : base.substr(end));
}

namespace {

class ScratchCleanup : public ::testing::Environment {
 public:
  explicit ScratchCleanup(std::string root) : root_(std::move(root)) {}
  void TearDown() override {
    std::error_code ec;
    if (!::testing::UnitTest::GetInstance()->Failed()) std::filesystem::remove_all(root_, ec);
  }

 private:
  std::string root_;
};

}  // namespace

std::string scratch_root(const std::string& prefix) {
  static std::string root;
  if (root.empty()) {
    root = (std::filesystem::path(::testing::TempDir()) / (prefix + "_" + std::to_string(::getpid()))).string();
    ::testing::AddGlobalTestEnvironment(new ScratchCleanup(root));
  }
  return root;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

int start_in(const std::string& dir, const std::string& program, const std::vector<std::string>& args,
             const ChildSetup& setup) {
  const std::string out_path = dir + "/../stdout" + setup.tag + ".txt", err_path = dir + "/../stderr" + setup.tag + ".txt";
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (::chdir(dir.c_str()) != 0) ::_exit(126);
    const int fo = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int fe = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int fi = ::open("/dev/null", O_RDONLY);
    if (fo < 0 || fe < 0 || fi < 0) ::_exit(126);
    ::dup2(fi, 0);
    ::dup2(fo, 1);
    ::dup2(fe, 2);
    ::setenv("GRANFLOW_DATA_DIR", GRANFLOW_SOURCE_DIR "/data", 1);
    for (const auto& [k, v] : setup.env) ::setenv(k.c_str(), v.c_str(), 1);
    if (setup.file_size_limit >= 0) {
      ::signal(SIGXFSZ, SIG_IGN);  // write() then fails with EFBIG instead of killing the process
      const rlimit r{static_cast<rlim_t>(setup.file_size_limit), static_cast<rlim_t>(setup.file_size_limit)};
      if (::setrlimit(RLIMIT_FSIZE, &r) != 0) ::_exit(125);
    }
    if (setup.address_space_limit >= 0) {
      const rlimit r{static_cast<rlim_t>(setup.address_space_limit), static_cast<rlim_t>(setup.address_space_limit)};
      if (::setrlimit(RLIMIT_AS, &r) != 0) ::_exit(125);
    }
    std::vector<char*> av;
    av.push_back(const_cast<char*>(program.c_str()));
    for (const auto& a : args) av.push_back(const_cast<char*>(a.c_str()));
    av.push_back(nullptr);
    ::execv(program.c_str(), av.data());
    ::_exit(127);
  }
  return pid;
}

Outcome finish(int pid, const std::string& dir, double timeout_s, const std::string& tag) {
  Outcome o;
  const std::string out_path = dir + "/../stdout" + tag + ".txt", err_path = dir + "/../stderr" + tag + ".txt";
  const auto t0 = std::chrono::steady_clock::now();
  int status = 0;
  for (;;) {
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) break;
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > timeout_s) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      o.timed_out = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  if (WIFSIGNALED(status)) {
    o.signaled = true;
    o.signal = WTERMSIG(status);
  } else if (WIFEXITED(status)) {
    o.exit_code = WEXITSTATUS(status);
  }
  o.out = slurp(out_path);
  o.err = slurp(err_path);
  return o;
}

Outcome run_in(const std::string& dir, const std::string& program, const std::vector<std::string>& args,
               double timeout_s, const ChildSetup& setup) {
  return finish(start_in(dir, program, args, setup), dir, timeout_s, setup.tag);
}

std::string small_column_scene() {
  std::string s = slurp(std::string(GRANFLOW_SOURCE_DIR) + "/mpm/scenes/column_collapse_ci.toml");
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
           {"size = [0.60, 0.15]", "size = [0.60, 0.16]"},
           {"h = 0.01", "h = 0.02"},
           {"dt = 5e-5", "dt = 2e-4"},
           {"duration = 0.1\n", "duration = 0.04\n"},
           {"duration = 0.4\n", "duration = 0.36\n"},
           {"times = [0.05, 0.25, 0.4]", "times = [0.05, 0.25, 0.36]\ncheckpoint_dt = 0.02"},
           {"series_dt = 5e-3", "series_dt = 0.004"}})
    s = edit(s, from, to);
  return s;
}

}  // namespace reliability
