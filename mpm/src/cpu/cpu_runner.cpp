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
      // fp64 only: the twin's split is the decomposition's test bed, and each compiled
      // combination costs CI about a second (the fp32 and mixed ones another minute).
      if constexpr (std::is_same_v<S, double> && std::is_same_v<typename Model::Scalar, double>)
        return std::make_unique<cpu::SlabRunner<D, S, Model, Shape, kB, kM>>(su, slabs);
      else
        throw std::invalid_argument(std::string("slabs: the CPU twin splits fp64 scenes only (solver.precision = ") +
                                    precision_name(su.scene.precision) + ")");
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
