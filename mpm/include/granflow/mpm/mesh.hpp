// Triangle meshes of bodies and obstacles (docs/mpm_meshes.md): plain data, the reader and the placement.
// Reading goes through assimp in one file (mesh_read.cpp) where the build has it; the geometry
// (checks, seeding, inside test, normals) is library-free (scene/mesh_geometry.hpp).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace granflow::mpm {

// A surface mesh: vertices (x y z each) and triangles (three vertex indices each, counter-
// clockwise seen from outside). The reader welds vertices of the same position.
struct TriMesh {
  std::string file;                // as the scene names it (messages)
  std::vector<double> xyz;         // 3 per vertex
  std::vector<std::int32_t> tri;   // 3 per triangle
  long vertices() const { return static_cast<long>(xyz.size() / 3); }
  long triangles() const { return static_cast<long>(tri.size() / 3); }
};

// Files above this size are refused before they are read.
constexpr long long kMeshMaxBytes = 1LL << 30;  // 1 GiB (a binary STL of 2e7 triangles)

// Placement: scale first, then rotation about x, then y, then z (degrees), then offset [m].
struct MeshPlacement {
  double scale = 1;
  std::array<double, 3> rotation{0, 0, 0};
  std::array<double, 3> offset{0, 0, 0};
};

// Whether this build reads meshes (assimp found at configure time).
bool mesh_reader_available();

// Reads an STL (binary or ASCII), OBJ (all objects merged, polygons split into triangles) or
// PLY file and welds vertices of equal position. Throws io::InputError naming the file: a
// folder, a file above kMeshMaxBytes, what assimp cannot read, no triangle, a non-finite vertex;
// without assimp, always (naming the package libassimp-dev).
TriMesh read_mesh(const std::string& path);
// The same from bytes in memory (the fuzz target); `format` is the file's extension (stl, obj, ply).
TriMesh read_mesh_bytes(const void* data, std::size_t size, const std::string& format, const std::string& name);

// Applies the placement to every vertex.
void place_mesh(TriMesh& m, const MeshPlacement& p);

}  // namespace granflow::mpm
