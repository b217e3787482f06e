// The MPM test scenes have a few hundred particles: more threads only add barrier waits (and on
// a shared CI machine descheduled threads stall every barrier). OMP_NUM_THREADS still rules.
#pragma once

#include <cstdlib>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace granflow::mpm::test {

inline const bool kOneThread = [] {
#ifdef _OPENMP
  if (!std::getenv("OMP_NUM_THREADS")) omp_set_num_threads(1);
#endif
  return true;
}();

}  // namespace granflow::mpm::test
