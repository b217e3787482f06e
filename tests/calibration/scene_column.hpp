// The CI column as a calibration experiment, shared by the scene-experiment tests.
#pragma once

#include <string>

namespace granflow::calibration::test {

// The CI column on a 20 mm grid, 0.06 s consolidation and 0.3 s collapse (1800 steps of 200 points).
inline const char* const kSets[] = {"grid.h=0.02", "grid.size=[0.6, 0.16]", "time.dt=2e-4",
                                    "stage[0].duration=0.06", "stage[1].duration=0.3", "output.times=[0.1, 0.3]", "output.series_dt=0.01"};

inline std::string set_array() {
  std::string s = "[";
  for (const char* a : kSets) s += std::string(s.size() > 1 ? ", " : "") + "\"" + a + "\"";
  return s + "]";
}

}  // namespace granflow::calibration::test
