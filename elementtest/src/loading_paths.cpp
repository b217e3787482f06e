// Loading paths (loading_paths.hpp) and the mixed control of Driver: the unknown normal strain
// rate that holds the controlled stress of a shear box or triaxial cell constant.
#include "loading_paths.hpp"

#include "element_driver.hpp"

namespace granflow::elementtest::detail {

bool is_shear(LoadingPath p) {
  return p == LoadingPath::UndrainedSimpleShear || p == LoadingPath::SimpleShearConstantNormal;
}
bool is_mixed(LoadingPath p) {
  return p == LoadingPath::SimpleShearConstantNormal || p == LoadingPath::DrainedTriaxial;
}
int controlled_index(LoadingPath p) {
  return p == LoadingPath::SimpleShearConstantNormal || p == LoadingPath::Oedometric ? 1 : 0;
}

M3 velocity_gradient(LoadingPath p, double r, double u) {
  M3 L = M3::Zero();
  switch (p) {
    case LoadingPath::UndrainedSimpleShear: L(0, 1) = r; break;
    case LoadingPath::SimpleShearConstantNormal: L(0, 1) = r; L(1, 1) = u; break;
    case LoadingPath::DrainedTriaxial: L(1, 1) = -r; L(0, 0) = L(2, 2) = u; break;
    case LoadingPath::UndrainedTriaxial: L(1, 1) = -r; L(0, 0) = L(2, 2) = 0.5 * r; break;
    case LoadingPath::Oedometric: L(1, 1) = -r; break;
    case LoadingPath::Isotropic: L = -r * M3::Identity(); break;
  }
  return L;
}

// "Controlled" normal stress: sigma_f,ii - p_c (the viscous normal stress of the collisional
// part is not controlled: it would make the mixed control an index-2 DAE in D).
template <class Model>
double Driver<Model>::controlled_stress(const ElementState& x) const {
  const int i = controlled_index(test_.path);
  double v = 0;
  if constexpr (kF) v += x.sf(i, i);
  if constexpr (kC) {
    const auto& c = cpar(p_);
    const KineticCoefficients<double> kc = kinetic_coefficients(c, 1.0 / (1.0 + x.e));
    v -= collisional_transport(c, kc, x.s).p;
  }
  return v;
}

template <class Model>
double Driver<Model>::controlled_rate(const ElementState& x, const ElementState& d) const {
  const int i = controlled_index(test_.path);
  double v = 0;
  if constexpr (kF) v += d.sf(i, i);
  if constexpr (kC) {
    // d(-p_c)/dt = -rho_p [ d(V_s p*)/de de/dt s^2 + V_s p* 2 s ds/dt ]
    const auto& c = cpar(p_);
    auto vp = [&](double e) {
      const KineticCoefficients<double> kc = kinetic_coefficients(c, 1.0 / (1.0 + e));
      return kc.Vs * kc.p_star;
    };
    const double h = 1e-7 * (1.0 + x.e);
    const double dvp = (vp(x.e + h) - vp(x.e - h)) / (2 * h);
    v -= c.rho_p * (dvp * d.e * x.s * x.s + vp(x.e) * 2.0 * x.s * d.s);
  }
  return v;
}

// Solves the mixed control for u (secant on a piecewise-linear function); returns L.
template <class Model>
M3 Driver<Model>::solve_mixed(const ElementState& x, double r, bool plastic) const {
  const double target = controlled_target_rate(r);
  auto g = [&](double u) { return controlled_rate(x, rates_for(x, L_of(r, u), plastic)) - target; };
  double u0 = 0, g0 = g(u0);
  // second guess: half the control rate (drained triaxial), or a strain rate of the order of
  // the stress rate over sigma_ref (stress control)
  double u1 = stress_control() ? -1e-3 * r / sigma_ref_ - 1e-12 : -0.5 * r - 1e-12, g1 = g(u1);
  const double tol = 1e-12 * (std::fabs(g0) + std::fabs(g1)) + 1e-300;
  for (int it = 0; it < 40 && std::fabs(g1) > tol; ++it) {
    if (g1 == g0) break;
    const double u2 = u1 - g1 * (u1 - u0) / (g1 - g0);
    u0 = u1; g0 = g1;
    u1 = u2; g1 = g(u1);
  }
  return L_of(r, u1);
}

template <class Model>
M3 Driver<Model>::grad_v(const ElementState& x, double r, bool plastic) const {
  return mixed() ? solve_mixed(x, r, plastic) : velocity_gradient(test_.path, r, 0.0);
}

#define GRANFLOW_INSTANTIATE(Model)                                                                 \
  template double Driver<Model>::controlled_stress(const ElementState&) const;                        \
  template double Driver<Model>::controlled_rate(const ElementState&, const ElementState&) const;     \
  template M3 Driver<Model>::solve_mixed(const ElementState&, double, bool) const;                    \
  template M3 Driver<Model>::grad_v(const ElementState&, double, bool) const;
GRANFLOW_ELEMENT_DRIVER_MODELS(GRANFLOW_INSTANTIATE)
#undef GRANFLOW_INSTANTIATE

}  // namespace granflow::elementtest::detail
