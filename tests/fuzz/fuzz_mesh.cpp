// libFuzzer target: bytes -> the mesh readers (assimp: STL, OBJ, PLY; the first byte picks the
// format) and, where they give a mesh, the geometry's checks (closed, oriented, no crossings).
// Any exception other than io::InputError or SceneError is a bug.
#include <cstdint>
#include <string>

#include <granflow/io/input_error.hpp>
#include <granflow/mpm/mesh.hpp>

#include "scene/mesh_geometry.hpp"

using namespace granflow;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  static const char* kFormats[] = {"stl", "obj", "ply"};
  const std::string format = kFormats[data[0] % 3];
  try {
    const mpm::TriMesh m = mpm::read_mesh_bytes(data + 1, size - 1, format, "fuzz." + format);
    if (m.triangles() <= 20000) mpm::detail::MeshSolid solid(m, "body[0].mesh");
  } catch (const io::InputError&) {
  } catch (const mpm::SceneError&) {
  }
  return 0;
}
