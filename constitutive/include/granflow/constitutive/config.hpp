// Host/device portability layer of the constitutive library.
// Every function of the library is marked GF_HD so one source serves the CPU
// (element-test driver, CPU MPM twin) and CUDA kernels.
#pragma once

#if defined(__CUDACC__)
#define GF_HD __host__ __device__
#else
#define GF_HD
#endif

#define GF_HDI GF_HD inline

#include <cstdint>

namespace granflow {

// Compile-time selection of model variants (MODEL.md resolutions A1 and A8).
enum class LodeShape {
  SmoothMohrCoulomb,  // Sheng, Sloan & Yu (2000) g(theta); default
  Circular            // g == 1, compression-matched Drucker-Prager-like cone
};

// Integration of the frictional law over a strain increment (MODEL.md 3.6, A7).
enum class StressIntegrator {
  ImplicitReturn,  // backward-Euler return map in (p, dLambda) at the trial Lode angle: the
                   // default of every model (MPM and incremental driver): bounded work per point
  Hybrid,          // error-controlled substepping; an increment that exhausts the substep budget
                   // (stiff: 2 G deps >> p near the free surface) is completed by the return map
  ExplicitSubstep  // substepping only; past the budget, eight uncontrolled steps (flagged)
};

enum class RestitutionUse {
  Everywhere,      // effective restitution in all kinetic functions (the source's text)
  DissipationOnly  // effective restitution only in the cooling terms (MFIX user routine)
};

// Bit flags reported by every update; none of them stops a computation.
namespace info {
inline constexpr std::uint32_t kTensionCutoff = 1u << 0;   // p_f fell to the cut-off: sigma_f := 0
inline constexpr std::uint32_t kPressureFloor = 1u << 1;   // moduli evaluated at p_min
inline constexpr std::uint32_t kVsClamped = 1u << 2;       // V_s clamped below V_sd in kinetic functions
inline constexpr std::uint32_t kSubstepLimit = 1u << 3;    // substep budget exhausted (result less accurate)
inline constexpr std::uint32_t kReturnFallback = 1u << 6;  // return map failed; substepping used
inline constexpr std::uint32_t kNonFinite = 1u << 4;       // a non-finite value was produced: state not updated
inline constexpr std::uint32_t kInadmissible = 1u << 5;    // inadmissible input state (e <= 0, e >= 2.97, T < 0)
inline constexpr std::uint32_t kErrorMask = kNonFinite | kInadmissible;
}  // namespace info

struct UpdateInfo {
  std::uint32_t flags = 0;
  int substeps = 0;
  GF_HDI bool ok() const { return (flags & info::kErrorMask) == 0; }
};

}  // namespace granflow
