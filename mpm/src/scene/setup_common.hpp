// What make_setup's parts share: the scene's error, numbers in its messages, the base's height, the memory estimate.
#pragma once

#include <cstddef>
#include <sstream>
#include <string>
#include <vector>

#include <granflow/mpm/runner.hpp>

namespace granflow::mpm::detail {

[[noreturn]] inline void fail(const std::string& key, const std::string& msg) { throw SceneError(key, msg); }

inline std::string fmt(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// The base polyline's height at x, level beyond its ends.
inline double polyline(const std::vector<double>& xs, const std::vector<double>& ys, double x) {
  if (x <= xs.front()) return ys.front();
  if (x >= xs.back()) return ys.back();
  for (size_t i = 1; i < xs.size(); ++i)
    if (x <= xs[i]) return ys[i - 1] + (ys[i] - ys[i - 1]) * (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
  return ys.back();
}

// Host memory of a run, roughly: grid fields, masks and bins per node; the packed particle
// buffer, its host copy and the per-particle work arrays.
inline double memory_bytes(int D, double nodes, double particles, size_t stages) {
  const double per_node = 8.0 * (1 + 4 * D) + 24 + static_cast<double>(stages);
  const double per_particle = 2 * 8.0 * (2 * D + 1 + 6 + D * D + 6 + 3) + 32;
  return nodes * per_node + particles * per_particle;
}

inline std::string gb(double bytes) {
  std::ostringstream os;
  os.precision(3);
  os << bytes / 1e9 << " GB";
  return os.str();
}

}  // namespace granflow::mpm::detail
