// One scene split into slabs along x (docs/mpm_slabs.md), run by the CPU twin: the slabs are
// CpuRunners of a window of the grid each, stepped one after another with the exchanges a
// GPU per slab makes between its phases:
//   P2G   slab s - 1's partial sums of the columns it shares with slab s -> slab s, which
//         continues them (cpu_runner.hpp: the gather sums bins along x outermost, so the shared
//         nodes are summed in the one-slab order and the result is bitwise that of one slab);
//   grid  the updated nodes of those columns, slab s -> slab s - 1, before its G2P;
//   G2P   points whose stencil now starts in another slab's columns move there (migration);
//   then  when the fullest slab holds `imbalance` times the mean (or every `every` steps), the
//         borders move so that each slab holds about as many points (re-partitioning).
#pragma once

#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <string>

#include "cpu/cpu_runner.hpp"
#include "backend/slab_borders.hpp"

namespace granflow::mpm::cpu {

template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
class SlabRunner final : public Runner {
  using Slab = CpuRunner<D, S, Model, Shape, kBoundary, kMembers>;
  using Lay = ParticleLayout<D, Model::kCollisional>;
  using G = GridLayout<D>;
  static constexpr int K = Shape::K;

 public:
  SlabRunner(const SceneSetup& su, const SlabOptions& o)
      : su_(su), opt_(o), whole_(detail::grid_desc<D, S>(su)), flip_(su.scene.flip) {
    check_split(su, o, K);
    rule_.opt = o;
    if constexpr (kBoundary) {
      probes_ = su.probes;
      parts_ = su.force_parts;
      n_boundaries_ = static_cast<int>(su.force_boundaries.size());
      forces_.parts.assign(parts_.size(), ForceSums{});
      forces_.boundaries.assign(n_boundaries_, ForceSums{});
      forces_.node_impulse.assign(static_cast<size_t>(D) * probes_.size(), 0.0);
    }
    report_.slabs = o.slabs;
    distribute(whole_points(detail::pack<D, S, Model::kCollisional>(su.particles)));
  }

  void set_stage(int stage, double damping, double flip) override {
    stage_ = stage;
    damping_ = damping;
    flip_ = flip;
    for (auto& s : slabs_) s->set_stage(stage, damping, flip);
  }

  SpanResult advance_span(const Span& s) override {
    t_ = s.t;
    return Runner::advance_span(s);
  }

  StepResult step(double dt, bool want_dt_limit) override {
    const int n = static_cast<int>(slabs_.size());
    for (auto& s : slabs_) s->begin_step(t_, dt, want_dt_limit);
    t_ += dt;
    auto t0 = Clock::now();
    for (int s = 0; s < n; ++s) {
      int seeded = 0;
      if (s > 0) {
        seeded = slabs_[s - 1]->window().whi;
        const auto tx = Clock::now();
        copy_columns(*slabs_[s - 1], *slabs_[s], borders()[s], seeded, 0, 1 + 2 * D);
        times_.exchange += seconds_since(tx);
      }
      slabs_[s]->p2g_phase(seeded);
    }
    times_.p2g += seconds_since(t0);
    t0 = Clock::now();
    for (auto& s : slabs_) s->grid_phase();
    if (!probes_.empty()) {
      dp_.assign(static_cast<size_t>(D) * probes_.size(), 0.0);
      for (auto& s : slabs_) s->probe_momenta(dp_);
      add_step_forces<D>(forces_, parts_, n_boundaries_, probes_, dp_, dt, step_sums_);
    }
    times_.grid += seconds_since(t0);
    t0 = Clock::now();
    for (int s = 0; s + 1 < n; ++s)
      copy_columns(*slabs_[s + 1], *slabs_[s], borders()[s + 1], slabs_[s]->window().whi, 0, G::N);
    times_.exchange += seconds_since(t0);
    t0 = Clock::now();
    StepResult r;
    double lim = std::numeric_limits<double>::infinity();
    for (auto& s : slabs_) {
      const StepResult q = s->g2p_phase();
      if (!q.ok && (r.ok || q.particle < r.particle)) {
        r.ok = false;
        r.particle = q.particle;
        r.status = q.status;
      }
      lim = std::min(lim, q.dt_limit);
    }
    if (want_dt_limit) r.dt_limit = lim;
    times_.g2p += seconds_since(t0);
    ++times_.steps;
    if (!r.ok) return r;
    t0 = Clock::now();
    migrate();
    rebalance_if_needed();
    times_.exchange += seconds_since(t0);
    return r;
  }

  void frame(Frame& out, bool diagnostics, const std::vector<long>& subset) override {
    const SlabPoints<S> all = gather();
    auto members = slabs_[0]->params().members;
    members.material = all.material.empty() ? nullptr : all.material.data();
    detail::make_frame<D, S, Model>(all.part, all.n, slabs_[0]->params().mp, out, diagnostics, subset, members);
  }
  void download(HostParticles& out) override {
    const SlabPoints<S> all = gather();
    detail::unpack<D, S, Model::kCollisional>(all.part, all.n, out);
  }
  void upload(const HostParticles& in) override {
    detail::check_upload(in, su_.particles.n, D);
    distribute(whole_points(detail::pack<D, S, Model::kCollisional>(in)));
  }
  PhaseTimes times() const override { return times_; }
  void reset_times() override { times_ = PhaseTimes{}; }
  UpdateStats update_stats() const override {
    UpdateStats u = retired_stats_;
    for (const auto& s : slabs_) u = u + s->update_stats();
    return u;
  }
  void take_forces(BoundaryForces& out, bool keep) override { take_host_forces(forces_, out, keep); }
  void restore_forces(const BoundaryForces& in) override { restore_host_forces(forces_, in); }
  std::string device() const override {
    return slabs_[0]->device() + ", " + std::to_string(slabs_.size()) + " slabs along x";
  }
  long particles() const override { return su_.particles.n; }
  long nodes() const override { return su_.n_nodes; }
  SlabReport slab_report() const override { return report_; }

 private:
  // node columns: slab s owns [borders()[s], borders()[s + 1]) (kept in the report)
  const std::vector<int>& borders() const { return report_.borders; }
  SlabPoints<S> whole_points(std::vector<S> part) const {
    SlabPoints<S> all;
    all.n = su_.particles.n;
    all.part = std::move(part);
    all.ids.resize(all.n);
    std::iota(all.ids.begin(), all.ids.end(), 0L);
    all.material = su_.point_material;
    return all;
  }

  int slab_of(int column) const { return slab_of_column(borders(), column); }

  // The slabs made anew from all points (ids 0..n-1 in order); the borders balanced first.
  void distribute(SlabPoints<S>&& all) {
    const int n = opt_.slabs, cols = su_.nodes[0];
    std::vector<int> col(all.n);
    const ParticleView<S> pv{all.part.data(), all.n};
#pragma omp parallel for schedule(static)
    for (long p = 0; p < all.n; ++p)
      col[p] = std::clamp(base_column<D, S, Shape, Model::kCollisional>(pv, p, whole_), 0, cols - 1);
    const std::vector<std::vector<long>> which = assign_slabs(col, cols, n, K, report_);
    for (const auto& s : slabs_) retired_stats_ = retired_stats_ + s->update_stats();
    slabs_.clear();
    report_.halo_nodes = 0;
    const long rest = su_.n_nodes / cols;
    for (int s = 0; s < n; ++s) {
      SlabPoints<S> pts = subset(all, which[s]);
      const SlabWindow w{borders()[s], borders()[s + 1], std::min(borders()[s + 1] + K - 1, cols)};
      report_.halo_nodes += 2 * static_cast<long>(w.whi - w.hi) * rest;
      slabs_.push_back(std::make_unique<Slab>(su_, &pts, &w));
      slabs_.back()->set_stage(stage_, damping_, flip_);
    }
  }

  static SlabPoints<S> subset(const SlabPoints<S>& from, const std::vector<long>& which) {
    SlabPoints<S> out;
    out.n = static_cast<long>(which.size());
    out.part.resize(static_cast<size_t>(Lay::N) * out.n);
    const ParticleView<S> src{const_cast<S*>(from.part.data()), from.n}, dst{out.part.data(), out.n};
    for (long j = 0; j < out.n; ++j) {
      gather_slot(src, dst, Lay::N, j, which[j]);
      out.ids.push_back(from.ids[which[j]]);
      if (!from.material.empty()) out.material.push_back(from.material[which[j]]);
    }
    return out;
  }

  // All points in their original order.
  SlabPoints<S> gather() const {
    SlabPoints<S> all;
    all.n = su_.particles.n;
    all.part.resize(static_cast<size_t>(Lay::N) * all.n);
    all.ids.resize(all.n);
    std::iota(all.ids.begin(), all.ids.end(), 0L);
    if (!su_.point_material.empty()) all.material.resize(all.n);
    const ParticleView<S> dst{all.part.data(), all.n};
    for (const auto& s : slabs_) {
      const ParticleView<S> src = s->points();
      const std::vector<long>& ids = s->ids();
      for (long j = 0; j < src.n; ++j) {
        gather_slot(src, dst, Lay::N, ids[j], j);
        if (!all.material.empty()) all.material[ids[j]] = s->material()[j];
      }
    }
    return all;
  }

  // Columns [c0, c1) of grid fields [f0, f1) from one slab's storage into another's.
  static void copy_columns(Slab& from, Slab& to, int c0, int c1, int f0, int f1) {
    const GridDesc<D, S>& a = from.grid();
    const GridDesc<D, S>& b = to.grid();
    const long rest = a.n_nodes / a.nx;
    const S* src = from.grid_data();
    S* dst = to.grid_data();
    for (int f = f0; f < f1; ++f)
      for (long r = 0; r < rest; ++r)
        for (int c = c0; c < c1; ++c)
          dst[f * b.n_nodes + r * b.nx + (c - b.x0)] = src[f * a.n_nodes + r * a.nx + (c - a.x0)];
  }

  // Points whose stencil now starts in another slab's columns move there.
  void migrate() {
    SlabPoints<S> moving;
    std::vector<int> cols;
    for (auto& s : slabs_) s->emigrate(moving, cols);
    if (moving.n == 0) return;
    report_.migrated += moving.n;
    std::vector<std::vector<long>> to(slabs_.size());
    for (long j = 0; j < moving.n; ++j) to[slab_of(std::clamp(cols[j], 0, su_.nodes[0] - 1))].push_back(j);
    for (size_t s = 0; s < slabs_.size(); ++s) {
      if (to[s].empty()) continue;
      std::sort(to[s].begin(), to[s].end(), [&](long a, long b) { return moving.ids[a] < moving.ids[b]; });
      SlabPoints<S> in = subset(moving, to[s]);
      slabs_[s]->immigrate(in);
    }
  }

  void rebalance_if_needed() {
    long most = 0;
    for (const auto& s : slabs_) most = std::max(most, s->particles());
    if (rule_.after_step(most, su_.particles.n, static_cast<int>(slabs_.size()), report_)) distribute(gather());
  }

  SceneSetup su_;
  SlabOptions opt_;
  GridDesc<D, S> whole_;
  std::vector<std::unique_ptr<Slab>> slabs_;
  int stage_ = 0;
  double damping_ = 0, flip_ = 0, t_ = 0;
  Repartitioning rule_;
  std::vector<ForceProbe> probes_;
  std::vector<ForcePart> parts_;
  int n_boundaries_ = 0;
  BoundaryForces forces_;
  std::vector<ForceSums> step_sums_;
  std::vector<double> dp_;
  UpdateStats retired_stats_;
  PhaseTimes times_;
  SlabReport report_;
};

}  // namespace granflow::mpm::cpu
