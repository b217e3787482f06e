// granflow.mpm: an MPM scene run as `granflow mpm SCENE` runs it (load_scene with the
// overrides, make_setup_for_file, the CPU twin or CUDA runner, mpm::run), with the series,
// the tracked points, the final particles and the free surface returned as arrays instead of files.
#include <signal.h>

#include <cmath>
#include <csignal>

#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/scene_file.hpp>

#include "common.hpp"
#include <granflow/io/input_error.hpp>

namespace granflow::python {

namespace {

// Ctrl-C during a run: the time loop polls this after every step and stops (as the CLI's
// SignalGuard); Python's handler is put back afterwards and KeyboardInterrupt raised.
volatile std::sig_atomic_t g_interrupt = 0;
void on_sigint(int sig) { g_interrupt = sig; }

class SigintGuard {
 public:
  SigintGuard() {
    g_interrupt = 0;
    struct sigaction sa {};
    sa.sa_handler = on_sigint;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    sigaction(SIGINT, &sa, &old_);
  }
  ~SigintGuard() { sigaction(SIGINT, &old_, nullptr); }

 private:
  struct sigaction old_ {};
};

// Component-major (x[d * n + i]) -> (n, dim).
py::array_t<double> points(const std::vector<double>& v, long n, int dim) {
  py::array_t<double> a({static_cast<py::ssize_t>(n), static_cast<py::ssize_t>(dim)});
  for (long i = 0; i < n; ++i)
    for (int d = 0; d < dim; ++d) a.mutable_at(i, d) = v[static_cast<std::size_t>(d) * n + i];
  return a;
}

py::dict mpm_run(py::handle scene, py::handle params, py::handle overrides, const std::string& backend,
                 py::handle precision, double stop_after, bool progress) {
  if (!std::isfinite(stop_after))
    throw io::InputError("mpm: stop_after = " + std::to_string(stop_after) +
                         ": must be a finite time [s] (> 0 stops there, <= 0 runs the whole scene)");
  mpm::SceneOverrides ov;
  // one set (name or path) or NAME=SET strings for a scene's [[material]] tables, as --params
  if (!params.is_none()) {
    if (py::isinstance<py::str>(params) || py::hasattr(params, "__fspath__"))
      mpm::add_params(ov, path_arg(params, "params"));
    else
      for (const std::string& p : strings_arg(params, "params")) mpm::add_params(ov, p);
  }
  ov.sets = strings_arg(overrides, "overrides");
  if (backend != "cpu" && backend != "cuda")
    throw io::InputError("mpm: backend '" + backend + "': expected cpu or cuda");
  mpm::Scene sc = mpm::load_scene(path_arg(scene, "scene"), ov);
  if (!precision.is_none()) {
    const std::string p = precision.cast<std::string>();
    if (!mpm::parse_precision(p, sc.precision)) throw io::InputError("mpm: precision '" + p + "': expected fp64, mixed or fp32");
  }
  const mpm::SceneSetup su = mpm::make_setup_for_file(sc);
  mpm::RunSummary s;
  mpm::Frame fr;
  std::vector<std::pair<double, double>> surface;
  std::string device;
  {
    py::gil_scoped_release nogil;
    auto runner = backend == "cuda" ? mpm::make_cuda_runner(su) : mpm::make_cpu_runner(su);
    mpm::RunOptions ro;  // no out_dir: nothing is written
    ro.progress = progress;
    ro.stop_after = stop_after;
    ro.interrupt = &g_interrupt;
    SigintGuard guard;
    s = mpm::run(su, *runner, ro);
    runner->frame(fr, true);
    surface = mpm::free_surface(fr, su);
    device = runner->device();
  }
  if (s.interrupted) {
    PyErr_SetNone(PyExc_KeyboardInterrupt);
    throw py::error_already_set();
  }
  if (!s.ok) throw std::runtime_error("run stopped: " + s.message);

  const mpm::Scene& scn = su.scene;
  // runout.csv and tracked.csv, column by column (driver.cpp, write_series_csv)
  std::vector<std::vector<double>> a(9);
  for (const auto& r : s.series) {
    const double row[] = {r.t, r.t_flow, double(r.stage), r.m.runout, r.m.height, r.m.max_speed,
                          r.m.kinetic_energy, r.m.mean_T, r.m.max_T};
    for (int i = 0; i < 9; ++i) a[i].push_back(row[i]);
  }
  py::dict series = columns_dict({"t", "t_flow", "stage", "runout", "height", "max_speed", "kinetic_energy", "mean_T", "max_T"}, a);
  std::vector<std::vector<double>> b(12);
  py::list names;
  for (const auto& r : s.tracks) {
    const double row[] = {r.t, r.t_flow, r.x, r.y, r.vx, r.vy, r.p, r.q, r.eps_pd, r.T, r.eta_c, r.K_col};
    for (int i = 0; i < 12; ++i) b[i].push_back(row[i]);
    names.append(scn.tracks[r.track].name);
  }
  py::dict tracked;
  const char* tcols[] = {"t", "t_flow", "x", "y", "vx", "vy", "p", "q", "eps_pd", "T", "eta_c", "K_col"};
  for (int i = 0; i < 12; ++i) {
    tracked[py::str(tcols[i])] = to_array(b[i]);
    if (i == 1) tracked["name"] = py::module_::import("numpy").attr("array")(names, py::arg("dtype") = "U");
  }

  // gauges.csv (scenes with [[gauge]]) and materials.csv (several materials), column by column
  py::dict gauges;
  if (!scn.gauges.empty()) {
    std::vector<std::vector<double>> g(8);
    py::list gnames;
    for (const auto& r : s.gauges) {
      const double row[] = {r.t, r.t_flow, r.depth, r.u, r.u_along, r.density, r.mass_flux, double(r.points)};
      for (int i = 0; i < 8; ++i) g[i].push_back(row[i]);
      gnames.append(scn.gauges[r.gauge].name);
    }
    const char* gcols[] = {"t [s]", "t_flow [s]", "depth [m]", "u [m/s]", "u_along [m/s]", "density [kg/m^3]",
                           "mass_flux [kg/(m s)]", "points"};
    for (int i = 0; i < 8; ++i) {
      gauges[py::str(gcols[i])] = to_array(g[i]);
      if (i == 1) gauges["gauge"] = py::module_::import("numpy").attr("array")(gnames, py::arg("dtype") = "U");
    }
  }
  py::dict materials;
  const int nmat = scn.material_count();
  if (nmat > 1 && s.material_series.size() == static_cast<size_t>(nmat) * s.series.size()) {
    std::vector<std::vector<double>> c(9);
    py::list mnames;
    for (size_t i = 0; i < s.series.size(); ++i)
      for (int k = 0; k < nmat; ++k) {
        const auto& r = s.series[i];
        const mpm::Measures& m = s.material_series[i * nmat + k];
        const double row[] = {r.t, r.t_flow, double(r.stage), m.runout, m.height, m.max_speed, m.kinetic_energy,
                              m.mean_T, m.max_T};
        for (int j = 0; j < 9; ++j) c[j].push_back(row[j]);
        mnames.append(scn.material_at(k).label);
      }
    const char* mcols[] = {"t", "t_flow", "stage", "runout", "height", "max_speed", "kinetic_energy", "mean_T", "max_T"};
    for (int j = 0; j < 9; ++j) {
      materials[py::str(mcols[j])] = to_array(c[j]);
      if (j == 2) materials["material"] = py::module_::import("numpy").attr("array")(mnames, py::arg("dtype") = "U");
    }
  }
  py::dict forces;  // per boundary with force probes: what granflow mpm prints
  for (const mpm::ForcePeak& f : s.forces)
    forces[py::str(f.boundary)] = py::dict(py::arg("peak") = f.peak, py::arg("t_peak") = f.t_peak,
                                           py::arg("impulse") = f.impulse, py::arg("step_peak") = f.step_peak);

  py::dict particles;
  particles["x"] = points(fr.x, fr.n, fr.dim);
  particles["v"] = points(fr.v, fr.n, fr.dim);
  const std::pair<const char*, const std::vector<double>*> fields[] = {
      {"p", &fr.p},     {"q", &fr.q},         {"eps_pd", &fr.eps_pd}, {"T", &fr.T},     {"eta_c", &fr.eta_c},
      {"K_col", &fr.K_col}, {"e", &fr.e},     {"sxx", &fr.sxx},       {"syy", &fr.syy}, {"sxy", &fr.sxy}};
  for (const auto& [name, v] : fields) particles[name] = to_array(*v);
  particles["m"] = to_array(su.particles.m);

  std::vector<std::vector<double>> prof(2);
  for (const auto& [x, y] : surface) {
    prof[0].push_back(x);
    prof[1].push_back(y);
  }
  py::dict out;
  out["scene"] = scn.name;
  out["device"] = device;
  out["particles_count"] = fr.n;
  out["steps"] = s.steps;
  out["t_end"] = s.t_end;
  out["wall_s"] = s.wall_s;
  out["final"] = py::dict(py::arg("runout") = s.final.runout, py::arg("height") = s.final.height,
                          py::arg("max_speed") = s.final.max_speed, py::arg("kinetic_energy") = s.final.kinetic_energy,
                          py::arg("mean_T") = s.final.mean_T, py::arg("max_T") = s.final.max_T);
  out["series"] = series;
  out["tracked"] = tracked;
  out["gauges"] = gauges;
  out["materials"] = materials;
  out["forces"] = forces;
  out["particles"] = particles;
  out["surface"] = columns_dict({"x", "surface_y"}, prof);
  return out;
}

}  // namespace

void register_mpm(py::module_& m) {
  m.def("mpm", &mpm_run, py::arg("scene"), py::arg("params") = py::none(), py::arg("overrides") = py::none(),
        py::arg("backend") = "cpu", py::arg("precision") = py::none(), py::arg("stop_after") = -1.0,
        py::arg("progress") = false,
        R"(Runs an MPM scene (mpm/scenes/*.toml) as `granflow mpm SCENE --no-png` does, writing no files.

params      parameter set instead of material.parameters (name or path, as --params), or
            "NAME=SET" strings (one or a list) for the scene's [[material]] tables
overrides   KEY=VALUE strings, scene or parameter-set keys (as --set), e.g. "grid.h=0.02"
backend     "cpu" (the OpenMP twin; OMP_NUM_THREADS threads) or "cuda"
precision   "fp64", "mixed" or "fp32" instead of solver.precision
stop_after  > 0: stop at this simulated time [s]; <= 0: the whole scene

Returns a dict: series (runout.csv's columns), tracked (tracked.csv's, name as strings),
gauges (gauges.csv's, gauge as strings; empty without [[gauge]]), materials (materials.csv's;
empty with one material), forces (per boundary measured: peak, t_peak, impulse, step_peak),
particles (final state: x and v (n, dim), p, q, eps_pd, T, eta_c, K_col, e, sxx, syy, sxy, m),
surface (profile_final.csv's x, surface_y), final (run-out, height, ...), steps, t_end,
wall_s, device. A failed run raises RuntimeError("run stopped: ...") as the CLI does; Ctrl-C
stops the run after the current step (KeyboardInterrupt).)");
  m.def("cuda_available", [] { return mpm::cuda_backend_available() && mpm::cuda_device_count() > 0; },
        "True where the CUDA backend is built and a device is visible");
}

}  // namespace granflow::python
