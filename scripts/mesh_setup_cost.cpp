// Set-up cost of a mesh (issue 54): a UV sphere of about 1e6 triangles written as binary STL, read
// (assimp, welding), then make_setup of (a) a body inside it seeded with about 1e7 points and (b)
// the same sphere as an obstacle beside a box body of about 1e7 points. Wall times per phase.
//   ./mesh_setup_cost DIR [NLAT]
// Built against a build tree's libraries (here build/, a Release build of this tree with assimp):
//   g++ -O2 -std=c++17 -fopenmp -I mpm/include -I io/include -I constitutive/include -I tests/mpm \
//       -isystem /usr/include/eigen3 scripts/mesh_setup_cost.cpp build/mpm/libgranflow_mpm.a \
//       build/io/libgranflow_io.a -lassimp -ltomlplusplus -lgdal -o /tmp/mesh_setup_cost
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

#include <granflow/mpm/mesh.hpp>
#include <granflow/mpm/runner.hpp>

#include "mesh_files.hpp"

using namespace granflow::mpm;

namespace {
double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: mesh_setup_cost DIR [NLAT]\n");
    return 2;
  }
  const std::string dir = argv[1];
  const int nlat = argc > 2 ? std::atoi(argv[2]) : 708;  // 2 nlat (nlat - 1) triangles: 1.0e6
  std::filesystem::create_directories(dir);
  const double c[3] = {0.15, 0.12, 0.12}, r = 0.1;
  const std::string path = dir + "/sphere.stl";
  auto t0 = std::chrono::steady_clock::now();
  test::write_stl(path, test::sphere_mesh(c, r, nlat, nlat), true);
  std::printf("wrote %s (%ld bytes) in %.2f s\n", path.c_str(), static_cast<long>(std::filesystem::file_size(path)), since(t0));
  t0 = std::chrono::steady_clock::now();
  auto m = std::make_shared<TriMesh>(read_mesh(path));
  std::printf("read: %ld triangles, %ld vertices in %.2f s\n", m->triangles(), m->vertices(), since(t0));

  Scene sc = small_column_scene(ModelKind::Frictional);
  sc.dim = 3;
  sc.h = 0.0015;  // 8 points per cell of 0.75 mm: 1e7 in the sphere
  sc.dt = 1e-5;
  sc.origin = {0.0, 0.0, 0.0};
  sc.size = {0.51, 0.24, 0.24};
  sc.gravity = {0.0, -9.81, 0.0};
  sc.walls = {{1, false, 0.0, false, "wall[0].side"}};
  sc.tracks.clear();
  sc.runout_x = {0.0, 0.51};
  sc.runout_y = {0.0, 0.0};
  sc.output.times.clear();
  Stage st;
  st.name = "s";
  st.duration = 1e-3;
  sc.stages = {st};
  Scene body = sc;
  body.bodies = {Body{}};
  body.bodies[0].mesh = m;
  t0 = std::chrono::steady_clock::now();
  {
  const SceneSetup a = make_setup(body);
  std::printf("(a) body inside the mesh: %ld points (seeded %.6g m^3, mesh %.6g m^3, %+.3f %%), set-up %.2f s\n",
              a.particles.n, a.seeded_volume[0], a.geometric_volume[0], 100 * (a.seeded_volume[0] / a.geometric_volume[0] - 1),
              since(t0));
  }
  Scene obst = sc;
  Body box;
  box.box_min = {0.27, 0.0015, 0.0};
  box.box_max = {0.45, 0.1365, 0.24};  // 120 x 90 x 160 cells x 8: 1.4e7 points
  obst.bodies = {box};
  Obstacle o;
  o.name = "sphere";
  o.key = "obstacle[0]";
  o.kind = "mesh";
  o.shape = Obstacle::Shape::Mesh;
  o.mesh = m;
  obst.obstacles = {o};
  t0 = std::chrono::steady_clock::now();
  const SceneSetup b = make_setup(obst);
  std::printf("(b) obstacle beside a box body: %ld points, %zu held nodes, %zu probes, set-up %.2f s\n", b.particles.n,
              b.obstacle_nodes.size(), b.probes.size(), since(t0));
  return 0;
}
