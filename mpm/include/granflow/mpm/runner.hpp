// Backend-independent view of a simulation: the set-up on the host (particles seeded, grid,
// boundary masks per stage) and the Runner interface both backends implement. A Runner is
// one compiled combination (dimension, scalar, model, shape, boundary code on/off).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "scene.hpp"

namespace granflow::mpm {

// Host-side particle state in double precision, structure of arrays (component-major for
// vectors: x[d * n + i]). What a checkpoint would hold.
struct HostParticles {
  long n = 0;
  int dim = 2;
  std::vector<double> x, v, m;
  std::vector<double> sig, sigf;  // 6 * n, Voigt xx yy zz yz xz xy
  std::vector<double> L;          // dim * dim * n
  std::vector<double> eps, e, s;  // s = sqrt(T)
};

struct SceneSetup {
  Scene scene;
  HostParticles particles;
  std::vector<double> origin;   // grid origin (padded)
  std::vector<int> nodes;       // nodes per axis
  std::vector<AxisWalls> walls; // per axis: wall node rows for the boundary-modified B-splines
  long n_nodes = 0;
  double spacing = 0;           // initial particle spacing h / ppc_axis
  std::vector<std::vector<std::uint8_t>> stage_masks;  // one node mask per stage
  bool has_boundary = false;
  std::vector<long> tracked;    // particle index per scene.tracks entry
  double dt_estimate = 0;       // h / c_p of the at-rest material (first adaptive step: cfl times this)
};

// Seeds particles, sets the initial stress, builds the node masks and checks the scene
// (material inside the grid, time step below the stability limit, boundary conditions).
SceneSetup make_setup(const Scene& scene);

struct StepResult {
  bool ok = true;
  long particle = -1;
  std::uint32_t status = 0;
  double dt_limit = 0;  // smallest stable step over particles (when asked for)
};

struct PhaseTimes {
  double p2g = 0, grid = 0, g2p = 0;  // seconds, accumulated
  long steps = 0;
};

// What the constitutive updates reported, summed over particles and steps.
struct UpdateStats {
  long updates = 0, substeps = 0;
  long substep_limit = 0;   // substep budget exhausted (less accurate update)
  long tension_cutoff = 0;  // sigma_f set to zero
  long vs_clamped = 0;      // V_s clamped below V_sd in the kinetic functions
  long separated = 0;       // points treated as separated (e at the cap)
};

// Diagnostics of one particle.
struct PointDiagnostics {
  double p = 0, q = 0, eps_pd = 0, T = 0, eta_c = 0, K_col = 0;
};

// Per-particle output fields (diagnostics evaluated with Model::diagnostics on the host).
// A light frame (diagnostics = false) has x, v and T only, plus `subset` for chosen particles.
struct Frame {
  long n = 0;
  int dim = 2;
  std::vector<double> x, v;  // component-major
  std::vector<double> T;     // always (zero for the frictional-only model)
  std::vector<double> p, q, eps_pd, eta_c, K_col, e, sxx, syy, sxy;  // full frames only
  std::vector<PointDiagnostics> subset;  // light frames: one per requested particle
};

class Runner {
 public:
  virtual ~Runner() = default;
  virtual void set_stage(int stage, double damping, double flip) = 0;
  // One explicit step; want_dt_limit asks for the smallest stable step of the new state.
  virtual StepResult step(double dt, bool want_dt_limit) = 0;
  // Copies the state to the host; with diagnostics the derived fields of Frame are filled.
  virtual void frame(Frame& out, bool diagnostics, const std::vector<long>& subset = {}) = 0;
  virtual void download(HostParticles& out) = 0;
  virtual PhaseTimes times() const = 0;
  virtual void reset_times() = 0;
  // CPU twin only (the CUDA backend records them per particle but does not sum them yet).
  virtual UpdateStats update_stats() const { return {}; }
  virtual std::string device() const = 0;
  virtual long particles() const = 0;
  virtual long nodes() const = 0;
};

std::unique_ptr<Runner> make_cpu_runner(const SceneSetup& setup);
// Defined by the CUDA backend library; throws when CUDA was not built or no device exists.
std::unique_ptr<Runner> make_cuda_runner(const SceneSetup& setup);
bool cuda_backend_available();

}  // namespace granflow::mpm
