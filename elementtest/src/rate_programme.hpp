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
// segment per rate, built by the caller), with the sign of g.direction.
std::vector<Segment> segments_of(const RateProgramme& g);

// A Data programme as segments of constant signed rate (one per monotonic run of the control
// column) and one output time per data row: time advances by |change| / rate. Stress control
// starts at sigma_v0 and holds it while the column is below it; strain control starts at the
// first row's value (`start`, the initial eps_a).
struct DataSchedule {
  std::vector<Segment> segments;
  std::vector<double> out_times;
  double start = 0;
};
DataSchedule data_schedule(const RateProgramme& g, double sigma_v0, const std::string& file);

}  // namespace granflow::elementtest::detail
