// Synthetic data for a job's element experiments (round-trip tests, benchmark).
#pragma once

#include <string>

#include <granflow/io/parameter_set.hpp>

namespace granflow::calibration {

struct SynthesisOptions {
  io::ParameterSet truth;    // the set the curves are generated from
  double noise = 0.02;       // relative, Gaussian
  unsigned long seed = 1;    // experiment i uses seed + i
  long stride = 1;           // keep every stride-th output row
  bool force = false;        // replace data files that exist (otherwise refused, nothing written)
};

// Writes the data file of every element experiment of the job (steady-shear ones are skipped):
// all of them or, on an error, none.
void synthesize_job_data(const std::string& job_path, const SynthesisOptions& options);

}  // namespace granflow::calibration
