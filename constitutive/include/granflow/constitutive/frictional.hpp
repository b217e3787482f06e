// Frictional part: SIMSAND-type critical-state elastoplasticity (MODEL.md 3), one header per
// concern under frictional/:
//   state.hpp           FrictionalState: stress, plastic strain, void ratio (1.3)
//   elasticity.hpp      moduli K, G and the elastic predictor, Eq. (13) (3.2)
//   critical_state.hpp  critical void ratio e_c, Eq. (16), and the angle trigonometry (3.3)
//   lode_shape.hpp      deviatoric shape g(theta) (3.4, A1)
//   yield_state.hpp     yield function, Eq. (14), hardening, flow rule, Eq. (15), angles,
//                       Eqs. (17)-(18); initial hardening variable (3.4-3.5, A4)
//   rate.hpp            consistency and plastic multiplier, rate form (3.6)
//   return_map.hpp      implicit return map, the default integrator (3.6, A7)
//   substepping.hpp     modified-Euler substepping with error control (3.6, A7)
//   update.hpp          the update from a velocity gradient: objective rotation (3.1, A6)
//
// One rate law (frictional_rate) serves every driver: the CVODE element test integrates it
// directly; the incremental update (frictional_increment) integrates it over a strain
// increment with the explicit modified-Euler substepping of Sloan et al. (2001), local error
// control and yield-surface drift correction. The models' update (frictional_update) uses the
// implicit return map unless StressIntegrator asks for substepping.
#pragma once

#include "config.hpp"
#include "frictional/critical_state.hpp"
#include "frictional/elasticity.hpp"
#include "frictional/lode_shape.hpp"
#include "frictional/rate.hpp"
#include "frictional/return_map.hpp"
#include "frictional/state.hpp"
#include "frictional/substepping.hpp"
#include "frictional/update.hpp"
#include "frictional/yield_state.hpp"

namespace granflow {

// The tolerance table reproduces the FP64 literals exactly for double (double results unchanged).
static_assert(Tolerances<double>::kIsotropic == 1e-10 && Tolerances<double>::kVolResidual == 1e-12 &&
                  Tolerances<double>::kMinSubstep == 1e-9 && Tolerances<double>::kFtol == 1e-9 &&
                  Tolerances<double>::kStol == 1e-6,
              "FP64 tolerances changed");

}  // namespace granflow
