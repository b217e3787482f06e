#include <granflow/mpm/scene_file.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <optional>
#include <sstream>

#include <granflow/io/csv_table.hpp>
#include <granflow/io/input_error.hpp>
#include <granflow/io/parameter_set.hpp>
#include <granflow/io/raster.hpp>
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

// Why a closed polygon is not simple (edges i and j cross or touch, or it encloses no area), or
// "" for a simple one. Its interior, area and centroid (an obstacle's default moment point) are
// then those of one region: a bow-tie's cancel to 0/0.
std::string polygon_defect(const std::vector<double>& x, const std::vector<double>& y) {
  const size_t n = x.size();
  double area2 = 0, scale = 0;
  for (size_t i = 0; i < n; ++i) {
    const size_t j = (i + 1) % n;
    area2 += x[i] * y[j] - x[j] * y[i];
    scale = std::max({scale, std::abs(x[i] - x[0]), std::abs(y[i] - y[0])});
  }
  for (size_t i = 0; i < n; ++i)
    if (x[i] == x[(i + 1) % n] && y[i] == y[(i + 1) % n])
      return "repeats vertex " + std::to_string(i) + " as vertex " + std::to_string((i + 1) % n) +
             " (an edge of zero length)";
  auto cross = [&](size_t a, size_t b, size_t c) {  // orientation of c about a -> b
    return (x[b] - x[a]) * (y[c] - y[a]) - (y[b] - y[a]) * (x[c] - x[a]);
  };
  auto on = [&](size_t a, size_t b, size_t c) {  // c on the segment a-b, given collinear
    return std::min(x[a], x[b]) <= x[c] && x[c] <= std::max(x[a], x[b]) && std::min(y[a], y[b]) <= y[c] &&
           y[c] <= std::max(y[a], y[b]);
  };
  for (size_t i = 0; i < n; ++i)
    for (size_t j = i + 1; j < n; ++j) {
      const size_t i1 = (i + 1) % n, j1 = (j + 1) % n;
      const bool adjacent = j == i + 1 || (i == 0 && j1 == 0);
      const double d1 = cross(i, i1, j), d2 = cross(i, i1, j1), d3 = cross(j, j1, i), d4 = cross(j, j1, i1);
      bool meet = false;
      if (adjacent) {  // they share a vertex: a fold back along the other edge is the only fault
        const size_t shared = j == i + 1 ? j : i, far_i = shared == j ? i : i1, far_j = shared == j ? j1 : j;
        meet = cross(shared, far_i, far_j) == 0 && ((x[far_i] - x[shared]) * (x[far_j] - x[shared]) +
                                                        (y[far_i] - y[shared]) * (y[far_j] - y[shared])) > 0;
      } else {
        meet = ((d1 > 0) != (d2 > 0) && d1 != 0 && d2 != 0 && (d3 > 0) != (d4 > 0) && d3 != 0 && d4 != 0) ||
               (d1 == 0 && on(i, i1, j)) || (d2 == 0 && on(i, i1, j1)) || (d3 == 0 && on(j, j1, i)) ||
               (d4 == 0 && on(j, j1, i1));
      }
      if (meet) {
        std::ostringstream os;
        os << "is not a simple polygon: edge " << i << " (vertices " << i << "-" << i1 << ") and edge " << j
           << " (vertices " << j << "-" << j1 << ") " << (adjacent ? "fold back onto each other" : "cross or touch")
           << "; list the vertices once around the outline, without crossings";
        return os.str();
      }
    }
  if (!(std::abs(area2) > 1e-12 * scale * scale)) return "encloses no area";  // a guard: a simple polygon has area
  return "";
}

// A file a scene names: relative paths from the scene file's folder (else as given, from the
// working directory).
std::string beside(const std::string& scene, const std::string& file) {
  const std::filesystem::path p(file);
  if (p.is_absolute()) return file;
  const std::filesystem::path rel = std::filesystem::path(scene).parent_path() / p;
  return std::filesystem::exists(rel) || !std::filesystem::exists(p) ? rel.string() : file;
}

// A mesh key (body.mesh, an obstacle's mesh) read and placed: scale, rotation (x, then y, then z,
// degrees), offset (docs/mpm_meshes.md). 3D only; the geometry's checks come at set-up.
std::shared_ptr<const mpm::TriMesh> placed_mesh(TomlTable& t, const std::string& scene, int dim) {
  if (dim != 3) t.fail("mesh", "meshes need grid.dim = 3 (a 2D scene takes polygons)");
  const std::string file = t.string("mesh");
  mpm::MeshPlacement p;
  p.scale = t.number_or("scale", 1.0, Bounds::positive());
  if (t.has("rotation")) {
    const std::vector<double> r = vec(t, "rotation", 3);
    std::copy(r.begin(), r.end(), p.rotation.begin());
  }
  if (t.has("offset")) {
    const std::vector<double> o = vec(t, "offset", 3);
    std::copy(o.begin(), o.end(), p.offset.begin());
  }
  auto m = std::make_shared<mpm::TriMesh>();
  try {
    *m = mpm::read_mesh(beside(scene, file));
  } catch (const InputError& e) {
    t.fail("mesh", e.what());
  }
  m->file = file;
  mpm::place_mesh(*m, p);
  return m;
}

// One part of a --set key: a table or key name, with an index into an array of tables.
struct KeyPart {
  std::string name;
  long index = -1;
};

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t") - a + 1);
}

// "stage[1].duration" -> {stage, 1}, {duration}; empty when malformed.
std::vector<KeyPart> split_key(const std::string& key) {
  std::vector<KeyPart> parts;
  std::size_t at = 0;
  for (;;) {
    std::size_t end = at;
    while (end < key.size() && (std::isalnum(static_cast<unsigned char>(key[end])) || key[end] == '_' || key[end] == '-'))
      ++end;
    if (end == at) return {};
    KeyPart p{key.substr(at, end - at)};
    if (end < key.size() && key[end] == '[') {
      const std::size_t close = key.find(']', end);
      const std::string digits = close == std::string::npos ? "" : key.substr(end + 1, close - end - 1);
      if (digits.empty() || digits.size() > 6 || digits.find_first_not_of("0123456789") != std::string::npos) return {};
      p.index = std::stol(digits);
      end = close + 1;
    }
    parts.push_back(p);
    if (end == key.size()) return parts;
    if (key[end] != '.') return {};
    at = end + 1;
  }
}

bool is_parameter_set_key(const std::vector<KeyPart>& parts) {
  for (const char* t : kParameterSetTables)
    if (parts.front().name == t && parts.front().index < 0) return true;
  return false;
}

// VALUE as a TOML value ("v" of the returned table). Its source names the --set, so the
// strict reader's messages point to it and not to a line of the file. A bare word is a string.
toml::table parse_value(const std::string& value, const std::string& origin, const std::string& who) {
  if (trim(value).empty()) throw InputError(who + "no value after '='");
  const bool bare_word = value.find_first_of("\"'[]{}=#\\ \t\r\n") == std::string::npos;
  toml::table t;
  try {
    t = toml::parse("v = " + value, std::string_view(origin));
  } catch (const toml::parse_error& e) {
    const std::string why = "not a TOML value (" + std::string(e.description()) +
                            "); strings with spaces need quotes, e.g. name=\"my run\"";
    if (!bare_word) throw InputError(who + why);
    try {
      t = toml::parse("v = \"" + value + "\"", std::string_view(origin));
    } catch (const toml::parse_error&) {  // e.g. a control character
      throw InputError(who + why);
    }
  }
  if (t.size() != 1 || !t.contains("v")) throw InputError(who + "VALUE must be one TOML value");
  return t;
}

// Puts value at the key path in the scene document; missing tables are made (the strict reader
// then names an unknown one), arrays of tables are indexed but not extended.
void set_scene_value(toml::table& doc, const std::vector<KeyPart>& parts, toml::table value,
                     const std::string& origin, const std::string& who) {
  toml::table* t = &doc;
  std::string dotted;
  for (std::size_t i = 0; i + 1 < parts.size(); ++i) {
    const KeyPart& p = parts[i];
    dotted += (dotted.empty() ? "" : ".") + p.name;
    toml::node* n = t->get(p.name);
    if (p.index >= 0) {
      if (!n || !n->is_array_of_tables()) throw InputError(who + "the scene has no [[" + dotted + "]] tables");
      toml::array& a = *n->as_array();
      if (static_cast<std::size_t>(p.index) >= a.size())
        throw InputError(who + "the scene has " + std::to_string(a.size()) + " [[" + dotted + "]] table" +
                         (a.size() == 1 ? "" : "s") + " (" + dotted + "[0] to " + dotted + "[" +
                         std::to_string(a.size() - 1) + "]); --set changes entries, it does not add them");
      t = a.get(static_cast<std::size_t>(p.index))->as_table();
      dotted += "[" + std::to_string(p.index) + "]";
      continue;
    }
    if (!n) {
      toml::table fresh = toml::parse("v = {}", std::string_view(origin));  // sourced: an unknown table names the --set
      t->insert(p.name, std::move(*fresh.get("v")->as_table()));
      n = t->get(p.name);
    }
    if (n->is_array_of_tables())
      throw InputError(who + "'" + dotted + "' is an array of tables: give an index, e.g. " + dotted + "[0]." +
                       parts[i + 1].name);
    if (!n->is_table()) throw InputError(who + "'" + dotted + "' is a value, not a table");
    t = n->as_table();
  }
  if (parts.back().index >= 0)
    throw InputError(who + "KEY must end in a key name, e.g. stage[1].duration, not in an index");
  t->insert_or_assign(parts.back().name, std::move(*value.get("v")));
}

std::string override_key(const std::string& assignment) { return trim(assignment.substr(0, assignment.find('='))); }

// " (with --set 'a' --set 'b')": said after messages about keys of the file the overrides may explain.
std::string with_overrides(const std::vector<std::string>& sets) {
  std::string s;
  for (const auto& a : sets) s += (s.empty() ? " (with " : " ") + ("--set '" + a + "'");
  return s.empty() ? s : s + ")";
}

// A material name: letters, digits, _ and - (so that NAME= and NAME: parse unambiguously).
bool material_name_ok(const std::string& name) {
  if (name.empty()) return false;
  for (char c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '-') return false;
  return true;
}

// The command line's material overrides: an unqualified --params and parameter-set --set keys,
// and those naming a material (--params NAME=SET, --set NAME:frictional.KEY=VALUE).
struct MaterialOverrides {
  std::string params;
  std::vector<std::pair<std::string, std::string>> named_params;  // name, set
  struct Set {
    std::string material;    // "" unqualified
    std::string assignment;  // without NAME:
    std::string given;       // as given
  };
  std::vector<Set> sets;
};

// One [material] or [[material]] table: its parameter set (params or the table's), the
// overrides of that set, model, rho_p, e0, T0.
mpm::Material read_material(TomlTable& mat, const std::string& path, const std::string& params,
                            const std::vector<MaterialOverrides::Set>& sets, const std::string& params_flag) {
  mpm::Material m;
  std::string pset = params;
  if (params.empty()) {
    pset = mat.string("parameters");
    const std::filesystem::path rel = std::filesystem::path(path).parent_path() / pset;
    if (pset.find('/') != std::string::npos && std::filesystem::exists(rel)) pset = rel.string();
  } else {
    mat.string_or("parameters", "");  // replaced by --params
  }
  auto fail_set = [&](const std::string& message) {
    if (!params.empty()) throw InputError("--params '" + params_flag + "': " + message);
    mat.fail("parameters", message);
  };
  ParameterSet set;
  try {
    set = load_parameter_set(pset);
  } catch (const InputError& e) {
    fail_set(e.what());
  }
  for (const auto& a : sets)
    apply_override(set, a.assignment, a.material.empty() ? "--set" : "--set (material " + a.material + ")");
  m.name = set.file;
  const std::string model = mat.choice("model", {"phase_transition", "frictional"}, "phase_transition");
  m.model = model == "frictional" ? mpm::ModelKind::Frictional : mpm::ModelKind::PhaseTransition;
  if (!set.has_frictional()) fail_set("the set " + set.file + " has no [frictional] part");
  m.params.f = *set.frictional;
  if (set.has_collisional()) m.params.c = *set.collisional;
  if (m.model == mpm::ModelKind::PhaseTransition && !set.has_collisional())
    mat.fail("model", "\"phase_transition\" needs a set with a [collisional] part; " + set.file + " has none");
  if (mat.has("rho_p")) m.params.c.rho_p = mat.number("rho_p", Bounds::positive());
  if (!(m.params.c.rho_p > 0))
    mat.fail("rho_p", "the parameter set gives no particle density: set " + mat.dotted("rho_p"));
  const auto e0 = mat.optional_number("e0", Bounds::open(0, kVoidRatioMax));
  if (!e0 && set.e0.empty()) mat.fail("e0", "required: the parameter set names no initial void ratio");
  m.e0 = e0 ? *e0 : set.e0.front();
  check_initial_void_ratio(set, m.e0, "'" + mat.dotted("e0") + "' in " + path);
  m.T0 = mat.number_or("T0", set.T0.value_or(1e-15), Bounds::non_negative());
  // the table's e0 and T0 win over the set's initial ones: a --set (or an ensemble's [[vary]]) of
  // those would run unchanged
  for (const auto& a : sets) {
    const std::string key = override_key(a.assignment);
    for (const char* k : {"e0", "T0"}) {
      if (key != std::string("initial.") + k || !mat.has(k)) continue;
      throw InputError("--set '" + a.given + "' changes nothing: " + where(path, mat.line(k)) + "'" + mat.dotted(k) +
                       "' takes precedence over the parameter set's " + key + "; set " +
                       (a.material.empty() ? std::string("material.") + k : a.material + ":" + k) + " instead");
    }
  }
  return m;
}

// The scene's materials: one [material], or [[material]] tables each with a name.
void read_materials(TomlTable& root, mpm::Scene& sc, const std::string& path, const MaterialOverrides& mo) {
  const toml::node* node = root.raw().get("material");
  if (!node || !node->is_array_of_tables()) {  // one unnamed material (or the reader's error)
    TomlTable mat = root.table("material");
    for (const auto& [name, set] : mo.named_params)
      throw InputError("--params '" + name + "=" + set + "': the scene has one unnamed [material], no [[material]] "
                       "named '" + name + "': use --params " + set);
    for (const auto& a : mo.sets)
      if (!a.material.empty())
        throw InputError("--set '" + a.given + "': the scene has one unnamed [material], no [[material]] named '" +
                         a.material + "': use --set " + a.assignment);
    sc.material = read_material(mat, path, mo.params, mo.sets, mo.params);
    mat.finish();
    return;
  }
  auto tables = root.array_of_tables("material");
  std::vector<std::string> names;
  for (auto& t : tables) {
    const std::string name = t.string("name");
    if (!material_name_ok(name))
      t.fail("name", "'" + name + "' is not a material name: letters, digits, _ and - only");
    for (size_t j = 0; j < names.size(); ++j)
      if (names[j] == name) t.fail("name", "'" + name + "' names material[" + std::to_string(j) + "] too");
    names.push_back(name);
  }
  std::string list;
  for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
  const bool several = names.size() > 1;
  auto known = [&](const std::string& name, const std::string& who) {
    if (std::find(names.begin(), names.end(), name) == names.end())
      throw InputError(who + ": the scene has no [[material]] named '" + name + "' (its materials: " + list + ")");
  };
  for (const auto& [name, set] : mo.named_params) known(name, "--params '" + name + "=" + set + "'");
  if (several && !mo.params.empty())
    throw InputError("--params '" + mo.params + "': the scene has " + std::to_string(names.size()) +
                     " materials (" + list + "): name one, e.g. --params " + names[0] + "=" + mo.params);
  for (const auto& a : mo.sets) {
    if (!a.material.empty()) known(a.material, "--set '" + a.given + "'");
    else if (several)
      throw InputError("--set '" + a.given + "': the scene has " + std::to_string(names.size()) + " materials (" +
                       list + "): name the one to change, e.g. --set " + names[0] + ":" + a.assignment);
  }
  for (size_t i = 0; i < tables.size(); ++i) {
    std::string params = several ? "" : mo.params, flag = params;
    for (const auto& [name, set] : mo.named_params)
      if (name == names[i]) params = set, flag = name + "=" + set;
    std::vector<MaterialOverrides::Set> sets;
    for (const auto& a : mo.sets)
      if (a.material.empty() || a.material == names[i]) sets.push_back(a);
    mpm::Material m = read_material(tables[i], path, params, sets, flag);
    m.label = names[i];
    tables[i].finish();
    if (i > 0 && m.model != sc.material.model) {
      auto word = [](mpm::ModelKind k) { return k == mpm::ModelKind::Frictional ? "\"frictional\"" : "\"phase_transition\""; };
      tables[i].fail("model", std::string(word(m.model)) + " differs from material[0].model (" + word(sc.material.model) +
                                  "): every material of a scene has the same model (the kernels are compiled for "
                                  "one model)");
    }
    if (i == 0) sc.material = m;
    else sc.other_materials.push_back(m);
  }
}

Scene read_scene(const toml::table& doc, const std::string& path, const MaterialOverrides& mo) {
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
  sc.cap_to_stable = time.boolean_or("cap_to_stable", true);
  sc.stop_at_rest = time.number_or("stop_at_rest", 0.0, Bounds::open(0, 1));
  sc.rest_hold = time.number_or("rest_hold", 0.1, Bounds::positive());
  if (time.has("rest_hold") && sc.stop_at_rest == 0)
    time.fail("rest_hold", "holds only with time.stop_at_rest (a kinetic-energy ratio in (0, 1), e.g. 1e-3)");
  note(time, "dt");
  if (time.has("stop_at_rest")) note(time, "stop_at_rest");
  time.finish();

  if (auto s = root.optional_table("solver")) {
    const bool tpic = s->choice("transfer", {"flip", "tpic"}, "flip") == "tpic";
    sc.transfer = tpic ? mpm::Scene::Transfer::TaylorPic : mpm::Scene::Transfer::FlipPic;
    sc.flip = s->number_or("flip", tpic ? 0.0 : 0.99, Bounds::closed(0, 1));
    sc.pic_speed = s->number_or("pic_speed", 0.0, Bounds::non_negative());  // 0: no rate, flip per step
    sc.light_node_mass = s->number_or("light_node_mass", 0.05, Bounds::closed(0, 1));
    if (s->has("flip") && sc.pic_speed > 0)
      s->fail("pic_speed", "give either flip (a fraction per step) or pic_speed (a rate), not both "
                           "(pic_speed = 0 turns the rate off)");
    sc.volumetric_averaging = s->boolean_or("volumetric_averaging", false);
    mpm::parse_precision(s->choice("precision", {"fp64", "mixed", "fp32"}, "fp64"), sc.precision);
    if (s->has("gravity")) {
      sc.gravity = vec(*s, "gravity", D);
      note(*s, "gravity");
    }
    s->finish();
  }
  if (sc.gravity.empty()) {
    sc.gravity.assign(D, 0.0);
    sc.gravity[1] = -9.81;
  }

  read_materials(root, sc, path, mo);

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
    for (const char* k : {"min", "max", "polygon_x", "polygon_y", "top", "bottom", "plan_x", "plan_z", "mesh", "scale",
                          "rotation", "offset"})
      note(b, k);
    mpm::Body body;
    if (b.has("material")) {
      const std::string name = b.string("material");
      if (sc.material.label.empty())
        b.fail("material", "the scene has one unnamed [material]; name materials in [[material]] tables to choose one");
      body.material = sc.material_index(name);
      if (body.material < 0) {
        std::string list;
        for (int i = 0; i < sc.material_count(); ++i) list += (list.empty() ? "" : ", ") + sc.material_at(i).label;
        b.fail("material", "no [[material]] is named '" + name + "' (the scene's materials: " + list + ")");
      }
    } else if (sc.material_count() > 1) {
      b.fail_missing("material", "the name of its [[material]]: the scene has " +
                                     std::to_string(sc.material_count()) + " materials");
    }
    note(b, "material");
    if (b.has("mesh")) {  // inside a closed triangle mesh
      for (const char* k : {"min", "max", "polygon_x", "polygon_y", "top", "bottom", "plan_x", "plan_z"})
        if (b.has(k)) b.fail(k, "give either mesh or a box, polygon or surfaces, not both");
      body.mesh = placed_mesh(b, path, D);
    } else if (b.has("top") || b.has("bottom") || b.has("plan_x") || b.has("plan_z")) {  // a release volume
      if (D != 3) b.fail(b.has("top") ? "top" : "bottom", "a body between surfaces needs grid.dim = 3");
      for (const char* k : {"min", "max", "polygon_x", "polygon_y"})
        if (b.has(k)) b.fail(k, "give either top (and bottom, plan_x, plan_z) or a box or polygon, not both");
      if (!b.has("top")) b.fail_missing("top", "the raster of the ground before failure");
      auto surface = [&](const std::string& k) {
        try {
          return std::make_shared<const io::Raster>(read_raster(beside(path, b.string(k))));
        } catch (const InputError& e) {
          b.fail(k, e.what());
        }
      };
      body.top = surface("top");
      if (b.has("bottom") && b.string("bottom") != "terrain") body.bottom = surface("bottom");  // else the terrain
      if (b.has("plan_x") || b.has("plan_z")) {
        body.plan_x = b.numbers("plan_x", Bounds::any(), false);
        body.plan_z = b.numbers("plan_z", Bounds::any(), false);
        if (body.plan_x.size() != body.plan_z.size() || body.plan_x.size() < 3)
          b.fail("plan_z", "plan_x and plan_z need the same number (>= 3) of vertices");
        if (const std::string why = polygon_defect(body.plan_x, body.plan_z); !why.empty()) b.fail("plan_x", "the plan " + why);
      }
    } else if (b.has("polygon_x") || b.has("polygon_y")) {
      if (D != 2) b.fail("polygon_x", "polygons need grid.dim = 2");
      body.poly_x = b.numbers("polygon_x", Bounds::any(), false);
      body.poly_y = b.numbers("polygon_y", Bounds::any(), false);
      if (body.poly_x.size() != body.poly_y.size() || body.poly_x.size() < 3)
        b.fail("polygon_y", "polygon_x and polygon_y need the same number (>= 3) of vertices");
      if (const std::string why = polygon_defect(body.poly_x, body.poly_y); !why.empty()) b.fail("polygon_x", "the polygon " + why);
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
    if (D != 2) b->fail(b->has("file") ? "file" : "x", "an inclined base needs grid.dim = 2 (3D scenes: [terrain])");
    sc.lines["base"] = b->line();
    mpm::BaseLine base;
    if (b->has("file")) {  // a profile: CSV columns x and y
      if (b->has("x") || b->has("y")) b->fail("file", "give either file (a profile) or x and y, not both");
      base.file = beside(path, b->string("file"));
      try {
        const CsvColumns t = read_csv_columns(base.file, {"x", "y"});
        if (t.rows() < 2) throw InputError(where(base.file) + "a profile needs at least two points");
        require_strictly_increasing(t, "x");
        base.x = t.column("x");
        base.y = t.column("y");
      } catch (const InputError& e) {
        b->fail("file", e.what());
      }
    } else {
      base.x = increasing(*b, "x");
      base.y = b->numbers("y", Bounds::any(), false);
      if (base.y.size() != base.x.size()) b->fail("y", "needs as many points as base.x");
    }
    if (b->has("mu")) base.mu = b->number("mu", Bounds::non_negative());  // absent: no-slip
    b->finish();
    sc.base = base;
  }

  if (auto t = root.optional_table("terrain")) {
    if (D != 3)
      t->fail("file", "terrain needs grid.dim = 3; a 2D scene takes its ground as [base] (x and y, or file = a "
                      "profile CSV)");
    sc.lines["terrain"] = t->line();
    for (const char* k : {"file", "origin", "mu", "contact"}) note(*t, k);
    mpm::Terrain terrain;
    terrain.file = t->string("file");
    terrain.origin = vec(*t, "origin", 3);
    if (t->has("mu")) terrain.mu = t->number("mu", Bounds::non_negative());  // absent: no-slip
    terrain.contact = t->choice("contact", {"support", "nodes"}, "support") == "nodes" ? mpm::Terrain::Contact::Nodes
                                                                                    : mpm::Terrain::Contact::Support;
    try {
      terrain.raster = std::make_shared<const io::Raster>(read_raster(beside(path, terrain.file)));
    } catch (const InputError& e) {
      t->fail("file", e.what());
    }
    t->finish();
    sc.terrain = terrain;
  }

  auto stages = root.array_of_tables("stage");
  if (stages.empty()) root.fail("stage", "at least one [[stage]] with a duration is required");
  for (auto& s : stages) {
    mpm::Stage st;
    st.name = s.string_or("name", "");
    // the stage frame's file name is frame_NNNN_<name>.vtu: refused here, not at the stage's end
    if (st.name.size() > 200) s.fail("name", "is " + std::to_string(st.name.size()) + " bytes long; a stage name names a frame file and may have at most 200");
    for (const char c : st.name)
      if (c == '/' || c == '\\' || static_cast<unsigned char>(c) < 0x20)
        s.fail("name", "names the stage's frame file (frame_NNNN_<name>.vtu) and may not hold '/', '\\' or control characters");
    st.duration = s.number("duration", Bounds::positive());
    st.damping = s.number_or("damping", 0, Bounds{0.0, 1.0, false, true});
    if (s.has("flip")) st.flip = s.number("flip", Bounds::closed(0, 1));
    if (auto g = s.optional_table("gate")) {
      mpm::Gate gate;
      gate.point = vec(*g, "point", D);
      gate.normal_only = g->choice("hold", {"normal", "all"}, "normal") == "normal";
      gate.lift_speed = g->number_or("lift_speed", 0.0, Bounds::positive());
      if (g->has("radius")) {  // a vertical cylinder about point: no normal
        if (D != 3) g->fail("radius", "a cylindrical gate needs a 3D scene (grid.dim = 3)");
        gate.radius = g->number("radius", Bounds::positive());
        if (g->has("normal")) g->fail("normal", "a cylindrical gate (radius) has no normal: its axis is vertical through point");
        note(*g, "radius");
      } else {
        gate.normal = vec(*g, "normal", D);
        int nz = 0;
        for (double c : gate.normal) nz += c != 0;
        if (nz == 0) g->fail("normal", "must not be zero");
        if (gate.normal_only && nz != 1)
          g->fail("hold", "\"normal\" needs an axis-aligned normal; use \"all\" for an inclined gate");
        if (gate.lift_speed > 0 && gate.normal[1] != 0)
          g->fail("lift_speed", "a gate is lifted along y: its normal must have no y component (a vertical gate)");
      }
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

  for (auto& o : root.array_of_tables("obstacle")) {
    mpm::Obstacle ob;
    ob.key = o.dotted("kind");
    ob.key = ob.key.substr(0, ob.key.rfind('.'));
    sc.lines[ob.key] = o.line();
    const std::string kinds = D == 2 ? "box, segment or polygon (2D)" : "box, cylinder or mesh (3D)";
    if (!o.has("kind")) o.fail("kind", "required: " + kinds);
    ob.kind = o.string("kind");
    const bool known2 = ob.kind == "box" || ob.kind == "segment" || ob.kind == "polygon";
    const bool known3 = ob.kind == "box" || ob.kind == "cylinder" || ob.kind == "mesh";
    if (D == 2 ? !known2 : !known3)
      o.fail("kind", "\"" + ob.kind + "\" " + ((D == 2 ? known3 : known2) ? "needs grid.dim = " + std::to_string(5 - D)
                                                                    : std::string("is not an obstacle kind")) +
                          "; a " + std::to_string(D) + "D scene takes " + kinds);
    ob.name = o.string_or("name", ob.key);
    for (const auto& other : sc.obstacles)
      if (other.name == ob.name) o.fail("name", "a second obstacle named '" + ob.name + "'");
    for (const char* k : {"kind", "name", "mu", "min", "max", "from", "to", "thickness", "x", "y", "center", "radius",
                          "mesh", "scale", "rotation", "offset"})
      note(o, k);
    if (ob.kind == "box") {
      const std::vector<double> lo = vec(o, "min", D), hi = vec(o, "max", D);
      for (int d = 0; d < D; ++d)
        if (!(hi[d] > lo[d])) o.fail("max", "must exceed min in every component");
      if (D == 2) {  // counter-clockwise from the lower left corner: faces y-, x+, y+, x-
        ob.poly_x = {lo[0], hi[0], hi[0], lo[0]};
        ob.poly_y = {lo[1], lo[1], hi[1], hi[1]};
      } else {
        ob.shape = mpm::Obstacle::Shape::Box;
        ob.box_min = lo;
        ob.box_max = hi;
      }
    } else if (ob.kind == "segment") {  // a wall of some thickness about the line from -> to
      const std::vector<double> a = vec(o, "from", 2), b = vec(o, "to", 2);
      const double t = o.number("thickness", Bounds::positive());
      const double dx = b[0] - a[0], dy = b[1] - a[1], len = std::hypot(dx, dy);
      if (!(len > 0)) o.fail("to", "must differ from 'from'");
      const double nx = -dy / len * t / 2, ny = dx / len * t / 2;  // half the thickness, to the left
      ob.poly_x = {a[0] - nx, b[0] - nx, b[0] + nx, a[0] + nx};
      ob.poly_y = {a[1] - ny, b[1] - ny, b[1] + ny, a[1] + ny};
    } else if (ob.kind == "polygon") {
      ob.poly_x = o.numbers("x", Bounds::any(), false);
      ob.poly_y = o.numbers("y", Bounds::any(), false);
      if (ob.poly_x.size() < 3) o.fail("x", "a polygon needs at least three vertices");
      if (ob.poly_y.size() != ob.poly_x.size()) o.fail("y", "needs as many vertices as x");
      if (const std::string why = polygon_defect(ob.poly_x, ob.poly_y); !why.empty()) o.fail("x", "the polygon " + why);
    } else if (ob.kind == "mesh") {  // a closed triangle mesh
      if (!o.has("mesh")) o.fail_missing("mesh", "the mesh file (STL, OBJ or PLY)");
      ob.shape = mpm::Obstacle::Shape::Mesh;
      ob.mesh = placed_mesh(o, path, D);
    } else {  // cylinder: a vertical pier
      ob.shape = mpm::Obstacle::Shape::Cylinder;
      ob.center = o.numbers("center", Bounds::any(), false);
      if (ob.center.size() != 2) o.fail("center", "needs the axis' plan position [x, z]");
      ob.radius = o.number("radius", Bounds::positive());
      const std::vector<double> y = o.numbers("y", Bounds::any(), false);
      if (y.size() != 2 || !(y[1] > y[0])) o.fail("y", "needs the pier's [bottom, top] heights, bottom below top");
      ob.y_min = y[0];
      ob.y_max = y[1];
    }
    if (o.has("mu")) ob.mu = o.number("mu", Bounds::non_negative());  // absent: no-slip
    if (o.has("moment_point")) ob.moment_point = vec(o, "moment_point", D);
    o.finish();
    sc.obstacles.push_back(ob);
  }

  for (auto& t : root.array_of_tables("track")) {
    mpm::Track tr;
    tr.name = t.string("name");
    tr.x = vec(t, "position", D);
    t.finish();
    sc.tracks.push_back(tr);
  }

  for (auto& g : root.array_of_tables("gauge")) {
    mpm::Gauge ga;
    std::string key = g.dotted("from");
    key = key.substr(0, key.rfind('.'));
    if (D != 2) g.fail("from", "gauges are 2D only (a cross-section line); a 3D scene has none");
    ga.name = g.string_or("name", key);
    for (const auto& other : sc.gauges)
      if (other.name == ga.name) g.fail("name", "a second gauge named '" + ga.name + "'");
    ga.from = vec(g, "from", 2);
    ga.to = vec(g, "to", 2);
    if (!(std::hypot(ga.to[0] - ga.from[0], ga.to[1] - ga.from[1]) > 0)) g.fail("to", "must differ from 'from'");
    for (const auto* pt : {&ga.from, &ga.to})
      for (int d = 0; d < 2; ++d)
        if ((*pt)[d] < sc.origin[d] || (*pt)[d] > sc.origin[d] + sc.size[d])
          g.fail(pt == &ga.from ? "from" : "to", "lies outside the grid");
    ga.width = g.number_or("width", sc.h, Bounds::positive());
    g.finish();
    sc.gauges.push_back(ga);
  }

  if (auto o = root.optional_table("output")) {
    if (o->has("map_cell")) note(*o, "map_cell");  // make_setup counts the map cells
    if (o->has("times")) sc.output.times = o->numbers("times", Bounds::non_negative());
    sc.output.series_dt = o->number_or("series_dt", 1e-3, Bounds::positive());
    note(*o, "series_dt");  // checked against time.dt by make_setup, after the stable step
    const std::string format = o->choice("format", {"binary", "base64", "ascii"}, "binary");
    sc.output.format = format == "base64" ? FrameFormat::Base64 : format == "ascii" ? FrameFormat::Ascii : FrameFormat::Raw;
    sc.output.frames_in_stages = o->boolean_or("stage_frames", true);
    sc.output.checkpoint_dt = o->number_or("checkpoint_dt", 0.0, Bounds::positive());
    if (o->has("fields")) {
      const auto& valid = mpm::frame_field_names();
      for (const std::string& f : o->strings("fields")) {
        if (std::find(valid.begin(), valid.end(), f) != valid.end()) {
          if (std::find(sc.output.fields.begin(), sc.output.fields.end(), f) == sc.output.fields.end())
            sc.output.fields.push_back(f);
          continue;
        }
        std::string list;
        for (const auto& v : valid) list += (list.empty() ? "" : ", ") + v;
        o->fail("fields", "unknown point array '" + f + "'; the frames can carry: " + list +
                              " (position always)");
      }
    }
    if (o->has("deposit_direction")) {
      if (D != 3 || !sc.terrain) o->fail("deposit_direction", "deposit measures need a 3D scene with [terrain]");
      const std::vector<double> d = o->numbers("deposit_direction", Bounds::any(), false);
      if (d.size() != 2 || !std::isfinite(d[0]) || !std::isfinite(d[1]) || !(std::hypot(d[0], d[1]) > 0))
        o->fail("deposit_direction", "needs a plan direction [dx, dz] of two numbers, not both zero");
      sc.output.deposit_direction = d;
    }
    if (o->has("deposit_centre")) {
      if (D != 3 || !sc.terrain) o->fail("deposit_centre", "deposit measures need a 3D scene with [terrain]");
      const std::vector<double> c = o->numbers("deposit_centre", Bounds::any(), false);
      if (c.size() != 2 || !std::isfinite(c[0]) || !std::isfinite(c[1]))
        o->fail("deposit_centre", "needs a plan position [x, z] of two finite numbers (grid coordinates, m)");
      const double x0 = sc.origin[0], z0 = sc.origin[2], x1 = x0 + sc.size[0], z1 = z0 + sc.size[2];
      if (c[0] < x0 || c[0] > x1 || c[1] < z0 || c[1] > z1) {
        std::ostringstream os;
        os << "[" << c[0] << ", " << c[1] << "] lies outside the grid's plan [" << x0 << ", " << x1 << "] x [" << z0
           << ", " << z1 << "] m";
        o->fail("deposit_centre", os.str());
      }
      sc.output.deposit_centre = c;
    }
    if (o->has("edge_thickness")) {
      if (sc.output.deposit_centre.empty()) o->fail("edge_thickness", "reads the edge about output.deposit_centre, which is not given");
      sc.output.edge_thickness = o->number("edge_thickness", Bounds::positive());
    }
    if (o->has("map_cell") && D == 2) {  // the bins of a profile along the base
      if (!sc.base) o->fail("map_cell", "maps need a 3D scene with [terrain] or a 2D one with [base]");
      sc.output.map_cell = o->number("map_cell", Bounds::positive());
    } else if (o->has("map_cell")) {
      if (!sc.terrain) o->fail("map_cell", "maps need a 3D scene with [terrain] or a 2D one with [base]");
      const double c = o->number("map_cell", Bounds::positive());
      const double cs = sc.terrain->raster->cellsize, k = std::round(c / cs);
      auto g = [](double v) {
        std::ostringstream os;
        os << v;
        return os.str();
      };
      if (k < 1 || std::abs(c - k * cs) > 1e-9 * c)
        o->fail("map_cell", "must be a whole multiple of the terrain raster's cell size " + g(cs) + " m (" +
                                sc.terrain->file + "), e.g. " + g(std::max(1.0, k) * cs));
      sc.output.map_cell = k * cs;
    }
    if (o->has("forces")) sc.output.forces = o->boolean_or("forces", true);
    if (o->has("moment_point")) sc.output.moment_point = vec(*o, "moment_point", D);
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

}  // namespace

mpm::Scene load_scene(const std::string& path, const SceneOverrides& overrides) {
  if (!std::filesystem::exists(path)) throw InputError(where(path) + "no such scene file");
  toml::table doc = TomlTable::parse_file(path);
  MaterialOverrides mo;
  mo.params = overrides.params;
  for (const std::string& a : overrides.material_params) {
    const auto eq = a.find('=');
    const std::string name = eq == std::string::npos ? "" : a.substr(0, eq);
    if (!material_name_ok(name) || eq + 1 >= a.size())
      throw InputError("--params '" + a + "': expected NAME=SET (a [[material]] name and a parameter set)");
    mo.named_params.emplace_back(name, a.substr(eq + 1));
  }
  for (const std::string& a : overrides.sets) {
    const std::string origin = "--set '" + a + "'", who = where(path) + origin + ": ";
    const auto eq = a.find('=');
    // NAME:KEY addresses the [[material]] named NAME
    const auto colon = a.find(':');
    std::string material, assignment = a;
    if (colon != std::string::npos && colon < eq) {
      material = trim(a.substr(0, colon));
      assignment = a.substr(colon + 1);
      if (!material_name_ok(material))
        throw InputError(who + "expected NAME:KEY=VALUE with a [[material]] name, e.g. weak:frictional.phi_c_deg=20");
    }
    const auto aeq = assignment.find('=');
    const std::vector<KeyPart> parts =
        aeq == std::string::npos ? std::vector<KeyPart>{} : split_key(override_key(assignment));
    if (parts.empty())
      throw InputError(who + "expected KEY=VALUE, e.g. grid.h=0.0025, stage[1].duration=0.5 or frictional.phi_c_deg=30");
    if (is_parameter_set_key(parts)) {
      mo.sets.push_back({material, assignment, a});
    } else if (!material.empty()) {  // a key of that [[material]] table
      const toml::node* m = doc.get("material");
      long index = -1;
      if (m && m->is_array_of_tables())
        for (std::size_t i = 0; i < m->as_array()->size(); ++i) {
          const toml::node* name = m->as_array()->get(i)->as_table()->get("name");
          if (name && name->value<std::string>() == material) index = static_cast<long>(i);
        }
      if (index < 0) throw InputError(who + "the scene has no [[material]] named '" + material + "'");
      if (parts.size() != 1 || parts[0].index >= 0 || parts[0].name == "name")
        throw InputError(who + "NAME:KEY takes a key of the material's table (parameters, model, rho_p, e0, T0) or of "
                               "its parameter set (frictional., collisional., initial., numerics.)");
      std::vector<KeyPart> full = {KeyPart{"material", index}, parts[0]};
      set_scene_value(doc, full, parse_value(assignment.substr(aeq + 1), origin, who), origin, who);
    } else {
      set_scene_value(doc, parts, parse_value(a.substr(eq + 1), origin, who), origin, who);
    }
  }
  Scene sc;
  try {
    sc = read_scene(doc, path, mo);
  } catch (const InputError& e) {
    const std::string msg = e.what();
    if (overrides.sets.empty() || msg.find("--set '") != std::string::npos) throw;
    throw InputError(msg + with_overrides(overrides.sets));
  }
  sc.overrides = overrides.sets;
  return sc;
}

void add_params(SceneOverrides& ov, const std::string& value) {
  const auto eq = value.find('=');
  if (eq != std::string::npos && material_name_ok(value.substr(0, eq))) {
    ov.material_params.push_back(value);
    return;
  }
  if (!ov.params.empty())
    throw InputError("--params '" + value + "': a second set for the scene's material (first: '" + ov.params +
                     "'); name materials with NAME=SET");
  ov.params = value;
}

std::optional<InputError> scene_error_at(const Scene& sc, const SceneError& e) {
  const std::string message = "'" + e.key() + "': " + (e.what() + e.key().size() + 2);
  // the --set of the key (or of the table holding it: "body[0].min" -> "body[0]"), else its line
  for (std::string k = e.key(); !k.empty();) {
    for (auto a = sc.overrides.rbegin(); a != sc.overrides.rend(); ++a)
      if (override_key(*a) == k) return InputError(where(sc.file) + "--set '" + *a + "': " + message);
    const auto it = sc.lines.find(k);
    if (it != sc.lines.end() && it->second > 0)
      return InputError(where(sc.file, it->second) + message + with_overrides(sc.overrides));
    const auto cut = k.find_last_of(".[");
    k = cut == std::string::npos ? "" : k.substr(0, cut);
  }
  return std::nullopt;
}

SceneSetup make_setup_for_file(const Scene& sc) {
  try {
    return make_setup(sc);
  } catch (const SceneError& e) {
    if (auto located = scene_error_at(sc, e)) throw *located;
    throw InputError(where(sc.file) + "'" + e.key() + "': " + (e.what() + e.key().size() + 2) +
                     with_overrides(sc.overrides));
  }
}

}  // namespace granflow::mpm
