// Scene files (mpm/scenes/*.toml) -> granflow::mpm::Scene, strictly validated: unknown keys,
// missing keys, wrong types and out-of-range values are errors naming file, line and key.
// Command-line overrides (--params, --set) pass through the same validation and errors name them.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <granflow/io/input_error.hpp>
#include <granflow/mpm/runner.hpp>
#include <granflow/mpm/scene.hpp>

namespace granflow::mpm {

// Values given on the command line over a scene file.
struct SceneOverrides {
  // A parameter set (name under data/params or a file) instead of the scene's material.parameters.
  std::string params;
  // KEY=VALUE, applied in order. KEY is routed by its first part: a table of parameter sets
  // (frictional, collisional, initial, numerics; see kParameterSetTables) changes the material's
  // parameter set (io::apply_override); any other KEY is a scene key: a dotted path such as
  // grid.h, time.adaptive or solver.precision, with [i] for an entry of an array of tables
  // (stage[1].duration, body[0].max). VALUE is a TOML value (0.0025, true, [0.6, 0.16], "x");
  // a bare word such as frictional is read as a string. NAME:KEY=VALUE addresses the
  // [[material]] named NAME: its parameter set (NAME:frictional.phi_c_deg=30) or a key of its
  // table (NAME:e0=0.8). A scene with two or more materials refuses a parameter-set KEY
  // without NAME.
  std::vector<std::string> sets;
  // NAME=SET: the parameter set of the [[material]] named NAME (--params NAME=SET).
  std::vector<std::string> material_params;
};

// The first parts of --set keys that go to the parameter set, not to the scene.
inline const char* const kParameterSetTables[] = {"frictional", "collisional", "initial", "numerics"};

// One --params value (also Python's mpm(params=...)): NAME=SET, a [[material]] name then a set,
// goes to material_params; a plain SET to params, once (a second is an InputError).
void add_params(SceneOverrides& overrides, const std::string& value);

Scene load_scene(const std::string& path, const SceneOverrides& overrides = {});

// make_setup for a scene from load_scene: its consistency errors (SceneError) become input
// errors naming the file and line of the offending key, or the --set that gave it.
SceneSetup make_setup_for_file(const Scene& scene);
// The input error naming where in the scene's file (or its --set) the key of `e` was given, or
// the table holding it; nullopt when the scene gave neither (a key of another file's making).
std::optional<io::InputError> scene_error_at(const Scene& scene, const SceneError& e);

}  // namespace granflow::mpm
