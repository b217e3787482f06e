// The CPU twin's runners: one per compiled combination, whole or split into slabs along x.
#include "cpu/cpu_slabs.hpp"

namespace granflow::mpm {
namespace {

struct MakeCpu {
  SlabOptions slabs;
  template <int D, class S, class Model, class Shape, bool kB, bool kM>
  std::unique_ptr<Runner> run(const SceneSetup& su) {
    if (slabs.slabs > 1) return std::make_unique<cpu::SlabRunner<D, S, Model, Shape, kB, kM>>(su, slabs);
    return std::make_unique<cpu::CpuRunner<D, S, Model, Shape, kB, kM>>(su);
  }
};

}  // namespace

std::unique_ptr<Runner> make_cpu_runner(const SceneSetup& su) { return detail::dispatch(su, MakeCpu{}); }
std::unique_ptr<Runner> make_cpu_runner(const SceneSetup& su, const SlabOptions& slabs) {
  return detail::dispatch(su, MakeCpu{slabs});
}

}  // namespace granflow::mpm
