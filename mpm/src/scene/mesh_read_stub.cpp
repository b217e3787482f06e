// The mesh reader of a build without assimp: every mesh key is refused, naming the package.
#include <granflow/mpm/mesh.hpp>

#include <granflow/io/input_error.hpp>

namespace granflow::mpm {
namespace {
[[noreturn]] void refuse(const std::string& name) {
  throw io::InputError(io::where(name) + "this granflow was built without mesh reading: install libassimp-dev "
                                         "(scripts/install_deps.sh --tests) and configure again (GRANFLOW_ASSIMP)");
}
}  // namespace

bool mesh_reader_available() { return false; }
TriMesh read_mesh(const std::string& path) { refuse(path); }
TriMesh read_mesh_bytes(const void*, std::size_t, const std::string&, const std::string& name) { refuse(name); }

}  // namespace granflow::mpm
