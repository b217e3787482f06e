// Scene files (mpm/scenes/*.toml) -> granflow::mpm::Scene, strictly validated: unknown keys,
// missing keys, wrong types and out-of-range values are errors naming file, line and key.
#pragma once

#include <string>

#include <granflow/mpm/scene.hpp>

namespace granflow::mpm {

Scene load_scene(const std::string& path);

}  // namespace granflow::mpm
