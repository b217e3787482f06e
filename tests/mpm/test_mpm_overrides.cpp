// --set and --params over scene files (load_scene with SceneOverrides): an override gives what
// editing the file gives, bad ones are refused naming the --set, keys are routed to the
// parameter set or the scene, and the scene files with the mesh-series overrides of
// scripts/gpu.sh are the scenes the tests and mpm_cuda_check build in code.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <granflow/io/input_error.hpp>
#include <granflow/io/parameter_set.hpp>
#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/scene_file.hpp>

#include "one_thread.hpp"
#include "test_constants.hpp"

using namespace granflow;
using namespace granflow::mpm;
namespace fs = std::filesystem;

namespace {

// Line numbers in the messages below refer to this text.
const std::string kTiny =
    "name = \"tiny\"\n"                      // 1
    "[grid]\n"                               // 2
    "origin = [0.0, 0.0]\n"                  // 3
    "size = [0.4, 0.2]\n"                    // 4
    "h = 0.02\n"                             // 5
    "[particles]\n"                          // 6
    "per_cell = 4\n"                         // 7
    "[time]\n"                               // 8
    "dt = 1e-4\n"                            // 9
    "[material]\n"                           // 10
    "parameters = \"column_collapse\"\n"     // 11
    "model = \"frictional\"\n"               // 12
    "[[body]]\n"                             // 13
    "min = [0.0, 0.0]\n"                     // 14
    "max = [0.1, 0.1]\n"                     // 15
    "[[wall]]\n"                             // 16
    "side = \"x-\"\n"                        // 17
    "type = \"free_slip\"\n"                 // 18
    "[[wall]]\n"                             // 19
    "side = \"y-\"\n"                        // 20
    "[[stage]]\n"                            // 21
    "duration = 0.002\n"                     // 22
    "[[stage]]\n"                            // 23
    "duration = 0.01\n"                      // 24
    "[output]\n"                             // 25
    "times = [0.005]\n";                     // 26

fs::path scratch() {
  const fs::path d = fs::temp_directory_path() / ("granflow_overrides_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

std::string write(const std::string& name, const std::string& text) {
  const fs::path p = scratch() / name;
  std::ofstream(p, std::ios::binary) << text;
  return p.string();
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string edit(std::string s, const std::string& from, const std::string& to) {
  const auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? s : s.replace(at, from.size(), to);
}

Scene load(const std::string& path, std::vector<std::string> sets, const std::string& params = "") {
  SceneOverrides o;
  o.sets = std::move(sets);
  o.params = params;
  return load_scene(path, o);
}

// The message of the input error that loading and setting up gives ("" when none).
std::string error_of(const std::string& path, std::vector<std::string> sets, const std::string& params = "") {
  try {
    make_setup_for_file(load(path, std::move(sets), params));
  } catch (const io::InputError& e) {
    return e.what();
  }
  return "";
}

// Runs a scene on the CPU twin into `out`; the files written, name -> bytes.
std::map<std::string, std::string> run_files(const Scene& sc, const std::string& out) {
  const SceneSetup su = make_setup_for_file(sc);
  auto r = make_cpu_runner(su);
  fs::remove_all(out);
  RunOptions opt;
  opt.out_dir = out;
  opt.progress = false;
  const RunSummary s = run(su, *r, opt);
  EXPECT_TRUE(s.ok) << s.message;
  std::map<std::string, std::string> files;
  for (const auto& e : fs::directory_iterator(out)) files[e.path().filename().string()] = slurp(e.path());
  return files;
}

void expect_same_scene(const Scene& a, const Scene& b) {
  const double tol = 2e-5;  // the TOML files print the flume geometry with 5 decimals
  EXPECT_EQ(a.dim, b.dim);
  for (int d = 0; d < a.dim; ++d) {
    EXPECT_NEAR(a.origin[d], b.origin[d], tol);
    EXPECT_NEAR(a.size[d], b.size[d], tol);
  }
  EXPECT_DOUBLE_EQ(a.h, b.h);
  EXPECT_EQ(a.ppc_axis, b.ppc_axis);
  EXPECT_EQ(a.shape, b.shape);
  EXPECT_EQ(a.modified_boundary_splines, b.modified_boundary_splines);
  EXPECT_DOUBLE_EQ(a.dt, b.dt);
  EXPECT_EQ(a.adaptive, b.adaptive);
  EXPECT_DOUBLE_EQ(a.cfl, b.cfl);
  EXPECT_DOUBLE_EQ(a.flip, b.flip);
  EXPECT_DOUBLE_EQ(a.pic_speed, b.pic_speed);
  EXPECT_EQ(a.transfer, b.transfer);
  EXPECT_EQ(a.precision, b.precision);
  EXPECT_EQ(a.material.model, b.material.model);
  EXPECT_DOUBLE_EQ(a.material.e0, b.material.e0);
  EXPECT_DOUBLE_EQ(a.material.T0, b.material.T0);
  const auto& fa = a.material.params.f;
  const auto& fb = b.material.params.f;
  for (auto m : {&FrictionalParams<double>::K0, &FrictionalParams<double>::nu, &FrictionalParams<double>::n,
                 &FrictionalParams<double>::phi_c, &FrictionalParams<double>::e_ref, &FrictionalParams<double>::lambda_c,
                 &FrictionalParams<double>::xi, &FrictionalParams<double>::A_d, &FrictionalParams<double>::k_p,
                 &FrictionalParams<double>::n_p, &FrictionalParams<double>::n_d, &FrictionalParams<double>::p_at})
    EXPECT_NEAR(fa.*m, fb.*m, 1e-12 * std::fabs(fa.*m));
  const auto& ca = a.material.params.c;
  const auto& cb = b.material.params.c;
  for (auto m : {&CollisionalParams<double>::rho_p, &CollisionalParams<double>::d, &CollisionalParams<double>::V_sd,
                 &CollisionalParams<double>::V_m, &CollisionalParams<double>::eps_n, &CollisionalParams<double>::mu_p})
    EXPECT_NEAR(ca.*m, cb.*m, 1e-12 * std::fabs(ca.*m));
  ASSERT_EQ(a.bodies.size(), b.bodies.size());
  for (size_t i = 0; i < a.bodies.size(); ++i) {
    ASSERT_EQ(a.bodies[i].poly_x.size(), b.bodies[i].poly_x.size());
    for (size_t k = 0; k < a.bodies[i].poly_x.size(); ++k) {
      EXPECT_NEAR(a.bodies[i].poly_x[k], b.bodies[i].poly_x[k], tol);
      EXPECT_NEAR(a.bodies[i].poly_y[k], b.bodies[i].poly_y[k], tol);
    }
    EXPECT_EQ(a.bodies[i].box_min, b.bodies[i].box_min);
    EXPECT_EQ(a.bodies[i].box_max, b.bodies[i].box_max);
  }
  ASSERT_EQ(a.walls.size(), b.walls.size());
  for (size_t i = 0; i < a.walls.size(); ++i) {
    EXPECT_EQ(a.walls[i].axis, b.walls[i].axis);
    EXPECT_EQ(a.walls[i].at_max, b.walls[i].at_max);
    EXPECT_NEAR(a.walls[i].position, b.walls[i].position, tol);
    EXPECT_EQ(a.walls[i].no_slip, b.walls[i].no_slip);
    EXPECT_EQ(a.walls[i].mu, b.walls[i].mu);
  }
  ASSERT_EQ(a.base.has_value(), b.base.has_value());
  if (a.base) EXPECT_EQ(a.base->mu, b.base->mu);
  if (a.base)
    for (size_t k = 0; k < a.base->x.size(); ++k) {
      EXPECT_NEAR(a.base->x[k], b.base->x[k], tol);
      EXPECT_NEAR(a.base->y[k], b.base->y[k], tol);
    }
  ASSERT_EQ(a.stages.size(), b.stages.size());
  for (size_t i = 0; i < a.stages.size(); ++i) {
    EXPECT_DOUBLE_EQ(a.stages[i].duration, b.stages[i].duration);
    EXPECT_DOUBLE_EQ(a.stages[i].damping, b.stages[i].damping);
    ASSERT_EQ(a.stages[i].gate.has_value(), b.stages[i].gate.has_value());
    if (a.stages[i].gate) {
      EXPECT_NEAR(a.stages[i].gate->point[0], b.stages[i].gate->point[0], tol);
      EXPECT_EQ(a.stages[i].gate->normal, b.stages[i].gate->normal);
      EXPECT_EQ(a.stages[i].gate->normal_only, b.stages[i].gate->normal_only);
      EXPECT_EQ(a.stages[i].gate->lift_speed, b.stages[i].gate->lift_speed);
    }
  }
  ASSERT_EQ(a.runout_x.size(), b.runout_x.size());
  for (size_t k = 0; k < a.runout_x.size(); ++k) {
    EXPECT_NEAR(a.runout_x[k], b.runout_x[k], tol);
    EXPECT_NEAR(a.runout_y[k], b.runout_y[k], tol);
  }
  ASSERT_EQ(a.tracks.size(), b.tracks.size());
  for (size_t k = 0; k < a.tracks.size(); ++k)
    for (int d = 0; d < a.dim; ++d) EXPECT_NEAR(a.tracks[k].x[d], b.tracks[k].x[d], tol);
  EXPECT_EQ(a.output.times, b.output.times);
  EXPECT_DOUBLE_EQ(a.output.series_dt, b.output.series_dt);
}

}  // namespace

// Every kind of key (number, boolean, bare word, array, an entry of an array of tables, a
// table the file lacks, a parameter of the set) overridden on the command line gives the run
// that the edited files give, file for file and byte for byte.
TEST(MpmOverrides, AnOverrideIsTheSameAsEditingTheFile) {
  const std::string scene = write("tiny.toml", kTiny);
  const std::vector<std::string> sets = {
      "grid.h=0.01",         "time.dt = 5e-5",           "time.adaptive=true", "material.model=phase_transition",
      "body[0].max=[0.12, 0.1]", "wall[0].type=no_slip", "stage[1].duration=0.006", "solver.pic_speed=1.0",
      "frictional.phi_c_deg=31", "collisional.mu_p=0.3"};
  const Scene overridden = load(scene, sets);
  EXPECT_EQ(overridden.overrides, sets);

  std::string params = slurp(io::data_directory() + "/params/column_collapse.toml");
  params = edit(params, "phi_c_deg = 19.8", "phi_c_deg = 31");
  params = edit(params, "mu_p = 0.2", "mu_p = 0.3");
  write("edited_params.toml", params);
  std::string text = kTiny;
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
           {"h = 0.02", "h = 0.01"},
           {"dt = 1e-4", "dt = 5e-5\nadaptive = true"},
           {"\"column_collapse\"", "\"./edited_params.toml\""},
           {"\"frictional\"", "\"phase_transition\""},
           {"max = [0.1, 0.1]", "max = [0.12, 0.1]"},
           {"type = \"free_slip\"", "type = \"no_slip\""},
           {"duration = 0.01", "duration = 0.006"},
           {"[material]", "[solver]\npic_speed = 1.0\n[material]"}})
    text = edit(text, from, to);
  const Scene edited = load(write("edited.toml", text), {});

  expect_same_scene(overridden, edited);
  const auto a = run_files(overridden, (scratch() / "overridden").string());
  const auto b = run_files(edited, (scratch() / "edited").string());
  ASSERT_EQ(a.size(), b.size());
  EXPECT_GE(a.size(), 6u);  // frames, PVD, three CSVs
  for (const auto& [name, bytes] : a) {
    ASSERT_TRUE(b.count(name)) << name;
    EXPECT_TRUE(bytes == b.at(name)) << name << " differs";
  }
}

// A later --set of the same key wins; the other overrides stay.
TEST(MpmOverrides, LaterOverridesWin) {
  const std::string scene = write("tiny.toml", kTiny);
  const Scene sc = load(scene, {"time.dt=5e-5", "grid.h=0.01", "time.dt=2e-5", "frictional.K0=100", "frictional.K0=90"});
  EXPECT_DOUBLE_EQ(sc.dt, 2e-5);
  EXPECT_DOUBLE_EQ(sc.h, 0.01);
  EXPECT_DOUBLE_EQ(sc.material.params.f.K0, 90);
}

// Keys of a parameter set's tables change the material's set; all others are scene keys.
TEST(MpmOverrides, ParameterSetKeysGoToTheSetAndOthersToTheScene) {
  const std::string scene = write("tiny.toml", kTiny);  // no material.e0: the set's initial.e0
  const Scene base = load(scene, {});
  EXPECT_DOUBLE_EQ(base.material.e0, io::load_parameter_set("column_collapse").e0.front());
  const Scene sc = load(scene, {"initial.e0=[0.9]", "initial_stress.kind=geostatic", "numerics.max_substeps=7"});
  EXPECT_DOUBLE_EQ(sc.material.e0, 0.9);
  EXPECT_TRUE(sc.initial.geostatic);
  EXPECT_EQ(sc.material.params.f.max_substeps, 7);

  // --params replaces material.parameters; --set then changes that set
  const io::ParameterSet flume = io::load_parameter_set("flume");
  const Scene other = load(scene, {"frictional.K0=77"}, "flume");
  EXPECT_EQ(other.material.name, flume.file);
  EXPECT_DOUBLE_EQ(other.material.params.f.phi_c, flume.frictional->phi_c);
  EXPECT_DOUBLE_EQ(other.material.params.f.K0, 77);
  EXPECT_DOUBLE_EQ(other.material.params.c.d, flume.collisional->d);
  // a scene without material.parameters runs with --params
  const std::string bare = write("bare.toml", edit(kTiny, "parameters = \"column_collapse\"\n", ""));
  EXPECT_NE(error_of(bare, {}).find("'material.parameters': required key is missing"), std::string::npos);
  EXPECT_EQ(error_of(bare, {}, "column_collapse"), "");
}

// [[material]] tables: NAME:KEY and --params NAME=SET change one material, others keep theirs.
TEST(MpmOverrides, NamedMaterialsTakeTheirOwnOverrides) {
  const std::string two = write("two.toml", edit(edit(kTiny,
      "[material]\nparameters = \"column_collapse\"\nmodel = \"frictional\"\n",
      "[[material]]\nname = \"strong\"\nparameters = \"column_collapse\"\nmodel = \"frictional\"\n"
      "[[material]]\nname = \"weak\"\nparameters = \"column_collapse\"\nmodel = \"frictional\"\ne0 = 0.9\n"),
      "max = [0.1, 0.1]\n", "max = [0.1, 0.04]\nmaterial = \"weak\"\n[[body]]\nmin = [0.0, 0.04]\nmax = [0.1, 0.1]\n"
      "material = \"strong\"\n"));
  SceneOverrides o;
  o.sets = {"weak:frictional.phi_c_deg=20", "weak:e0=0.92", "strong:frictional.K0=90"};
  o.material_params = {"strong=flume"};
  const Scene sc = load_scene(two, o);
  ASSERT_EQ(sc.material_count(), 2);
  const Material &strong = sc.material_at(0), &weak = sc.material_at(1);
  EXPECT_EQ(strong.label, "strong");
  EXPECT_EQ(weak.label, "weak");
  const io::ParameterSet flume = io::load_parameter_set("flume"), cc = io::load_parameter_set("column_collapse");
  EXPECT_EQ(strong.name, flume.file);
  EXPECT_DOUBLE_EQ(strong.params.f.phi_c, flume.frictional->phi_c);
  EXPECT_DOUBLE_EQ(strong.params.f.K0, 90);
  EXPECT_EQ(weak.name, cc.file);
  EXPECT_DOUBLE_EQ(weak.params.f.phi_c, 20 * M_PI / 180);
  EXPECT_DOUBLE_EQ(weak.params.f.K0, cc.frictional->K0);
  EXPECT_DOUBLE_EQ(weak.e0, 0.92);
  ASSERT_EQ(sc.bodies.size(), 2u);
  EXPECT_EQ(sc.bodies[0].material, 1);
  EXPECT_EQ(sc.bodies[1].material, 0);
  // the set-up gives each point its body's material, density and void ratio
  const SceneSetup su = make_setup_for_file(sc);
  ASSERT_EQ(su.point_material.size(), static_cast<size_t>(su.particles.n));
  for (long i = 0; i < su.particles.n; ++i) {
    const int m = su.point_material[i];
    EXPECT_EQ(m, sc.bodies[su.point_body[i]].material);
    EXPECT_DOUBLE_EQ(su.particles.e[i], sc.material_at(m).e0);
  }
  // one [[material]] table: unqualified keys and --params go to it
  const std::string one = write("one.toml", edit(kTiny, "[material]\n", "[[material]]\nname = \"sand\"\n"));
  const Scene sc1 = load(one, {"frictional.K0=91", "sand:e0=0.93"}, "flume");
  EXPECT_EQ(sc1.material_count(), 1);
  EXPECT_DOUBLE_EQ(sc1.material.params.f.K0, 91);
  EXPECT_DOUBLE_EQ(sc1.material.e0, 0.93);
  EXPECT_TRUE(make_setup_for_file(sc1).point_material.empty());  // one material: today's kernels
}

// Bad overrides: one message naming the --set (and the scene file where the key is a scene key)
// and saying what is allowed.
TEST(MpmOverrides, BadOverridesAreRefusedNamingTheSet) {
  const std::string scene = write("tiny.toml", kTiny);
  struct Bad {
    std::vector<std::string> sets;
    std::string params;
    std::vector<std::string> expect;
  };
  const std::string file = scene + ": ";
  const Bad cases[] = {
      {{"grid.hh=0.01"}, "", {file + "--set 'grid.hh=0.01': unknown key 'grid.hh'", "allowed here:", "h,"}},
      {{"gird.h=0.01"}, "", {file + "--set 'gird.h=0.01': unknown key 'gird'"}},
      {{"time.dt=fast"}, "", {file + "--set 'time.dt=fast': 'time.dt': expected a number, got a string"}},
      {{"time.adaptive=yes"}, "", {"--set 'time.adaptive=yes'", "expected true or false"}},
      {{"grid.h=-0.01"}, "", {file + "--set 'grid.h=-0.01': 'grid.h': must be > 0, got -0.01"}},
      {{"material.model=viscous"}, "", {"--set 'material.model=viscous'", "must be one of 'phase_transition', 'frictional'"}},
      {{"body[0].max=[0.1]"}, "", {"--set 'body[0].max=[0.1]'", "'body[0].max': needs 2 components"}},
      {{"grid.h"}, "", {file + "--set 'grid.h': expected KEY=VALUE"}},
      {{"=0.01"}, "", {"--set '=0.01': expected KEY=VALUE"}},
      {{"grid..h=1"}, "", {"expected KEY=VALUE"}},
      {{"grid.h="}, "", {"--set 'grid.h=': no value after '='"}},
      {{"name=my run"}, "", {"--set 'name=my run': not a TOML value", "need quotes"}},
      {{"name=a\x01" "b"}, "", {"not a TOML value"}},
      {{"stage[2].duration=1"}, "", {"--set 'stage[2].duration=1': the scene has 2 [[stage]] tables (stage[0] to stage[1])"}},
      {{"stage.duration=1"}, "", {"'stage' is an array of tables: give an index, e.g. stage[0].duration"}},
      {{"grid.h.x=1"}, "", {"'grid.h' is a value, not a table"}},
      {{"stage[0]=1"}, "", {"KEY must end in a key name"}},
      // the set's own checks, as for granflow element --set
      {{"frictional.phi_c_deg=95"}, "", {"--set 'frictional.phi_c_deg=95': 'frictional.phi_c_deg': must be in (0, 90), got 95"}},
      {{"frictional.phi=30"}, "", {"--set 'frictional.phi=30': unknown key 'frictional.phi'"}},
      {{"initial.e0=[5]"}, "", {"--set 'initial.e0=[5]'", "must be in (0, "}},
      {{}, "no_such_set", {"--params 'no_such_set': no_such_set: no such file, and no parameter set of that name"}},
      // make_setup's checks name the --set of the key ...
      {{"time.dt=0.01"}, "", {file + "--set 'time.dt=0.01': 'time.dt':", "above the stability limit"}},
      // ... or the line of a file key, with the overrides that may explain it
      {{"grid.h=0.03"}, "", {file.substr(0, file.size() - 2) + ":4:", "'grid.size': each extent must be a whole number of cells",
                             "(with --set 'grid.h=0.03')"}},
  };
  for (const Bad& b : cases) {
    const std::string err = error_of(scene, b.sets, b.params);
    for (const auto& e : b.expect)
      EXPECT_NE(err.find(e), std::string::npos) << "expected '" << e << "' in: " << err;
    EXPECT_EQ(err.find('\n'), std::string::npos) << err;
  }
}

// The paper's scene files, and with the overrides scripts/gpu.sh gives for its mesh series, CFL
// steps, linear shapes and shorter runs, are the scenes built in code (the fixtures of the tests
// and of mpm_cuda_check, and what granflow-mpm built for its options).
TEST(MpmOverrides, SceneFilesWithSeriesOverridesAreTheInCodeScenes) {
  using MK = ModelKind;
  using SK = ShapeKind;
  const std::string column = kScenes + "column_collapse.toml", flume = kScenes + "flume.toml";
  expect_same_scene(load(column, {}), column_scene(0.001, 1e-5, MK::PhaseTransition, SK::QuadraticBSpline, 1.0));
  expect_same_scene(load(kScenes + "column_collapse_frictional.toml", {}),
                    column_scene(0.001, 1e-5, MK::Frictional, SK::QuadraticBSpline, 1.0));
  expect_same_scene(load(flume, {}), flume_scene(0.005, 1e-6, MK::PhaseTransition, SK::QuadraticBSpline, 3.0));
  expect_same_scene(load(kScenes + "flume_frictional.toml", {}),
                    flume_scene(0.005, 1e-6, MK::Frictional, SK::QuadraticBSpline, 3.0));
  Scene ci = small_column_scene(MK::PhaseTransition);
  ci.output.times = {0.05, 0.25, 0.4};
  expect_same_scene(load(kScenes + "column_collapse_ci.toml", {}), ci);

  // mesh series (gpu.sh series): grid.h, time.dt, coarser sampling from 5 mm up
  expect_same_scene(load(column, {"grid.h=0.0025", "time.dt=2.5e-5"}),
                    column_scene(0.0025, 2.5e-5, MK::PhaseTransition, SK::QuadraticBSpline, 1.0));
  expect_same_scene(load(column, {"grid.h=0.01", "time.dt=1e-4", "output.series_dt=5e-3", "material.model=frictional"}),
                    column_scene(0.01, 1e-4, MK::Frictional, SK::QuadraticBSpline, 1.0));
  // the flume's grid height is a whole number of cells: 2.16 m at 20 and 10 mm, 2.1525 m at 2.5 mm
  expect_same_scene(load(flume, {"grid.h=0.02", "grid.size=[3.2, 2.16]", "time.dt=1e-5"}),
                    flume_scene(0.02, 1e-5, MK::PhaseTransition, SK::QuadraticBSpline, 3.0));
  expect_same_scene(load(flume, {"grid.h=0.01", "grid.size=[3.2, 2.16]", "time.dt=1e-5"}),
                    flume_scene(0.01, 1e-5, MK::PhaseTransition, SK::QuadraticBSpline, 3.0));
  expect_same_scene(load(flume, {"grid.h=0.0025", "grid.size=[3.2, 2.1525]", "time.dt=1e-5"}),
                    flume_scene(0.0025, 1e-5, MK::PhaseTransition, SK::QuadraticBSpline, 3.0));
  // CFL step: time.dt is then the largest step
  Scene cfl = column_scene(0.005, 1e-4, MK::PhaseTransition, SK::QuadraticBSpline, 1.0);
  cfl.adaptive = true;
  cfl.cfl = 0.4;
  expect_same_scene(load(column, {"grid.h=0.005", "time.dt=1e-4", "time.adaptive=true", "time.cfl=0.4",
                                  "output.series_dt=5e-3"}),
                    cfl);
  // linear shape functions with the FLIP/PIC blend; a shorter collapse with its frames
  expect_same_scene(load(column, {"grid.h=0.005", "time.dt=5e-5", "grid.shape=linear", "solver.transfer=flip",
                                  "output.series_dt=5e-3"}),
                    column_scene(0.005, 5e-5, MK::PhaseTransition, SK::Linear, 1.0));
  expect_same_scene(load(column, {"stage[1].duration=0.4", "output.times=[0.05, 0.25]"}),
                    column_scene(0.001, 1e-5, MK::PhaseTransition, SK::QuadraticBSpline, 0.4));
  // a fixed FLIP fraction per step instead of the PIC rate
  Scene flip = column_scene(0.001, 1e-5, MK::PhaseTransition, SK::QuadraticBSpline, 1.0);
  flip.transfer = Scene::Transfer::FlipPic;
  flip.flip = 0.99;
  flip.pic_speed = 0;
  expect_same_scene(load(column, {"solver.transfer=flip", "solver.pic_speed=0", "solver.flip=0.99"}), flip);
}
