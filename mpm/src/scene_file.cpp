#include <granflow/mpm/scene_file.hpp>

#include <cmath>
#include <filesystem>
#include <sstream>

#include <granflow/io/input_error.hpp>
#include <granflow/io/parameter_set.hpp>
#include <granflow/io/toml_reader.hpp>

namespace granflow::mpm {
using namespace granflow::io;  // the strict TOML reader this file format is built on
namespace {

std::vector<double> vec(TomlTable& t, const std::string& key, int dim, Bounds b = Bounds::any()) {
  std::vector<double> v = t.numbers(key, b, false);
  if (static_cast<int>(v.size()) != dim)
    t.fail(key, "needs " + std::to_string(dim) + " components (grid.dim = " + std::to_string(dim) + "), got " +
                    std::to_string(v.size()));
  return v;
}

std::vector<double> increasing(TomlTable& t, const std::string& key) {
  std::vector<double> v = t.numbers(key, Bounds::any(), false);
  if (v.size() < 2) t.fail(key, "needs at least two points");
  for (size_t i = 1; i < v.size(); ++i)
    if (!(v[i] > v[i - 1])) t.fail(key, "must increase strictly");
  return v;
}

}  // namespace

mpm::Scene load_scene(const std::string& path) {
  if (!std::filesystem::exists(path)) throw InputError(where(path) + "no such scene file");
  const toml::table doc = TomlTable::parse_file(path);
  TomlTable root(doc, path);
  mpm::Scene sc;
  sc.file = path;
  sc.name = root.string_or("name", std::filesystem::path(path).stem().string());
  // lines of the keys make_setup's checks name, so its messages can point into the file
  auto note = [&sc](const TomlTable& t, const std::string& key) { sc.lines[t.dotted(key)] = t.line(key); };

  TomlTable grid = root.table("grid");
  sc.dim = static_cast<int>(grid.integer_or("dim", 2, 2, 3));
  const int D = sc.dim;
  sc.origin = vec(grid, "origin", D);
  sc.size = vec(grid, "size", D, Bounds::positive());
  sc.h = grid.number("h", Bounds::positive());
  sc.shape = grid.choice("shape", {"linear", "quadratic"}, "linear") == "linear" ? mpm::ShapeKind::Linear
                                                                                  : mpm::ShapeKind::QuadraticBSpline;
  for (const char* k : {"dim", "origin", "size", "h"}) note(grid, k);
  sc.modified_boundary_splines = grid.choice("boundary_splines", {"modified", "truncated"}, "modified") == "modified";
  grid.finish();

  TomlTable part = root.table("particles");
  const long ppc = part.integer("per_cell", 1, 1000);
  const int axis = static_cast<int>(std::lround(std::pow(double(ppc), 1.0 / D)));
  if (std::lround(std::pow(double(axis), D)) != ppc)
    part.fail("per_cell", "must be n^" + std::to_string(D) + " (a regular lattice: 1, 4, 9, 16 in 2D), got " +
                              std::to_string(ppc));
  sc.ppc_axis = axis;
  note(part, "per_cell");
  part.finish();

  TomlTable time = root.table("time");
  sc.dt = time.number("dt", Bounds::positive());
  sc.adaptive = time.boolean_or("adaptive", false);
  sc.cfl = time.number_or("cfl", 0.5, Bounds{0.0, 1.0, true, false});
  note(time, "dt");
  time.finish();

  if (auto s = root.optional_table("solver")) {
    const bool tpic = s->choice("transfer", {"flip", "tpic"}, "flip") == "tpic";
    sc.transfer = tpic ? mpm::Scene::Transfer::TaylorPic : mpm::Scene::Transfer::FlipPic;
    sc.flip = s->number_or("flip", tpic ? 0.0 : 0.99, Bounds::closed(0, 1));
    sc.pic_speed = s->number_or("pic_speed", 0.0, Bounds::positive());
    if (s->has("flip") && s->has("pic_speed"))
      s->fail("pic_speed", "give either flip (a fraction per step) or pic_speed (a rate), not both");
    sc.volumetric_averaging = s->boolean_or("volumetric_averaging", false);
    mpm::parse_precision(s->choice("precision", {"fp64", "mixed", "fp32"}, "fp64"), sc.precision);
    if (s->has("gravity")) sc.gravity = vec(*s, "gravity", D);
    s->finish();
  }
  if (sc.gravity.empty()) {
    sc.gravity.assign(D, 0.0);
    sc.gravity[1] = -9.81;
  }

  TomlTable mat = root.table("material");
  {
    std::string pset = mat.string("parameters");
    const std::filesystem::path rel = std::filesystem::path(path).parent_path() / pset;
    if (pset.find('/') != std::string::npos && std::filesystem::exists(rel)) pset = rel.string();
    ParameterSet set;
    try {
      set = load_parameter_set(pset);
    } catch (const InputError& e) {
      mat.fail("parameters", e.what());
    }
    sc.material.name = set.file;
    const std::string model = mat.choice("model", {"phase_transition", "frictional"}, "phase_transition");
    sc.material.model = model == "frictional" ? mpm::ModelKind::Frictional : mpm::ModelKind::PhaseTransition;
    if (!set.has_frictional()) mat.fail("parameters", "the set " + set.file + " has no [frictional] part");
    sc.material.params.f = *set.frictional;
    if (set.has_collisional()) sc.material.params.c = *set.collisional;
    if (sc.material.model == mpm::ModelKind::PhaseTransition && !set.has_collisional())
      mat.fail("model", "\"phase_transition\" needs a set with a [collisional] part; " + set.file + " has none");
    if (mat.has("rho_p")) sc.material.params.c.rho_p = mat.number("rho_p", Bounds::positive());
    if (!(sc.material.params.c.rho_p > 0))
      mat.fail("rho_p", "the parameter set gives no particle density: set material.rho_p");
    const auto e0 = mat.optional_number("e0", Bounds::open(0, kVoidRatioMax));
    if (!e0 && set.e0.empty()) mat.fail("e0", "required: the parameter set names no initial void ratio");
    sc.material.e0 = e0 ? *e0 : set.e0.front();
    check_initial_void_ratio(set, sc.material.e0, "'" + mat.dotted("e0") + "' in " + path);
    sc.material.T0 = mat.number_or("T0", set.T0.value_or(1e-15), Bounds::non_negative());
  }
  mat.finish();

  if (auto is = root.optional_table("initial_stress")) {
    sc.initial.geostatic = is->choice("kind", {"zero", "geostatic"}, "zero") == "geostatic";
    sc.initial.K0 = is->number_or("K0", -1, Bounds{0.0, 3.0, true, false});
    note(*is, "K0");
    is->finish();
  }

  auto bodies = root.array_of_tables("body");
  if (bodies.empty()) root.fail("body", "at least one [[body]] (the material region) is required");
  sc.lines["body"] = bodies.front().line();
  for (auto& b : bodies) {
    sc.lines["body[" + std::to_string(sc.bodies.size()) + "]"] = b.line();
    for (const char* k : {"min", "max", "polygon_x", "polygon_y"}) note(b, k);
    mpm::Body body;
    if (b.has("polygon_x") || b.has("polygon_y")) {
      if (D != 2) b.fail("polygon_x", "polygons need grid.dim = 2");
      body.poly_x = b.numbers("polygon_x", Bounds::any(), false);
      body.poly_y = b.numbers("polygon_y", Bounds::any(), false);
      if (body.poly_x.size() != body.poly_y.size() || body.poly_x.size() < 3)
        b.fail("polygon_y", "polygon_x and polygon_y need the same number (>= 3) of vertices");
      if (b.has("min") || b.has("max")) b.fail("min", "give either min/max or polygon_x/polygon_y, not both");
    } else {
      body.box_min = vec(b, "min", D);
      body.box_max = vec(b, "max", D);
      for (int d = 0; d < D; ++d)
        if (!(body.box_max[d] > body.box_min[d])) b.fail("max", "must exceed min in every component");
    }
    b.finish();
    sc.bodies.push_back(body);
  }

  for (auto& w : root.array_of_tables("wall")) {
    mpm::Wall wall;
    const std::string side = w.choice("side", {"x-", "x+", "y-", "y+", "z-", "z+"}, "");
    if (side.empty()) w.fail("side", "required: one of x-, x+, y-, y+, z-, z+");
    wall.axis = side[0] - 'x';
    if (wall.axis >= D) w.fail("side", "axis " + side + " does not exist in " + std::to_string(D) + "D");
    wall.at_max = side[1] == '+';
    wall.position = w.number_or("position", wall.at_max ? sc.origin[wall.axis] + sc.size[wall.axis]
                                                        : sc.origin[wall.axis]);
    // type = "frictional" with mu (mu alone implies it); no_slip and free_slip take no mu
    const std::string type = w.choice("type", {"no_slip", "free_slip", "frictional"}, w.has("mu") ? "frictional" : "no_slip");
    wall.no_slip = type == "no_slip";
    if (type == "frictional") {
      if (!w.has("mu")) w.fail("mu", "required with type = \"frictional\" (the Coulomb friction coefficient, >= 0)");
      wall.mu = w.number("mu", Bounds::non_negative());
      note(w, "mu");
    } else if (w.has("mu")) {
      w.fail("mu", "friction needs type = \"frictional\" (this wall is \"" + type + "\")");
    }
    wall.key = w.dotted("side");
    note(w, "side");
    if (wall.position < sc.origin[wall.axis] || wall.position > sc.origin[wall.axis] + sc.size[wall.axis])
      w.fail("position", "the wall at " + std::string(1, side[0]) + " = " + std::to_string(wall.position) +
                             " lies outside the grid [" + std::to_string(sc.origin[wall.axis]) + ", " +
                             std::to_string(sc.origin[wall.axis] + sc.size[wall.axis]) + "] (grid.origin, grid.size)");
    for (const auto& o : sc.walls)
      if (o.axis == wall.axis && o.at_max == wall.at_max)
        w.fail("side", "a second wall on side " + side + " (first: " + o.key + ") contradicts it");
    w.finish();
    sc.walls.push_back(wall);
  }

  if (auto b = root.optional_table("base")) {
    if (D != 2) b->fail("x", "an inclined base needs grid.dim = 2");
    sc.lines["base"] = b->line();
    mpm::BaseLine base;
    base.x = increasing(*b, "x");
    base.y = b->numbers("y", Bounds::any(), false);
    if (base.y.size() != base.x.size()) b->fail("y", "needs as many points as base.x");
    if (b->has("mu")) base.mu = b->number("mu", Bounds::non_negative());  // absent: no-slip
    b->finish();
    sc.base = base;
  }

  auto stages = root.array_of_tables("stage");
  if (stages.empty()) root.fail("stage", "at least one [[stage]] with a duration is required");
  for (auto& s : stages) {
    mpm::Stage st;
    st.name = s.string_or("name", "");
    st.duration = s.number("duration", Bounds::positive());
    st.damping = s.number_or("damping", 0, Bounds{0.0, 1.0, false, true});
    if (s.has("flip")) st.flip = s.number("flip", Bounds::closed(0, 1));
    if (auto g = s.optional_table("gate")) {
      mpm::Gate gate;
      gate.point = vec(*g, "point", D);
      gate.normal = vec(*g, "normal", D);
      gate.normal_only = g->choice("hold", {"normal", "all"}, "normal") == "normal";
      int nz = 0;
      for (double c : gate.normal) nz += c != 0;
      if (nz == 0) g->fail("normal", "must not be zero");
      if (gate.normal_only && nz != 1)
        g->fail("hold", "\"normal\" needs an axis-aligned normal; use \"all\" for an inclined gate");
      gate.lift_speed = g->number_or("lift_speed", 0.0, Bounds::positive());
      if (gate.lift_speed > 0 && gate.normal[1] != 0)
        g->fail("lift_speed", "a gate is lifted along y: its normal must have no y component (a vertical gate)");
      note(*g, "normal");
      note(*g, "hold");
      note(*g, "lift_speed");
      g->finish();
      st.gate = gate;
    }
    s.finish();
    sc.stages.push_back(st);
  }

  if (auto r = root.optional_table("runout")) {
    sc.runout_x = r->numbers("x", Bounds::any(), false);
    sc.runout_y = r->numbers("y", Bounds::any(), false);
    if (sc.runout_x.size() != sc.runout_y.size() || sc.runout_x.size() < 2)
      r->fail("y", "runout.x and runout.y need the same number (>= 2) of points");
    r->finish();
  }

  for (auto& t : root.array_of_tables("track")) {
    mpm::Track tr;
    tr.name = t.string("name");
    tr.x = vec(t, "position", D);
    t.finish();
    sc.tracks.push_back(tr);
  }

  if (auto o = root.optional_table("output")) {
    if (o->has("times")) sc.output.times = o->numbers("times", Bounds::non_negative());
    sc.output.series_dt = o->number_or("series_dt", 1e-3, Bounds::positive());
    sc.output.binary = o->choice("format", {"binary", "ascii"}, "binary") == "binary";
    sc.output.frames_in_stages = o->boolean_or("stage_frames", true);
    sc.output.checkpoint_dt = o->number_or("checkpoint_dt", 0.0, Bounds::positive());
    const double last = sc.stages.back().duration;
    for (double t : sc.output.times)
      if (t > last * (1 + 1e-12))
        o->fail("times", "frame time " + std::to_string(t) + " s is after the end of the last stage (" +
                             std::to_string(last) + " s; times count from the start of the last stage)");
    o->finish();
  }
  root.finish();
  return sc;
}

}  // namespace granflow::mpm
