// Output of the element driver: the result table's rows and the times they are taken at.
#pragma once

#include <vector>

#include "granflow/elementtest/run.hpp"

namespace granflow::elementtest::detail {

// Output times of a run over [t0, t1]: `points` of them, linear or log-spaced, ending at t1.
std::vector<double> output_times(const OutputSettings& o, double t0, double t1);

}  // namespace granflow::elementtest::detail
