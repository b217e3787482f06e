// Admissible random states of the phase-transition model (column-collapse set, inside or on the
// yield surface) with random velocity gradients, shared by the float-against-double test and the
// host/device test (tests/cuda). Deterministic on every platform.
#pragma once

#include <cmath>
#include <vector>

#include "reference.hpp"

namespace granflow::test {

struct Lcg {
  unsigned long long s = 0x9E3779B97F4A7C15ull;
  double uniform() {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(s >> 11) * (1.0 / 9007199254740992.0);
  }
  double in(double a, double b) { return a + (b - a) * uniform(); }
};

struct RandomCase {
  PhaseTransitionModel<double>::State st;
  Mat3<double> L;
  double dt;
};

// p from 1 Pa to 100 kPa, deviatoric parts up to 0.3 p, eps_pd at least the value that puts the
// state on its yield surface; the largest strain increment |L| dt is 10^max_log_strain.
inline std::vector<RandomCase> random_cases(int n, double max_log_strain, unsigned long long seed) {
  Lcg rng;
  rng.s = seed;
  const auto params = table3_collapse();
  std::vector<RandomCase> cases(n);
  for (auto& c : cases) {
    const double p = std::pow(10.0, rng.in(0.0, 5.0));
    Mat3<double> s;
    for (int i = 0; i < 3; ++i)
      for (int j = i; j < 3; ++j) s(i, j) = s(j, i) = rng.in(-0.3, 0.3) * p;
    c.st.sigma_f = s - p * Mat3<double>::Identity();
    c.st.e = rng.in(0.7, 1.1);
    c.st.eps_pd = std::pow(10.0, rng.in(-5.0, -0.5));
    const double eps0 = initial_plastic_strain<LodeShape::SmoothMohrCoulomb>(params.f, c.st.sigma_f, c.st.e);
    if (eps0 < 0) c.st.sigma_f = -p * Mat3<double>::Identity();
    if (eps0 > c.st.eps_pd) c.st.eps_pd = eps0 * (1 + 1e-6);
    c.st.s = std::pow(10.0, rng.in(-8.0, -0.5));
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) c.L(i, j) = rng.in(-1.0, 1.0) * std::pow(10.0, rng.in(-2.0, 2.0));
    c.dt = std::pow(10.0, rng.in(max_log_strain - 6.0, max_log_strain - 2.0));
  }
  return cases;
}

}  // namespace granflow::test
