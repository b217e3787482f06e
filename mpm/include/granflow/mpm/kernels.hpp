// The MPM step, written once for every backend (MODEL.md 9; STYLE.md: one phase, one function).
//
//   1. P2G   (p2g_load + p2g_contribution): mass, momentum and force  f = -sum V sigma grad N
//   2. grid  (grid_update_node): v_old = p/m, v_new = v_old + dt (f/m + g), boundary masks,
//            friction and lifting gates (boundary.hpp)
//   3. G2P   (g2p_particle): FLIP/PIC velocity, position with the grid velocity, velocity
//            gradient from v_new, then the constitutive update (Model::update, Jaumann inside).
//
// This is USL (update stress last): the stress that produces the forces of step n+1 comes
// from the velocity gradient of step n. The CPU twin gathers contributions per node
// (deterministic); the CUDA backend scatters them per particle with atomics. Both call the
// same per-pair function, so they differ only in summation order.
#pragma once

#include <cmath>
#include <cstdint>

#include <granflow/constitutive.hpp>

#include "boundary.hpp"
#include "layout.hpp"
#include "shape.hpp"

namespace granflow::mpm {

// Status of one particle after G2P (0: fine). The constitutive flags go in the bits above 8.
enum Status : std::uint32_t {
  kOk = 0,
  kLeftGrid = 1,          // field "position": the stencil of the new position leaves the grid
  kNonFiniteVelocity = 2, // field "velocity"
  kConstitutive = 3,      // field "stress": Model::update reported non-finite / inadmissible
  kCompacted = 4,         // field "void ratio": the step's volumetric strain takes e to <= 0
  kDeferredPoint = 5,     // not a failure: UpdatePart::ElasticOnly left the plastic return to a later Full call
};

// Void ratio at which a dilating point counts as separated (just inside e < 2.97 of Eq. 13).
inline constexpr double kSeparatedVoidRatio = 2.9;
// Bit of the per-particle update record marking a separated point (library flags use bits 0-6).
inline constexpr std::uint32_t kSeparatedFlag = 1u << 7;
// The rest of the record: bits 8-11 the return map's halving trials (at most 15), 12-14 its
// plastic / floored / bracketed flags (info::kPlasticReturn.. shifted down by 9), 16-31 the
// residual evaluations (substeps, at most 65535).
namespace record {
inline constexpr int kHalvingsShift = 8;
inline constexpr std::uint32_t kPlastic = 1u << 12, kFloored = 1u << 13, kBracketed = 1u << 14;
GF_HDI std::uint32_t pack(const UpdateInfo& inf) {
  const std::uint32_t nsub = inf.substeps < 65535 ? static_cast<std::uint32_t>(inf.substeps) : 65535u;
  const std::uint32_t halv = inf.halvings < 15 ? static_cast<std::uint32_t>(inf.halvings) : 15u;
  return (inf.flags & 0x7fu) | (halv << kHalvingsShift) | (((inf.flags >> 9) & 7u) << 12) | (nsub << 16);
}
GF_HDI int evaluations(std::uint32_t r) { return static_cast<int>(r >> 16); }
GF_HDI int halvings(std::uint32_t r) { return static_cast<int>((r >> kHalvingsShift) & 15u); }
}  // namespace record

// ---- ensembles ---------------------------------------------------------------------------
// N members of one scene advance in the same loops and launches (docs/mpm_ensembles.md).
// Member k owns particles [k P, (k + 1) P) and grid nodes [k G, (k + 1) G) of every field, and
// its stage block of masks and contact table starts k * mask_stride bytes into the stage's
// block. Members differ in the values below (per member, on the device for CUDA), in their
// particles' initial state, and in their masks and tables (friction, gate speed); the grid
// description, the step and the stages are shared. Sorting keys put member k before k + 1,
// so a slot's member stays slot / P when particles are reordered.
// Several materials in one scene run the same path: each member has `materials` entries of
// values, and a point's entry is k * materials + material[p] (its material index, kept with
// the point when particles are reordered); the materials of a member share its grid block,
// and its grid update reads entry k * materials (mass_eps and mass_floor, the same for all of
// the member's entries). A single run of several materials is one member.
template <class Params, class S>
struct MemberValues {
  Params mp;
  S rho_p, mass_eps, mass_floor;
};

template <class Params, class S>
struct Members {
  int count = 1;
  int materials = 1;   // entries of values per member (in count's padding: kernel parameters keep their size
                       // but for the pointer `material`)
  long particles = 0;  // per member (P)
  long nodes = 0;      // per member (G)
  long mask_stride = 0;
  const MemberValues<Params, S>* values = nullptr;  // count * materials entries
  const std::uint32_t* dead = nullptr;  // non-zero: the member failed earlier; its points are skipped
  const std::uint8_t* material = nullptr;  // per point (slot): material index; null with one material
  GF_HDI int of_particle(long p) const { return static_cast<int>(p / particles); }
  // Entry of `values` for point p of member k, and the entry of member k's grid update.
  GF_HDI int value_index(int k, long p) const { return material ? k * materials + material[p] : k * materials; }
  GF_HDI int node_values(int k) const { return k * materials; }
  GF_HDI int of_node(long I) const { return static_cast<int>(I / nodes); }
  GF_HDI bool skipped(int k) const { return dead != nullptr && dead[k] != 0u; }
};

// Everything a step needs besides the arrays; passed by value to kernels.
template <int D, class S, class Model>
struct StepParams {
  GridDesc<D, S> grid;
  typename Model::Params mp;
  S rho_p;            // particle (grain) density; bulk density = rho_p / (1 + e)
  S gravity[D];
  S dt;
  S flip;             // FLIP fraction of the FLIP/PIC blend (1: FLIP, 0: PIC)
  int affine;         // P2G carries the affine part m L (x_I - x_p) of the momentum (Taylor PIC)
  S pic_speed;        // > 0: PIC fraction per step min(1, pic_speed dt / h) instead of 1 - flip
  S damping;          // Cundall local damping on the grid (consolidation stages), 0: none
  S mass_eps;         // nodes lighter than this are treated as empty
  S mass_floor;       // internal-force acceleration f / max(m, mass_floor) (light nodes)
  S cfl;              // safety factor of the time-step limit
  int want_dt_limit;  // compute the per-particle stable time step in G2P
  int vol_avg;        // replace tr L by its volume-weighted mean over the particle's bin
  double t;           // time at the start of the step [s] (the lifting gate's edge)
  Members<typename Model::Params, S> members;  // ensembles only (kMembers instantiations)
};

// The step parameters with entry i of the members' values (Members::value_index, node_values),
// and member k's view of the grid (node indices local to the member).
template <int D, class S, class Model>
GF_HDI void apply_member(StepParams<D, S, Model>& sp, int i) {
  const MemberValues<typename Model::Params, S>& v = sp.members.values[i];
  sp.mp = v.mp;
  sp.rho_p = v.rho_p;
  sp.mass_eps = v.mass_eps;
  sp.mass_floor = v.mass_floor;
}
template <class S, class P>
GF_HDI GridView<S> member_grid(const GridView<S>& gv, const Members<P, S>& m, int k) {
  GridView<S> v = gv;
  v.a += static_cast<long>(k) * m.nodes;
  if (v.g2p_mass) v.g2p_mass += static_cast<long>(k) * m.nodes;
  if (v.mask) v.mask += static_cast<long>(k) * m.mask_stride;
  v.block = m.nodes;
  return v;
}

// ---- 1. P2G ------------------------------------------------------------------------------

template <int D, class S>
struct P2GParticle {
  S xi[D];        // grid coordinate (x - origin) / h
  S m;
  S mv[D];        // momentum
  S mLh[D][D];    // m L h: affine momentum per grid unit of (I - xi) (zero without Taylor PIC)
  S Vsig[D][D];   // volume times stress (the in-plane block in 2D)
  AxisWalls walls[D];  // walls of the grid (boundary-modified quadratic B-splines)
};

template <int D, class S, class Model>
GF_HDI P2GParticle<D, S> p2g_load(const ParticleView<S>& pv, long p, const StepParams<D, S, Model>& sp) {
  using Lay = ParticleLayout<D, Model::kCollisional>;
  P2GParticle<D, S> q;
  q.m = pv.f(Lay::M, p);
  for (int d = 0; d < D; ++d) {
    q.walls[d] = sp.grid.walls[d];
    q.xi[d] = (pv.f(Lay::X + d, p) - sp.grid.origin[d]) * sp.grid.inv_h;
    q.mv[d] = q.m * pv.f(Lay::V + d, p);
  }
  const S mh = sp.affine ? q.m * sp.grid.h : S(0);
  for (int a = 0; a < D; ++a)
    for (int b = 0; b < D; ++b) q.mLh[a][b] = mh * pv.f(Lay::L + a * D + b, p);
  const S V = q.m * (S(1) + pv.f(Lay::E, p)) / sp.rho_p;  // V = m / rho, rho = rho_p / (1 + e)
  const Mat3<S> sig = load_sym(pv, Lay::SIG, p);
  for (int a = 0; a < D; ++a)
    for (int b = 0; b < D; ++b) q.Vsig[a][b] = V * sig(a, b);
  return q;
}

// Contribution of one particle to node I: out[0] mass, out[1..D] momentum, out[1+D..2D] force.
template <int D, class S, class Shape>
GF_HDI void p2g_contribution(const P2GParticle<D, S>& q, const int* I, S inv_h, S* out) {
  S w[D], g[D];
  for (int d = 0; d < D; ++d) {
    weight_1d<Shape>(q.xi[d], I[d], q.walls[d], w[d], g[d]);
    g[d] *= inv_h;
  }
  S N = S(1);
  for (int d = 0; d < D; ++d) N *= w[d];
  S gradN[D];
  for (int d = 0; d < D; ++d) {
    S v = g[d];
    for (int k = 0; k < D; ++k)
      if (k != d) v *= w[k];
    gradN[d] = v;
  }
  out[0] = N * q.m;
  for (int d = 0; d < D; ++d) {
    S mv = q.mv[d];
    for (int b = 0; b < D; ++b) mv += q.mLh[d][b] * (S(I[b]) - q.xi[b]);
    out[1 + d] = N * mv;
  }
  for (int a = 0; a < D; ++a) {
    S f = S(0);
    for (int b = 0; b < D; ++b) f -= q.Vsig[a][b] * gradN[b];
    out[1 + D + a] = f;
  }
}

// The K^D nodes of a stencil: node k lies at base + (k mod K, (k / K) mod K, ...).
template <int D, int K>
GF_HDI constexpr int stencil_size() {
  int n = 1;
  for (int d = 0; d < D; ++d) n *= K;
  return n;
}

template <int D, int K>
GF_HDI void stencil_node(const int* base, int k, int* I) {
  for (int d = 0; d < D; ++d) {
    I[d] = base[d] + k % K;
    k /= K;
  }
}

// Lowest stencil node of a particle (per axis) and whether the whole stencil is on the grid.
template <int D, class S, class Shape>
GF_HDI bool stencil_base(const S* xi, const GridDesc<D, S>& g, int* base) {
  bool inside = true;
  for (int d = 0; d < D; ++d) {
    if (!(xi[d] > S(-4) && xi[d] < S(g.nodes[d] + 4))) {  // also catches NaN
      base[d] = 0;
      inside = false;
      continue;
    }
    base[d] = stencil_base_1d<Shape>(xi[d], g.walls[d]);
    if (base[d] < 0 || base[d] + Shape::K > g.nodes[d]) inside = false;
  }
  return inside;
}

// ---- 2. grid update ----------------------------------------------------------------------

// kContacts (with kBoundary): nodes flagged kContactNode go through contact_node (friction,
// lifting gates: boundary.hpp). A separate instantiation, run only for the stages that have
// them: the call alone, never taken, made the update of every node slower (CPU: 0.75 -> 1.5 ms
// per 360,000 nodes; CUDA grid kernel: 28 -> 50 registers in fp32, 38 -> 58 in fp64).
template <int D, class S, class Model, bool kBoundary, bool kContacts = false>
GF_HDI void grid_update_node(const GridView<S>& gv, long I, const StepParams<D, S, Model>& sp) {
  using G = GridLayout<D>;
  const S m = gv.f(G::M, I);
  if (!(m > sp.mass_eps)) {
    for (int d = 0; d < D; ++d) gv.f(G::VOLD + d, I) = gv.f(G::VNEW + d, I) = S(0);
    return;
  }
  std::uint8_t mask = 0;
  if constexpr (kBoundary) mask = gv.mask[I];
  for (int d = 0; d < D; ++d) {
    const S vo = gv.f(G::P + d, I) / m;
    // A node touched only by the edge of a stencil has a tiny mass but not a tiny force
    // (linear hats: the full gradient; quadratic: ~ sqrt of the weight), so f / m is unbounded
    // and one step can give its neighbours' points any velocity gradient: a point at the
    // released column face at 2.5 mm (linear) got tr L dt = -1.7 in one step and an
    // inadmissible void ratio. Below mass_floor the force is applied to mass_floor instead.
    S a = gv.f(G::F + d, I) / (m > sp.mass_floor ? m : sp.mass_floor) + sp.gravity[d];
    if (sp.damping > S(0)) a -= sp.damping * std::fabs(a) * (vo > S(0) ? S(1) : (vo < S(0) ? S(-1) : S(0)));
    S vn = vo + sp.dt * a;
    if constexpr (kBoundary) {
      if (mask & (1u << d)) vn = S(0);
    }
    gv.f(G::VOLD + d, I) = vo;
    gv.f(G::VNEW + d, I) = vn;
  }
  if constexpr (kBoundary && kContacts) {
    if (mask & kContactNode) contact_node<D, S>(gv, I, sp.grid, sp.t);
  }
}

// ---- forces on the boundaries ------------------------------------------------------------

// The grid update's velocity of node I before any hold, recomputed as grid_update_node computes
// it (vd, with the stage's damping) and without damping (v), and the node's mass (0 for an empty
// node, whose velocities are then zero). Taken after P2G: the CUDA grid kernel clears mass,
// momentum and force.
template <int D, class S, class Model>
GF_HDI double trial_velocity(const GridView<S>& gv, long I, const StepParams<D, S, Model>& sp, double* v,
                             double* vd) {
  using G = GridLayout<D>;
  for (int d = 0; d < D; ++d) v[d] = vd[d] = 0;
  const S m = gv.f(G::M, I);
  if (!(m > sp.mass_eps)) return 0;
  for (int d = 0; d < D; ++d) {
    const S vo = gv.f(G::P + d, I) / m;
    S a = gv.f(G::F + d, I) / (m > sp.mass_floor ? m : sp.mass_floor) + sp.gravity[d];
    v[d] = static_cast<double>(vo + sp.dt * a);
    if (sp.damping > S(0)) a -= sp.damping * std::fabs(a) * (vo > S(0) ? S(1) : (vo < S(0) ? S(-1) : S(0)));
    vd[d] = static_cast<double>(vo + sp.dt * a);
  }
  return static_cast<double>(m);
}

// The momentum the boundaries removed from node I in this step, after every hold of the step:
// m (v - v_new) in each component a hold changed (v_new differs from the damped trial vd), zero
// in the others. The undamped trial v: at a held node the velocity mapped from the points is
// nearly zero and of either sign, and Cundall's damping term (damping |a| against that sign) is
// no force of the boundary's.
template <int D, class S>
GF_HDI void removed_momentum(const GridView<S>& gv, long I, double m, const double* v, const double* vd, double* dp) {
  using G = GridLayout<D>;
  constexpr double rel = sizeof(S) == sizeof(double) ? 1e-9 : 1e-5;  // the grid kernel may round differently
  for (int d = 0; d < D; ++d) {
    const double vn = static_cast<double>(gv.f(G::VNEW + d, I));
    const bool held = std::fabs(vn - vd[d]) > rel * (std::fabs(vd[d]) + std::fabs(vn)) + 1e-300;
    dp[d] = held ? m * (v[d] - vn) : 0.0;
  }
}

// ---- 3. G2P and constitutive update ------------------------------------------------------

// 2D plane strain: the in-plane gradient embedded in 3x3 with a zero z row and column.
template <int D, class S>
GF_HDI Mat3<S> embed_gradient(const S (&L)[D][D]) {
  Mat3<S> L3 = Mat3<S>::Zero();
  for (int a = 0; a < D; ++a)
    for (int b = 0; b < D; ++b) L3(a, b) = L[a][b];
  return L3;
}

// Stable time step of one particle: CFL with the elastic P-wave speed of the skeleton
// (K_f, G_f from the library) plus the particle speed, and the viscous (diffusive) limit
// dt <= rho h^2 / (2 n_dim (4/3 eta_c + kappa_c)) of MODEL.md 9.
// Evaluated in the model's scalar MS (double in the "mixed" precision, where S is float).
template <int D, class S, class Model>
GF_HDI S particle_dt_limit(const typename Model::State& st, const StepParams<D, S, Model>& sp, S speed) {
  using MS = typename Model::Scalar;
  const FrictionalParams<MS>& fp = frictional_params(sp.mp);
  const MS rho = MS(sp.rho_p) / (MS(1) + st.e);
  Mat3<MS> sigf;
  if constexpr (Model::kCollisional) sigf = st.sigma_f; else sigf = st.sigma;
  const ElasticModuli<MS> c = elastic_moduli(fp, mean_pressure(sigf), st.e);
  const MS wave = std::sqrt((c.K + MS(4) / MS(3) * c.G) / rho);
  const MS h = MS(sp.grid.h);
  MS lim = MS(sp.cfl) * h / (wave + MS(speed));
  if constexpr (Model::kCollisional) {
    const KineticCoefficients<MS> kc = kinetic_coefficients(sp.mp.c, MS(1) / (MS(1) + st.e));
    const CollisionalTransport<MS> t = collisional_transport(sp.mp.c, kc, st.s);
    const MS visc = MS(4) / MS(3) * t.eta + t.kappa;
    if (visc > MS(0)) {
      const MS lv = MS(sp.cfl) * rho * h * h / (MS(2) * MS(D) * visc);
      lim = lv < lim ? lv : lim;
    }
  }
  return S(lim);
}

// Light nodes and the stable step (linear hats). A node that a point reaches with a small
// weight has a small mass but, with linear hats, not a small stiffness: a hat's gradient does
// not vanish at its edge. Gershgorin on the lumped mass bounds the node's frequency by
// omega^2 <= (V M / m_I) |grad N_Ip| sum_J |grad N_Jp| (M = K + 4/3 G = rho c_p^2), so the
// node's stable step is
//   dt_I = 2 sqrt(m_I / (m_p g_I sum_J g_J)) h / c_p,   g = h |grad N| (grid units),
// with m_I the force's mass max(m_I, mass_floor) (grid_update_node). A point touching a node
// at the light-node floor (0.05 of a point) sees 0.32 h / c_p; an interior node (8 points a
// cell in 3D) gives about 4.6 h / c_p and never binds. The factor below is that step in units
// of h / c_p; the limit multiplies particle_dt_limit by it. Quadratic B-splines have a gradient
// that vanishes like the square root of the weight, so no such node: their factor is 1.
struct LightNodeFactor {
  double min_ratio = 1e300;  // min over the stencil of m_I / (m_p g_I)
  double sum_g = 0;          // sum over the stencil of g_J
  GF_HDI double factor() const {
    if (!(sum_g > 0)) return 1e300;
    return 2.0 * std::sqrt(min_ratio / sum_g);
  }
};

// 3a. Velocity, position and velocity gradient of one particle (L stored in the particle).
// With dt_limit (linear hats, when the step computes its stable limit): *dt_limit is lowered
// to the stable step of the point's lightest node (LightNodeFactor), where that is below the
// point's own; the constitutive update then lowers it to the point's own limit.
template <int D, class S, class Model, class Shape>
GF_HDI std::uint32_t g2p_kinematics(const ParticleView<S>& pv, const GridView<S>& gv, long p,
                                    const StepParams<D, S, Model>& sp, S* dt_limit = nullptr) {
  using Lay = ParticleLayout<D, Model::kCollisional>;
  using G = GridLayout<D>;
  constexpr bool kLight = Shape::kind == ShapeKind::Linear;
  const bool light = kLight && dt_limit != nullptr && sp.want_dt_limit;
  LightNodeFactor lf;
  S xi[D];
  for (int d = 0; d < D; ++d) xi[d] = (pv.f(Lay::X + d, p) - sp.grid.origin[d]) * sp.grid.inv_h;
  int base[D];
  if (!stencil_base<D, S, Shape>(xi, sp.grid, base)) return kLeftGrid;

  S vpic[D] = {}, dv[D] = {}, L[D][D] = {};
  for (int k = 0; k < stencil_size<D, Shape::K>(); ++k) {
    int I[D];
    stencil_node<D, Shape::K>(base, k, I);
    S w[D], g[D];
    for (int d = 0; d < D; ++d) {
      weight_1d<Shape>(xi[d], I[d], sp.grid.walls[d], w[d], g[d]);
      g[d] *= sp.grid.inv_h;
    }
    S N = S(1);
    for (int d = 0; d < D; ++d) N *= w[d];
    S gradN[D];
    for (int d = 0; d < D; ++d) {
      S v = g[d];
      for (int j = 0; j < D; ++j)
        if (j != d) v *= w[j];
      gradN[d] = v;
    }
    const long n = sp.grid.linear(I);
    if constexpr (kLight) {
      if (light) {
        double g2 = 0;
        for (int d = 0; d < D; ++d) g2 += double(gradN[d]) * double(gradN[d]);
        const double g = std::sqrt(g2) * double(sp.grid.h);
        if (g > 0) {
          const S m = gv.node_mass_g2p(G::M, n);
          const double r = double(m > sp.mass_floor ? m : sp.mass_floor) / (double(pv.f(Lay::M, p)) * g);
          lf.min_ratio = r < lf.min_ratio ? r : lf.min_ratio;
          lf.sum_g += g;
        }
      }
    }
    for (int a = 0; a < D; ++a) {
      const S vn = gv.f(G::VNEW + a, n);
      vpic[a] += N * vn;
      dv[a] += N * (vn - gv.f(G::VOLD + a, n));
      for (int b = 0; b < D; ++b) L[a][b] += vn * gradN[b];
    }
  }
  S flip = sp.flip;
  if (sp.pic_speed > S(0)) {
    const S pic = sp.pic_speed * sp.dt * sp.grid.inv_h;
    flip = pic < S(1) ? S(1) - pic : S(0);
  }
  for (int d = 0; d < D; ++d) {
    const S v = flip * (pv.f(Lay::V + d, p) + dv[d]) + (S(1) - flip) * vpic[d];
    if (!std::isfinite(v)) return kNonFiniteVelocity;
    pv.f(Lay::V + d, p) = v;
    pv.f(Lay::X + d, p) += sp.dt * vpic[d];
  }
  for (int a = 0; a < D; ++a)
    for (int b = 0; b < D; ++b) pv.f(Lay::L + a * D + b, p) = L[a][b];
  for (int d = 0; d < D; ++d) xi[d] = (pv.f(Lay::X + d, p) - sp.grid.origin[d]) * sp.grid.inv_h;
  if (!stencil_base<D, S, Shape>(xi, sp.grid, base)) return kLeftGrid;
  if constexpr (kLight) {
    const double f = light ? lf.factor() : 1e300;
    if (f < 1.0) {  // the point's c_p from its state at the start of the step
      S speed2 = S(0);
      for (int d = 0; d < D; ++d) speed2 += pv.f(Lay::V + d, p) * pv.f(Lay::V + d, p);
      const S lim = S(f) * particle_dt_limit<D, S, Model>(StateIO<Model>::template load<D>(pv, p), sp,
                                                          std::sqrt(speed2));
      *dt_limit = lim < *dt_limit ? lim : *dt_limit;
    }
  }
  return kOk;
}

// Volume and in-plane volumetric rate of a particle after 3a (for cell averaging).
template <int D, class S, class Model>
GF_HDI void volumetric_rate(const ParticleView<S>& pv, long p, const StepParams<D, S, Model>& sp, S& V, S& trL) {
  using Lay = ParticleLayout<D, Model::kCollisional>;
  V = pv.f(Lay::M, p) * (S(1) + pv.f(Lay::E, p)) / sp.rho_p;
  trL = S(0);
  for (int d = 0; d < D; ++d) trL += pv.f(Lay::L + d * D + d, p);
}

// 3b. Constitutive update of one particle from the stored L. With tr_bar finite, the
// volumetric part of L is replaced by tr_bar (the volume-weighted mean over the particle's
// bin: the "cell-averaged volumetric strain rate" that damps pressure checkerboarding).
// The update runs in the model's scalar MS = Model::Scalar: S (fp64, fp32) or double with
// float storage ("mixed": state, L and dt converted to double and the result back).
// With P = ElasticOnly a point that needs a plastic return is left as it was (kDeferredPoint).
template <int D, class S, class Model, UpdatePart P = UpdatePart::Full>
GF_HDI std::uint32_t constitutive_particle(const ParticleView<S>& pv, long p, const StepParams<D, S, Model>& sp,
                                           S tr_bar, S* dt_limit, std::uint32_t* upd_info) {
  using Lay = ParticleLayout<D, Model::kCollisional>;
  S L[D][D];
  for (int a = 0; a < D; ++a)
    for (int b = 0; b < D; ++b) L[a][b] = pv.f(Lay::L + a * D + b, p);
  if (std::isfinite(tr_bar)) {
    S tr = S(0);
    for (int d = 0; d < D; ++d) tr += L[d][d];
    for (int d = 0; d < D; ++d) L[d][d] += (tr_bar - tr) / S(D);
  }
  using IO = StateIO<Model>;
  using MS = typename Model::Scalar;
  typename Model::State st = IO::template load<D>(pv, p);
  Mat3<MS> stress;
  const Mat3<MS> L3 = embed_gradient<D, S>(L).template cast<MS>();
  const MS dt = MS(sp.dt);
  const MS e_trial = (MS(1) + st.e) * std::exp(trace(L3) * dt) - MS(1);
  const UpdateInfo inf = Model::template update<P>(sp.mp, st, L3, dt, stress);
  if (inf.deferred()) return kDeferredPoint;
  *upd_info = record::pack(inf);
  if (inf.ok()) {
    IO::template store<D>(pv, p, st);
    store_sym(pv, Lay::SIG, p, stress);
  } else if ((inf.flags & info::kInadmissible) && e_trial >= MS(kSeparatedVoidRatio)) {
    // A point torn off the bulk (free surface, rear of a slide) dilates past the range of
    // Eq. (13): the grains have separated. It carries no stress and keeps e at the cap until
    // it is compressed again (MPM policy, not part of the constitutive model).
    store_sym(pv, Lay::SIGF, p, Mat3<S>(Mat3<S>::Zero()));
    store_sym(pv, Lay::SIG, p, Mat3<S>(Mat3<S>::Zero()));
    pv.f(Lay::E, p) = S(kSeparatedVoidRatio);
    *upd_info |= kSeparatedFlag;
  } else if ((inf.flags & info::kInadmissible) && !(e_trial > S(0))) {
    // Compaction past e = 0 in one step: no granular skeleton does that; it is a velocity
    // gradient from a blown-up node (light nodes, grid_update_node), reported as such.
    return kCompacted | (inf.flags << 8);
  } else {
    return kConstitutive | (inf.flags << 8);
  }
  if (sp.want_dt_limit) {
    S speed2 = S(0);
    for (int d = 0; d < D; ++d) speed2 += pv.f(Lay::V + d, p) * pv.f(Lay::V + d, p);
    const S lim = particle_dt_limit<D, S, Model>(st, sp, std::sqrt(speed2));
    *dt_limit = lim < *dt_limit ? lim : *dt_limit;  // g2p_kinematics may have lowered it (light nodes)
  }
  return kOk;
}

// 3. G2P and constitutive update fused (no volumetric averaging). With P = ElasticOnly a
// kDeferredPoint has its kinematics done (L stored) and needs constitutive_particle (Full).
template <int D, class S, class Model, class Shape, UpdatePart P = UpdatePart::Full>
GF_HDI std::uint32_t g2p_particle(const ParticleView<S>& pv, const GridView<S>& gv, long p,
                                  const StepParams<D, S, Model>& sp, S* dt_limit, std::uint32_t* upd_info) {
  const std::uint32_t s = g2p_kinematics<D, S, Model, Shape>(pv, gv, p, sp, dt_limit);
  if (s != kOk) return s;
  return constitutive_particle<D, S, Model, P>(pv, p, sp, S(NAN), dt_limit, upd_info);
}

inline const char* status_field(std::uint32_t s) {
  switch (s & 0xffu) {
    case kLeftGrid: return "position (left the grid)";
    case kNonFiniteVelocity: return "velocity (non-finite)";
    case kConstitutive:
      return (s >> 8) & info::kInadmissible ? "stress (inadmissible state: stress, eps_pd, void ratio or T)"
                                            : "stress (non-finite constitutive update)";
    case kCompacted: return "void ratio (compacted to e <= 0 within one step: a blown-up velocity gradient)";
    case kDeferredPoint: return "none (plastic return deferred)";
    default: return "none";
  }
}

}  // namespace granflow::mpm
