// The CI column as a calibration experiment, shared by the scene-experiment tests.
#pragma once

#include <string>
#include <vector>

namespace granflow::calibration::test {

// The CI column on a 20 mm grid (200 points), 0.06 s consolidation and `collapse` s of collapse
// at dt = 2e-4 s (1800 steps for 0.3 s), frames at collapse / 3 and at the end.
inline std::vector<std::string> column_sets(double collapse = 0.3) {
  return {"grid.h=0.02", "grid.size=[0.6, 0.16]", "time.dt=2e-4", "stage[0].duration=0.06",
          "stage[1].duration=" + std::to_string(collapse),
          "output.times=[" + std::to_string(collapse / 3) + ", " + std::to_string(collapse) + "]",
          "output.series_dt=0.01"};
}

// The sets as a TOML array of strings (a job's `set`).
inline std::string set_array(const std::vector<std::string>& sets = column_sets()) {
  std::string s = "[";
  for (const std::string& a : sets) s += std::string(s.size() > 1 ? ", " : "") + "\"" + a + "\"";
  return s + "]";
}

}  // namespace granflow::calibration::test
