// GPU against CPU twin on the CI column collapse (built in code: no TOML reader on the GPU
// machine). Exits 77 ("no CUDA device") where there is no GPU, so ctest marks it skipped.
#include <cmath>
#include <cstdio>
#include <cstring>

#include <granflow/mpm/driver.hpp>

using namespace granflow::mpm;

int main(int argc, char** argv) {
  if (!cuda_backend_available()) {
    std::printf("no CUDA device\n");
    return 77;
  }
  const double tol = 0.005;
  int fails = 0;
  struct Case {
    ModelKind model;
    ShapeKind shape;
    bool vol_avg;
  };
  const Case cases[] = {{ModelKind::PhaseTransition, ShapeKind::Linear, false},
                        {ModelKind::PhaseTransition, ShapeKind::QuadraticBSpline, false},
                        {ModelKind::Frictional, ShapeKind::Linear, false},
                        {ModelKind::Frictional, ShapeKind::QuadraticBSpline, false},
                        {ModelKind::PhaseTransition, ShapeKind::Linear, true}};
  for (const Case& c : cases) {
    {
      const ModelKind model = c.model;
      const ShapeKind shape = c.shape;
      Scene sc = small_column_scene(model, shape);
      sc.volumetric_averaging = c.vol_avg;
      if (argc > 1 && std::strcmp(argv[1], "--short") == 0) sc.stages.back().duration = 0.1;
      const SceneSetup su = make_setup(sc);
      RunOptions opt;
      opt.progress = false;
      auto cpu = make_cpu_runner(su);
      auto gpu = make_cuda_runner(su);
      const RunSummary a = run(su, *cpu, opt);
      const RunSummary b = run(su, *gpu, opt);
      const double rel = std::fabs(b.final.runout - a.final.runout) / a.final.runout;
      const double relh = std::fabs(b.final.height - a.final.height) / a.final.height;
      const bool ok = a.ok && b.ok && rel <= tol && relh <= tol;
      std::printf("%-55s %-9s %s cpu run-out %.5f m height %.5f m (%.2f s) | gpu run-out %.5f m height %.5f m "
                  "(%.2f s, %s) | rel. diff %.2e / %.2e %s\n",
                  sc.name.c_str(), shape == ShapeKind::Linear ? "linear" : "quadratic", c.vol_avg ? "vol-avg" : "",
                  a.final.runout,
                  a.final.height, a.wall_s, b.final.runout, b.final.height, b.wall_s, b.device.c_str(), rel, relh,
                  ok ? "OK" : "FAIL");
      if (!a.ok) std::printf("  cpu: %s\n", a.message.c_str());
      if (!b.ok) std::printf("  gpu: %s\n", b.message.c_str());
      fails += ok ? 0 : 1;
    }
  }
  return fails == 0 ? 0 : 1;
}
