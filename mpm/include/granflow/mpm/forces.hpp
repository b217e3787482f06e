// The forces on a run's boundaries (docs/mpm_obstacles.md): rows per sample from the runner's
// sums (Runner::take_forces), obstacle_forces.csv, the pressure along 2D obstacles' faces at the
// frames, and the obstacles' geometry for ParaView. Host-side.
#pragma once

#include <string>
#include <vector>

#include "runner.hpp"

namespace granflow::mpm {

// The sums of one boundary (part < 0) or one of its parts over the steps since the last sample.
struct ForceRow {
  double t = 0, t_flow = 0;
  int boundary = 0;
  int part = -1;
  ForceSums sums;
};

// What a restart continues (the checkpoint payload): the rows so far, the runner's sums since
// the last sample, and the last sample's sums (a frame right after a restart at a sample, as
// at a stage end, writes its pressure profile from them).
struct ForcesState {
  std::vector<ForceRow> rows;
  BoundaryForces pending, last;
};

// Per boundary over a run: the largest single-step force and the total impulse (ensemble
// summaries, design studies).
// peak: the largest mean force over one output.series_dt sample (what a load cell with that
// response reads); step_peak: the largest force of a single step, which spikes when a point
// crosses a cell (10-50 times the peak on the load-cell flume: docs/mpm_results.md).
struct ForcePeak {
  std::string boundary;
  double peak = 0, impulse = 0;  // N (2D: N/m), N s (2D: N s/m; the magnitude of the summed dp)
  double t_peak = 0;             // end of the sample interval that held the peak
  double step_peak = 0;          // N (2D: N/m)
};

class ForceRecorder {
 public:
  explicit ForceRecorder(const SceneSetup& su);
  bool active() const { return active_; }

  // A sample at t: the runner's sums since the last one, as one row per boundary and, where a
  // boundary has several parts, one per part.
  void sample(double t, double t_flow, Runner& runner);
  // The same from sums already taken (an ensemble member's share of the runner's).
  void sample(double t, double t_flow, const BoundaryForces& taken);
  // dir/obstacle_forces.csv: t, t_flow, boundary, part, the mean force since the previous
  // sample, the largest single-step force, the mean normal and tangential parts, the mean
  // moment and the impulse (units in the header).
  void write_csv(const std::string& dir) const;
  // 2D obstacles: the text of obstacle_pressure_NNNN.csv (pressure_file: the frame's number)
  // from the last sample's node sums: obstacle, face, node x and y, s along the face, normal and
  // shear stress. Empty where there is none (no 2D obstacle, no sample); the frame writer
  // writes it after its frame.
  std::string pressure_csv() const;
  static std::string pressure_file(int frame_no);
  // dir/obstacles.vtu: the obstacles' outlines (2D polygons) or solids (3D), cell data `obstacle`.
  static void write_geometry(const std::string& dir, const Scene& sc);

  std::vector<ForcePeak> peaks() const;
  const std::vector<ForceRow>& rows() const { return st_.rows; }
  // A checkpoint's state: the rows and the runner's pending sums (put back into the runner).
  ForcesState state(Runner& runner) const;
  void restore(const ForcesState& s, Runner& runner);

 private:
  const SceneSetup* su_;
  bool active_ = false;
  ForcesState st_;
  BoundaryForces last_;  // the last sample's sums (pressure profiles)
};

}  // namespace granflow::mpm
