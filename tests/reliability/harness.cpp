#include "harness.hpp"

#include <fcntl.h>
#include <signal.h>
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

int start_in(const std::string& dir, const std::string& program, const std::vector<std::string>& args) {
  const std::string out_path = dir + "/../" + "stdout.txt", err_path = dir + "/../" + "stderr.txt";
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
    std::vector<char*> av;
    av.push_back(const_cast<char*>(program.c_str()));
    for (const auto& a : args) av.push_back(const_cast<char*>(a.c_str()));
    av.push_back(nullptr);
    ::execv(program.c_str(), av.data());
    ::_exit(127);
  }
  return pid;
}

Outcome finish(int pid, const std::string& dir, double timeout_s) {
  Outcome o;
  const std::string out_path = dir + "/../" + "stdout.txt", err_path = dir + "/../" + "stderr.txt";
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
               double timeout_s) {
  return finish(start_in(dir, program, args), dir, timeout_s);
}

}  // namespace reliability
