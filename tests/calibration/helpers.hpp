// Shared helpers of the calibration tests: a scratch folder and error-message checks.
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <unistd.h>

#include <granflow/io/input_error.hpp>

namespace granflow::calibration::test {

namespace fs = std::filesystem;

inline std::string source_dir() { return GRANFLOW_SOURCE_DIR; }

class Scratch {
 public:
  Scratch() {
    static std::atomic<int> counter{0};
    dir_ = fs::temp_directory_path() /
           ("granflow_calib_" + std::to_string(getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  ~Scratch() { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) const {
    const fs::path p = dir_ / name;
    fs::create_directories(p.parent_path());
    std::ofstream(p) << text;
    return p.string();
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

 private:
  fs::path dir_;
};

// Runs f, expects an io::InputError whose message contains every fragment.
inline void expect_input_error(const std::function<void()>& f, const std::vector<std::string>& fragments) {
  try {
    f();
    ADD_FAILURE() << "no error raised; expected one containing '" << fragments.front() << "'";
  } catch (const io::InputError& e) {
    const std::string msg = e.what();
    for (const auto& frag : fragments) EXPECT_NE(msg.find(frag), std::string::npos) << "message: " << msg << "\nmissing: " << frag;
  }
}

// Every parameter the Jacobian analysis calls identifiable (approximate relative standard
// deviation below 2.5 %, so 5 % is two standard deviations, and in no pair with |correlation| > 0.95)
// must be recovered within 5 %; `expected` lists the parameters that must be identifiable.
template <class Job, class Result>
void expect_recovered(const Job& job, const Result& r, const std::vector<std::pair<std::string, double>>& truth,
                      const std::vector<std::string>& expected, const std::string& report) {
  for (std::size_t j = 0; j < job.free.size(); ++j) {
    bool correlated = r.identifiability.singular;
    for (const auto& [a, b] : r.identifiability.correlated) correlated = correlated || a == j || b == j;
    const bool identifiable = !correlated && r.identifiability.rel_sd[j] < 0.025;
    double t = 0;
    for (const auto& [k, v] : truth)
      if (k == job.free[j].key) t = v;
    if (identifiable) {
      EXPECT_NEAR(r.theta[j], t, 0.05 * std::fabs(t)) << job.free[j].key << "\n" << report;
    }
    for (const auto& e : expected)
      if (e == job.free[j].key) EXPECT_TRUE(identifiable) << e << " should be identifiable\n" << report;
  }
}

}  // namespace granflow::calibration::test
