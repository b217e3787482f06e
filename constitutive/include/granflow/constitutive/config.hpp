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
#include <limits>

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

// How much of an update a call may do. ElasticOnly stops where a plastic return would begin:
// the update reports info::kDeferred and leaves the state untouched, so that a later Full call
// from the same state gives the result of one Full call bit for bit. The GPU's first G2P pass
// runs ElasticOnly (without the return map's code it needs half the registers, and its warps do
// not wait for a point whose return takes many iterations); a second pass runs Full on the
// deferred points alone (docs/mpm_gpu.md, "Split G2P").
enum class UpdatePart { Full, ElasticOnly };

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
inline constexpr std::uint32_t kReturnUnconverged = 1u << 6;  // return map unconverged; last iterate kept
inline constexpr std::uint32_t kNonFinite = 1u << 4;       // a non-finite value was produced: state not updated
inline constexpr std::uint32_t kInadmissible = 1u << 5;    // inadmissible input state (state_check.hpp)
inline constexpr std::uint32_t kErrorMask = kNonFinite | kInadmissible;
inline constexpr std::uint32_t kDeferred = 1u << 8;        // UpdatePart::ElasticOnly met a plastic step: state untouched
// What the return map did (cost records, docs/benchmarks.md "Plastic returns"; none is an error):
inline constexpr std::uint32_t kPlasticReturn = 1u << 9;    // the trial state lay outside the yield surface
inline constexpr std::uint32_t kFlooredReturn = 1u << 10;   // Newton handed over to the return along the pressure floor
inline constexpr std::uint32_t kBracketedReturn = 1u << 11; // ... and that to the bracketed 1D return
}  // namespace info

struct UpdateInfo {
  std::uint32_t flags = 0;
  int substeps = 0;
  int halvings = 0;  // return map: trials of halved Newton steps (after the full step was rejected)
  // The state was updated: no error, and not deferred.
  GF_HDI bool ok() const { return (flags & (info::kErrorMask | info::kDeferred)) == 0; }
  GF_HDI bool deferred() const { return (flags & info::kDeferred) != 0; }
};

// Tolerances of the stress integrators that depend on the floating-point type S (the library
// is templated on S; the MPM instantiates it for float in its "fp32" precision). Each is the
// FP64 value the library was tuned with; for a coarser type (float) it is raised to what that
// type can resolve: residual and yield tolerances to a multiple of its epsilon. For double
// every value below is exactly the FP64 literal (static_asserts at the end of frictional.hpp),
// so double results do not depend on this table.
namespace detail {
// The FP64 value for double (and finer types), the coarse one for float.
template <class S>
constexpr S tolerance_for(double fp64, double coarse) {
  return std::numeric_limits<S>::epsilon() > 1e-12 ? S(coarse) : S(fp64);
}
}  // namespace detail

template <class S>
struct Tolerances {
  static constexpr S eps = std::numeric_limits<S>::epsilon();
  // Coarser than double: tolerances come from epsilon instead of the FP64 literals.
  static constexpr bool kCoarse = std::numeric_limits<S>::epsilon() > 1e-12;

  // q / p below which a stress counts as isotropic (its deviatoric direction is round-off).
  static constexpr S kIsotropic = detail::tolerance_for<S>(1e-10, 64 * eps);
  // Return map: converged relative volumetric residual |R1|.
  static constexpr S kVolResidual = detail::tolerance_for<S>(1e-12, 32 * eps);
  // Substepping: smallest pseudo-time substep that error control may still reject.
  static constexpr S kMinSubstep = detail::tolerance_for<S>(1e-9, 64 * eps);
  // Defaults of FrictionalParams::ftol (yield surface) and ::stol (relative local error).
  static constexpr S kFtol = detail::tolerance_for<S>(1e-9, 64 * eps);
  static constexpr S kStol = detail::tolerance_for<S>(1e-6, 64 * eps);
};

}  // namespace granflow
