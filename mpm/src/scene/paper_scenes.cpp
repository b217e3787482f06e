// The paper's scenes built in code: the column collapse and the flume (Table 3's parameters).
#include <cmath>
#include <sstream>

#include <granflow/mpm/scene.hpp>

namespace granflow::mpm {
namespace {

void column_collapse_params(Material& m) {  // data/params/column_collapse.toml (Table 3)
  auto& c = m.params.c;
  c.rho_p = 2650; c.d = 1.25e-3; c.V_sd = 1.0 / 1.62; c.V_m = 0.4; c.eps_n = 0.6; c.mu_p = 0.2;
  auto& f = m.params.f;
  f.K0 = 120; f.nu = 0.2; f.n = 0.5; f.phi_c = 19.8 * M_PI / 180; f.e_ref = 0.977; f.lambda_c = 0.0596;
  f.xi = 0.365; f.A_d = 0.7; f.k_p = 0.0044; f.n_p = 2.4; f.n_d = 2.9; f.p_at = 101.3e3;
}

void flume_params(Material& m) {  // data/params/flume.toml (Table 3)
  auto& c = m.params.c;
  c.rho_p = 2500; c.d = 1.0e-3; c.V_sd = 1.0 / 1.60; c.V_m = 0.4; c.eps_n = 0.6; c.mu_p = 0.2;
  auto& f = m.params.f;
  f.K0 = 130; f.nu = 0.2; f.n = 0.5; f.phi_c = 38.0 * M_PI / 180; f.e_ref = 0.977; f.lambda_c = 0.0596;
  f.xi = 0.365; f.A_d = 0.4; f.k_p = 0.0044; f.n_p = 2.4; f.n_d = 2.9; f.p_at = 101.3e3;
}

const char* model_name(ModelKind m) { return m == ModelKind::PhaseTransition ? "phase transition" : "frictional only"; }

// What the paper's two plane-strain scenes share: grid of whole cells from the origin, 2 x 2
// points per cell, gravity, the step, the material's model and initial state.
Scene paper_scene(const char* title, double width, double height, double h, double dt, ModelKind model,
                  ShapeKind shape, const char* material, double e0) {
  Scene sc;
  std::ostringstream os;
  os << title << " (" << h * 1e3 << " mm), " << model_name(model);
  sc.name = os.str();
  sc.dim = 2;
  sc.origin = {0.0, 0.0};
  sc.size = {width, std::ceil(height / h - 1e-9) * h};  // whole cells
  sc.h = h;
  sc.ppc_axis = 2;
  sc.shape = shape;
  sc.gravity = {0.0, -9.81};
  sc.dt = dt;
  sc.pic_speed = 1.0;  // PIC part as a rate: flip 0.99 per step at 1 mm and 1e-5 s
  // Quadratic B-splines: Taylor PIC (affine momentum in P2G), which moves the deposit on and
  // brings it to rest without FLIP noise; linear hats (the CI scenes) keep FLIP, their velocity
  // gradient jumps at cell faces and its affine transfer tears points off (docs/mpm.md).
  if (shape == ShapeKind::QuadraticBSpline) {
    sc.transfer = Scene::Transfer::TaylorPic;
    sc.flip = 0.0;  // not used with pic_speed; the TOML default of "tpic"
  }
  Material& m = sc.material;
  m.name = material;
  m.model = model;
  m.e0 = e0;
  m.T0 = 1e-15;
  return sc;
}

}  // namespace

Scene column_scene(double h, double dt, ModelKind model, ShapeKind shape, double collapse_time) {
  Scene sc = paper_scene("column collapse", 0.60, 0.15, h, dt, model, shape,
                         "column_collapse (Table 3, as data/params/column_collapse.toml)", 0.95);
  column_collapse_params(sc.material);
  Body b;
  b.box_min = {0.0, 0.0};
  b.box_max = {0.2, 0.1};
  sc.bodies.push_back(b);
  sc.walls.push_back({0, false, 0.0, false, "wall[0].side"});
  sc.walls.push_back({0, true, 0.60, false, "wall[1].side"});
  sc.walls.push_back({1, false, 0.0, true, "wall[2].side"});
  Stage s1;
  s1.name = "consolidation";
  s1.duration = 0.1;
  s1.damping = 0.5;
  s1.gate = Gate{{0.2, 0.0}, {1.0, 0.0}, true};
  Stage s2;
  s2.name = "collapse";
  s2.duration = collapse_time;
  sc.stages = {s1, s2};
  sc.runout_x = {0.0, 0.6};
  sc.runout_y = {0.0, 0.0};
  sc.tracks = {{"A", {0.15, 0.095}}, {"B", {0.10, 0.05}}, {"C", {0.05, 0.01}}};
  for (double t : {0.05, 0.25, 0.5, 1.0})
    if (t <= collapse_time) sc.output.times.push_back(t);
  sc.output.series_dt = h >= 0.005 ? 5e-3 : 1e-3;
  return sc;
}

Scene small_column_scene(ModelKind model, ShapeKind shape) { return column_scene(0.01, 5e-5, model, shape, 0.4); }

Scene slab_3d_scene(ModelKind model, ShapeKind shape, double duration) {
  Scene sc = small_column_scene(model, shape);
  sc.dim = 3;
  sc.origin = {0.0, 0.0, 0.0};
  sc.size = {0.40, 0.16, 0.08};
  sc.gravity = {0.0, -9.81, 0.0};
  sc.walls[1].position = 0.40;
  sc.walls.push_back({2, false, 0.0, false, "wall[3].side"});
  sc.walls.push_back({2, true, 0.08, false, "wall[4].side"});
  sc.runout_x = {0.0, 0.40};
  sc.runout_y = {0.0, 0.0};
  sc.tracks.clear();
  sc.output.times.clear();
  sc.bodies[0].box_min.push_back(0.0);
  sc.bodies[0].box_max.push_back(0.08);
  Stage st;
  st.name = "collapse";
  st.duration = duration;
  sc.stages = {st};
  return sc;
}

Scene flume_scene(double h, double dt, ModelKind model, ShapeKind shape, double flow_time) {
  const double c45 = std::cos(M_PI / 4);
  const double H = 2.30 * c45, run = 0.5 * c45, thick = 0.30 / c45;
  Scene sc = paper_scene("flume", 3.20, H + thick + 0.1, h, dt, model, shape,
                         "flume (Table 3, as data/params/flume.toml)", 0.90);
  flume_params(sc.material);
  Body b;
  b.poly_x = {0.0, run, run, 0.0};
  b.poly_y = {H, H - run, H - run + thick, H + thick};
  sc.bodies.push_back(b);
  sc.walls.push_back({0, false, 0.0, false, "wall[0].side"});
  sc.walls.push_back({0, true, 3.20, false, "wall[1].side"});
  sc.base = BaseLine{{0.0, H, 3.20}, {H, 0.0, 0.0}};
  Stage s1;
  s1.name = "consolidation";
  s1.duration = 0.1;
  s1.damping = 0.5;
  s1.gate = Gate{{run, 0.0}, {1.0, 0.0}, true};
  Stage s2;
  s2.name = "flow";
  s2.duration = flow_time;
  sc.stages = {s1, s2};
  sc.runout_x = {0.0, H, 3.20};
  sc.runout_y = {H, 0.0, 0.0};
  sc.tracks = {{"A", {0.25, H - 0.25 + thick - 0.02}}, {"B", {0.18, H - 0.18 + thick / 2}}, {"C", {0.02, H + 0.01}}};
  for (double t : {0.1, 0.4, 0.8, 3.0})
    if (t <= flow_time) sc.output.times.push_back(t);
  sc.output.series_dt = 2e-3;
  return sc;
}

}  // namespace granflow::mpm
