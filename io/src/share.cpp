#include <granflow/io/share.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <granflow/io/parameter_set.hpp>

#ifndef GRANFLOW_BIN_TO_SHARE  // set by io/CMakeLists.txt from GNUInstallDirs
#define GRANFLOW_BIN_TO_SHARE "../share/granflow"
#endif

namespace granflow::io {

namespace fs = std::filesystem;

namespace {

// A folder laid out as the source tree: it has data/params.
bool is_share_root(const fs::path& p) {
  std::error_code ec;
  return !p.empty() && fs::is_directory(p / "data" / "params", ec);
}

// 2 and 3 of share.hpp, from the program's folder; "" if neither applies.
std::string from_program() {
  const std::string exe_dir = program_directory();
  if (exe_dir.empty()) return "";
  const fs::path installed = fs::path(exe_dir) / GRANFLOW_BIN_TO_SHARE;
  if (is_share_root(installed)) return installed.lexically_normal().string();
  // Build tree: granflow_source_dir.txt in the build folder, at most four levels above a test.
  fs::path dir = exe_dir;
  for (int up = 0; up < 5 && !dir.empty(); ++up, dir = dir.parent_path()) {
    std::ifstream in(dir / "granflow_source_dir.txt");
    std::string source;
    if (in && std::getline(in, source) && is_share_root(source)) return source;
    if (dir == dir.root_path()) break;
  }
  return "";
}

}  // namespace

std::string program_directory() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : exe.parent_path().string();
}

std::string share_directory() {
  if (const char* env = std::getenv("GRANFLOW_DATA_DIR"); env && *env)
    return (fs::path(env) / "..").lexically_normal().string();
  static const std::string found = [] {
    const std::string p = from_program();
    return p.empty() ? std::string(".") : p;
  }();
  return found;
}

std::string data_directory() {
  if (const char* env = std::getenv("GRANFLOW_DATA_DIR"); env && *env) return env;
  return (fs::path(share_directory()) / "data").string();
}

std::string data_directory_origin() {
  std::error_code ec;
  if (const char* env = std::getenv("GRANFLOW_DATA_DIR"); env && *env) {
    std::string s = "GRANFLOW_DATA_DIR = '" + std::string(env) + "'";
    if (fs::path(env).is_relative()) s += ", a relative path: from the current folder " + fs::current_path(ec).string();
    return s;
  }
  std::string searched;
  if (const std::string exe = program_directory(); !exe.empty())
    searched = (fs::path(exe) / GRANFLOW_BIN_TO_SHARE / "data").lexically_normal().string() +
               ", the source tree of a build folder above " + exe + ", ";
  return "GRANFLOW_DATA_DIR is not set; searched: " + searched + "./data";
}

std::string script_path(const std::string& name) {
  std::error_code ec;
  for (const std::string& root : {share_directory(), from_program(), std::string(".")}) {
    if (root.empty()) continue;
    const fs::path p = fs::path(root) / "scripts" / name;
    if (fs::is_regular_file(p, ec)) return p.string();
  }
  return "";
}

}  // namespace granflow::io
