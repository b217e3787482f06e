// Backend-independent view of a simulation: the set-up on the host (particles seeded, grid,
// boundary masks per stage) and the Runner interface both backends implement. A Runner is
// one compiled combination (dimension, scalar, model, shape, boundary code on/off).
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "boundary.hpp"
#include "scene.hpp"
#include "span.hpp"

namespace granflow::mpm {

// Host-side particle state in double precision, structure of arrays (component-major for
// vectors: x[d * n + i]). What a checkpoint holds.
struct HostParticles {
  long n = 0;
  int dim = 2;
  std::vector<double> x, v, m;
  std::vector<double> sig, sigf;  // 6 * n, Voigt xx yy zz yz xz xy
  std::vector<double> L;          // dim * dim * n
  std::vector<double> eps, e, s;  // s = sqrt(T)
};

// A part of a boundary whose force is reported: the probes [first, first + count) of
// SceneSetup::probes, and the point its moments are taken about.
struct ForcePart {
  int boundary = 0;
  std::string name;  // "x-" (a wall), "base", "ground", an obstacle's face ("y+", "face2", "side")
  long first = 0, count = 0;
  double moment_point[3] = {0, 0, 0};
};

struct BoundaryForces {
  std::vector<ForceSums> parts, boundaries;  // SceneSetup::force_parts, force_boundaries
  std::vector<double> node_impulse;          // sum of dp per probe, component-major (dim x probes)
};

// Runner::take_forces and restore_forces of a back end that keeps its sums on the host.
inline void take_host_forces(BoundaryForces& sums, BoundaryForces& out, bool keep) {
  out = sums;
  if (keep) return;
  std::fill(sums.parts.begin(), sums.parts.end(), ForceSums{});
  std::fill(sums.boundaries.begin(), sums.boundaries.end(), ForceSums{});
  std::fill(sums.node_impulse.begin(), sums.node_impulse.end(), 0.0);
}
inline void restore_host_forces(BoundaryForces& sums, const BoundaryForces& in) {
  if (in.parts.size() == sums.parts.size() && in.boundaries.size() == sums.boundaries.size() &&
      in.node_impulse.size() == sums.node_impulse.size())
    sums = in;
}

struct SceneSetup {
  Scene scene;
  HostParticles particles;
  std::vector<double> origin;   // grid origin (padded)
  std::vector<int> nodes;       // nodes per axis
  std::vector<AxisWalls> walls; // per axis: wall node rows for the boundary-modified B-splines
  long n_nodes = 0;
  double spacing = 0;           // initial particle spacing h / ppc_axis
  // One node mask per stage, followed by its ContactTable where it has one (boundary.hpp).
  std::vector<std::vector<std::uint8_t>> stage_masks;
  bool has_boundary = false;
  // Frictional terrain (3D, terrain.mu): the nodes within reach of material on or below the
  // ground with its normals, for the step's terrain pass (runs only when non-empty); deeper
  // nodes and no-slip terrain are held by the masks.
  std::vector<TerrainNode> terrain;
  double terrain_mu = 0;
  // Obstacles (docs/mpm_obstacles.md): the nodes inside each or on its surface, with the
  // normal of the nearest face, for the step's obstacle pass (runs only when non-empty).
  std::vector<ObstacleNode> obstacle_nodes;
  // Forces on the boundaries (output.forces; none: no force pass): the measured nodes, in the
  // order of their parts, and the parts (a wall, the base, the terrain, an obstacle's face).
  std::vector<ForceProbe> probes;
  std::vector<ForcePart> force_parts;
  std::vector<std::string> force_boundaries;  // ForcePart::boundary indexes it
  // Per body: the volume its points stand for (count times spacing^dim) and the volume of its
  // shape (release volumes: the integral of top - bottom over the plan, sampled at a quarter
  // spacing).
  std::vector<double> seeded_volume, geometric_volume;
  std::vector<long> tracked;    // particle index per scene.tracks entry
  // Per point: its body (scene.bodies) and, with two or more materials, its material index
  // (Scene::material_at; empty with one). Ensembles: member after member, as the particles.
  std::vector<int> point_body;
  std::vector<std::uint8_t> point_material;
  double dt_estimate = 0;       // h / c_p of the at-rest material (first adaptive step: cfl times this)
  // Ensembles (make_ensemble_setup, ensemble.hpp): `members` copies of the grid above, each
  // with its particles (particles holds them member after member, particles.n / members each),
  // its material and its stage blocks (stage_masks[s] holds them mask_stride bytes apart);
  // tracked indices are those of member 0. A single run has members = 1 and none of these.
  // member_materials: the materials of member 0, then of member 1, ... (scene.material_count()
  // each).
  int members = 1;
  std::vector<Material> member_materials;
  long mask_stride = 0;
  std::vector<char> stage_contacts;  // per stage: the members' blocks hold a ContactTable
};

// The stage's block holds a ContactTable after its masks (friction or a lifting gate): its
// grid update needs the kContacts instantiation of grid_update_node.
inline bool stage_has_contacts(const SceneSetup& su, int stage) {
  if (!su.stage_contacts.empty()) return su.stage_contacts[stage] != 0;
  return su.stage_masks[stage].size() > static_cast<size_t>(su.n_nodes);
}

// Seeds particles, sets the initial stress, builds the node masks and checks the scene
// (material inside the grid, time step below the stability limit, boundary conditions).
SceneSetup make_setup(const Scene& scene);

struct StepResult {
  bool ok = true;
  long particle = -1;
  std::uint32_t status = 0;
  double dt_limit = 0;  // smallest stable step over particles (when asked for)
  long steps = 0;       // advance: steps taken, the failed one included (it is the last)
};

// A span of steps run without host round-trips (Runner::advance_span). Each step has the size
// span_step_size(t, dt, t_land); adaptive spans take the next dt from the stable limit of the
// new state (span_next_dt with dt_max). The span ends after the first step that reaches
// t >= t_until, after max_steps steps, or on a failed step.
struct Span {
  long max_steps = 1;
  double t = 0;           // time at the start
  double dt = 0;          // step size (adaptive: of the first step) before landing
  bool adaptive = false;
  double dt_max = 0;      // adaptive: the largest step
  double t_land = std::numeric_limits<double>::infinity();
  double t_until = std::numeric_limits<double>::infinity();
  bool timing = false;    // time the phases of every step (benchmarks; costs a sync per step)
};

struct SpanResult {
  bool ok = true;
  long particle = -1;        // first bad particle (index of the set-up's order)
  std::uint32_t status = 0;
  long steps = 0;            // steps taken, the failed one included
  double t = 0;              // time after the last good step
  double dt = 0;             // step size for the next span (adaptive: from the last good step)
  double h_last = 0;         // size of the last step taken (the failed one on failure)
  long shortened = 0;        // steps planned below dt_max by the stable limit (adaptive spans)
  double dt_min = std::numeric_limits<double>::infinity();  // the smallest of those
};

struct PhaseTimes {
  double p2g = 0, grid = 0, g2p = 0;  // seconds, accumulated (CUDA: only in timed spans)
  double sort = 0;                    // CUDA: reordering particles by cell (timed spans)
  double exchange = 0;                // slabs: halo copies, migration, re-partitioning
  double device = 0;                  // CUDA: device time of all spans (start to end event)
  long steps = 0;                     // steps in the phase times
  long span_steps = 0;                // steps in `device`
  long deferred = 0;                  // CUDA split G2P: updates left to the plastic pass (in `device`)
  // Share of the updates of `span_steps` steps of n points that the plastic pass did.
  double deferred_share(long n) const {
    return span_steps > 0 && n > 0 ? double(deferred) / (double(span_steps) * double(n)) : 0.0;
  }
};

// Histograms of the return map's cost: entry e counts e residual evaluations (substeps), the
// last entry every count above kCostBins - 2.
inline constexpr int kCostBins = 34;
// A point is slow from this many evaluations on (a converged Newton return needs 2-7).
inline constexpr int kSlowEvaluations = 8;

// What the constitutive updates reported, summed over particles and steps.
struct UpdateStats {
  long updates = 0, substeps = 0;
  long substep_limit = 0;   // substep budget exhausted (less accurate update)
  long tension_cutoff = 0;  // sigma_f set to zero
  long vs_clamped = 0;      // V_s clamped below V_sd in the kinetic functions
  long separated = 0;       // points treated as separated (e at the cap)
  // What a GPU warp and a one-wave kernel wait for: the largest substep (return map: residual
  // evaluation) count of one update; over groups of 32 consecutive points the sum of each group's
  // largest count; over steps the sum of each step's largest count.
  long max_substeps = 0;
  long warp_max_substeps = 0, warps = 0;
  long step_max_substeps = 0, steps = 0;
  // The plastic returns (the return map ran): their count, halving trials, hand-overs to the
  // floored and the bracketed 1D returns, and the histogram of their evaluations; per group of
  // 32 points, the histogram of the group's largest count and of its number of slow points.
  long plastic = 0, halvings = 0, floored = 0, bracketed = 0;
  std::array<long, kCostBins> plastic_evaluations{}, group_max{};
  std::array<long, 33> slow_in_group{};
  double mean_warp_max() const { return warps > 0 ? double(warp_max_substeps) / double(warps) : 0.0; }
  double mean_step_max() const { return steps > 0 ? double(step_max_substeps) / double(steps) : 0.0; }
};

inline UpdateStats operator+(UpdateStats a, const UpdateStats& b) {
  a.updates += b.updates;
  a.substeps += b.substeps;
  a.substep_limit += b.substep_limit;
  a.tension_cutoff += b.tension_cutoff;
  a.vs_clamped += b.vs_clamped;
  a.separated += b.separated;
  a.max_substeps = std::max(a.max_substeps, b.max_substeps);
  a.warp_max_substeps += b.warp_max_substeps;
  a.warps += b.warps;
  a.step_max_substeps += b.step_max_substeps;
  a.steps += b.steps;
  a.plastic += b.plastic;
  a.halvings += b.halvings;
  a.floored += b.floored;
  a.bracketed += b.bracketed;
  for (int i = 0; i < kCostBins; ++i) {
    a.plastic_evaluations[i] += b.plastic_evaluations[i];
    a.group_max[i] += b.group_max[i];
  }
  for (int i = 0; i < 33; ++i) a.slow_in_group[i] += b.slow_in_group[i];
  return a;
}

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
  std::vector<int> material, body;  // per point ids (the driver's frames; empty: not written)
  std::vector<PointDiagnostics> subset;  // light frames: one per requested particle
};

// A member of an ensemble that failed in the last step: its first bad particle (index of the
// set-up's order) and status (kernels.hpp Status).
struct MemberFailure {
  int member = 0;
  long particle = -1;
  std::uint32_t status = 0;
};

// One scene split into slabs along x, one per GPU (docs/mpm_slabs.md); the CPU twin runs the
// slabs one after another in one process. Re-partitioning moves the borders so that each slab
// holds about the same number of points.
struct SlabOptions {
  int slabs = 1;
  double imbalance = 1.2;  // re-partition when the fullest slab holds this many times the mean
  long min_steps = 100;    // steps at least between two re-partitions for imbalance
  long every = 0;          // > 0: re-partition every this many steps as well (tests)
  std::vector<int> devices;  // CUDA: the device of each slab (empty: slab s on device s)
};

// How a decomposed run went (SlabRunner; slabs = 1: not decomposed).
struct SlabReport {
  int slabs = 1;
  std::vector<int> borders;      // node columns: slab s owns [borders[s], borders[s + 1])
  long repartitions = 0;         // re-partitions that moved a border
  long checks = 0;               // re-partitions asked for (imbalance or every)
  long migrated = 0;             // points that moved to another slab, summed over steps
  double max_imbalance = 1;      // largest (fullest slab / mean) seen after a step
  long halo_nodes = 0;           // nodes exchanged per step (both directions)
};

class Runner {
 public:
  virtual ~Runner() = default;
  virtual void set_stage(int stage, double damping, double flip) = 0;
  // One explicit step; want_dt_limit asks for the smallest stable step of the new state.
  virtual StepResult step(double dt, bool want_dt_limit) = 0;
  // A span of steps with no host round-trip in between (CUDA: the steps are queued, the
  // step size and the failure flag stay on the device, one synchronisation at the end). The
  // default is the host loop over step(): its results are the step-by-step ones, bitwise.
  virtual SpanResult advance_span(const Span& s);
  // nsteps steps of size dt (benchmarks); result.steps counts the steps taken.
  StepResult advance(long nsteps, double dt, bool timing = false);
  // Copies the state to the host; with diagnostics the derived fields of Frame are filled.
  virtual void frame(Frame& out, bool diagnostics, const std::vector<long>& subset = {}) = 0;
  // A light frame that does not stop the stream (ensemble samples): snapshot() queues its copy
  // behind the steps already queued and returns; collect() waits for that copy and fills `out`.
  // collect() may run on another thread while later spans run; one snapshot is pending at a
  // time. The default (CPU twin) copies at once.
  virtual void snapshot(const std::vector<long>& subset) { frame(snapshot_, false, subset); }
  virtual void collect(Frame& out) { out = std::move(snapshot_); }
  virtual void download(HostParticles& out) = 0;
  // Replaces the particle state (a checkpoint); same count and dimension as the set-up.
  virtual void upload(const HostParticles& in) = 0;
  virtual PhaseTimes times() const = 0;
  virtual void reset_times() = 0;
  // Forces on the boundaries since the last take (SceneSetup::probes; empty when none),
  // zeroed unless `keep` (a checkpoint); restore_forces puts a checkpoint's sums back.
  virtual void take_forces(BoundaryForces& out, bool keep = false) { out = {}; (void)keep; }
  virtual void restore_forces(const BoundaryForces& in) { (void)in; }
  // The CPU twin always; CUDA with CudaOptions::update_stats (else empty).
  virtual UpdateStats update_stats() const { return {}; }
  virtual std::string device() const = 0;
  // Settings of the backend's fast paths and kernel resources (benchmark output).
  virtual std::string config() const { return ""; }
  virtual long particles() const = 0;
  virtual long nodes() const = 0;
  // Ensembles: after a failed step or span, the members that failed in its last step, each
  // with its first bad particle. They are retired: skipped by every later step, their state
  // left as the failed step made it. The other members' last step is complete.
  virtual std::vector<MemberFailure> retire_failed_members() { return {}; }
  virtual SlabReport slab_report() const { return {}; }

 private:
  Frame snapshot_;  // the default snapshot()
};

inline SpanResult Runner::advance_span(const Span& s) {
  SpanResult r;
  r.t = s.t;
  r.dt = s.dt;
  for (long k = 0; k < s.max_steps; ++k) {
    const double h = span_step_size(r.t, r.dt, s.t_land);
    const StepResult st = step(h, s.adaptive);
    ++r.steps;
    r.h_last = h;
    if (!st.ok) {
      r.ok = false;
      r.particle = st.particle;
      r.status = st.status;
      return r;
    }
    r.t += h;
    if (s.adaptive) {
      r.dt = span_next_dt(st.dt_limit, s.dt_max);
      span_count_shortened(r.dt, s.dt_max, r.shortened, r.dt_min);
    }
    if (span_reached(r.t, s.t_until)) break;
  }
  return r;
}

// The outcome of a span as a StepResult (no step limit).
inline StepResult step_result(const SpanResult& r) {
  StepResult out;
  out.ok = r.ok;
  out.particle = r.particle;
  out.status = r.status;
  out.steps = r.steps;
  return out;
}

inline StepResult Runner::advance(long nsteps, double dt, bool timing) {
  Span s;
  s.max_steps = nsteps;
  s.dt = dt;
  s.timing = timing;
  return step_result(advance_span(s));
}

// Fast paths of the CUDA backend, each with a switch for comparisons (docs/mpm_gpu.md).
struct CudaOptions {
  bool graphs = true;         // replay captured chunks of steps as CUDA graphs
  int graph_steps = 32;       // longest captured chunk (steps; rounded down to a power of two)
  // Reorder particles by cell every N steps (0: never) and scatter with warp sums: with the
  // cheaper return map the 1 mm column's step costs 131 instead of 150 us, the 5 mm flume's 81
  // instead of 89 (H100, docs/benchmarks.md); sorting also groups points of like cost in a warp.
  int sort_every = 32;
  enum class P2G { Atomic, Warp, Tile };
  P2G p2g = P2G::Warp;        // scatter: atomics per particle / per run of a warp / block tile
  int g2p_block = 128;        // threads per block of G2P + constitutive (at most 128 with the cap)
  bool g2p_reg_cap = false;   // G2P + constitutive with at most 168 registers (12 warps/SM, more spills)
  // G2P in two passes: kinematics and elastic updates, then the plastic returns of the deferred
  // points packed together (no volumetric averaging; docs/mpm_gpu.md, "Split G2P"). It pays where
  // the step is throughput-bound and costs where it is latency-bound (a plastic point's path is
  // the elastic pass plus the whole update). H100: 3D slab (8e6 points) 9.6e8 instead of 8.1e8
  // particle-updates/s in fp32; 1 mm column (2.4 waves of the fused kernel) 126 instead of 131.5
  // us per step; 5 mm flume (0.7 waves) 95 instead of 82. Auto: split from 2 waves of the fused
  // kernel up.
  enum class Split { Auto, On, Off };
  Split g2p_split = Split::Auto;
  // Reduce the per-point update records into UpdateStats after every step (a kernel per step;
  // off by default): the plastic returns' cost histograms of granflow mpm's report.
  bool update_stats = false;
};
// Sets one option from its command-line spelling (graphs on|off, graph-steps N, sort N,
// p2g atomic|warp|tile, g2p-block N, g2p-regcap on|off, g2p-split auto|on|off, update-stats on|off); false for an unknown
// name or value.
bool set_cuda_option(CudaOptions& o, const std::string& name, const std::string& value);
inline std::string describe(const CudaOptions& o) {
  const char* p2g = o.p2g == CudaOptions::P2G::Atomic ? "atomic" : o.p2g == CudaOptions::P2G::Warp ? "warp" : "tile";
  return std::string("graphs ") + (o.graphs ? "on (chunks up to " + std::to_string(o.graph_steps) + " steps)" : "off") +
         ", sort " + (o.sort_every > 0 ? "every " + std::to_string(o.sort_every) + " steps" : "off") + ", p2g " + p2g +
         ", g2p block " + std::to_string(o.g2p_block) + (o.g2p_reg_cap ? " (<= 168 registers)" : "") +
         ", g2p split " +
         (o.g2p_split == CudaOptions::Split::Auto ? "auto" : o.g2p_split == CudaOptions::Split::On ? "on" : "off") +
         (o.update_stats ? ", update stats on" : "");
}

std::unique_ptr<Runner> make_cpu_runner(const SceneSetup& setup);
// slabs.slabs > 1: the scene split into slabs along x (single runs only; throws
// std::invalid_argument for an ensemble or a grid narrower than one stencil per slab).
std::unique_ptr<Runner> make_cpu_runner(const SceneSetup& setup, const SlabOptions& slabs);
// Defined by the CUDA backend library; throws when CUDA was not built or no device exists.
std::unique_ptr<Runner> make_cuda_runner(const SceneSetup& setup, const CudaOptions& options = {});
// slabs.slabs > 1: the scene split into slabs along x, one per GPU (slabs.devices; a device may
// take several slabs, as tests do on one GPU). Throws std::invalid_argument for what is not
// split (ensembles, several materials, no wall, volumetric averaging, too narrow a grid).
std::unique_ptr<Runner> make_cuda_runner(const SceneSetup& setup, const CudaOptions& options,
                                         const SlabOptions& slabs);
bool cuda_backend_available();
// Why the CUDA backend cannot run here ("" when it can): built without CUDA, or no device visible.
std::string cuda_unavailable_reason();
// Free and total memory of the current CUDA device; false without CUDA or a device.
bool cuda_memory_info(std::size_t& free, std::size_t& total);
// Visible CUDA devices (0 without CUDA); the device of the calling thread's later CUDA work.
int cuda_device_count();
void cuda_select_device(int device);

}  // namespace granflow::mpm
