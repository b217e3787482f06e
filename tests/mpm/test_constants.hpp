// Constants the MPM test sources share (one definition: the unity build compiles several test
// sources as one translation unit).
#pragma once

#include <cmath>
#include <string>

inline constexpr double kG = 9.81;            // gravity [m/s^2]
inline constexpr double kDeg = M_PI / 180;    // one degree [rad]
inline const std::string kScenes = std::string(GRANFLOW_SOURCE_DIR) + "/mpm/scenes/";
