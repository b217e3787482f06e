// CUDA backend: the runner class. Its members are defined by responsibility in cuda_span.cuh,
// cuda_step.cuh, cuda_particle_order.cuh, cuda_sampling.cuh and (buffers: allocation, release,
// upload) cuda_runner_impl.cuh, which includes them all.
#pragma once

#include <cuda_runtime.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <string>
#include <type_traits>
#include <vector>

#include "cuda_launch_config.cuh"
#include "backend/runner_common.hpp"

namespace granflow::mpm {
namespace {

struct SpanControl;  // cuda_span.cuh
template <int D, class S, class Model, class Shape, bool kBoundary>
class CudaSlabRunner;  // cuda_slabs.cuh

// A slab of a scene split over GPUs (cuda_slabs.cuh): the set-up holds the slab's points only,
// `ids` their indices in the whole scene (ids_ keeps them, so a bad particle is reported by its
// index in the scene), and the per-point buffers hold `capacity` points (migration adds points).
struct SlabInit {
  long capacity = 0;
  const std::vector<std::uint32_t>* ids = nullptr;
  const void* packed = nullptr;  // the points' state (field-major, storage type; the set-up's HostParticles hold n only)
};
struct FieldList;    // cuda_sampling.cuh
struct DeviceUpdateStats;  // cuda_step.cuh

// kMembers: an ensemble (kernels.hpp, Members). Particles stay member-major in every order
// (sort keys put member k before k + 1), so the member of slot p is p / P; the grid holds the
// members' nodes one block after another (nn_ nodes in all, sp_.grid.n_nodes per member).
// Boundary forces on the device: a probe's node mass and velocity before the holds, and a
// ForcePart's range and moment point.
struct ProbeTrial {
  double m;
  double v[3], vd[3];  // undamped, damped
};
struct PartRange {
  long first, count;
  int boundary;
  double about[3];
};

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
class CudaRunner final : public Runner {
  using G = GridLayout<D>;
  using Lay = ParticleLayout<D, Model::kCollisional>;
  using MV = MemberValues<typename Model::Params, S>;
  // Sort keys: member-major for ensembles, k * sort_key_bound + sort_key, which needs more
  // than 32 bits for large ensembles of large grids.
  using SortKey = std::conditional_t<kMembers, std::uint64_t, std::uint32_t>;
  static constexpr bool kColl = Model::kCollisional;
  // Frictional terrain (3D): plain runs and, in 3D, the single runs of several materials (3D
  // kMembers instantiations are never ensembles: one grid block, the terrain's node indices).
  static constexpr bool kTerrain = kBoundary && (!kMembers || D == 3);
  static constexpr bool kKeepMass = Shape::kind == ShapeKind::Linear;  // G2P's light-node limit (g2p_mass_)
  static constexpr int kElastic = elastic_min_blocks<typename Model::Scalar>(false);
  static constexpr int kElasticCap = elastic_min_blocks<typename Model::Scalar>(true);
  static constexpr int kPlastic = plastic_min_blocks<typename Model::Scalar>();

 public:
  CudaRunner(const SceneSetup& su, const CudaOptions& opt, const SlabInit* slab = nullptr);
  ~CudaRunner() override;

  void set_stage(int stage, double damping, double flip) override {
    stage_ = stage;
    damping_ = damping;
    flip_ = flip;
  }

  // cuda_span.cuh
  StepResult step(double dt, bool want_dt_limit) override;
  SpanResult advance_span(const Span& s) override;

  // cuda_sampling.cuh
  void frame(Frame& out, bool diagnostics, const std::vector<long>& subset) override;
  void snapshot(const std::vector<long>& subset) override;
  void collect(Frame& out) override;
  void take_forces(BoundaryForces& out, bool keep) override;
  void restore_forces(const BoundaryForces& in) override;

  void download(HostParticles& out) override { detail::unpack<D, S, kColl>(fetch_all(), n_, out); }
  void upload(const HostParticles& in) override {
    detail::check_upload(in, n_, D);
    load(in);
  }
  PhaseTimes times() const override { return times_; }
  void reset_times() override { times_ = PhaseTimes{}; }
  std::string device() const override {
    int dev = 0;
    cudaGetDevice(&dev);
    cudaDeviceProp prop;
    cudaGetDeviceProperties(&prop, dev);
    return std::string("CUDA ") + prop.name + " (sm_" + std::to_string(prop.major) + std::to_string(prop.minor) + ")";
  }
  std::string config() const override;  // cuda_step.cuh
  long particles() const override { return n_; }
  long nodes() const override { return nn_; }  // of all members
  std::vector<MemberFailure> retire_failed_members() override;  // cuda_span.cuh
  UpdateStats update_stats() const override;  // cuda_step.cuh (CudaOptions::update_stats)

 private:
  friend class CudaSlabRunner<D, S, Model, Shape, kBoundary>;
  enum { kP2G0, kGrid0, kG2P0, kG2P1, kSort0, kSort1, kSpan0, kSpan1, kNumEvents };

  ParticleView<S> part_view() const { return ParticleView<S>{part_, n_}; }
  bool split() const { return deferred_ != nullptr; }

  // cuda_step.cuh
  bool use_split();
  void preload() const;
  void enqueue_step(bool timed);
  void enqueue_p2g();
  void enqueue_grid();
  void enqueue_g2p();

  // cuda_particle_order.cuh
  void enqueue_sort();

  bool sort_due() const { return opt_.sort_every > 0 && since_sort_ >= opt_.sort_every; }

  // Steps up to the next sort, at most `left`.
  long chunk_limit(long left) const {
    return opt_.sort_every > 0 ? std::min(left, static_cast<long>(opt_.sort_every) - since_sort_) : left;
  }

  // cuda_span.cuh
  cudaGraphExec_t graph_for(int steps);
  cudaGraphExec_t capture(int steps);
  void span_start(const Span& s);
  void span_fetch();
  SpanResult span_result();
  void run_queued(long nsteps);
  void run_timed(long nsteps);

  // cuda_sampling.cuh
  const S* fetch(const FieldList& fl);
  std::vector<S> fetch_all();
  static FieldList light_fields();
  void fill_light(const S* h, Frame& out) const;
  void fill_subset(const std::vector<S>& small, const std::vector<long>& subset, Frame& out) const;

  // cuda_runner_impl.cuh
  void load(const HostParticles& hp, const S* packed = nullptr);

  // Ensembles: the members with their values in host memory (make_frame's diagnostics).
  Members<typename Model::Params, S> host_members() const {
    Members<typename Model::Params, S> m = sp_.members;
    m.values = values_.data();
    m.dead = nullptr;
    m.material = material_host_.empty() ? nullptr : material_host_.data();  // original order, as frames
    return m;
  }

  StepParams<D, S, Model> sp_;
  long n_;
  long cap_;           // points the per-point buffers hold (n_; a slab: more, SlabInit)
  bool slab_ = false;  // ids_ hold indices in the whole scene (no inv_)
  std::vector<std::uint32_t> slab_ids_;  // ... as set up (load())
  long nn_;  // grid nodes of all members (sp_.grid.n_nodes per member)
  CudaOptions opt_;
  int key_bits_ = 32;
  int stage_ = 0;
  double damping_ = 0, flip_ = 0;
  double t_ = 0;  // time after the last span: step() goes on from it
  long since_sort_ = 0;
  cudaStream_t stream_ = nullptr;
  S* part_ = nullptr;              // particle fields (ParticleLayout), slots in sorted order
  S* alt_ = nullptr;               // gather target of a sort; staging of downloads
  S* grid_ = nullptr;
  S* g2p_mass_ = nullptr;  // linear hats: node masses for G2P (GridView::g2p_mass)
  std::uint32_t* status_ = nullptr;
  std::uint32_t* info_ = nullptr;  // per-slot update record (kernels.hpp, record::pack)
  DeviceUpdateStats* stats_ = nullptr;  // their sums (CudaOptions::update_stats; null: not kept)
  std::uint32_t* ids_ = nullptr;   // original index of each slot
  std::uint32_t* ids_alt_ = nullptr;
  std::uint32_t* inv_ = nullptr;   // slot of each original index
  std::uint32_t* deferred_ = nullptr;  // slots whose plastic return the split G2P deferred
  unsigned* n_deferred_ = nullptr;     // their count (zeroed by the second pass)
  double fused_waves_ = 0;             // n / (threads of the fused G2P kernel resident at once)
  long* keys_ = nullptr;           // bin of each particle (volumetric averaging)
  S* bins_ = nullptr;              // per-bin V and V tr L (volumetric averaging)
  SortKey* sort_keys_[2] = {nullptr, nullptr};          // in/out
  std::uint32_t* sort_slots_[2] = {nullptr, nullptr};    // in/out
  unsigned char* sort_tmp_ = nullptr;
  size_t sort_tmp_bytes_ = 0;
  SpanControl* ctl_ = nullptr;
  SpanControl* ctl_in_ = nullptr;  // pinned
  SpanControl* ctl_out_ = nullptr; // pinned
  S* host_ = nullptr;              // pinned download staging
  long* sub_ids_ = nullptr;
  S* sub_out_ = nullptr;
  long sub_cap_ = 0;
  int device_ = 0;
  // snapshot(): its own gather buffers, pinned copies and copy stream (allocated when first used)
  S* snap_dev_ = nullptr;
  S* snap_host_ = nullptr;
  std::vector<long> snap_subset_;
  long* snap_sub_ids_ = nullptr;
  S* snap_sub_dev_ = nullptr;
  S* snap_sub_host_ = nullptr;
  cudaStream_t copy_stream_ = nullptr;
  cudaEvent_t snap_ready_ = nullptr, snap_done_ = nullptr;
  bool snap_pending_ = false;
  std::vector<std::uint8_t*> masks_;
  std::vector<bool> contacts_;  // per stage: the grid kernel with contact_node (cuda_step.cuh)
  TerrainNode* terrain_ = nullptr;  // frictional terrain's nodes (terrain_kernel; none: no launch)
  long n_terrain_ = 0;
  double terrain_mu_ = 0;
  ObstacleNode* obstacle_ = nullptr;  // obstacles' nodes (obstacle_kernel; none: no launch)
  long n_obstacle_ = 0;
  // boundary forces (probe_trial_kernel, force_parts_kernel, force_boundaries_kernel; none: no launch)
  ForceProbe* probes_ = nullptr;
  ProbeTrial* trial_ = nullptr;
  PartRange* parts_ = nullptr;
  ForceSums* part_step_ = nullptr;
  ForceSums* force_acc_ = nullptr;  // the parts', then the boundaries' sums since the last take
  double* node_impulse_ = nullptr;
  long n_probes_ = 0;
  int n_parts_ = 0, n_boundaries_ = 0;
  std::vector<MV> values_;                 // ensembles: per member and material (host copy)
  // Several materials: per slot, the point's material index (sp_.members.material), sorted
  // with the points; the host copy in the original order.
  std::uint8_t* material_ = nullptr;
  std::uint8_t* material_alt_ = nullptr;
  std::vector<std::uint8_t> material_host_;
  MV* values_dev_ = nullptr;               // ... on the device (sp_.members.values)
  std::uint32_t* dead_ = nullptr;          // per member, non-zero: retired (sp_.members.dead)
  std::vector<std::uint32_t> dead_host_;
  unsigned long long* member_bad_ = nullptr;  // per member: pack_bad of its first bad particle
  std::map<long, cudaGraphExec_t> graphs_;
  cudaEvent_t ev_[kNumEvents];
  PhaseTimes times_;
};

}  // namespace
}  // namespace granflow::mpm
