// Loading paths as velocity gradients: which component is the control rate, and which normal
// strain rate is the unknown of a mixed (stress-controlled) path. Axis 1 (y) is vertical.
#pragma once

#include <granflow/constitutive.hpp>

#include "granflow/elementtest/run.hpp"

namespace granflow::elementtest::detail {

// Simple shear (gamma = L_xy) rather than axial loading (gamma = D_xx - D_yy).
bool is_shear(LoadingPath p);
// Mixed control: one normal stress held constant by an unknown normal strain rate.
bool is_mixed(LoadingPath p);
// Stress component held constant under mixed control: yy (shear box) or xx (= zz, triaxial cell).
int controlled_index(LoadingPath p);
// Velocity gradient for control rate r and (mixed control) the unknown normal strain rate u.
Mat3<double> velocity_gradient(LoadingPath p, double r, double u);

}  // namespace granflow::elementtest::detail
