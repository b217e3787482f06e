// State of a material point's frictional part (MODEL.md 1.3).
#pragma once

#include "../tensor.hpp"

namespace granflow {

template <class S>
struct FrictionalState {
  Mat3<S> sigma = Mat3<S>::Zero();  // frictional Cauchy stress, tension-positive
  S eps_pd = 0;                     // accumulated equivalent plastic deviatoric strain
  S e = 0;                          // void ratio
};

}  // namespace granflow
