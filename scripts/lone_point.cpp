// One lone point on a no-slip level ground, CPU twin (issue 53: the fringe points that keep
// sliding; docs/mpm_results.md, "Lone points of the fringe"). Loads SCENE (a 3D scene with
// [terrain] on a node row, e.g. one of scripts/make_cylinder_collapse.py), keeps only its lowest
// point, moves it to (X, Y_H h, 0.05) with velocity (V, 0, 0), sets its stress to -P I with
// sigma_xy = TXY (P < 0: keeps its seeded stress), and prints its velocity and stress over STEPS.
// Parameter sets by name need GRANFLOW_DATA_DIR (the checkout's data/) outside the checkout.
//   ./lone_point SCENE Y_H V P TXY STEPS X
// Built against a build tree's libraries (here build-gpu/ of scripts/gpu.sh; -lassimp where the
// build reads meshes):
//   g++ -O2 -std=c++20 -fopenmp -I mpm/include -I io/include -I constitutive/include \
//       -I .deps/include scripts/lone_point.cpp build-gpu/mpm/libgranflow_mpm.a \
//       build-gpu/io/libgranflow_io.a -lassimp -o /tmp/lone_point
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <vector>

#include <granflow/mpm/runner.hpp>
#include <granflow/mpm/scene_file.hpp>

using namespace granflow::mpm;

// The component-major array a of n points reduced to point i0's components.
template <class T>
static void keep_one(std::vector<T>& a, long n, long i0) {
  if (a.empty()) return;
  const long k = static_cast<long>(a.size()) / n;
  std::vector<T> b(k);
  for (long c = 0; c < k; ++c) b[c] = a[c * n + i0];
  a = b;
}

static int run(int argc, char** argv) {
  if (argc != 8) {
    std::fprintf(stderr, "usage: %s SCENE Y_H V P TXY STEPS X\n", argv[0]);
    return 2;
  }
  const double y_h = std::atof(argv[2]), v0 = std::atof(argv[3]), p0 = std::atof(argv[4]);
  const double txy = std::atof(argv[5]), x0 = std::atof(argv[7]);
  const int steps = std::atoi(argv[6]);
  const Scene sc = load_scene(argv[1]);
  SceneSetup su = make_setup(sc);
  HostParticles& hp = su.particles;
  const long n = hp.n;
  if (hp.dim != 3 || n < 1 || steps < 1) {
    std::fprintf(stderr, "%s: needs a 3D scene with points and STEPS >= 1\n", argv[1]);
    return 2;
  }
  long i0 = 0;
  for (long i = 1; i < n; ++i)
    if (hp.x[n + i] < hp.x[n + i0]) i0 = i;
  for (auto* a : {&hp.x, &hp.v, &hp.m, &hp.sig, &hp.sigf, &hp.L, &hp.eps, &hp.e, &hp.s}) keep_one(*a, n, i0);
  if (!su.point_body.empty()) su.point_body = {su.point_body[i0]};
  if (!su.point_material.empty()) su.point_material = {su.point_material[i0]};
  su.tracked.clear();
  hp.n = 1;
  const double h = sc.h;
  hp.x[0] = x0, hp.x[1] = y_h * h, hp.x[2] = 0.05;
  hp.v[0] = v0, hp.v[1] = hp.v[2] = 0;
  if (p0 >= 0) {
    for (int c = 0; c < 6; ++c) hp.sig[c] = hp.sigf[c] = c < 3 ? -p0 : 0.0;
    hp.sig[5] = hp.sigf[5] = txy;
  }
  auto r = make_cpu_runner(su);
  r->set_stage(0, 0.0, sc.flip);
  std::printf("step t[s] y/h vx vy p sigma_xy T\n");
  for (int k = 1; k <= steps; ++k) {
    const StepResult res = r->step(sc.dt, false);
    if (!res.ok) {
      std::fprintf(stderr, "step %d failed (status %d)\n", k, static_cast<int>(res.status));
      return 1;
    }
    if (k <= 3 || k % std::max(1, steps / 20) == 0) {
      HostParticles o;
      r->download(o);
      std::printf("%d %.5f %.4f %+.5f %+.5f %.4g %+.4g %.3g\n", k, k * sc.dt, o.x[1] / h, o.v[0], o.v[1],
                  -(o.sig[0] + o.sig[1] + o.sig[2]) / 3, o.sig[5], o.s[0] * o.s[0]);
    }
  }
  return 0;
}

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {  // a scene's error names its file, line and key
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
}
