// Data layout of the MPM: structure-of-arrays particle and grid storage as one flat buffer
// each (field-major: field f of item i at a[f * n + i]). Plain arrays only, so a backend
// allocates, copies and checkpoints one block; kernels see a view of raw pointers.
#pragma once

#include <cstdint>

#include <granflow/constitutive.hpp>

#include "shape.hpp"

namespace granflow::mpm {

// Particle fields. Stresses are stored as symmetric 3x3 in Voigt order xx, yy, zz, yz, xz, xy
// (plane strain keeps sigma_zz). kColl adds sqrt(T); a frictional-only scene carries no T.
template <int D, bool kColl>
struct ParticleLayout {
  static constexpr int X = 0;            // position, D components
  static constexpr int V = X + D;        // velocity, D components
  static constexpr int M = V + D;        // mass (per unit thickness in 2D)
  static constexpr int SIG = M + 1;      // total Cauchy stress, 6 components (tension +)
  static constexpr int L = SIG + 6;      // velocity gradient of the last step, D*D, row-major
  static constexpr int SIGF = L + D * D; // frictional stress (model state), 6 components
  static constexpr int EPS = SIGF + 6;   // equivalent plastic deviatoric strain
  static constexpr int E = EPS + 1;      // void ratio
  static constexpr int SQT = E + 1;      // sqrt(T), only when kColl
  static constexpr int N = kColl ? SQT + 1 : SQT;
};

template <class S>
struct ParticleView {
  S* a = nullptr;
  long n = 0;
  GF_HDI S& f(int field, long i) const { return a[static_cast<long>(field) * n + i]; }
};

// Grid fields: mass, momentum, force, velocity before and after the update.
template <int D>
struct GridLayout {
  static constexpr int M = 0;
  static constexpr int P = 1;
  static constexpr int F = P + D;
  static constexpr int VOLD = F + D;
  static constexpr int VNEW = VOLD + D;
  static constexpr int N = VNEW + D;
};

template <class S>
struct GridView {
  S* a = nullptr;
  long n = 0;
  const std::uint8_t* mask = nullptr;  // bit d set: velocity component d held at zero
  // Nodes of the block whose masks precede the contact table (boundary.hpp); 0: n. An
  // ensemble member's view (member_grid) sees its own block of nodes, masks and table.
  long block = 0;
  // Node masses for G2P's light-node limit (linear hats): null reads field M (the CPU twin);
  // the CUDA grid kernel clears M after using it and leaves a copy here.
  S* g2p_mass = nullptr;
  GF_HDI S& f(int field, long i) const { return a[static_cast<long>(field) * n + i]; }
  GF_HDI S node_mass_g2p(int m_field, long i) const { return g2p_mass ? g2p_mass[i] : f(m_field, i); }
};

// Background grid: nodes at origin + I h, I in [0, cells] per axis. `walls` (default none)
// selects the boundary-modified quadratic B-splines at axis-aligned walls (shape.hpp).
// Storage may hold a window of node columns along x, [x0, x0 + nx) (a slab of a decomposed
// scene, docs/mpm_slabs.md): indices I stay global (positions, shapes and the on-grid test are
// those of the whole grid), linear() and multi() map them to and from the window's storage.
// The whole grid: x0 = 0, nx = nodes[0]; n_nodes counts the stored nodes. Only the CPU twin
// splits the grid yet: device code keeps the whole grid's arithmetic (its kernels' registers and
// spills, scripts/ptxas_report.sh, are those from before the windows).
template <int D, class S>
struct GridDesc {
  S origin[D];
  S h;
  S inv_h;
  int nodes[D];
  long n_nodes;
  AxisWalls walls[D] = {};
  int x0 = 0, nx = 0;
#ifdef __CUDA_ARCH__
  GF_HDI long linear(const int* I) const {
    long k = I[D - 1];
    for (int d = D - 2; d >= 0; --d) k = k * nodes[d] + I[d];
    return k;
  }
  GF_HDI void multi(long k, int* I) const {
    for (int d = 0; d < D; ++d) {
      I[d] = static_cast<int>(k % nodes[d]);
      k /= nodes[d];
    }
  }
#else
  GF_HDI long linear(const int* I) const {
    long k = 0;
    for (int d = D - 1; d >= 1; --d) k = k * nodes[d] + I[d];
    return k * nx + (I[0] - x0);
  }
  GF_HDI void multi(long k, int* I) const {
    I[0] = static_cast<int>(k % nx) + x0;
    k /= nx;
    for (int d = 1; d < D; ++d) {
      I[d] = static_cast<int>(k % nodes[d]);
      k /= nodes[d];
    }
  }
#endif
};

// Symmetric 3x3 <-> Voigt (xx, yy, zz, yz, xz, xy).
template <class S>
GF_HDI Mat3<S> load_sym(const ParticleView<S>& pv, int field, long i) {
  Mat3<S> m;
  m(0, 0) = pv.f(field, i);
  m(1, 1) = pv.f(field + 1, i);
  m(2, 2) = pv.f(field + 2, i);
  m(1, 2) = m(2, 1) = pv.f(field + 3, i);
  m(0, 2) = m(2, 0) = pv.f(field + 4, i);
  m(0, 1) = m(1, 0) = pv.f(field + 5, i);
  return m;
}
// m may be in another scalar T (the model's, "mixed" precision): rounded to S when stored.
template <class S, class T>
GF_HDI void store_sym(const ParticleView<S>& pv, int field, long i, const Mat3<T>& m) {
  pv.f(field, i) = S(m(0, 0));
  pv.f(field + 1, i) = S(m(1, 1));
  pv.f(field + 2, i) = S(m(2, 2));
  pv.f(field + 3, i) = S(T(0.5) * (m(1, 2) + m(2, 1)));
  pv.f(field + 4, i) = S(T(0.5) * (m(0, 2) + m(2, 0)));
  pv.f(field + 5, i) = S(T(0.5) * (m(0, 1) + m(1, 0)));
}

// Model state <-> particle arrays, one specialisation per model the MPM supports. The arrays'
// scalar T may differ from the model's S ("mixed" precision: float storage, double model).
template <class Model>
struct StateIO;

template <class S, LodeShape LS, StressIntegrator I>
struct StateIO<FrictionalModel<S, LS, I>> {
  using State = typename FrictionalModel<S, LS, I>::State;
  template <int D>
  using Lay = ParticleLayout<D, false>;
  template <int D, class T>
  static GF_HDI State load(const ParticleView<T>& pv, long i) {
    State st;
    st.sigma = load_sym(pv, Lay<D>::SIGF, i).template cast<S>();
    st.eps_pd = S(pv.f(Lay<D>::EPS, i));
    st.e = S(pv.f(Lay<D>::E, i));
    return st;
  }
  template <int D, class T>
  static GF_HDI void store(const ParticleView<T>& pv, long i, const State& st) {
    store_sym(pv, Lay<D>::SIGF, i, st.sigma);
    pv.f(Lay<D>::EPS, i) = T(st.eps_pd);
    pv.f(Lay<D>::E, i) = T(st.e);
  }
};

template <class S, LodeShape LS, RestitutionUse R, StressIntegrator I>
struct StateIO<PhaseTransitionModel<S, LS, R, I>> {
  using State = typename PhaseTransitionModel<S, LS, R, I>::State;
  template <int D>
  using Lay = ParticleLayout<D, true>;
  template <int D, class T>
  static GF_HDI State load(const ParticleView<T>& pv, long i) {
    State st;
    st.sigma_f = load_sym(pv, Lay<D>::SIGF, i).template cast<S>();
    st.eps_pd = S(pv.f(Lay<D>::EPS, i));
    st.e = S(pv.f(Lay<D>::E, i));
    st.s = S(pv.f(Lay<D>::SQT, i));
    return st;
  }
  template <int D, class T>
  static GF_HDI void store(const ParticleView<T>& pv, long i, const State& st) {
    store_sym(pv, Lay<D>::SIGF, i, st.sigma_f);
    pv.f(Lay<D>::EPS, i) = T(st.eps_pd);
    pv.f(Lay<D>::E, i) = T(st.e);
    pv.f(Lay<D>::SQT, i) = T(st.s);
  }
};

// Frictional parameters of either model (elastic moduli for the time-step limit).
template <class S>
GF_HDI const FrictionalParams<S>& frictional_params(const FrictionalParams<S>& p) { return p; }
template <class S>
GF_HDI const FrictionalParams<S>& frictional_params(const PhaseTransitionParams<S>& p) { return p.f; }

}  // namespace granflow::mpm
