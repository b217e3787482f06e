// Small helpers the calibration sources share (one definition: the unity build compiles several
// sources as one translation unit).
#pragma once

#include <iomanip>
#include <limits>
#include <sstream>
#include <string>

namespace granflow::calibration {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A number with `prec` significant digits.
inline std::string num(double v, int prec = 6) {
  std::ostringstream os;
  os << std::setprecision(prec) << v;
  return os.str();
}

}  // namespace granflow::calibration
