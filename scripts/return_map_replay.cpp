// Replays the return map's inputs recorded from an MPM run (scripts/return_map_dump.patch) through
// frictional_return_map of the headers it is compiled against: evaluations per return, the
// hand-overs, and the expected largest cost of 32 returns (what a GPU warp waits for).
// docs/benchmarks.md, "Plastic returns: the tail, and the cut", quotes its output.
//
// Record (fp32 run shown; fp64 the same with --precision fp64 and "double" below):
//   git apply scripts/return_map_dump.patch
//   cmake -S . -B /tmp/bdump -DCMAKE_BUILD_TYPE=Release -DGRANFLOW_CUDA=OFF -DCMAKE_CXX_FLAGS=-DGF_RETURN_DUMP
//   cmake --build /tmp/bdump --target granflow && git apply -R scripts/return_map_dump.patch
//   /tmp/bdump/granflow mpm mpm/scenes/column_collapse.toml --set grid.h=0.005 --set time.dt=5e-5 \
//       --precision fp32 --out /tmp/dump_run --force --no-png --quiet
//   (writes return_map_params.bin and return_map_inputs.bin in the working directory: every
//   return of 8 or more evaluations, one in 16 of the others, each with its weight)
// Replay, against these headers or another tree's:
//   g++ -O2 -std=c++17 -I constitutive/include -isystem /usr/include/eigen3 scripts/return_map_replay.cpp \
//       -o /tmp/return_map_replay
//   /tmp/return_map_replay return_map_inputs.bin return_map_params.bin float [stresses.bin]
// Two replays' stresses side by side:
//   /tmp/return_map_replay --compare old.bin new.bin
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <vector>

#include "granflow/constitutive/frictional.hpp"

using namespace granflow;

namespace {

template <class S>
struct Record {
  S v[20];  // sigma (9), deps (9), eps_pd, e: the return map's input after the half rotation
  int weight;
  std::uint32_t flags;
  int evaluations;
};

template <class S>
bool read(FILE* f, Record<S>& r) {
  return std::fread(r.v, sizeof r.v, 1, f) == 1 && std::fread(&r.weight, 4, 1, f) == 1 &&
         std::fread(&r.flags, 4, 1, f) == 1 && std::fread(&r.evaluations, 4, 1, f) == 1;
}

template <class S>
int replay(const char* inputs, const char* params, const char* out) {
  FrictionalParams<S> mp;
  FILE* pf = std::fopen(params, "rb");
  if (!pf || std::fread(&mp, sizeof mp, 1, pf) != 1) {
    std::fprintf(stderr, "%s: cannot read the parameters (a %s run's?)\n", params, sizeof(S) == 4 ? "fp32" : "fp64");
    return 1;
  }
  std::fclose(pf);
  FILE* f = std::fopen(inputs, "rb");
  if (!f) {
    std::fprintf(stderr, "%s: cannot open\n", inputs);
    return 1;
  }
  FILE* o = out ? std::fopen(out, "wb") : nullptr;
  constexpr int kCap = 40;  // a cost of 40+ counts as 40 in the quantiles
  std::map<int, double> hist;
  double W = 0, sum = 0, sum_recorded = 0, w_fl = 0, w_br = 0, ev_fl = 0, ev_br = 0;
  long n = 0, unconverged = 0, largest = 0;
  Record<S> r;
  while (read(f, r)) {
    FrictionalState<S> st;
    Mat3<S> deps;
    for (int i = 0; i < 9; ++i) st.sigma(i / 3, i % 3) = r.v[i], deps(i / 3, i % 3) = r.v[9 + i];
    st.eps_pd = r.v[18];
    st.e = r.v[19];
    const UpdateInfo inf = frictional_return_map<LodeShape::SmoothMohrCoulomb>(mp, st, deps);
    const double w = r.weight;
    ++n;
    W += w;
    sum += w * inf.substeps;
    sum_recorded += w * r.evaluations;
    hist[inf.substeps < kCap ? inf.substeps : kCap] += w;
    if (inf.substeps > largest) largest = inf.substeps;
    if (inf.flags & info::kBracketedReturn) w_br += w, ev_br += w * inf.substeps;
    else if (inf.flags & info::kFlooredReturn) w_fl += w, ev_fl += w * inf.substeps;
    if (inf.flags & info::kReturnUnconverged) ++unconverged;
    if (o) {
      const double s[4] = {double(mean_pressure(st.sigma)), double(deviatoric_q(st.sigma)), double(st.eps_pd), w};
      std::fwrite(s, sizeof s, 1, o);
    }
  }
  std::fclose(f);
  if (o) std::fclose(o);
  if (n == 0) {
    std::fprintf(stderr, "%s: no records\n", inputs);
    return 1;
  }
  std::vector<double> cdf(kCap + 1, 0.0);
  for (const auto& [k, v] : hist) cdf[k] += v / W;
  for (int k = 1; k <= kCap; ++k) cdf[k] += cdf[k - 1];
  double largest_of_32 = 0;  // E[max of 32 draws] = sum over k >= 1 of P(max >= k)
  for (int k = 1; k <= kCap; ++k) largest_of_32 += 1 - std::pow(cdf[k - 1], 32);
  auto quantile = [&](double q) {
    int k = 0;
    while (k < kCap && cdf[k] < q) ++k;
    return k;
  };
  std::printf("%ld records (weight %.0f): evaluations per return mean %.3f (as recorded %.3f), largest %ld; "
              "unconverged %ld\n",
              n, W, sum / W, sum_recorded / W, largest, unconverged);
  std::printf("floored (and not bracketed) %.3f %% at %.2f; bracketed %.3f %% at %.2f\n", 100 * w_fl / W,
              w_fl > 0 ? ev_fl / w_fl : 0.0, 100 * w_br / W, w_br > 0 ? ev_br / w_br : 0.0);
  std::printf("expected largest of 32: %.2f; quantiles 50 / 90 / 99 / 99.9 %%: %d / %d / %d / %d (%d+ counts as %d)\n",
              largest_of_32, quantile(0.5), quantile(0.9), quantile(0.99), quantile(0.999), kCap, kCap);
  return 0;
}

// Stress differences of two replays relative to |p| + q (+ p_floor below).
int compare(const char* a, const char* b) {
  FILE* fa = std::fopen(a, "rb");
  FILE* fb = std::fopen(b, "rb");
  if (!fa || !fb) {
    std::fprintf(stderr, "cannot open %s or %s\n", a, b);
    return 1;
  }
  double x[4], y[4], worst[3] = {0, 0, 0}, worst_abs_below = 0;
  long n = 0;
  const double bands[3] = {10, 100, 1000};
  while (std::fread(x, sizeof x, 1, fa) == 1 && std::fread(y, sizeof y, 1, fb) == 1) {
    ++n;
    const double mag = std::fabs(x[0]) + std::fabs(x[1]);
    const double d = std::fabs(x[0] - y[0]) + std::fabs(x[1] - y[1]);
    for (int i = 0; i < 3; ++i)
      if (mag > bands[i] && d / mag > worst[i]) worst[i] = d / mag;
    if (mag <= bands[0] && d > worst_abs_below) worst_abs_below = d;
  }
  std::printf("%ld returns: largest relative difference of |p| + |q| above 10 / 100 / 1000 Pa: %.3g / %.3g / %.3g; "
              "below 10 Pa largest difference %.3g Pa\n",
              n, worst[0], worst[1], worst[2], worst_abs_below);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 4 && std::strcmp(argv[1], "--compare") == 0) return compare(argv[2], argv[3]);
  if (argc < 4) {
    std::fprintf(stderr, "usage: %s INPUTS PARAMS float|double [STRESSES_OUT] | --compare A B\n", argv[0]);
    return 2;
  }
  const char* out = argc > 4 ? argv[4] : nullptr;
  return argv[3][0] == 'd' ? replay<double>(argv[1], argv[2], out) : replay<float>(argv[1], argv[2], out);
}
