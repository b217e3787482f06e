// Umbrella header of the granflow constitutive library (header-only, host and device).
#pragma once

#include "constitutive/collisional.hpp"
#include "constitutive/config.hpp"
#include "constitutive/frictional.hpp"
#include "constitutive/models.hpp"
#include "constitutive/params.hpp"
#include "constitutive/state_check.hpp"
#include "constitutive/tensor.hpp"
