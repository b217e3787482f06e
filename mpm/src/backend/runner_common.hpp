// Host code shared by the CPU and CUDA runners: packing the set-up into the SoA layout,
// step parameters, frames with diagnostics. Included by cpu_runner.cpp and cuda_runner.cu.
#pragma once

#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <thread>
#include <vector>

#include <granflow/mpm/kernels.hpp>
#include <granflow/mpm/runner.hpp>

namespace granflow::mpm::detail {

// The scene's (double) parameters in the model's scalar (params_cast: the identity for double).
template <class Model>
typename Model::Params model_params(const Material& m) {
  using MS = typename Model::Scalar;
  if constexpr (Model::kCollisional) {
    return params_cast<MS>(m.params);
  } else {
    return params_cast<MS>(m.params.f);
  }
}

template <int D, class S>
GridDesc<D, S> grid_desc(const SceneSetup& su) {
  GridDesc<D, S> g;
  for (int d = 0; d < D; ++d) {
    g.origin[d] = S(su.origin[d]);
    g.nodes[d] = su.nodes[d];
    g.walls[d] = d < static_cast<int>(su.walls.size()) ? su.walls[d] : AxisWalls{};
  }
  g.h = S(su.scene.h);
  g.inv_h = S(1) / g.h;
  g.n_nodes = su.n_nodes;
  g.x0 = 0;
  g.nx = su.nodes[0];
  return g;
}

// Ensembles and scenes of several materials run the kMembers instantiations (kernels.hpp,
// Members); a single run of one material the plain ones.
inline bool uses_members(const SceneSetup& su) { return su.members > 1 || su.scene.material_count() > 1; }

template <int D, class S, class Model>
StepParams<D, S, Model> step_params(const SceneSetup& su) {
  StepParams<D, S, Model> sp;
  sp.grid = grid_desc<D, S>(su);
  sp.mp = model_params<Model>(su.scene.material);
  sp.rho_p = S(su.scene.material.params.c.rho_p);
  for (int d = 0; d < D; ++d) sp.gravity[d] = S(su.scene.gravity[d]);
  sp.dt = S(su.scene.dt);
  sp.flip = S(su.scene.flip);
  sp.affine = su.scene.transfer == Scene::Transfer::TaylorPic ? 1 : 0;
  sp.pic_speed = S(su.scene.pic_speed);
  sp.damping = S(0);
  double mmin = 1e300;
  for (double m : su.particles.m) mmin = std::min(mmin, m);
  sp.mass_eps = S(1e-8 * mmin);
  sp.mass_floor = S(su.scene.light_node_mass * mmin);
  sp.cfl = S(su.scene.step_cfl());
  sp.want_dt_limit = 0;
  sp.vol_avg = su.scene.volumetric_averaging ? 1 : 0;
  sp.t = 0;
  if (uses_members(su)) {
    sp.members.count = su.members;
    sp.members.particles = su.particles.n / su.members;
    sp.members.nodes = su.n_nodes;
    sp.members.mask_stride = su.mask_stride;
    sp.members.materials = su.scene.material_count();
  }
  return sp;
}

// Per-member, per-material parameters (Members::values): member k's materials at
// k * materials + material. A single run takes the scene's materials.
template <int D, class S, class Model>
std::vector<MemberValues<typename Model::Params, S>> member_values(const SceneSetup& su) {
  std::vector<MemberValues<typename Model::Params, S>> out;
  const long np = su.particles.n / su.members;
  const int nmat = su.scene.material_count();
  for (int k = 0; k < su.members; ++k) {
    double mmin = 1e300;
    for (long i = k * np; i < (k + 1) * np; ++i) mmin = std::min(mmin, su.particles.m[i]);
    for (int j = 0; j < nmat; ++j) {
      const Material& mat = su.member_materials.empty() ? su.scene.material_at(j)
                                                        : su.member_materials.at(static_cast<size_t>(k * nmat + j));
      out.push_back({model_params<Model>(mat), S(mat.params.c.rho_p), S(1e-8 * mmin), S(su.scene.light_node_mass * mmin)});
    }
  }
  return out;
}

// Runs f(i0, i1) over [0, n) in chunks on all cores (std::thread: the CUDA back end's host code
// is built without OpenMP); one chunk below 65,536 items.
template <class F>
void parallel_chunks(long n, F&& f) {
  const long t = std::max(1L, std::min<long>(std::thread::hardware_concurrency(), (n + 65535) / 65536));
  if (t == 1) {
    f(0L, n);
    return;
  }
  std::vector<std::thread> pool;
  for (long k = 0; k < t; ++k) pool.emplace_back([&, k] { f(n * k / t, n * (k + 1) / t); });
  for (auto& th : pool) th.join();
}

// Points [i0, i1) of HostParticles into a field-major buffer of ParticleLayout<D, kColl> for all
// hp.n points (ranges may be packed on several threads).
template <int D, class S, bool kColl>
void pack_range(const HostParticles& hp, S* a, long i0, long i1) {
  using Lay = ParticleLayout<D, kColl>;
  const long n = hp.n;
  ParticleView<S> pv{a, n};
  for (long i = i0; i < i1; ++i) {
    for (int d = 0; d < D; ++d) {
      pv.f(Lay::X + d, i) = S(hp.x[d * n + i]);
      pv.f(Lay::V + d, i) = S(hp.v[d * n + i]);
    }
    pv.f(Lay::M, i) = S(hp.m[i]);
    for (int c = 0; c < 6; ++c) {
      pv.f(Lay::SIG + c, i) = S(hp.sig[c * n + i]);
      pv.f(Lay::SIGF + c, i) = S(hp.sigf[c * n + i]);
    }
    for (int c = 0; c < D * D; ++c) pv.f(Lay::L + c, i) = S(hp.L[c * n + i]);
    pv.f(Lay::EPS, i) = S(hp.eps[i]);
    pv.f(Lay::E, i) = S(hp.e[i]);
    if constexpr (kColl) pv.f(Lay::SQT, i) = S(hp.s[i]);
  }
}

// HostParticles -> field-major buffer of ParticleLayout<D, kColl>.
template <int D, class S, bool kColl>
std::vector<S> pack(const HostParticles& hp) {
  std::vector<S> a(static_cast<size_t>(ParticleLayout<D, kColl>::N) * hp.n);
  pack_range<D, S, kColl>(hp, a.data(), 0, hp.n);
  return a;
}

// A state to upload must come from the same set-up (count, dimension, field sizes).
inline void check_upload(const HostParticles& hp, long n, int dim) {
  const size_t un = static_cast<size_t>(n);
  if (hp.n != n || hp.dim != dim || hp.x.size() != dim * un || hp.v.size() != dim * un || hp.m.size() != un ||
      hp.sig.size() != 6 * un || hp.sigf.size() != 6 * un || hp.L.size() != dim * dim * un || hp.eps.size() != un ||
      hp.e.size() != un || hp.s.size() != un)
    throw std::invalid_argument("upload: particle state of " + std::to_string(hp.n) + " points in " +
                                std::to_string(hp.dim) + "D does not fit this runner (" + std::to_string(n) +
                                " in " + std::to_string(dim) + "D)");
}

template <int D, class S, bool kColl>
void unpack(const std::vector<S>& a, long n, HostParticles& hp) {
  using Lay = ParticleLayout<D, kColl>;
  ParticleView<S> pv{const_cast<S*>(a.data()), n};
  hp.n = n;
  hp.dim = D;
  hp.x.resize(D * n); hp.v.resize(D * n); hp.m.resize(n);
  hp.sig.resize(6 * n); hp.sigf.resize(6 * n); hp.L.resize(D * D * n);
  hp.eps.resize(n); hp.e.resize(n); hp.s.assign(n, 0.0);
  for (long i = 0; i < n; ++i) {
    for (int d = 0; d < D; ++d) {
      hp.x[d * n + i] = pv.f(Lay::X + d, i);
      hp.v[d * n + i] = pv.f(Lay::V + d, i);
    }
    hp.m[i] = pv.f(Lay::M, i);
    for (int c = 0; c < 6; ++c) {
      hp.sig[c * n + i] = pv.f(Lay::SIG + c, i);
      hp.sigf[c * n + i] = pv.f(Lay::SIGF + c, i);
    }
    for (int c = 0; c < D * D; ++c) hp.L[c * n + i] = pv.f(Lay::L + c, i);
    hp.eps[i] = pv.f(Lay::EPS, i);
    hp.e[i] = pv.f(Lay::E, i);
    if constexpr (kColl) hp.s[i] = pv.f(Lay::SQT, i);
  }
}

// Output fields from a host copy of the particle buffer. p and q are those of the total
// stress; eta_c, K_col and T come from Model::diagnostics with D of the last step.
// Ensembles: `members` gives each particle its member's parameters.
template <int D, class S, class Model>
void make_frame(const std::vector<S>& a, long n, const typename Model::Params& mp0, Frame& fr, bool diagnostics,
                const std::vector<long>& subset = {}, const Members<typename Model::Params, S>& members = {}) {
  using Lay = ParticleLayout<D, Model::kCollisional>;
  ParticleView<S> pv{const_cast<S*>(a.data()), n};
  fr.n = n;
  fr.dim = D;
  fr.x.resize(D * n);
  fr.v.resize(D * n);
  for (long i = 0; i < n; ++i)
    for (int d = 0; d < D; ++d) {
      fr.x[d * n + i] = pv.f(Lay::X + d, i);
      fr.v[d * n + i] = pv.f(Lay::V + d, i);
    }
  fr.T.assign(n, 0.0);
  if constexpr (Model::kCollisional)
    for (long i = 0; i < n; ++i) fr.T[i] = pv.f(Lay::SQT, i) * pv.f(Lay::SQT, i);
  using MS = typename Model::Scalar;
  auto point = [&](long i, Diagnostics<MS>& dg, Mat3<S>& sig) {
    const auto& mp = members.values ? members.values[members.value_index(members.of_particle(i), i)].mp : mp0;
    const auto st = StateIO<Model>::template load<D>(pv, i);
    Mat3<MS> L = Mat3<MS>::Zero();
    for (int r = 0; r < D; ++r)
      for (int c = 0; c < D; ++c) L(r, c) = MS(pv.f(Lay::L + r * D + c, i));
    dg = Model::diagnostics(mp, st, sym(L));
    sig = load_sym(pv, Lay::SIG, i);
  };
  fr.subset.clear();
  if (!diagnostics) {
    for (auto* f : {&fr.p, &fr.q, &fr.eps_pd, &fr.eta_c, &fr.K_col, &fr.e, &fr.sxx, &fr.syy, &fr.sxy}) f->clear();
    for (long i : subset) {
      Diagnostics<MS> dg;
      Mat3<S> sig;
      point(i, dg, sig);
      fr.subset.push_back({mean_pressure(sig), deviatoric_q(sig), dg.eps_pd, dg.T, dg.eta_c, dg.K_col});
    }
    return;
  }
  for (auto* f : {&fr.p, &fr.q, &fr.eps_pd, &fr.eta_c, &fr.K_col, &fr.e, &fr.sxx, &fr.syy, &fr.sxy})
    f->assign(n, 0.0);
  parallel_chunks(n, [&](long i0, long i1) {
    for (long i = i0; i < i1; ++i) {
      Diagnostics<MS> dg;
      Mat3<S> sig;
      point(i, dg, sig);
      fr.p[i] = mean_pressure(sig);
      fr.q[i] = deviatoric_q(sig);
      fr.eps_pd[i] = dg.eps_pd;
      fr.T[i] = dg.T;
      fr.eta_c[i] = dg.eta_c;
      fr.K_col[i] = dg.K_col;
      fr.e[i] = dg.e;
      fr.sxx[i] = sig(0, 0);
      fr.syy[i] = sig(1, 1);
      fr.sxy[i] = sig(0, 1);
    }
  });
}

// Dispatch of the compile-time choices a scene selects. F is a template functor
// F::template run<D, S, Model, Shape, kBoundary, kMembers>(setup): S is the scalar of particle and grid
// storage and of P2G, grid update and G2P, Model::Scalar that of the constitutive update
// (solver.precision): fp64 S = double, Model<double>; mixed S = float, Model<double>;
// fp32 S = float, Model<float>. fp32 and mixed are compiled for scenes with boundary code (every
// scene but free-fall tests has walls): 8 instantiations each instead of 16, per backend.
// Ensembles (kMembers) are compiled for 2D scenes with boundary code: 4 per precision; a single
// run of several materials also takes them in 2D, and in 3D 4 more per precision.
template <class S, class MS, bool kUnbounded, class F>
auto dispatch_scalar(const SceneSetup& su, F& f) {
  using PT = PhaseTransitionModel<MS>;
  using FR = FrictionalModel<MS>;
  const Scene& sc = su.scene;
  const bool pt = sc.material.model == ModelKind::PhaseTransition;
  const bool quad = sc.shape == ShapeKind::QuadraticBSpline;
#define GF_MPM_CASE_M(DIM, B, M)                                                   \
  if (pt && quad) return f.template run<DIM, S, PT, QuadraticShape, B, M>(su);    \
  if (pt) return f.template run<DIM, S, PT, LinearShape, B, M>(su);               \
  if (quad) return f.template run<DIM, S, FR, QuadraticShape, B, M>(su);          \
  return f.template run<DIM, S, FR, LinearShape, B, M>(su);
#define GF_MPM_CASE(DIM, B) GF_MPM_CASE_M(DIM, B, false)
  if (uses_members(su)) {
    if (su.members > 1 && (sc.dim != 2 || !su.has_boundary))
      throw SceneError("dimension", "ensembles are compiled for 2D scenes with a wall, a base or a gate");
    // A single run of several materials: with boundary code (a scene without walls has masks
    // that hold no node, scene/node_masks.cpp), in 2D and 3D.
    if (sc.dim == 3) {
      GF_MPM_CASE_M(3, true, true)
    }
    GF_MPM_CASE_M(2, true, true)
  }
  if (!su.has_boundary) {
    if constexpr (kUnbounded) {
      if (sc.dim == 3) {
        GF_MPM_CASE(3, false)
      }
      GF_MPM_CASE(2, false)
    } else {
      throw SceneError("solver.precision", std::string("\"") + precision_name(sc.precision) +
                       "\" is compiled only for scenes with a wall, a base or a gate (this one has none); "
                       "use \"fp64\"");
    }
  }
  if (sc.dim == 3) {
    GF_MPM_CASE(3, true)
  }
  GF_MPM_CASE(2, true)
#undef GF_MPM_CASE
#undef GF_MPM_CASE_M
}

template <class F>
auto dispatch(const SceneSetup& su, F&& f) {
  switch (su.scene.precision) {
    case Precision::Mixed: return dispatch_scalar<float, double, false>(su, f);
    case Precision::FP32: return dispatch_scalar<float, float, false>(su, f);
    default: return dispatch_scalar<double, double, true>(su, f);
  }
}

}  // namespace granflow::mpm::detail
