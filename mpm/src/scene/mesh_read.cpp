// The mesh reader through assimp: the one file of granflow that includes it (compiled when
// CMake finds assimp; else mesh_read_stub.cpp).
#include <granflow/mpm/mesh.hpp>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <system_error>
#include <unordered_map>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <granflow/io/input_error.hpp>

namespace granflow::mpm {
namespace {

using io::InputError;
using io::where;

// Triangles of every mesh of the scene (all OBJ objects), node transforms applied, vertices of
// equal position welded (STL repeats them per facet; assimp's own join also compares normals).
TriMesh collect(const aiScene* s, const std::string& name) {
  TriMesh m;
  m.file = name;
  struct Key {
    float x, y, z;
    bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      std::uint32_t b[3];
      std::memcpy(b, &k, sizeof b);
      return (std::size_t(b[0]) * 73856093u) ^ (std::size_t(b[1]) * 19349663u) ^ (std::size_t(b[2]) * 83492791u);
    }
  };
  std::unordered_map<Key, std::int32_t, Hash> index;
  for (unsigned k = 0; k < s->mNumMeshes; ++k) {
    const aiMesh* me = s->mMeshes[k];
    for (unsigned f = 0; f < me->mNumFaces; ++f) {
      const aiFace& face = me->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines (assimp splits polygons)
      std::int32_t t[3];
      for (int c = 0; c < 3; ++c) {
        if (face.mIndices[c] >= me->mNumVertices) throw InputError(where(name) + "a face names a vertex it does not have");
        const aiVector3D& v = me->mVertices[face.mIndices[c]];
        if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
          throw InputError(where(name) + "vertex " + std::to_string(face.mIndices[c]) + " of mesh " + std::to_string(k) +
                           " (face " + std::to_string(f) + ") is not a finite number (NaN or infinite)");
        const Key key{v.x + 0.0f, v.y + 0.0f, v.z + 0.0f};  // + 0: -0 welds with 0
        const auto [it, fresh] = index.emplace(key, static_cast<std::int32_t>(m.xyz.size() / 3));
        if (fresh) m.xyz.insert(m.xyz.end(), {double(key.x), double(key.y), double(key.z)});
        t[c] = it->second;
      }
      if (m.tri.size() / 3 >= 0x7fffffff / 3) throw InputError(where(name) + "more than 7e8 triangles");
      m.tri.insert(m.tri.end(), t, t + 3);
    }
  }
  if (m.tri.empty()) throw InputError(where(name) + "the mesh has no triangle (an empty mesh)");
  return m;
}

// PreTransformVertices: OBJ groups and PLY/STL nodes in scene coordinates, one flat list.
constexpr unsigned kFlags = aiProcess_Triangulate | aiProcess_PreTransformVertices;

}  // namespace

bool mesh_reader_available() { return true; }

TriMesh read_mesh(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(where(path) + "is a folder, not a mesh file");
  if (!std::filesystem::exists(path, ec)) throw InputError(where(path) + "no such file");
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(where(path) + "cannot be read: " + ec.message());
  if (size > static_cast<std::uintmax_t>(kMeshMaxBytes))
    throw InputError(where(path) + "is " + std::to_string(size) + " bytes, above the limit of " +
                     std::to_string(kMeshMaxBytes) + " bytes (1 GiB) for a mesh file: simplify the mesh");
  if (size == 0) throw InputError(where(path) + "is empty (0 bytes): an empty mesh");
  Assimp::Importer imp;
  const aiScene* s = imp.ReadFile(path, kFlags);
  if (!s) throw InputError(where(path) + "cannot be read as a mesh (STL, OBJ or PLY): " + imp.GetErrorString());
  return collect(s, path);
}

TriMesh read_mesh_bytes(const void* data, std::size_t size, const std::string& format, const std::string& name) {
  if (size == 0) throw InputError(where(name) + "is empty (0 bytes): an empty mesh");
  Assimp::Importer imp;
  const aiScene* s = imp.ReadFileFromMemory(data, size, kFlags, format.c_str());
  if (!s) throw InputError(where(name) + "cannot be read as a mesh (STL, OBJ or PLY): " + imp.GetErrorString());
  return collect(s, name);
}

}  // namespace granflow::mpm
