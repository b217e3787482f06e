// Table-driven bad-input harness: each case writes a few files into a fresh folder, runs a
// program (the real `granflow` binary by default) there as a subprocess and checks that
//   - it exits normally (no signal: no crash, no sanitizer abort) with the expected code,
//   - stderr holds ONE message (one line; CLI11's "Run with --help" hint aside) containing
//     every required substring (file:line, key, what is allowed),
//   - nothing was created in the folder (no output, no left-over temporary) and every file
//     the case wrote (an existing result among them) is byte-for-byte unchanged.
#pragma once

#include <map>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

namespace reliability {

// name -> content. kAbsent removes a default file from the case.
using Files = std::map<std::string, std::string>;
extern const char* const kAbsent;

struct Case {
  std::string name;                 // test name (letters, digits, '_')
  Files files;                      // written before the run (merged over the defaults)
  std::vector<std::string> argv;    // arguments; argv[0] "@csv" runs granflow_csv_probe instead of granflow
  int exit_code;                    // expected exit status (2: input error, 1: run failure, 1xx: CLI11)
  std::vector<std::string> stderr_has;  // required substrings of the one message
  std::vector<std::pair<std::string, std::string>> env = {};  // set in the child (after GRANFLOW_DATA_DIR)
};

inline void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

struct Outcome {
  bool signaled = false;
  int signal = 0;
  int exit_code = -1;
  bool timed_out = false;
  std::string out, err;
};

// What the child gets besides GRANFLOW_DATA_DIR: environment variables (e.g. GRANFLOW_FAULT_*,
// see granflow/io/output.hpp) and a file-size limit (RLIMIT_FSIZE, with SIGXFSZ ignored).
struct ChildSetup {
  std::vector<std::pair<std::string, std::string>> env;
  long file_size_limit = -1;  // bytes; < 0: none
  long address_space_limit = -1;  // bytes (RLIMIT_AS); < 0: none
  std::string tag = "";       // stdout/stderr go to dir/../stdout<tag>.txt (runs at the same time)
};

// Runs program with args in folder dir (cwd), with GRANFLOW_DATA_DIR set to the source data;
// stdout and stderr go to dir/../stdout.txt and stderr.txt.
Outcome run_in(const std::string& dir, const std::string& program, const std::vector<std::string>& args,
               double timeout_s = 120.0, const ChildSetup& setup = {});
// The same in two halves: start it (returns the pid), then wait for it (SIGKILL after timeout_s).
int start_in(const std::string& dir, const std::string& program, const std::vector<std::string>& args,
             const ChildSetup& setup = {});
Outcome finish(int pid, const std::string& dir, double timeout_s = 120.0, const std::string& tag = "");

// Returns base with the first occurrence of `from` replaced by `to`; a marker that fails the
// case when `from` is not in base (so a stale edit cannot silently test the good file).
std::string edit(const std::string& base, const std::string& from, const std::string& to);

// TempDir()/<prefix>_<pid>: scratch space of this test process (worktrees on one machine run the
// suites at the same time); removed at exit when every test passed, kept for a look otherwise.
std::string scratch_root(const std::string& prefix);
std::string drop_line(const std::string& base, const std::string& line_start);
// The whole file as bytes (empty when it cannot be read).
std::string slurp(const std::string& path);

// The CI column (mpm/scenes/column_collapse_ci.toml) on a 20 mm grid: 0.04 s consolidation +
// 0.36 s collapse (2000 steps, about half a second), a checkpoint every 0.02 s, frames at 0.05,
// 0.25 and 0.36 s. Holds "<edit target not found>" when the shipped scene changed.
std::string small_column_scene();

}  // namespace reliability
