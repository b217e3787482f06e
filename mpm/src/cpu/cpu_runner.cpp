// CPU twin: the kernels of kernels.hpp in OpenMP loops.
// P2G is a gather: particles are binned (stable counting sort) by the lowest node of their
// stencil, and each node sums the contributions of the bins that reach it in a fixed order.
// The result is bitwise independent of the thread count (restart tests rely on this).
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <limits>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "run/runner_common.hpp"

namespace granflow::mpm {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// kMembers: an ensemble (kernels.hpp, Members): every loop finds the member of its particle or
// node and works on the member's view of the step parameters and the grid.
template <int D, class S, class Model, class Shape, bool kBoundary, bool kMembers>
class CpuRunner final : public Runner {
  using Lay = ParticleLayout<D, Model::kCollisional>;
  using G = GridLayout<D>;
  using SP = StepParams<D, S, Model>;
  static constexpr int K = Shape::K;

 public:
  explicit CpuRunner(const SceneSetup& su)
      : masks_(su.stage_masks), sp_(detail::step_params<D, S, Model>(su)), n_(su.particles.n),
        nn_(su.n_nodes * su.members) {
    part_ = detail::pack<D, S, Model::kCollisional>(su.particles);
    grid_.assign(static_cast<size_t>(G::N) * nn_, S(0));
    if (sp_.vol_avg) trbar_.assign(nn_, S(0));
    bin_start_.assign(nn_ + 1, 0);
    if constexpr (kMembers) {
      values_ = detail::member_values<D, S, Model>(su);
      dead_.assign(su.members, 0u);
      material_ = su.point_material;  // the twin keeps points in their original order
      sp_.members.values = values_.data();
      sp_.members.dead = dead_.data();
      sp_.members.material = material_.empty() ? nullptr : material_.data();
      msp_.assign(values_.size(), sp_);
    }
    order_.resize(n_);
    key_.resize(n_);
    dtlim_.resize(n_);
    status_.resize(n_);
    info_.resize(n_);
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
      parts_ = su.force_parts;
      n_boundaries_ = static_cast<int>(su.force_boundaries.size());
      forces_.parts.assign(parts_.size(), ForceSums{});
      forces_.boundaries.assign(n_boundaries_, ForceSums{});
      forces_.node_impulse.assign(static_cast<size_t>(D) * probes_.size(), 0.0);
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
    sp_.t = t_;
    t_ += dt;
    sp_.dt = S(dt);
    sp_.want_dt_limit = want_dt_limit ? 1 : 0;
    if constexpr (kMembers)
      for (size_t i = 0; i < msp_.size(); ++i) {
        msp_[i] = sp_;
        apply_member(msp_[i], static_cast<int>(i));
      }
    const ParticleView<S> pv{part_.data(), n_};
    const GridView<S> gv{grid_.data(), nn_, masks_[stage_].data()};
    auto t0 = Clock::now();
    p2g(pv, gv);
    times_.p2g += seconds_since(t0);
    t0 = Clock::now();
    if (kBoundary && contacts_[stage_])
      grid_update<kBoundary>(gv);
    else
      grid_update<false>(gv);
    if (!terrain_.empty()) terrain_pass(gv);
    if (!obstacles_.empty()) obstacle_pass(gv);
    if (!probes_.empty()) force_pass(gv, dt);
    times_.grid += seconds_since(t0);
    t0 = Clock::now();
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
        st[p] = g2p_kinematics<D, S, Model, Shape>(pv, member_view(gv, k), p, params_of(k, p));
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
    // One pass over the update records in groups of 32 points (what a GPU warp waits for).
    long sub = 0, lim_hits = 0, cut = 0, clamp = 0, sep = 0, wsum = 0, most = 0;
    const long nw = (n_ + 31) / 32;
#pragma omp parallel for reduction(+ : sub, lim_hits, cut, clamp, sep, wsum) reduction(max : most)
    for (long w = 0; w < nw; ++w) {
      long m = 0;
      for (long p = 32 * w; p < std::min(n_, 32 * w + 32); ++p) {
        const std::uint32_t f = inf[p];
        sub += f >> 16;
        m = std::max(m, static_cast<long>(f >> 16));
        lim_hits += (f & info::kSubstepLimit) != 0;
        cut += (f & info::kTensionCutoff) != 0;
        clamp += (f & info::kVsClamped) != 0;
        sep += (f & kSeparatedFlag) != 0;
      }
      wsum += m;
      most = std::max(most, m);
    }
    stats_.updates += n_;
    stats_.substeps += sub;
    stats_.substep_limit += lim_hits;
    stats_.tension_cutoff += cut;
    stats_.vs_clamped += clamp;
    stats_.separated += sep;
    stats_.warp_max_substeps += wsum;
    stats_.warps += nw;
    stats_.max_substeps = std::max(stats_.max_substeps, most);
    stats_.step_max_substeps += most;
    ++stats_.steps;
    StepResult r;
    if (any) {
      for (long p = 0; p < n_; ++p)
        if (st[p]) {
          r.ok = false;
          r.particle = p;
          r.status = st[p];
          break;
        }
    }
    if (want_dt_limit) {
      S m = std::numeric_limits<S>::max();
#pragma omp parallel for reduction(min : m)
      for (long p = 0; p < n_; ++p) m = std::min(m, lim[p]);
      r.dt_limit = double(m);
    }
    return r;
  }

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
  void take_forces(BoundaryForces& out, bool keep) override {
    out = forces_;
    if (keep) return;
    std::fill(forces_.parts.begin(), forces_.parts.end(), ForceSums{});
    std::fill(forces_.boundaries.begin(), forces_.boundaries.end(), ForceSums{});
    std::fill(forces_.node_impulse.begin(), forces_.node_impulse.end(), 0.0);
  }
  void restore_forces(const BoundaryForces& in) override {
    if (in.parts.size() == forces_.parts.size() && in.boundaries.size() == forces_.boundaries.size() &&
        in.node_impulse.size() == forces_.node_impulse.size())
      forces_ = in;
  }
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

  // The forces on the boundaries: the momentum each probe's node lost to the holds of this step,
  // summed part by part in probe order, then boundary by boundary in part order.
  void force_pass(const GridView<S>& gv, double dt) {
    const long nm = sp_.grid.n_nodes, np = static_cast<long>(probes_.size());
    std::vector<ForceSums>& step = step_sums_;
    step.assign(parts_.size(), ForceSums{});
    for (size_t q = 0; q < parts_.size(); ++q) {
      const ForcePart& part = parts_[q];
      for (long i = part.first; i < part.first + part.count; ++i) {
        const ForceProbe& pr = probes_[i];
        double v[3] = {0, 0, 0}, vd[3] = {0, 0, 0}, dp[3] = {0, 0, 0};
        const double m = trial_velocity<D, S, Model>(gv, pr.node, node_params(static_cast<int>(pr.node / nm)), v, vd);
        removed_momentum<D, S>(gv, pr.node, m, v, vd, dp);
        add_probe_momentum<D>(step[q], pr, dp, part.moment_point);
        for (int d = 0; d < D; ++d) forces_.node_impulse[d * np + i] += dp[d];
      }
      add_force_step(forces_.parts[q], step[q], dt);
    }
    for (int b = 0; b < n_boundaries_; ++b) {
      ForceSums sb;
      for (size_t q = 0; q < parts_.size(); ++q)
        if (parts_[q].boundary == b) add_step_sums(sb, step[q]);
      add_force_step(forces_.boundaries[b], sb, dt);
    }
  }

  void p2g(const ParticleView<S>& pv, const GridView<S>& gv) {
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
    // 2. gather per node from the bins whose stencils reach it
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
      for (int k = 0; k < n_st; ++k) {
        int B[D], kk = k;
        bool ok = true;
        for (int d = 0; d < D; ++d) {
          B[d] = Im[d] - (K - 1) + kk % K;
          kk /= K;
          if (B[d] < 0) ok = false;
        }
        if (!ok) continue;
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
  std::vector<ForcePart> parts_;
  int n_boundaries_ = 0;
  BoundaryForces forces_;
  std::vector<ForceSums> step_sums_;
  SP sp_;
  long n_;
  long nn_;  // grid nodes of all members
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

struct MakeCpu {
  template <int D, class S, class Model, class Shape, bool kB, bool kM>
  std::unique_ptr<Runner> run(const SceneSetup& su) {
    return std::make_unique<CpuRunner<D, S, Model, Shape, kB, kM>>(su);
  }
};

}  // namespace

std::unique_ptr<Runner> make_cpu_runner(const SceneSetup& su) { return detail::dispatch(su, MakeCpu{}); }

}  // namespace granflow::mpm
