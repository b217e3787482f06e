// CUDA backend: one kernel per phase, each calling the per-particle / per-node functions of
// kernels.hpp that the CPU twin also uses. P2G scatters with atomicAdd on doubles (binning
// and warp-level reduction are later work, issue 7); the only host round-trip per step is
// the status word (and the step limit when the step is adaptive).
#include <cuda_runtime.h>
#include <thrust/device_ptr.h>
#include <thrust/extrema.h>
#include <thrust/functional.h>
#include <thrust/reduce.h>

#include <stdexcept>
#include <string>

#include "runner_common.hpp"

namespace granflow::mpm {
namespace {

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("CUDA error in ") + what + ": " + cudaGetErrorString(e));
}

template <int D, class S, class Model, class Shape>
__global__ void p2g_kernel(ParticleView<S> pv, GridView<S> gv, StepParams<D, S, Model> sp, long* keys) {
  using G = GridLayout<D>;
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (p >= pv.n) return;
  const P2GParticle<D, S> q = p2g_load<D, S, Model>(pv, p, sp);
  int base[D];
  stencil_base<D, S, Shape>(q.xi, sp.grid, base);
  keys[p] = sp.grid.linear(base);  // bin of the particle (volumetric averaging)
  for (int k = 0; k < stencil_size<D, Shape::K>(); ++k) {
    int I[D];
    stencil_node<D, Shape::K>(base, k, I);
    S c[1 + 2 * D];
    p2g_contribution<D, S, Shape>(q, I, sp.grid.inv_h, c);
    const long n = sp.grid.linear(I);
    atomicAdd(&gv.f(G::M, n), c[0]);
    for (int d = 0; d < D; ++d) {
      atomicAdd(&gv.f(G::P + d, n), c[1 + d]);
      atomicAdd(&gv.f(G::F + d, n), c[1 + D + d]);
    }
  }
}

template <int D, class S, class Model, bool kBoundary>
__global__ void grid_kernel(GridView<S> gv, StepParams<D, S, Model> sp) {
  const long I = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (I >= gv.n) return;
  grid_update_node<D, S, Model, kBoundary>(gv, I, sp);
}

template <int D, class S, class Model, class Shape>
__global__ void g2p_kernel(ParticleView<S> pv, GridView<S> gv, StepParams<D, S, Model> sp, S* dt_limit,
                           unsigned long long* first_bad, std::uint32_t* status, std::uint32_t* upd_info) {
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (p >= pv.n) return;
  const std::uint32_t st = g2p_particle<D, S, Model, Shape>(pv, gv, p, sp, &dt_limit[p], &upd_info[p]);
  status[p] = st;
  if (st) atomicMin(first_bad, static_cast<unsigned long long>(p));
}

// Split G2P for volumetric averaging: kinematics and bin sums, then the constitutive update.
template <int D, class S, class Model, class Shape>
__global__ void g2p_kinematics_kernel(ParticleView<S> pv, GridView<S> gv, StepParams<D, S, Model> sp,
                                      const long* keys, S* bin_v, S* bin_vtr, unsigned long long* first_bad,
                                      std::uint32_t* status) {
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (p >= pv.n) return;
  const std::uint32_t st = g2p_kinematics<D, S, Model, Shape>(pv, gv, p, sp);
  status[p] = st;
  if (st) {
    atomicMin(first_bad, static_cast<unsigned long long>(p));
    return;
  }
  S V, tr;
  volumetric_rate<D, S, Model>(pv, p, sp, V, tr);
  atomicAdd(&bin_v[keys[p]], V);
  atomicAdd(&bin_vtr[keys[p]], V * tr);
}

template <int D, class S, class Model>
__global__ void constitutive_kernel(ParticleView<S> pv, StepParams<D, S, Model> sp, const long* keys,
                                    const S* bin_v, const S* bin_vtr, S* dt_limit, unsigned long long* first_bad,
                                    std::uint32_t* status, std::uint32_t* upd_info) {
  const long p = blockIdx.x * static_cast<long>(blockDim.x) + threadIdx.x;
  if (p >= pv.n || status[p]) return;  // kinematics already failed here
  const long b = keys[p];
  const S tr_bar = bin_v[b] > S(0) ? bin_vtr[b] / bin_v[b] : S(0);
  const std::uint32_t st = constitutive_particle<D, S, Model>(pv, p, sp, tr_bar, &dt_limit[p], &upd_info[p]);
  status[p] = st;
  if (st) atomicMin(first_bad, static_cast<unsigned long long>(p));
}

template <class T>
T* device_alloc(size_t n) {
  T* p = nullptr;
  check(cudaMalloc(&p, n * sizeof(T) + 16), "cudaMalloc");
  return p;
}

template <int D, class S, class Model, class Shape, bool kBoundary>
class CudaRunner final : public Runner {
  using G = GridLayout<D>;
  static constexpr int kBlock = 128;

 public:
  explicit CudaRunner(const SceneSetup& su) : sp_(detail::step_params<D, S, Model>(su)), n_(su.particles.n) {
    const std::vector<S> host = detail::pack<D, S, Model::kCollisional>(su.particles);
    part_ = device_alloc<S>(host.size());
    check(cudaMemcpy(part_, host.data(), host.size() * sizeof(S), cudaMemcpyHostToDevice), "upload particles");
    n_part_fields_ = host.size();
    grid_ = device_alloc<S>(static_cast<size_t>(G::N) * sp_.grid.n_nodes);
    dtlim_ = device_alloc<S>(n_);
    status_ = device_alloc<std::uint32_t>(n_);
    info_ = device_alloc<std::uint32_t>(n_);
    keys_ = device_alloc<long>(n_);
    bins_ = device_alloc<S>(2 * static_cast<size_t>(sp_.grid.n_nodes));
    bad_ = device_alloc<unsigned long long>(1);
    for (const auto& m : su.stage_masks) {
      std::uint8_t* d = nullptr;
      if (!m.empty()) {
        d = device_alloc<std::uint8_t>(m.size());
        check(cudaMemcpy(d, m.data(), m.size(), cudaMemcpyHostToDevice), "upload masks");
      }
      masks_.push_back(d);
    }
    for (auto& e : ev_) check(cudaEventCreate(&e), "cudaEventCreate");
    set_stage(0, 0.0, su.scene.flip);
  }
  ~CudaRunner() override {
    cudaFree(part_); cudaFree(grid_); cudaFree(dtlim_); cudaFree(status_); cudaFree(info_); cudaFree(keys_); cudaFree(bins_); cudaFree(bad_);
    for (auto* m : masks_) cudaFree(m);
    for (auto& e : ev_) cudaEventDestroy(e);
  }

  void set_stage(int stage, double damping, double flip) override {
    stage_ = stage;
    sp_.damping = S(damping);
    sp_.flip = S(flip);
  }

  StepResult step(double dt, bool want_dt_limit) override {
    sp_.dt = S(dt);
    sp_.want_dt_limit = want_dt_limit ? 1 : 0;
    const long nn = sp_.grid.n_nodes;
    const ParticleView<S> pv{part_, n_};
    const GridView<S> gv{grid_, nn, masks_[stage_]};
    const unsigned pb = static_cast<unsigned>((n_ + kBlock - 1) / kBlock);
    const unsigned gb = static_cast<unsigned>((nn + kBlock - 1) / kBlock);
    const unsigned long long none = ~0ull;
    check(cudaMemcpyAsync(bad_, &none, sizeof none, cudaMemcpyHostToDevice), "reset status");
    cudaEventRecord(ev_[0]);
    check(cudaMemsetAsync(grid_, 0, sizeof(S) * (1 + 2 * D) * nn), "clear grid");
    p2g_kernel<D, S, Model, Shape><<<pb, kBlock>>>(pv, gv, sp_, keys_);
    cudaEventRecord(ev_[1]);
    grid_kernel<D, S, Model, kBoundary><<<gb, kBlock>>>(gv, sp_);
    cudaEventRecord(ev_[2]);
    if (!sp_.vol_avg) {
      g2p_kernel<D, S, Model, Shape><<<pb, kBlock>>>(pv, gv, sp_, dtlim_, bad_, status_, info_);
    } else {
      check(cudaMemsetAsync(bins_, 0, sizeof(S) * 2 * nn), "clear bins");
      g2p_kinematics_kernel<D, S, Model, Shape><<<pb, kBlock>>>(pv, gv, sp_, keys_, bins_, bins_ + nn, bad_, status_);
      constitutive_kernel<D, S, Model><<<pb, kBlock>>>(pv, sp_, keys_, bins_, bins_ + nn, dtlim_, bad_, status_, info_);
    }
    cudaEventRecord(ev_[3]);
    check(cudaGetLastError(), "kernel launch");
    StepResult r;
    if (want_dt_limit) {
      thrust::device_ptr<S> b(dtlim_);
      r.dt_limit = double(thrust::reduce(b, b + n_, S(1e300), thrust::minimum<S>()));
    }
    unsigned long long bad = 0;
    check(cudaMemcpy(&bad, bad_, sizeof bad, cudaMemcpyDeviceToHost), "status");
    float ms[3];
    for (int k = 0; k < 3; ++k) cudaEventElapsedTime(&ms[k], ev_[k], ev_[k + 1]);
    times_.p2g += 1e-3 * ms[0];
    times_.grid += 1e-3 * ms[1];
    times_.g2p += 1e-3 * ms[2];
    ++times_.steps;
    if (bad != none) {
      r.ok = false;
      r.particle = static_cast<long>(bad);
      check(cudaMemcpy(&r.status, status_ + bad, sizeof(std::uint32_t), cudaMemcpyDeviceToHost), "status");
    }
    return r;
  }

  void frame(Frame& out, bool diagnostics, const std::vector<long>& subset) override {
    std::vector<S> host = download_raw();
    detail::make_frame<D, S, Model>(host, n_, sp_.mp, out, diagnostics, subset);
  }
  void download(HostParticles& out) override {
    detail::unpack<D, S, Model::kCollisional>(download_raw(), n_, out);
  }
  void upload(const HostParticles& in) override {
    detail::check_upload(in, n_, D);
    const std::vector<S> host = detail::pack<D, S, Model::kCollisional>(in);
    check(cudaMemcpy(part_, host.data(), host.size() * sizeof(S), cudaMemcpyHostToDevice), "upload particles");
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
  long particles() const override { return n_; }
  long nodes() const override { return sp_.grid.n_nodes; }

 private:
  std::vector<S> download_raw() {
    std::vector<S> host(n_part_fields_);
    check(cudaMemcpy(host.data(), part_, host.size() * sizeof(S), cudaMemcpyDeviceToHost), "download");
    return host;
  }

  StepParams<D, S, Model> sp_;
  long n_;
  size_t n_part_fields_ = 0;
  int stage_ = 0;
  S* part_ = nullptr;
  S* grid_ = nullptr;
  S* dtlim_ = nullptr;
  std::uint32_t* status_ = nullptr;
  long* keys_ = nullptr;
  S* bins_ = nullptr;  // per-bin V and V tr L (volumetric averaging)
  std::uint32_t* info_ = nullptr;  // per-particle update record (not reduced on the GPU yet)
  unsigned long long* bad_ = nullptr;
  std::vector<std::uint8_t*> masks_;
  cudaEvent_t ev_[4];
  PhaseTimes times_;
};

struct MakeCuda {
  template <int D, class Model, class Shape, bool kB>
  std::unique_ptr<Runner> run(const SceneSetup& su) {
#ifndef GRANFLOW_MPM_CUDA_3D
    if constexpr (D == 3) {
      throw std::runtime_error("3D CUDA kernels are not compiled: configure with -DGRANFLOW_MPM_CUDA_3D=ON");
    } else
#endif
    {
      return std::make_unique<CudaRunner<D, double, Model, Shape, kB>>(su);
    }
  }
};

}  // namespace

bool cuda_backend_available() {
  int n = 0;
  return cudaGetDeviceCount(&n) == cudaSuccess && n > 0;
}

std::unique_ptr<Runner> make_cuda_runner(const SceneSetup& su) {
  if (!cuda_backend_available()) throw std::runtime_error("no CUDA device found; use --backend cpu");
  return detail::dispatch<double>(su, MakeCuda{});
}

}  // namespace granflow::mpm
