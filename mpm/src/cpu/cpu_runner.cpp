// The CPU twin's runners: one per compiled combination, whole or split into slabs along x.
#include <string>
#include <type_traits>

#include "cpu/cpu_slabs.hpp"

namespace granflow::mpm {
namespace {

struct MakeCpu {
  SlabOptions slabs;
  template <int D, class S, class Model, class Shape, bool kB, bool kM>
  std::unique_ptr<Runner> run(const SceneSetup& su) {
    if (slabs.slabs > 1) {
      // The twin's split is the decomposition's test bed, compiled for what its tests run: fp64
      // scenes of one material with a wall, a base or a gate (8 combinations). Each costs CI's
      // builds time; the others are refused.
      if constexpr (std::is_same_v<S, double> && std::is_same_v<typename Model::Scalar, double> && kB && !kM)
        return std::make_unique<cpu::SlabRunner<D, S, Model, Shape, kB, kM>>(su, slabs);
      else if (su.scene.precision != Precision::FP64)
        throw std::invalid_argument(std::string("slabs: the CPU twin splits fp64 scenes only (solver.precision = ") +
                                    precision_name(su.scene.precision) + ")");
      else if (su.scene.material_count() > 1)
        throw std::invalid_argument("slabs: scenes of several materials are not split yet (this one has " +
                                    std::to_string(su.scene.material_count()) + ")");
      else
        throw std::invalid_argument("slabs: a scene without a wall, a base or a gate is not split");
    }
    return std::make_unique<cpu::CpuRunner<D, S, Model, Shape, kB, kM>>(su);
  }
};

}  // namespace

std::unique_ptr<Runner> make_cpu_runner(const SceneSetup& su) { return detail::dispatch(su, MakeCpu{}); }
std::unique_ptr<Runner> make_cpu_runner(const SceneSetup& su, const SlabOptions& slabs) {
  return detail::dispatch(su, MakeCpu{slabs});
}

}  // namespace granflow::mpm
