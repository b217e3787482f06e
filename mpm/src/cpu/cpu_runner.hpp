// CPU twin: the kernels of kernels.hpp in OpenMP loops.
// P2G is a gather: particles are binned (stable counting sort) by the lowest node of their
// stencil, and each node sums the contributions of the bins that reach it in a fixed order
// (bins along x outermost, then the other axes, then the points of a bin by index). The result
// is bitwise independent of the thread count (restart tests rely on this) and of a split into
// slabs along x (cpu_slabs.hpp): a slab starts the nodes it shares with its left neighbour from
// that neighbour's partial sums, which hold exactly the bins that come first.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <limits>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include <granflow/mpm/binning.hpp>

#include "backend/runner_common.hpp"

namespace granflow::mpm::cpu {

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// A slab of a scene split along x (cpu_slabs.hpp): it owns node columns [lo, hi) and the points
// whose stencil starts in them, and stores columns [lo, whi), whi = hi + K - 1 (the grid's end
// at most): the columns its points reach in the right neighbour.
struct SlabWindow {
  int lo = 0, hi = 0, whi = 0;
};

// The points a slab starts with (original indices ascending) and their packed state.
template <class S>
struct SlabPoints {
  std::vector<S> part;  // field-major, n points
  long n = 0;
  std::vector<long> ids;
  std::vector<std::uint8_t> material;  // empty with one material
};

// The lowest stencil node column of point p (the column of its bin in the next P2G).
template <int D, class S, class Shape, bool kColl>
int base_column(const ParticleView<S>& pv, long p, const GridDesc<D, S>& g) {
  S xi[D];
  int base[D];
  particle_base<D, S, Shape, kColl>(pv, p, g, xi, base);
  return base[0];
}

// The forces of one step from each probe's momentum dp (component-major, dim x probes), summed
// part by part in probe order, then boundary by boundary in part order.
template <int D>
void add_step_forces(BoundaryForces& f, const std::vector<ForcePart>& parts, int n_boundaries,
                     const std::vector<ForceProbe>& probes, const std::vector<double>& dp, double dt,
                     std::vector<ForceSums>& step) {
  const long np = static_cast<long>(probes.size());
  step.assign(parts.size(), ForceSums{});
  for (size_t q = 0; q < parts.size(); ++q) {
    const ForcePart& part = parts[q];
    for (long i = part.first; i < part.first + part.count; ++i) {
      double d3[3] = {0, 0, 0};
      for (int d = 0; d < D; ++d) d3[d] = dp[d * np + i];
      add_probe_momentum<D>(step[q], probes[i], d3, part.moment_point);
      for (int d = 0; d < D; ++d) f.node_impulse[d * np + i] += d3[d];
    }
    add_force_step(f.parts[q], step[q], dt);
  }
  for (int b = 0; b < n_boundaries; ++b) {
    ForceSums sb;
    for (size_t q = 0; q < parts.size(); ++q)
      if (parts[q].boundary == b) add_step_sums(sb, step[q]);
    add_force_step(f.boundaries[b], sb, dt);
  }
}

// kMembers: an ensemble (kernels.hpp, Members): every loop finds the member of its particle or
// node and works on the member's view of the step parameters and the grid.
// A slab (SlabPoints given): the window's nodes and the given points only; the masks, terrain,
// obstacle and probe lists are those of its owned columns, and it runs the phases of a step
// as cpu_slabs.hpp calls them.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
class CpuRunner final : public Runner {
  using Lay = ParticleLayout<D, Model::kCollisional>;
  using G = GridLayout<D>;
  using SP = StepParams<D, S, Model>;

 public:
  static constexpr int K = Shape::K;

  explicit CpuRunner(const SceneSetup& su, SlabPoints<S>* slab = nullptr, const SlabWindow* w = nullptr)
      : masks_(su.stage_masks), sp_(detail::step_params<D, S, Model>(su)), nn_(su.n_nodes * su.members) {
    if (slab) {
      win_ = *w;
      sliced_ = true;
      part_ = std::move(slab->part);
      n_ = slab->n;
      ids_ = std::move(slab->ids);
      material_ = std::move(slab->material);
      sp_.grid.x0 = win_.lo;
      sp_.grid.nx = win_.whi - win_.lo;
      sp_.grid.n_nodes = su.n_nodes / su.nodes[0] * sp_.grid.nx;
      nn_ = sp_.grid.n_nodes;
      sp_.members.nodes = nn_;  // one member (several materials): its grid view is the window
      slice_masks(su);
    } else {
      win_ = {0, su.nodes[0], su.nodes[0]};
      n_ = su.particles.n;
      part_ = detail::pack<D, S, Model::kCollisional>(su.particles);
      material_ = su.point_material;  // the twin keeps points in their original order
      ids_.resize(n_);
      for (long p = 0; p < n_; ++p) ids_[p] = p;
    }
    grid_.assign(static_cast<size_t>(G::N) * nn_, S(0));
    if (sp_.vol_avg) trbar_.assign(nn_, S(0));
    bin_start_.assign(nn_ + 1, 0);
    if constexpr (kMembers) {
      values_ = detail::member_values<D, S, Model>(su);
      dead_.assign(su.members, 0u);
      sp_.members.values = values_.data();
      sp_.members.dead = dead_.data();
      msp_.assign(values_.size(), sp_);
    }
    resize_points();
    for (size_t s = 0; s < masks_.size(); ++s) contacts_.push_back(stage_has_contacts(su, static_cast<int>(s)));
    // frictional terrain (3D): in 3D kMembers runs are single runs of several materials
    if constexpr (kBoundary && (!kMembers || D == 3)) {
      terrain_ = su.terrain;
      terrain_mu_ = su.terrain_mu;
    }
    // obstacles and boundary forces: ensembles list each member's nodes (global indices)
    if constexpr (kBoundary) {
      obstacles_ = su.obstacle_nodes;
      probes_ = su.probes;
      probe_ids_.resize(probes_.size());
      for (size_t i = 0; i < probes_.size(); ++i) probe_ids_[i] = static_cast<long>(i);
      parts_ = su.force_parts;
      n_boundaries_ = static_cast<int>(su.force_boundaries.size());
      forces_.parts.assign(parts_.size(), ForceSums{});
      forces_.boundaries.assign(n_boundaries_, ForceSums{});
      forces_.node_impulse.assign(static_cast<size_t>(D) * probes_.size(), 0.0);
      if (sliced_) slice_node_lists(su);
    }
    set_stage(0, 0.0, su.scene.flip);
  }

  void set_stage(int stage, double damping, double flip) override {
    stage_ = stage;
    sp_.damping = S(damping);
    sp_.flip = S(flip);
  }

  // The span's steps start from its time (a lifting gate's edge depends on it).
  SpanResult advance_span(const Span& s) override {
    t_ = s.t;
    return Runner::advance_span(s);
  }

  // One step from the runner's clock: the time the last span started from plus the steps
  // taken since (Runner::advance_span adds them in the same order).
  StepResult step(double dt, bool want_dt_limit) override {
    begin_step(t_, dt, want_dt_limit);
    t_ += dt;
    p2g_phase(0);
    grid_phase();
    if (!probes_.empty()) {
      probe_dp_.assign(static_cast<size_t>(D) * probes_.size(), 0.0);
      probe_momenta(probe_dp_);
      add_step_forces<D>(forces_, parts_, n_boundaries_, probes_, probe_dp_, dt, step_sums_);
    }
    return g2p_phase();
  }

  // ---- the phases of a step (a slab runs them with the exchanges of cpu_slabs.hpp between) ----

  void begin_step(double t, double dt, bool want_dt_limit) {
    sp_.t = t;
    sp_.dt = S(dt);
    sp_.want_dt_limit = want_dt_limit ? 1 : 0;
    if constexpr (kMembers)
      for (size_t i = 0; i < msp_.size(); ++i) {
        msp_[i] = sp_;
        apply_member(msp_[i], static_cast<int>(i));
      }
  }

  // P2G into the stored columns; nodes of columns below `seeded_hi` start from the values
  // already stored in them (the left neighbour's partial sums), bins left of the window are
  // left out (they are in those sums).
  __attribute__((noinline)) void p2g_phase(int seeded_hi) {
    const auto t0 = Clock::now();
    p2g(points(), grid_view(), seeded_hi);
    times_.p2g += seconds_since(t0);
  }

  __attribute__((noinline)) void grid_phase() {
    const auto t0 = Clock::now();
    const GridView<S> gv = grid_view();
    if (kBoundary && contacts_[stage_])
      grid_update<kBoundary>(gv);
    else
      grid_update<false>(gv);
    if (!terrain_.empty()) terrain_pass(gv);
    if (!obstacles_.empty()) obstacle_pass(gv);
    times_.grid += seconds_since(t0);
  }

  // The momentum this step's holds removed from each probe's node, written into dp at the
  // probe's index in the set-up (component-major, dim x all probes).
  __attribute__((noinline)) void probe_momenta(std::vector<double>& dp) {
    const auto t0 = Clock::now();
    const GridView<S> gv = grid_view();
    const long nm = sp_.grid.n_nodes, np = static_cast<long>(dp.size()) / D;
    for (size_t i = 0; i < probes_.size(); ++i) {
      const ForceProbe& pr = probes_[i];
      double v[3] = {0, 0, 0}, vd[3] = {0, 0, 0}, d3[3] = {0, 0, 0};
      const double m = trial_velocity<D, S, Model>(gv, pr.node, node_params(static_cast<int>(pr.node / nm)), v, vd);
      removed_momentum<D, S>(gv, pr.node, m, v, vd, d3);
      for (int d = 0; d < D; ++d) dp[d * np + probe_ids_[i]] = d3[d];
    }
    times_.grid += seconds_since(t0);
  }

  __attribute__((noinline)) StepResult g2p_phase() {
    const auto t0 = Clock::now();
    const ParticleView<S> pv = points();
    const GridView<S> gv = grid_view();
    std::uint32_t any = 0;
    S* lim = dtlim_.data();
    std::uint32_t* st = status_.data();
    std::uint32_t* inf = info_.data();
    if (!sp_.vol_avg) {
#pragma omp parallel for schedule(dynamic, 256) reduction(| : any)
      for (long p = 0; p < n_; ++p) {
        inf[p] = 0;
        st[p] = 0;
        lim[p] = std::numeric_limits<S>::max();
        const int k = member_of(p);
        if (skipped(k)) continue;
        st[p] = g2p_particle<D, S, Model, Shape>(pv, member_view(gv, k), p, params_of(k, p), &lim[p], &inf[p]);
        any |= st[p];
      }
    } else {
#pragma omp parallel for schedule(static) reduction(| : any)
      for (long p = 0; p < n_; ++p) {
        inf[p] = 0;
        st[p] = 0;
        lim[p] = std::numeric_limits<S>::max();
        const int k = member_of(p);
        if (skipped(k)) continue;
        st[p] = g2p_kinematics<D, S, Model, Shape>(pv, member_view(gv, k), p, params_of(k, p), &lim[p]);
        any |= st[p];
      }
      if (!any || kMembers) {  // a member whose kinematics failed does not stop the others
        // volume-weighted mean of tr L per bin (the particles binned in P2G, in order)
        const long nn = nn_;
        S* tb = trbar_.data();
#pragma omp parallel for schedule(static)
        for (long b = 0; b < nn; ++b) {
          S sv = S(0), st_ = S(0);
          for (long j = bin_start_[b]; j < bin_start_[b + 1]; ++j) {
            S V, tr;
            volumetric_rate<D, S, Model>(pv, order_[j], params_of(member_of(order_[j]), order_[j]), V, tr);
            sv += V;
            st_ += V * tr;
          }
          tb[b] = sv > S(0) ? st_ / sv : S(0);
        }
#pragma omp parallel for schedule(dynamic, 256) reduction(| : any)
        for (long p = 0; p < n_; ++p) {
          const int k = member_of(p);
          if (skipped(k) || st[p]) continue;
          st[p] = constitutive_particle<D, S, Model>(pv, p, params_of(k, p), tb[key_[p]], &lim[p], &inf[p]);
          any |= st[p];
        }
      }
    }
    times_.g2p += seconds_since(t0);
    ++times_.steps;
    count_updates();
    StepResult r;
    if (any) {
      for (long p = 0; p < n_; ++p)
        if (st[p]) {
          r.ok = false;
          r.particle = ids_[p];
          r.status = st[p];
          break;
        }
    }
    if (sp_.want_dt_limit) {
      S m = std::numeric_limits<S>::max();
#pragma omp parallel for reduction(min : m)
      for (long p = 0; p < n_; ++p) m = std::min(m, lim[p]);
      r.dt_limit = double(m);
    }
    return r;
  }

  // ---- a slab's points and nodes (cpu_slabs.hpp) ----

  // Removes the points whose stencil starts outside the owned columns and appends them to `out`
  // (their original index, material and state); the others keep their order.
  void emigrate(SlabPoints<S>& out, std::vector<int>& column) {
    std::vector<char> leaves(n_, 0);
    std::vector<int> col(n_);
    long nl = 0;
    const ParticleView<S> pv = points();
#pragma omp parallel for schedule(static) reduction(+ : nl)
    for (long p = 0; p < n_; ++p) {
      col[p] = base_column<D, S, Shape, Model::kCollisional>(pv, p, sp_.grid);
      leaves[p] = col[p] < win_.lo || col[p] >= win_.hi;
      nl += leaves[p];
    }
    if (nl == 0) return;
    SlabPoints<S> stay;
    std::vector<long> kept, gone;
    for (long p = 0; p < n_; ++p) (leaves[p] ? gone : kept).push_back(p);
    append_points(out, gone);
    for (long p : gone) column.push_back(col[p]);
    append_points(stay, kept);
    set_points(std::move(stay));
  }

  // Adds points (original indices ascending) among this slab's, in original-index order.
  void immigrate(SlabPoints<S>& in) {
    if (in.n == 0) return;
    SlabPoints<S> both;
    both.n = n_ + in.n;
    both.part.resize(static_cast<size_t>(Lay::N) * both.n);
    both.ids.resize(both.n);
    if (!material_.empty()) both.material.resize(both.n);
    const ParticleView<S> a = points(), b{in.part.data(), in.n}, c{both.part.data(), both.n};
    long i = 0, j = 0;
    for (long k = 0; k < both.n; ++k) {
      const bool take_a = j >= in.n || (i < n_ && ids_[i] < in.ids[j]);
      const ParticleView<S>& src = take_a ? a : b;
      const long from = take_a ? i++ : j++;
      gather_slot(src, c, Lay::N, k, from);
      both.ids[k] = take_a ? ids_[from] : in.ids[from];
      if (!material_.empty()) both.material[k] = take_a ? material_[from] : in.material[from];
    }
    set_points(std::move(both));
  }

  const SlabWindow& window() const { return win_; }
  const GridDesc<D, S>& grid() const { return sp_.grid; }
  S* grid_data() { return grid_.data(); }
  ParticleView<S> points() { return {part_.data(), n_}; }
  const std::vector<long>& ids() const { return ids_; }
  const std::vector<std::uint8_t>& material() const { return material_; }
  const SP& params() const { return sp_; }
  std::vector<S>& packed() { return part_; }

  // ---- Runner ----

  void frame(Frame& out, bool diagnostics, const std::vector<long>& subset) override {
    detail::make_frame<D, S, Model>(part_, n_, sp_.mp, out, diagnostics, subset, sp_.members);
  }
  void download(HostParticles& out) override { detail::unpack<D, S, Model::kCollisional>(part_, n_, out); }
  void upload(const HostParticles& in) override {
    detail::check_upload(in, n_, D);
    part_ = detail::pack<D, S, Model::kCollisional>(in);
  }
  PhaseTimes times() const override { return times_; }
  UpdateStats update_stats() const override { return stats_; }
  void reset_times() override { times_ = PhaseTimes{}; }
  void take_forces(BoundaryForces& out, bool keep) override { take_host_forces(forces_, out, keep); }
  void restore_forces(const BoundaryForces& in) override { restore_host_forces(forces_, in); }
  std::string device() const override {
    int threads = 1;
#ifdef _OPENMP
    threads = omp_get_max_threads();
#endif
    return "CPU twin (OpenMP, " + std::to_string(threads) + " threads)";
  }
  long particles() const override { return n_; }
  long nodes() const override { return nn_; }

  std::vector<MemberFailure> retire_failed_members() override {
    std::vector<MemberFailure> out;
    if constexpr (kMembers) {
      for (long p = 0; p < n_; ++p) {
        const int k = member_of(p);
        if (status_[p] && !dead_[k]) {
          dead_[k] = 1;
          out.push_back({k, p, status_[p]});
        }
      }
    }
    return out;
  }

 private:
  int member_of(long p) const {
    if constexpr (kMembers) return sp_.members.of_particle(p); else return 0;
  }
  bool skipped(int k) const {
    if constexpr (kMembers) return dead_[k] != 0; else return false;
  }
  // The step parameters of point p of member k, and of member k's grid update.
  const SP& params_of(int k, long p) const {
    if constexpr (kMembers) return msp_[sp_.members.value_index(k, p)]; else return sp_;
  }
  const SP& node_params(int k) const {
    if constexpr (kMembers) return msp_[sp_.members.node_values(k)]; else return sp_;
  }
  GridView<S> member_view(const GridView<S>& gv, int k) const {
    if constexpr (kMembers) return member_grid(gv, sp_.members, k); else return gv;
  }
  GridView<S> grid_view() { return {grid_.data(), nn_, masks_[stage_].data()}; }

  void resize_points() {
    order_.resize(n_);
    key_.resize(n_);
    dtlim_.resize(n_);
    status_.resize(n_);
    info_.resize(n_);
    if constexpr (kMembers) sp_.members.material = material_.empty() ? nullptr : material_.data();
  }
  void set_points(SlabPoints<S>&& pts) {
    part_ = std::move(pts.part);
    n_ = pts.n;
    ids_ = std::move(pts.ids);
    material_ = std::move(pts.material);
    resize_points();
  }
  void append_points(SlabPoints<S>& out, const std::vector<long>& which) {
    const long n0 = out.n, n1 = n0 + static_cast<long>(which.size());
    std::vector<S> part(static_cast<size_t>(Lay::N) * n1);
    const ParticleView<S> old{out.part.data(), n0}, dst{part.data(), n1}, src = points();
    for (long i = 0; i < n0; ++i) gather_slot(old, dst, Lay::N, i, i);
    for (size_t j = 0; j < which.size(); ++j) {
      gather_slot(src, dst, Lay::N, n0 + static_cast<long>(j), which[j]);
      out.ids.push_back(ids_[which[j]]);
      if (!material_.empty()) out.material.push_back(material_[which[j]]);
    }
    out.part = std::move(part);
    out.n = n1;
  }

  // The slab's blocks of masks (and contact tables) and its owned entries of the node lists.
  void slice_masks(const SceneSetup& su) {
    const GridDesc<D, S> whole = detail::grid_desc<D, S>(su);
    for (auto& block : masks_) {
      std::vector<std::uint8_t> local(static_cast<size_t>(nn_), 0);
      int I[D];
      for (long k = 0; k < nn_; ++k) {
        sp_.grid.multi(k, I);
        local[k] = block[whole.linear(I)];
      }
      if (block.size() > static_cast<size_t>(su.n_nodes)) {  // a ContactTable and its segments
        const size_t from = static_cast<size_t>(contact_table_offset(su.n_nodes));
        local.resize(static_cast<size_t>(contact_table_offset(nn_)), 0);
        local.insert(local.end(), block.begin() + static_cast<long>(from), block.end());
      }
      block = std::move(local);
    }
  }
  void slice_node_lists(const SceneSetup& su) {
    const GridDesc<D, S> whole = detail::grid_desc<D, S>(su);
    auto local = [&](long node, long& out) {
      int I[D];
      whole.multi(node, I);
      if (I[0] < win_.lo || I[0] >= win_.hi) return false;
      out = sp_.grid.linear(I);
      return true;
    };
    auto keep = [&](auto& list) {
      size_t j = 0;
      for (auto e : list)
        if (local(e.node, e.node)) list[j++] = e;
      list.resize(j);
    };
    keep(terrain_);
    keep(obstacles_);
    std::vector<ForceProbe> probes;
    std::vector<long> ids;
    for (size_t i = 0; i < probes_.size(); ++i) {
      ForceProbe pr = probes_[i];
      if (!local(pr.node, pr.node)) continue;
      probes.push_back(pr);
      ids.push_back(static_cast<long>(i));
    }
    probes_ = std::move(probes);
    probe_ids_ = std::move(ids);
  }

  // Update records in groups of 32 points (what a GPU warp waits for).
  void count_updates() {
    const std::uint32_t* inf = info_.data();
    const long nw = (n_ + 31) / 32;
    UpdateStats sum;
#pragma omp parallel
    {
      UpdateStats u;
#pragma omp for schedule(static)
      for (long w = 0; w < nw; ++w) {
        long m = 0, slow = 0;
        for (long p = 32 * w; p < std::min(n_, 32 * w + 32); ++p) {
          const std::uint32_t f = inf[p];
          const long e = record::evaluations(f);
          u.substeps += e;
          m = std::max(m, e);
          u.substep_limit += (f & info::kSubstepLimit) != 0;
          u.tension_cutoff += (f & info::kTensionCutoff) != 0;
          u.vs_clamped += (f & info::kVsClamped) != 0;
          u.separated += (f & kSeparatedFlag) != 0;
          if (f & record::kPlastic) {
            ++u.plastic;
            ++u.plastic_evaluations[std::min<long>(e, kCostBins - 1)];
            u.halvings += record::halvings(f);
            u.floored += (f & record::kFloored) != 0;
            u.bracketed += (f & record::kBracketed) != 0;
          }
          slow += e >= kSlowEvaluations;
        }
        u.warp_max_substeps += m;
        u.max_substeps = std::max(u.max_substeps, m);
        ++u.group_max[std::min<long>(m, kCostBins - 1)];
        ++u.slow_in_group[slow];
      }
#pragma omp critical
      sum = sum + u;
    }
    sum.updates = n_;
    sum.warps = nw;
    sum.step_max_substeps = sum.max_substeps;
    sum.steps = 1;
    stats_ = stats_ + sum;
  }

  template <bool kContacts>
  void grid_update(const GridView<S>& gv) {
    const long nn = nn_, nm = sp_.grid.n_nodes;
#pragma omp parallel for schedule(static)
    for (long I = 0; I < nn; ++I) {
      const int k = static_cast<int>(I / nm);
      grid_update_node<D, S, Model, kBoundary, kContacts>(member_view(gv, k), I - k * nm, node_params(k));
    }
  }

  // Friction with the terrain on its listed nodes (boundary.hpp terrain_contact).
  void terrain_pass(const GridView<S>& gv) {
    const long nt = static_cast<long>(terrain_.size());
    const TerrainNode* t = terrain_.data();
#pragma omp parallel for schedule(static)
    for (long i = 0; i < nt; ++i) terrain_contact<D, S>(gv, t[i], terrain_mu_);
  }

  // Obstacles' hold on their listed nodes (boundary.hpp obstacle_contact).
  void obstacle_pass(const GridView<S>& gv) {
    const long no = static_cast<long>(obstacles_.size());
    const ObstacleNode* o = obstacles_.data();
#pragma omp parallel for schedule(static)
    for (long i = 0; i < no; ++i) obstacle_contact<D, S>(gv, o[i]);
  }

  void p2g(const ParticleView<S>& pv, const GridView<S>& gv, int seeded_hi) {
    const long nn = nn_, nm = sp_.grid.n_nodes;
    // 1. bin by the lowest stencil node (stable counting sort: order by particle index); the
    // bins of member k follow those of member k - 1, a retired member's points are left out
    std::fill(bin_start_.begin(), bin_start_.end(), 0L);
#pragma omp parallel for schedule(static)
    for (long p = 0; p < n_; ++p) {
      S xi[D];
      int base[D];
      const int k = member_of(p);
      for (int d = 0; d < D; ++d) xi[d] = (pv.f(Lay::X + d, p) - sp_.grid.origin[d]) * sp_.grid.inv_h;
      stencil_base<D, S, Shape>(xi, sp_.grid, base);  // G2P guarantees the stencil is inside
      key_[p] = skipped(k) ? -1 : k * nm + sp_.grid.linear(base);
    }
    for (long p = 0; p < n_; ++p)
      if (key_[p] >= 0) ++bin_start_[key_[p] + 1];
    for (long k = 0; k < nn; ++k) bin_start_[k + 1] += bin_start_[k];
    {
      std::vector<long>& fill = fill_;
      fill.assign(bin_start_.begin(), bin_start_.end() - 1);
      for (long p = 0; p < n_; ++p)
        if (key_[p] >= 0) order_[fill[key_[p]]++] = p;
    }
    // 2. gather per node from the bins whose stencils reach it: along x outermost
    const long* start = bin_start_.data();
    const long* order = order_.data();
    const GridDesc<D, S>& g = sp_.grid;
    int n_st = 1;
    for (int d = 0; d < D; ++d) n_st *= K;
#pragma omp parallel for schedule(static)
    for (long I = 0; I < nn; ++I) {
      int Im[D];
      const int m = static_cast<int>(I / nm);
      g.multi(I - m * nm, Im);
      S acc[1 + 2 * D] = {};
      if (Im[0] < seeded_hi) {
        acc[0] = gv.f(G::M, I);
        for (int d = 0; d < D; ++d) {
          acc[1 + d] = gv.f(G::P + d, I);
          acc[1 + D + d] = gv.f(G::F + d, I);
        }
      }
      for (int k = 0; k < n_st; ++k) {
        int B[D], kk = k;
        bool ok = true;
        for (int d = D - 1; d >= 0; --d) {
          B[d] = Im[d] - (K - 1) + kk % K;
          kk /= K;
          if (B[d] < 0) ok = false;
        }
        if (!ok || B[0] < g.x0) continue;
        const long b = m * nm + g.linear(B);
        for (long j = start[b]; j < start[b + 1]; ++j) {
          const P2GParticle<D, S> q = p2g_load<D, S, Model>(pv, order[j], params_of(m, order[j]));
          S c[1 + 2 * D];
          p2g_contribution<D, S, Shape>(q, Im, g.inv_h, c);
          for (int f = 0; f < 1 + 2 * D; ++f) acc[f] += c[f];
        }
      }
      gv.f(G::M, I) = acc[0];
      for (int d = 0; d < D; ++d) {
        gv.f(G::P + d, I) = acc[1 + d];
        gv.f(G::F + d, I) = acc[1 + D + d];
      }
    }
  }

  std::vector<std::vector<std::uint8_t>> masks_;
  std::vector<bool> contacts_;  // per stage: friction or a lifting gate (stage_has_contacts)
  std::vector<TerrainNode> terrain_;  // frictional terrain (empty: no terrain pass)
  double terrain_mu_ = 0;
  std::vector<ObstacleNode> obstacles_;  // obstacles' nodes (empty: no obstacle pass)
  std::vector<ForceProbe> probes_;       // boundary forces (empty: no force pass)
  std::vector<long> probe_ids_;          // per entry of probes_: its index in the set-up
  std::vector<ForcePart> parts_;
  int n_boundaries_ = 0;
  BoundaryForces forces_;
  std::vector<ForceSums> step_sums_;
  std::vector<double> probe_dp_;
  SP sp_;
  long n_ = 0;
  long nn_;  // grid nodes of all members (a slab: of its window)
  SlabWindow win_;
  bool sliced_ = false;
  std::vector<long> ids_;  // per point: its index in the set-up (a slab's ascending)
  std::vector<MemberValues<typename Model::Params, S>> values_;
  std::vector<std::uint32_t> dead_;
  std::vector<SP> msp_;  // per entry of values_: sp_ with its values (kMembers)
  std::vector<std::uint8_t> material_;  // per point: material index (several materials)
  int stage_ = 0;
  double t_ = 0;
  std::vector<S> part_, grid_, dtlim_, trbar_;
  std::vector<long> bin_start_, order_, key_, fill_;
  std::vector<std::uint32_t> status_, info_;
  UpdateStats stats_;
  PhaseTimes times_;
};

}  // namespace granflow::mpm::cpu
