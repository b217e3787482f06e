// One scene split into slabs along x over the GPUs of a host (docs/mpm_slabs.md): a CudaRunner
// per slab, on its own device, driven phase by phase with the exchanges of the CPU twin's split
// (cpu_slabs.hpp) between them:
//   P2G   slab s adds slab s - 1's partial sums of the K - 1 columns they share (a kernel on s
//         reading s - 1's grid through peer access; s - 1's grid update waits for it);
//   grid  slab s copies the updated velocities of the K - 1 columns it shares with s + 1 from
//         there before its G2P;
//   G2P   points whose stencil now starts in another slab's columns are counted on the device;
//         where any are, they go through the host to their new slab, which appends them;
//   then  the borders move by point count (re-partitioning), as on the CPU twin.
// Unlike the twin's slabs, every GPU stores the whole grid (its nodes cost 1/25 of the points'
// memory in the 3D slab) so that the kernels keep the one-GPU grid arithmetic and registers; the
// grid kernel returns at once on the nodes no point of the slab reaches. Node lists (terrain,
// obstacles, force probes) are sliced to the owned columns. The host drives every step (one
// synchronisation per step: the stable step is the smallest of all slabs'), so no CUDA graphs.
// Sums of shared nodes are atomic, as on one GPU: a split run agrees with one GPU to round-off,
// not bit for bit (mpm_cuda_check's slab cases).
#pragma once

#include <cuda_runtime.h>

#include <cub/device/device_partition.cuh>
#include <thrust/iterator/counting_iterator.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <numeric>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cuda_particle_order.cuh"
#include "cuda_runner_class.cuh"
#include "cuda_span.cuh"
#include "backend/slab_borders.hpp"

namespace granflow::mpm {
namespace {

// Fields [f0, f0 + nf) of columns [c0, c0 + width) of every row, dst = src (kAdd: dst += src);
// both grids whole (the same linear index), src on a peer device.
template <class S, bool kAdd>
__global__ void slab_columns_kernel(S* dst, const S* src, long n_nodes, int nx, long rows, int c0, int width, int f0,
                                    int nf) {
  const long i = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (i >= static_cast<long>(nf) * rows * width) return;
  const int c = c0 + static_cast<int>(i % width);
  const long rf = i / width;
  const long k = static_cast<long>(f0 + rf / rows) * n_nodes + (rf % rows) * nx + c;
  if constexpr (kAdd) dst[k] += src[k]; else dst[k] = src[k];
}

// Points whose stencil starts outside the owned columns [lo, hi): flagged and counted.
template <int D, class S, class Shape, bool kColl>
__global__ void slab_mark_kernel(ParticleView<S> pv, GridDesc<D, S> g, int lo, int hi, std::uint8_t* leave,
                                 unsigned* count) {
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (p >= pv.n) return;
  S xi[D];
  int base[D];
  particle_base<D, S, Shape, kColl>(pv, p, g, xi, base);
  const bool out = base[0] < lo || base[0] >= hi;
  leave[p] = out;
  if (out) atomicAdd(count, 1u);
}

template <int D, class S, class Model, class Shape, bool kBoundary>
class CudaSlabRunner final : public Runner {
  using Slab = CudaRunner<D, S, Model, Shape, kBoundary, false>;
  using Lay = ParticleLayout<D, Model::kCollisional>;
  using G = GridLayout<D>;
  using Clock = std::chrono::steady_clock;
  static constexpr int K = Shape::K;
  static constexpr bool kColl = Model::kCollisional;
  enum { kBegin, kP2G, kAdd, kGrid, kHalo, kEnd, kEvents };

  // Points in packed form (field-major, n of them) with their indices in the scene.
  struct Points {
    std::vector<S> part;
    long n = 0;
    std::vector<std::uint32_t> ids;
  };

  // A slab: its runner and device, the owned columns, its probes' indices in the scene's list,
  // and the buffers of migration (flags, the partition's order and scratch, the leaving points).
  struct Part {
    int dev = 0, lo = 0, hi = 0;
    std::unique_ptr<Slab> r;
    std::vector<long> probe_ids;
    cudaEvent_t ev[kEvents] = {};
    std::uint8_t* leave = nullptr;
    unsigned* count = nullptr;       // device
    unsigned* count_host = nullptr;  // pinned
    std::uint32_t* perm = nullptr;
    int* n_sel = nullptr;
    void* tmp = nullptr;
    size_t tmp_bytes = 0;
    S* out = nullptr;
    std::uint32_t* out_ids = nullptr;
    long out_cap = 0;
    ~Part() {
      if (!r) return;
      cudaSetDevice(dev);
      r.reset();
      for (auto e : ev) cudaEventDestroy(e);
      for (void* p : {static_cast<void*>(leave), static_cast<void*>(count), static_cast<void*>(perm),
                      static_cast<void*>(n_sel), tmp, static_cast<void*>(out), static_cast<void*>(out_ids)})
        cudaFree(p);
      cudaFreeHost(count_host);
    }
  };

 public:
  CudaSlabRunner(const SceneSetup& su, const CudaOptions& co, const SlabOptions& o)
      : su_(su), sp_whole_(detail::step_params<D, S, Model>(su)), co_(co), opt_(o), whole_(sp_whole_.grid),
        flip_(su.scene.flip) {
    su_.particles = {};  // the slabs get theirs (distribute)
    check_split(su, o, K);
    if (su.scene.volumetric_averaging)
      throw std::invalid_argument("slabs: volumetric averaging is not split over GPUs yet");
    rule_.opt = o;
    devices_ = o.devices;
    if (devices_.empty())
      for (int s = 0; s < o.slabs; ++s) devices_.push_back(s);
    if (static_cast<int>(devices_.size()) != o.slabs)
      throw std::invalid_argument("slabs: " + std::to_string(devices_.size()) + " devices for " +
                                  std::to_string(o.slabs) + " slabs");
    int have = 0;
    cudaGetDeviceCount(&have);
    for (int d : devices_)
      if (d < 0 || d >= have)
        throw std::invalid_argument("slabs: CUDA device " + std::to_string(d) + " does not exist (" +
                                    std::to_string(have) + " visible)");
    for (int s = 0; s + 1 < o.slabs; ++s) enable_peers(devices_[s], devices_[s + 1]);
    if constexpr (kBoundary) {
      forces_.parts.assign(su.force_parts.size(), ForceSums{});
      forces_.boundaries.assign(su.force_boundaries.size(), ForceSums{});
      forces_.node_impulse.assign(static_cast<size_t>(D) * su.probes.size(), 0.0);
    }
    report_.slabs = o.slabs;
    rows_ = su.n_nodes / su.nodes[0];
    distribute(whole_points(su.particles));
  }

  void set_stage(int stage, double damping, double flip) override {
    stage_ = stage;
    damping_ = damping;
    flip_ = flip;
    for (auto& p : parts_) {
      cudaSetDevice(p->dev);
      p->r->set_stage(stage, damping, flip);
    }
  }

  SpanResult advance_span(const Span& s) override {
    t_ = s.t;
    return Runner::advance_span(s);
  }

  StepResult step(double dt, bool want_dt_limit) override {
    const auto t0 = Clock::now();
    const int n = static_cast<int>(parts_.size());
    const int cols = su_.nodes[0];
    const Span sp = one_step_span(t_, dt, want_dt_limit);
    for (auto& p : parts_) {
      Slab& r = *p->r;
      cudaSetDevice(p->dev);
      r.span_start(sp);
      if (r.sort_due()) {
        r.enqueue_sort();
        r.since_sort_ = 0;
      }
      ++r.since_sort_;
      cudaEventRecord(p->ev[kBegin], r.stream_);
      r.enqueue_p2g();
      cudaEventRecord(p->ev[kP2G], r.stream_);
    }
    for (int s = 0; s < n; ++s) {  // the left neighbour's partial sums of the shared columns
      Part& p = *parts_[s];
      cudaSetDevice(p.dev);
      if (s > 0) {
        Part& l = *parts_[s - 1];
        check(cudaStreamWaitEvent(p.r->stream_, l.ev[kP2G], 0), "slab exchange");
        columns<true>(p, l, p.lo, std::min(p.lo + K - 1, cols), 0, 1 + 2 * D);
      }
      cudaEventRecord(p.ev[kAdd], p.r->stream_);
    }
    for (int s = 0; s < n; ++s) {  // the grid update, after the right neighbour took the sums
      Part& p = *parts_[s];
      cudaSetDevice(p.dev);
      if (s + 1 < n) check(cudaStreamWaitEvent(p.r->stream_, parts_[s + 1]->ev[kAdd], 0), "slab exchange");
      p.r->enqueue_grid();
      cudaEventRecord(p.ev[kGrid], p.r->stream_);
    }
    for (int s = 0; s < n; ++s) {  // the right neighbour's velocities, then G2P
      Part& p = *parts_[s];
      Slab& r = *p.r;
      cudaSetDevice(p.dev);
      if (s + 1 < n) {
        Part& q = *parts_[s + 1];
        check(cudaStreamWaitEvent(r.stream_, q.ev[kGrid], 0), "slab exchange");
        columns<false>(p, q, q.lo, std::min(q.lo + K - 1, cols), G::VOLD, G::N - G::VOLD);
      }
      cudaEventRecord(p.ev[kHalo], r.stream_);
      r.enqueue_g2p();
      check(cudaMemsetAsync(p.count, 0, sizeof(unsigned), r.stream_), "slab migration");
      if (r.n_ > 0)
        slab_mark_kernel<D, S, Shape, kColl><<<blocks_for(r.n_, kAuxBlock), kAuxBlock, 0, r.stream_>>>(
            r.part_view(), whole_, p.lo, p.hi, p.leave, p.count);
      r.span_fetch();
      check(cudaMemcpyAsync(p.count_host, p.count, sizeof(unsigned), cudaMemcpyDeviceToHost, r.stream_),
            "slab migration");
      if (kBoundary && r.n_probes_ > 0)
        check(cudaMemcpyAsync(step_host(s), r.part_step_, sizeof(ForceSums) * r.n_parts_, cudaMemcpyDeviceToHost,
                              r.stream_),
              "slab forces");
      cudaEventRecord(p.ev[kEnd], r.stream_);
    }
    StepResult res;
    double lim = std::numeric_limits<double>::infinity();
    double ph[4] = {0, 0, 0, 0};  // p2g, grid, g2p, exchange: the slowest slab's
    long leaving = 0;
    for (auto& pp : parts_) {
      Part& p = *pp;
      cudaSetDevice(p.dev);
      check(cudaStreamSynchronize(p.r->stream_), "slab step");
      check(cudaGetLastError(), "slab step kernels");
      const SpanResult q = p.r->span_result();
      if (!q.ok && (res.ok || q.particle < res.particle)) {
        res.ok = false;
        res.particle = q.particle;
        res.status = q.status;
      }
      lim = std::min(lim, q.dt);
      float ms[kEvents - 1];
      for (int k = 0; k + 1 < kEvents; ++k) cudaEventElapsedTime(&ms[k], p.ev[k], p.ev[k + 1]);
      ph[0] = std::max(ph[0], 1e-3 * ms[kBegin]);
      ph[1] = std::max(ph[1], 1e-3 * ms[kAdd]);
      ph[2] = std::max(ph[2], 1e-3 * ms[kHalo]);
      ph[3] = std::max(ph[3], 1e-3 * (ms[kP2G] + ms[kGrid]));
      leaving += *p.count_host;
    }
    if (want_dt_limit) res.dt_limit = lim;
    if constexpr (kBoundary)
      if (!su_.probes.empty()) add_forces(dt);
    t_ += dt;
    times_.p2g += ph[0];
    times_.grid += ph[1];
    times_.g2p += ph[2];
    times_.exchange += ph[3];
    ++times_.steps;
    if (res.ok) {
      const auto tm = Clock::now();
      if (leaving > 0) migrate();
      rebalance_if_needed();
      times_.exchange += std::chrono::duration<double>(Clock::now() - tm).count();
    }
    times_.device += std::chrono::duration<double>(Clock::now() - t0).count();
    ++times_.span_steps;
    return res;
  }

  void frame(Frame& out, bool diagnostics, const std::vector<long>& subset) override {
    const Points all = gather(!diagnostics, subset);
    detail::make_frame<D, S, Model>(all.part, all.n, sp_whole_.mp, out, diagnostics, subset);
  }
  void download(HostParticles& out) override {
    const Points all = gather();
    detail::unpack<D, S, kColl>(all.part, all.n, out);
  }
  void upload(const HostParticles& in) override {
    detail::check_upload(in, n_total_, D);
    distribute(whole_points(in));
  }
  PhaseTimes times() const override { return times_; }
  void reset_times() override { times_ = PhaseTimes{}; }
  UpdateStats update_stats() const override {
    UpdateStats u = retired_stats_;
    for (const auto& p : parts_) {
      cudaSetDevice(p->dev);
      u = u + p->r->update_stats();
    }
    return u;
  }
  void take_forces(BoundaryForces& out, bool keep) override {
    collect_node_impulse();
    take_host_forces(forces_, out, keep);
  }
  void restore_forces(const BoundaryForces& in) override {
    collect_node_impulse();  // clears the slabs' sums
    restore_host_forces(forces_, in);
  }
  std::string device() const override {
    std::string d;
    for (size_t s = 0; s < parts_.size(); ++s) d += (s ? "," : "") + std::to_string(parts_[s]->dev);
    cudaSetDevice(parts_[0]->dev);
    return parts_[0]->r->device() + ", " + std::to_string(parts_.size()) + " slabs along x on devices " + d;
  }
  std::string config() const override {
    cudaSetDevice(parts_[0]->dev);
    return parts_[0]->r->config() + "  slabs: " + std::to_string(parts_.size()) +
           " along x, one step at a time (no graphs), whole grid on every GPU\n";
  }
  long particles() const override { return n_total_; }
  long nodes() const override { return su_.n_nodes; }
  SlabReport slab_report() const override { return report_; }

 private:
  // node columns: slab s owns [borders()[s], borders()[s + 1]) (kept in the report)
  const std::vector<int>& borders() const { return report_.borders; }
  static void enable_peers(int a, int b) {
    if (a == b) return;
    for (auto [x, y] : {std::pair{a, b}, std::pair{b, a}}) {
      int can = 0;
      cudaDeviceCanAccessPeer(&can, x, y);
      if (!can)
        throw std::runtime_error("slabs: CUDA devices " + std::to_string(x) + " and " + std::to_string(y) +
                                 " cannot access each other's memory (peer access)");
      cudaSetDevice(x);
      const cudaError_t e = cudaDeviceEnablePeerAccess(y, 0);
      if (e == cudaErrorPeerAccessAlreadyEnabled)
        cudaGetLastError();
      else
        check(e, "peer access");
    }
  }

  // Columns [c0, c1) of fields [f0, f0 + nf) of `from`'s grid into `to`'s, on `to`'s stream.
  template <bool kAdd>
  void columns(Part& to, Part& from, int c0, int c1, int f0, int nf) {
    if (c1 <= c0) return;
    const long total = static_cast<long>(nf) * rows_ * (c1 - c0);
    slab_columns_kernel<S, kAdd><<<blocks_for(total, kAuxBlock), kAuxBlock, 0, to.r->stream_>>>(
        to.r->grid_, from.r->grid_, su_.n_nodes, su_.nodes[0], rows_, c0, c1 - c0, f0, nf);
  }

  ForceSums* step_host(int s) { return step_host_[s].data(); }

  // The step's forces: each part's sums over the slabs, then each boundary's over its parts
  // (force_boundaries_kernel's order).
  void add_forces(double dt) {
    const size_t np = su_.force_parts.size();
    std::vector<ForceSums> step(np);
    for (size_t s = 0; s < parts_.size(); ++s)
      if (parts_[s]->r->n_probes_ > 0)
        for (size_t q = 0; q < np; ++q) add_step_sums(step[q], step_host_[s][q]);
    for (size_t q = 0; q < np; ++q) add_force_step(forces_.parts[q], step[q], dt);
    for (size_t b = 0; b < forces_.boundaries.size(); ++b) {
      ForceSums sb;
      for (size_t q = 0; q < np; ++q)
        if (su_.force_parts[q].boundary == static_cast<int>(b)) add_step_sums(sb, step[q]);
      add_force_step(forces_.boundaries[b], sb, dt);
    }
  }

  // The slabs' per-probe impulses added to forces_ and cleared on the slabs.
  void collect_node_impulse() {
    const long np = static_cast<long>(su_.probes.size());
    for (auto& p : parts_) {
      if (p->r->n_probes_ == 0) continue;
      cudaSetDevice(p->dev);
      BoundaryForces f;
      p->r->take_forces(f, false);
      const long m = static_cast<long>(p->probe_ids.size());
      for (int d = 0; d < D; ++d)
        for (long i = 0; i < m; ++i) forces_.node_impulse[d * np + p->probe_ids[i]] += f.node_impulse[d * m + i];
    }
  }

  // All points of a state in the scene's order, packed on all cores.
  static Points whole_points(const HostParticles& hp) {
    Points all;
    all.n = hp.n;
    all.part.resize(static_cast<size_t>(Lay::N) * all.n);
    detail::parallel_chunks(all.n, [&](long i0, long i1) { detail::pack_range<D, S, kColl>(hp, all.part.data(), i0, i1); });
    all.ids.resize(all.n);
    std::iota(all.ids.begin(), all.ids.end(), 0u);
    return all;
  }

  // The points of the slabs in the scene's order. light: positions, velocities and sqrt(T)
  // only (a light frame; the other fields zero) but every field of the points in `whole`.
  Points gather(bool light = false, const std::vector<long>& whole = {}) {
    Points all;
    all.n = n_total_;
    all.part.assign(static_cast<size_t>(Lay::N) * all.n, S(0));
    all.ids.resize(all.n);
    std::iota(all.ids.begin(), all.ids.end(), 0u);
    std::vector<int> fields;
    for (int f = 0; f < Lay::N; ++f)
      if (!light || (f >= Lay::X && f < Lay::X + D) || (f >= Lay::V && f < Lay::V + D) || (kColl && f == Lay::SQT))
        fields.push_back(f);
    const long nf = static_cast<long>(fields.size());
    for (auto& p : parts_) {
      Slab& r = *p->r;
      cudaSetDevice(p->dev);
      const long n = r.n_;
      std::vector<S> buf(static_cast<size_t>(nf) * n);
      std::vector<std::uint32_t> ids(n);
      for (long k = 0; k < nf; ++k)
        check(cudaMemcpyAsync(buf.data() + k * n, r.part_ + static_cast<long>(fields[k]) * n, sizeof(S) * n,
                              cudaMemcpyDeviceToHost, r.stream_),
              "slab download");
      check(cudaMemcpyAsync(ids.data(), r.ids_, sizeof(std::uint32_t) * n, cudaMemcpyDeviceToHost, r.stream_),
            "slab download");
      check(cudaStreamSynchronize(r.stream_), "slab download");
      S* out = all.part.data();
      const long N = all.n;
      detail::parallel_chunks(n, [&](long j0, long j1) {
        for (long k = 0; k < nf; ++k)
          for (long j = j0; j < j1; ++j) out[fields[k] * N + ids[j]] = buf[k * n + j];
      });
      if (!light) continue;
      for (long g : whole)
        for (long j = 0; j < n; ++j)
          if (ids[j] == static_cast<std::uint32_t>(g)) {
            for (int f = 0; f < Lay::N; ++f)
              check(cudaMemcpy(out + f * N + g, r.part_ + static_cast<long>(f) * n + j, sizeof(S),
                               cudaMemcpyDeviceToHost),
                    "slab download");
            break;
          }
    }
    return all;
  }

  int column_of(const ParticleView<S>& pv, long p) const {
    S xi[D];
    int base[D];
    particle_base<D, S, Shape, kColl>(pv, p, whole_, xi, base);
    return std::clamp(base[0], 0, su_.nodes[0] - 1);
  }

  // The slabs made anew (in parallel, one thread per slab) from all points; borders balanced
  // first. The old slabs' update statistics and forces are kept.
  void distribute(Points&& all) {
    for (auto& p : parts_) {
      cudaSetDevice(p->dev);
      retired_stats_ = retired_stats_ + p->r->update_stats();
    }
    collect_node_impulse();
    parts_.clear();
    n_total_ = all.n;
    const int n = opt_.slabs, cols = su_.nodes[0];
    const ParticleView<S> pv{all.part.data(), all.n};
    std::vector<int> col(all.n);
    detail::parallel_chunks(all.n, [&](long p0, long p1) {
      for (long p = p0; p < p1; ++p) col[p] = column_of(pv, p);
    });
    const std::vector<std::vector<long>> which = assign_slabs(col, cols, n, K, report_);
    const std::vector<int>& b = borders();
    for (int s = 0; s < n; ++s)
      if (which[s].empty())
        throw std::runtime_error("slabs: slab " + std::to_string(s) + " (node columns " + std::to_string(b[s]) +
                                 " to " + std::to_string(b[s + 1] - 1) + ") holds no points: the material spans "
                                 "too few columns for " + std::to_string(n) + " slabs");
    report_.halo_nodes = 2L * (K - 1) * rows_ * (n - 1);
    parts_.resize(n);
    step_host_.assign(n, std::vector<ForceSums>(su_.force_parts.size()));
    std::vector<std::string> errors(n);
    std::vector<std::thread> threads;
    for (int s = 0; s < n; ++s)
      threads.emplace_back([&, s] {
        try {
          parts_[s] = make_part(s, all, which[s]);
        } catch (const std::exception& e) {
          errors[s] = e.what();
        }
      });
    for (auto& t : threads) t.join();
    for (int s = 0; s < n; ++s)
      if (!errors[s].empty()) throw std::runtime_error("slab " + std::to_string(s) + ": " + errors[s]);
  }

  std::unique_ptr<Part> make_part(int s, const Points& all, const std::vector<long>& which) {
    auto p = std::make_unique<Part>();
    p->dev = devices_[s];
    p->lo = borders()[s];
    p->hi = borders()[s + 1];
    check(cudaSetDevice(p->dev), "cudaSetDevice");
    SceneSetup su = su_;
    Points mine;
    mine.n = static_cast<long>(which.size());
    mine.part.resize(static_cast<size_t>(Lay::N) * mine.n);
    mine.ids.resize(mine.n);
    const ParticleView<S> src{const_cast<S*>(all.part.data()), all.n}, dst{mine.part.data(), mine.n};
    detail::parallel_chunks(mine.n, [&](long j0, long j1) {
      for (long j = j0; j < j1; ++j) {
        gather_slot(src, dst, Lay::N, j, which[j]);
        mine.ids[j] = all.ids[which[j]];
      }
    });
    su.particles = HostParticles{};  // the runner takes the packed state (SlabInit::packed)
    su.particles.n = mine.n;
    su.particles.dim = D;
    su.tracked.clear();
    su.point_body.clear();
    slice_node_lists(su, *p);
    // room for the points of a slab at the re-partitioning threshold, and some
    const long mean = (n_total_ + opt_.slabs - 1) / opt_.slabs;
    SlabInit init;
    init.capacity = std::max(mine.n + mine.n / 8, static_cast<long>(1.3 * opt_.imbalance * mean)) + 1024;
    init.ids = &mine.ids;
    init.packed = mine.part.data();
    p->r = std::make_unique<Slab>(su, co_, &init);
    p->r->sp_.mass_eps = sp_whole_.mass_eps;  // the whole scene's, not the slab's lightest point's
    p->r->sp_.mass_floor = sp_whole_.mass_floor;
    p->r->set_stage(stage_, damping_, flip_);
    const long cap = p->r->cap_;
    for (auto& e : p->ev) check(cudaEventCreate(&e), "cudaEventCreate");
    p->leave = device_alloc<std::uint8_t>(cap);
    p->count = device_alloc<unsigned>(1);
    check(cudaMallocHost(&p->count_host, sizeof(unsigned)), "cudaMallocHost");
    *p->count_host = 0;
    p->perm = device_alloc<std::uint32_t>(cap);
    p->n_sel = device_alloc<int>(1);
    thrust::counting_iterator<std::uint32_t> iota(0);
    check(cub::DevicePartition::Flagged(nullptr, p->tmp_bytes, iota, p->leave, p->perm, p->n_sel,
                                        static_cast<int>(cap)),
          "partition size");
    p->tmp = device_alloc<unsigned char>(p->tmp_bytes);
    check(cudaDeviceSynchronize(), "slab set-up");
    return p;
  }

  // The slab's entries of the node lists (its owned columns); the force parts' ranges within
  // its probes.
  void slice_node_lists(SceneSetup& su, Part& p) const {
    auto owned = [&](long node) { return node % su_.nodes[0] >= p.lo && node % su_.nodes[0] < p.hi; };
    auto keep = [&](auto& list) {
      size_t j = 0;
      for (auto e : list)
        if (owned(e.node)) list[j++] = e;
      list.resize(j);
    };
    keep(su.terrain);
    keep(su.obstacle_nodes);
    std::vector<ForceProbe> probes;
    for (ForcePart& fp : su.force_parts) {
      const long first = static_cast<long>(probes.size());
      for (long i = fp.first; i < fp.first + fp.count; ++i)
        if (owned(su_.probes[i].node)) {
          probes.push_back(su_.probes[i]);
          p.probe_ids.push_back(i);
        }
      fp.first = first;
      fp.count = static_cast<long>(probes.size()) - first;
    }
    su.probes = std::move(probes);
  }

  // Points whose stencil now starts in another slab's columns move there through the host.
  void migrate() {
    const int n = static_cast<int>(parts_.size());
    Points moving;
    std::vector<long> leaving(n, 0);
    for (int s = 0; s < n; ++s) {
      Part& p = *parts_[s];
      const long m = *p.count_host;
      leaving[s] = m;
      if (m == 0) continue;
      Slab& r = *p.r;
      cudaSetDevice(p.dev);
      partition(p);
      if (m > p.out_cap) {
        cudaFree(p.out);
        cudaFree(p.out_ids);
        p.out_cap = 2 * m;
        p.out = device_alloc<S>(static_cast<size_t>(Lay::N) * p.out_cap);
        p.out_ids = device_alloc<std::uint32_t>(p.out_cap);
      }
      gather_kernel<S><<<blocks_for(m, kAuxBlock), kAuxBlock, 0, r.stream_>>>(
          r.part_view(), ParticleView<S>{p.out, m}, Lay::N, p.perm, m, 0, r.ids_, p.out_ids);
      std::vector<S> part(static_cast<size_t>(Lay::N) * m);
      std::vector<std::uint32_t> ids(m);
      check(cudaMemcpyAsync(part.data(), p.out, sizeof(S) * part.size(), cudaMemcpyDeviceToHost, r.stream_),
            "slab migration");
      check(cudaMemcpyAsync(ids.data(), p.out_ids, sizeof(std::uint32_t) * m, cudaMemcpyDeviceToHost, r.stream_),
            "slab migration");
      check(cudaStreamSynchronize(r.stream_), "slab migration");
      append(moving, part, m, ids);
    }
    report_.migrated += moving.n;
    // each moving point to the slab that owns its column, in the scene's order
    std::vector<std::vector<long>> to(n);
    const ParticleView<S> mv{moving.part.data(), moving.n};
    for (long j = 0; j < moving.n; ++j) to[slab_of_column(borders(), column_of(mv, j))].push_back(j);
    bool fits = true;
    for (int s = 0; s < n; ++s) {
      std::sort(to[s].begin(), to[s].end(), [&](long a, long b) { return moving.ids[a] < moving.ids[b]; });
      const long after = parts_[s]->r->n_ - leaving[s] + static_cast<long>(to[s].size());
      fits = fits && after > 0 && after <= parts_[s]->r->cap_;
    }
    if (!fits) {  // a slab would overflow or empty: re-partition (the leaving points are still in their slots)
      distribute(gather());
      ++report_.checks;
      rule_.since = 0;
      return;
    }
    for (int s = 0; s < n; ++s) {
      if (leaving[s] == 0 && to[s].empty()) continue;
      Part& p = *parts_[s];
      cudaSetDevice(p.dev);
      if (leaving[s] == 0) partition(p);  // nothing leaves: every slot stays
      rebuild(p, leaving[s], moving, to[s]);
    }
  }

  // The slab's slots in the partition's order: leaving points first (in slot order), then the
  // staying ones (cub: in reverse slot order).
  void partition(Part& p) {
    Slab& r = *p.r;
    thrust::counting_iterator<std::uint32_t> iota(0);
    check(cub::DevicePartition::Flagged(p.tmp, p.tmp_bytes, iota, p.leave, p.perm, p.n_sel, static_cast<int>(r.n_),
                                        r.stream_),
          "slab partition");
  }

  // The slab's staying points, then the arriving ones, into the second buffer, which becomes the
  // first (no graphs capture the buffers' addresses here).
  void rebuild(Part& p, long leaving, const Points& moving, const std::vector<long>& arriving) {
    Slab& r = *p.r;
    const long stay = r.n_ - leaving, in = static_cast<long>(arriving.size()), n1 = stay + in;
    const ParticleView<S> dst{r.alt_, n1};
    if (stay > 0)
      gather_kernel<S><<<blocks_for(stay, kAuxBlock), kAuxBlock, 0, r.stream_>>>(
          r.part_view(), dst, Lay::N, p.perm + leaving, stay, 0, r.ids_, r.ids_alt_);
    if (in > 0) {
      std::vector<S> part(static_cast<size_t>(Lay::N) * in);
      std::vector<std::uint32_t> ids(in);
      const ParticleView<S> src{const_cast<S*>(moving.part.data()), moving.n}, pk{part.data(), in};
      for (long j = 0; j < in; ++j) {
        gather_slot(src, pk, Lay::N, j, arriving[j]);
        ids[j] = moving.ids[arriving[j]];
      }
      check(cudaMemcpy2DAsync(r.alt_ + stay, sizeof(S) * n1, part.data(), sizeof(S) * in, sizeof(S) * in, Lay::N,
                              cudaMemcpyHostToDevice, r.stream_),
            "slab migration");
      check(cudaMemcpyAsync(r.ids_alt_ + stay, ids.data(), sizeof(std::uint32_t) * in, cudaMemcpyHostToDevice,
                            r.stream_),
            "slab migration");
      check(cudaStreamSynchronize(r.stream_), "slab migration");  // the host buffers go out of scope
    }
    std::swap(r.part_, r.alt_);
    std::swap(r.ids_, r.ids_alt_);
    r.n_ = n1;
  }

  static void append(Points& to, const std::vector<S>& part, long m, const std::vector<std::uint32_t>& ids) {
    Points both;
    both.n = to.n + m;
    both.part.resize(static_cast<size_t>(Lay::N) * both.n);
    const ParticleView<S> a{to.part.data(), to.n}, b{const_cast<S*>(part.data()), m}, dst{both.part.data(), both.n};
    for (long j = 0; j < to.n; ++j) gather_slot(a, dst, Lay::N, j, j);
    for (long j = 0; j < m; ++j) gather_slot(b, dst, Lay::N, to.n + j, j);
    both.ids = to.ids;
    both.ids.insert(both.ids.end(), ids.begin(), ids.end());
    to = std::move(both);
  }

  void rebalance_if_needed() {
    long most = 0;
    for (const auto& p : parts_) most = std::max(most, p->r->n_);
    if (rule_.after_step(most, n_total_, static_cast<int>(parts_.size()), report_)) distribute(gather());
  }

  SceneSetup su_;  // without its particles
  StepParams<D, S, Model> sp_whole_;  // of the whole scene (its lightest point sets the mass floors)
  CudaOptions co_;
  SlabOptions opt_;
  GridDesc<D, S> whole_;
  std::vector<int> devices_;
  std::vector<std::unique_ptr<Part>> parts_;
  std::vector<std::vector<ForceSums>> step_host_;  // per slab: the last step's part sums
  long rows_ = 0, n_total_ = 0;
  int stage_ = 0;
  double damping_ = 0, flip_ = 0, t_ = 0;
  Repartitioning rule_;
  BoundaryForces forces_;
  UpdateStats retired_stats_;
  PhaseTimes times_;
  SlabReport report_;
};

}  // namespace
}  // namespace granflow::mpm
