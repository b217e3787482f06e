// The time loop on the host: stages, adaptive or fixed step, sampling, outputs, failure stop.
#pragma once

#include <string>
#include <vector>

#include "runner.hpp"

namespace granflow::mpm {

struct RunOptions {
  std::string out_dir;    // empty: write nothing (tests)
  bool progress = true;   // progress line on stderr
  double stop_after = -1; // > 0: stop at this simulated time (short CPU throughput runs)
  long max_span = 10000;  // most steps queued without a host round-trip (1: one per step)
};

// Run-out and height of a frame, measured along the scene's run-out polyline.
struct Measures {
  double runout = 0, height = 0, max_speed = 0, kinetic_energy = 0, mean_T = 0, max_T = 0;
};
Measures measure(const Frame& fr, const SceneSetup& su, const std::vector<double>& mass);
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

// Vertical stress against rho g depth at the end of the first stage, away from the walls.
struct ConsolidationCheck {
  bool done = false;
  double max_rel_error = 0;      // over depth bins below the top layer, middle half of the body
  double base_sigma_v = 0, base_rho_g_h = 0;
};

struct RunSummary {
  bool ok = true;
  std::string message;
  long steps = 0;
  double t_end = 0;
  double wall_s = 0;
  Measures final;
  std::vector<SeriesRow> series;
  std::vector<TrackRow> tracks;
  ConsolidationCheck consolidation;
  PhaseTimes times;
  UpdateStats stats;
  std::string device;
};

RunSummary run(const SceneSetup& su, Runner& runner, const RunOptions& opt);

// Writers (files are written to a temporary name and renamed when complete).
void write_vtu(const std::string& path, const Frame& fr, bool binary);
void write_pvd(const std::string& path, const std::vector<std::pair<double, std::string>>& frames);

}  // namespace granflow::mpm
