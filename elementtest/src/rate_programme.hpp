// Rate programmes as piecewise-linear segments of the control rate in time. Segment ends are
// the programme's kinks and jumps: the solvers restart there so no step straddles one.
#pragma once

#include <vector>

#include "granflow/elementtest/run.hpp"

namespace granflow::elementtest::detail {

struct Segment {
  double t0, t1, r0, r1;
  double rate(double t) const { return t1 > t0 ? r0 + (r1 - r0) * (t - t0) / (t1 - t0) : r0; }
};

// The segments of a Constant, Acceleration or Table programme (a Sweep runs one constant
// segment per rate, built by the caller).
std::vector<Segment> segments_of(const RateProgramme& g);

}  // namespace granflow::elementtest::detail
