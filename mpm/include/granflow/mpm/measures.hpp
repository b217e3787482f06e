// What a sample measures on a frame (output/measures.cpp, output/gauges.cpp): run-out, height,
// speeds and energies along the run-out polyline, the free surface, gauges, the consolidation
// check; the rows the time loop keeps of them.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "runner.hpp"

namespace granflow::mpm {

// Run-out and height of a frame, measured along the scene's run-out polyline.
struct Measures {
  double runout = 0, height = 0, max_speed = 0, kinetic_energy = 0, mean_T = 0, max_T = 0;
};
// material >= 0: of that material's points only (su.point_material), for scenes of several.
Measures measure(const Frame& fr, const SceneSetup& su, const std::vector<double>& mass, int material = -1);
// Of the runs of consecutive bins of positive weight, the one of the largest total weight (the
// first of equal ones): its first and last bin; {0, -1} when every bin is empty. The run-out's
// deposit (point counts) and a gauge's flow (mass) are such runs.
std::pair<long, long> heaviest_run(const std::vector<double>& weight);
// Free surface: for bins of one grid cell along x, the highest particle top (x, y).
std::vector<std::pair<double, double>> free_surface(const Frame& fr, const SceneSetup& su);

struct SeriesRow {
  double t, t_flow;
  int stage;
  Measures m;
};
struct TrackRow {
  double t, t_flow;
  size_t track;
  double x, y, vx, vy, p, q, eps_pd, T, eta_c, K_col;
};

// One sample of a gauge (Scene::gauges): the contiguous run of points along the line that holds
// the most mass, within width/2 of it. depth: its extent along the line; u: the mass-weighted
// velocity across the line (positive to the right of from -> to), u_along: along it; density:
// its mass over depth x width; mass_flux: rho h u [kg/(m s)]. All zero where no point is near.
struct GaugeRow {
  double t, t_flow;
  size_t gauge;
  double depth, u, u_along, density, mass_flux;
  long points;
};
std::vector<GaugeRow> measure_gauges(const Frame& fr, const SceneSetup& su, const std::vector<double>& mass,
                                     double t, double t_flow);
// dir/gauges.csv (written only for a scene with gauges).
void write_gauges_csv(const std::string& dir, const Scene& sc, const std::vector<GaugeRow>& rows);

// Vertical stress against rho g depth at the end of the first stage, away from the walls.
struct ConsolidationCheck {
  bool done = false;
  double max_rel_error = 0;      // over depth bins below the top layer, middle half of the body
  double base_sigma_v = 0, base_rho_g_h = 0;
};

// From a full frame at the end of the first stage.
ConsolidationCheck check_consolidation(const Frame& fr, const SceneSetup& su);

}  // namespace granflow::mpm
