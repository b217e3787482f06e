// The source's element tests (Figs. 4-7, MODEL.md 8), the DEM steady-shear comparison and the
// work-precision benchmark, as reusable definitions: `granflow figures`, `granflow bench element`
// and the tests build the same cases from here.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "run.hpp"

namespace granflow::elementtest::paper {

// Fig. 4: frictional only (Table 1), undrained simple shear from 100 kPa, K0 = 1 - sin(phi_c) (the source
// does not state the initial stress: our choice), 1 1/s to gamma = gamma_end.
ElementTest fig4_test(double e0, double gamma_end = 0.3);
// Fig. 5: collisional only (Table 2), undrained simple shear, gammadot = 50 t for 0 <= t <= 3 s.
ElementTest fig5_test(double e0);
// Fig. 6: full model (Table 3 element column), 500 Pa isotropic, 10 1/s for 0.5 s, then
// 50 1/s^2 until 20 s.
ElementTest fig6_test(double e0);
// Fig. 6 steady-state sweep over 1e-4..1e2 1/s (each rate run to gamma = 5).
ElementTest fig6_sweep(double e0);
// Fig. 7 (e0 = 1.10): a constant-rate sweep that ends at a fixed small strain gamma_end (before
// the frictional stress vanishes at gamma ~ 0.004), frictional and collisional parts vs rate.
ElementTest fig7_fixed_strain_sweep(double e0 = 1.10, double gamma_end = 0.002);

// One model curve against one DEM curve (dimensionless p, s, T vs solid fraction).
struct DemComparison {
  double mu_p = 0, eps_n = 0;
  std::vector<double> nu, p_dem, s_dem, T_dem, p_model, s_model, T_model;
  double rms_log_p = 0, rms_log_s = 0, rms_log_T = 0;  // RMS of ln(model/DEM) over points with nu < V_sd
  int points_used = 0;
};
// Steady simple shear of the collisional model (closed form, MODEL.md 5.3) against the DEM data
// file: the model takes each curve's restitution and friction and the collisional parameters
// d, V_m, V_sd of `base` (d and rho_p drop out of the dimensionless groups).
std::vector<DemComparison> dem_comparison(const std::string& csv_path, const io::ParameterSet& base);

// Writes fig4..fig7 and dem CSVs into dir; returns the list of files; logs timings.
std::vector<std::string> write_figures(const std::string& dir, std::ostream& log);

// Work-precision benchmark (CSV + table on log).
void bench_element(const std::string& dir, bool quick, std::ostream& log);

}  // namespace granflow::elementtest::paper
