// Maps and deposit measures of a 3D terrain run (docs/mpm_terrain.md, "Maps"), or profiles of a
// 2D run over a base: per cell of the
// terrain raster inside the grid's footprint, the bulk thickness (point volumes over the cell's
// area), and the largest speed and thickness over the run's samples; and per sample the
// deposit's area, volume and extent along a plan direction. Host-side, from frames.
#pragma once

#include <string>
#include <vector>

#include "runner.hpp"

namespace granflow::mpm {

struct DepositRow {
  double t = 0, t_flow = 0;
  double area = 0, volume = 0, extent = 0;  // m^2, m^3, m
  // 3D: the points below the terrain at the sample and the deepest one's depth along the
  // ground's normal [m] (0 and 0 when none is).
  double ground_points = 0, ground_depth = 0;
  // 3D with output.deposit_centre: the deposit's edge about it (deposit_edges) [m], over
  // all directions, and over the cells within 15 deg of a grid axis and of a diagonal.
  double edge_radius = 0, edge_axes = 0, edge_diagonals = 0;
};

// The deposit's edge about a plan centre (x0, z0), on map cells given by their plan centres (cx,
// cz) and thickness th: the cells fall into annuli of `width` by the distance of their centres;
// each annulus's mean thickness is placed at its cells' mean distance, and the edge is where that
// piecewise-linear curve first falls below `threshold` going outward. 0 when the innermost
// annulus is already below it; NaN when none is (the deposit reaches the map's edge). A thickness
// linear in the distance across the crossing gives its root exactly. Read over all the cells, and
// over those whose direction from the centre lies within 15 deg of a grid axis (x or z), and of a
// diagonal (angles modulo 90 deg), in one pass.
struct DepositEdges {
  double all = 0, axes = 0, diagonals = 0;
};
DepositEdges deposit_edges(const std::vector<double>& cx, const std::vector<double>& cz, const std::vector<double>& th,
                           double x0, double z0, double width, double threshold);

// What a restart must continue (the checkpoint payload): the maxima and the rows so far.
struct MapsState {
  std::vector<double> max_speed, max_depth;  // window cells, row-major (empty: no maps)
  std::vector<DepositRow> deposit;
};

class TerrainMaps {
 public:
  // Inactive (nothing measured or written) unless the scene is 3D with a terrain, or 2D with a
  // base: then the "maps" are one row of bins along x (deposit_profile.csv), and deposit.csv's
  // area and volume are a length and an area per unit width.
  explicit TerrainMaps(const SceneSetup& su);
  bool active() const { return active_; }

  // Thickness per window cell of a frame: the sum of the volumes (the seeded spacing^3 each) of
  // the points whose plan position lies in the cell, over the cell's area.
  std::vector<double> thickness(const Frame& fr) const;
  // A sample at t: the maxima per cell, and a deposit row.
  void sample(double t, double t_flow, const Frame& fr);

  // The maps of the final frame, in dir/maps/: deposit_thickness, max_speed, max_depth and the
  // terrain itself, as .asc (a .prj beside each where the terrain has a coordinate system) and,
  // with GDAL, .tif; the map cells over the grid's footprint, on the terrain raster's cell lattice
  // (its cell size unless output.map_cell joins its cells).
  void write_maps(const std::string& dir, const Frame& final_frame) const;
  // dir/deposit.csv: t, t_flow [s], area [m^2], volume [m^3], extent [m].
  void write_deposit_csv(const std::string& dir) const;

  const MapsState& state() const { return st_; }
  // A checkpoint's state; refused (std::runtime_error) when its maps do not fit this set-up.
  void restore(const MapsState& s);
  // Window cells [row0, row1] x [col0, col1] of the map (row 0 the northern); the map's cells are
  // blocks of block() x block() terrain raster cells (output.map_cell), from its south-west corner.
  long row0 = 0, row1 = -1, col0 = 0, col1 = -1;
  long block() const { return block_; }

 private:
  long cell_of(double x, double z) const;  // window index of a plan position (clamped)
  void below_ground(const Frame& fr, double& count, double& deepest) const;
  double terrain_mean(long row, long col) const;  // mean elevation of a map cell's raster cells
  double cell_measure() const { return profile_ ? cellsize_ : cellsize_ * cellsize_; }  // m (2D), m^2
  bool profile_ = false;  // 2D with [base]: one row of bins along x, deposit_profile.csv
  long block_ = 1, ncols_ = 0, nrows_ = 0;
  double cellsize_ = 0;
  bool active_ = false;
  const SceneSetup* su_ = nullptr;
  double east0_ = 0, north0_ = 0;  // terrain.origin's easting and northing
  std::vector<double> cell_x_, cell_z_;  // 3D: the window cells' plan centres, grid coordinates
  double point_volume_ = 0, dir_x_ = 1, dir_z_ = 0;
  MapsState st_;
};

}  // namespace granflow::mpm
