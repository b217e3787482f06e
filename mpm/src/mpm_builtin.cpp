// granflow-mpm: the paper's scenes built in code, for machines without the TOML/CLI
// dependencies (the GPU machine has only Eigen and CUDA). Same outputs as `granflow mpm`.
//
//   granflow-mpm column|flume [--h H] [--dt DT] [--time T] [--adaptive CFL] [--model pt|frictional]
//                [--shape linear|quadratic] [--backend cpu|cuda] [--out DIR]
//                [--transfer flip|tpic] [--flip F | --pic-speed U] [--stop-after T] [--span N] [--bench N [--warmup M] [--loop span|step] [--split N]]
//                [CUDA options: --graphs on|off --graph-steps N --sort N --p2g atomic|warp|tile
//                 --g2p-block N --g2p-regcap on|off --g2p-split auto|on|off] [--precision fp64|mixed|fp32]
// Defaults of the paper's scenes: Taylor PIC with quadratic B-splines (FLIP with linear hats),
// the PIC part as a rate (--pic-speed 1 m/s, Scene::pic_speed). --transfer flip|tpic picks the
// transfer, --flip F a fixed FLIP fraction per step instead of the rate (the scheme before:
// --transfer flip --flip 0.99).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/memory.hpp>

using namespace granflow::mpm;

namespace {

int usage() {
  std::fprintf(stderr,
               "usage: granflow-mpm column|flume [--h H] [--dt DT] [--time T] [--adaptive CFL] [--model pt|frictional]\n"
               "       [--shape linear|quadratic] [--backend cpu|cuda] [--out DIR] [--stop-after T]\n"
               "       [--transfer flip|tpic] [--flip F | --pic-speed U] [--span N] [--bench N [--warmup M] [--loop span|step] [--split N]]\n"
               "       CUDA: [--graphs on|off] [--graph-steps N] [--sort N] [--p2g atomic|warp|tile]\n"
               "             [--g2p-block N] [--g2p-regcap on|off] [--g2p-split auto|on|off]\n"
               "       [--precision fp64|mixed|fp32] (default fp64; docs/mpm.md)\n"
               "defaults: quadratic B-spline, Taylor PIC (FLIP with --shape linear), pic-speed 1 m/s; column h 0.001 dt 1e-5 time 1.0; flume h 0.005 dt 1e-6 time 3.0;\n"
               "--span: most steps without a host round-trip (1: one per step; default 10000);\n"
               "CUDA defaults: graphs on, graph-steps 32, sort 32, p2g warp, g2p-block 128, g2p-regcap off, g2p-split auto\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage();
  const std::string which = argv[1];
  if (which != "column" && which != "flume") return usage();
  const bool column = which == "column";
  double h = column ? 0.001 : 0.005, dt = column ? 1e-5 : 1e-6, time = column ? 1.0 : 3.0, stop = -1;
  ModelKind model = ModelKind::PhaseTransition;
  ShapeKind shape = ShapeKind::QuadraticBSpline;  // linear is unstable at 2.5 and 1 mm (docs/mpm.md)
  std::string backend = "cpu", out, transfer;
  double flip = -1, pic_speed = -1, cfl = -1;
  long bench = 0, span = 10000;
  BenchOptions bo;
  bo.warmup = 10;
  CudaOptions copt;
  Precision precision = Precision::FP64;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return usage();
    const char* v = argv[++i];
    if (a == "--h") h = std::atof(v);
    else if (a == "--dt") dt = std::atof(v);
    else if (a == "--time") time = std::atof(v);
    else if (a == "--adaptive") cfl = std::atof(v);
    else if (a == "--stop-after") stop = std::atof(v);
    else if (a == "--model") model = std::strcmp(v, "frictional") == 0 ? ModelKind::Frictional : ModelKind::PhaseTransition;
    else if (a == "--shape") shape = std::strcmp(v, "quadratic") == 0 ? ShapeKind::QuadraticBSpline : ShapeKind::Linear;
    else if (a == "--backend") backend = v;
    else if (a == "--transfer") transfer = v;
    else if (a == "--flip") flip = std::atof(v);
    else if (a == "--pic-speed") pic_speed = std::atof(v);
    else if (a == "--out") out = v;
    else if (a == "--bench") bench = std::atol(v);
    else if (a == "--warmup") bo.warmup = std::atol(v);
    else if (a == "--split") bo.split_steps = std::atol(v);
    else if (a == "--span") span = std::atol(v);
    else if (a == "--precision") {
      if (!parse_precision(v, precision)) return usage();
    }
    else if (a == "--loop" && (std::strcmp(v, "span") == 0 || std::strcmp(v, "step") == 0)) bo.step_by_step = std::strcmp(v, "step") == 0;
    else if (a.rfind("--", 0) == 0 && set_cuda_option(copt, a.substr(2), v)) continue;
    else return usage();
  }
  try {
    if (!transfer.empty() && transfer != "flip" && transfer != "tpic") return usage();
    Scene sc = column ? column_scene(h, dt, model, shape, time) : flume_scene(h, dt, model, shape, time);
    sc.precision = precision;
    if (cfl > 0) {  // CFL step; --dt is then the largest step
      sc.adaptive = true;
      sc.cfl = cfl;
    }
    if (transfer == "tpic") {
      sc.transfer = Scene::Transfer::TaylorPic;
      sc.flip = 0.0;
    } else if (transfer == "flip") {
      sc.transfer = Scene::Transfer::FlipPic;
      sc.flip = 0.99;
    }
    if (flip >= 0) {
      sc.flip = flip;
      sc.pic_speed = 0.0;
    }
    if (pic_speed >= 0) sc.pic_speed = pic_speed;
    const SceneSetup su = make_setup(sc);
    auto r = backend == "cuda" ? make_cuda_runner(su, copt) : make_cpu_runner(su);
    std::fprintf(stderr, "%s: %ld particles, %ld nodes, %s, precision %s\n  %s\n", sc.name.c_str(), r->particles(),
                 r->nodes(), r->device().c_str(), precision_name(precision), memory_line(su).c_str());
    if (bench > 0) {
      bo.steps = bench;
      const BenchResult b = granflow::mpm::bench(su, *r, bo);
      std::fputs(bench_report(su, *r, bo, b).c_str(), stdout);
      std::printf("precision: %s\n", precision_name(precision));
      return 0;
    }
    RunOptions opt;
    opt.out_dir = out;
    opt.stop_after = stop;
    opt.max_span = span;
    const RunSummary s = run(su, *r, opt);
    std::printf("scene: %s\ndevice: %s\nparticles: %ld\nsteps: %ld\nsimulated: %.6g s\nwall: %.3f s\n"
                "particle-updates/s: %.4g\nfinal run-out: %.4f m\nfinal height: %.4f m\n",
                sc.name.c_str(), s.device.c_str(), r->particles(), s.steps, s.t_end, s.wall_s,
                r->particles() * double(s.steps) / s.wall_s, s.final.runout, s.final.height);
    std::printf("precision: %s\n", precision_name(precision));
    if (s.steps > 0 && s.times.steps > 0)
      std::printf("kernel time per step: P2G %.2f us, grid %.2f us, G2P + constitutive %.2f us; wall per step %.2f us\n",
                  1e6 * s.times.p2g / s.times.steps, 1e6 * s.times.grid / s.times.steps,
                  1e6 * s.times.g2p / s.times.steps, 1e6 * s.wall_s / s.steps);
    if (s.steps > 0 && s.times.span_steps > 0)
      std::printf("device time per step (spans): %.2f us; wall per step %.2f us; %s\n",
                  1e6 * s.times.device / s.times.span_steps, 1e6 * s.wall_s / s.steps,
                  backend == "cuda" ? describe(copt).c_str() : "CPU twin");
    if (s.times.deferred > 0)
      std::printf("plastic returns (second G2P pass): %.1f %% of the updates\n",
                  100.0 * s.times.deferred_share(r->particles()));
    if (s.stats.updates > 0 && s.stats.warps > 0)
      std::printf("constitutive updates: %.3g, mean substeps %.2f, largest %ld; mean over 32-point groups of their "
                  "largest %.2f; mean over steps of the step's largest %.2f\n",
                  double(s.stats.updates), double(s.stats.substeps) / double(s.stats.updates), s.stats.max_substeps,
                  s.stats.mean_warp_max(), s.stats.mean_step_max());
    if (s.consolidation.done)
      std::printf("after stage 1: base sigma_v %.1f Pa vs rho g h %.1f Pa, max rel. error %.3f\n",
                  s.consolidation.base_sigma_v, s.consolidation.base_rho_g_h, s.consolidation.max_rel_error);
    for (const auto& row : s.series)
      if (row.t_flow > -1e-12 && std::fmod(row.t_flow + 1e-9, 0.1) < 2e-9 + 1e-12)
        std::printf("  t_flow %.2f s: run-out %.4f m, height %.4f m, max speed %.3f m/s, mean T %.3g\n", row.t_flow,
                    row.m.runout, row.m.height, row.m.max_speed, row.m.mean_T);
    if (!s.ok) {
      std::fprintf(stderr, "run stopped: %s\n", s.message.c_str());
      return 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "granflow-mpm: %s\n", e.what());
    return 1;
  }
  return 0;
}
