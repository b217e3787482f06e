// Bodies and obstacles from triangle meshes (issue 54, docs/mpm_meshes.md): the readers, seeding
// against the mesh's own volume, a box given as STL against the analytic box (bit for bit on
// the CPU twin), a faceted pier against the analytic cylinder, and the geometry's refusals.
#include <gtest/gtest.h>

#include <array>
#include <climits>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/mesh.hpp>
#include <granflow/mpm/runner.hpp>
#include <granflow/mpm/scene_file.hpp>

#include "mesh_files.hpp"
#include "scene/mesh_geometry.hpp"
#include "tiny_column.hpp"

using namespace granflow;
using namespace granflow::mpm;
namespace fs = std::filesystem;

namespace {

std::string temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("granflow_mesh_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d.string();
}

std::shared_ptr<const TriMesh> mesh_of(const std::vector<test::Tri>& tris) {
  auto m = std::make_shared<TriMesh>();
  m->file = "in memory";
  for (const test::Tri& t : tris)
    for (int k = 0; k < 3; ++k) {
      m->xyz.insert(m->xyz.end(), {t[3 * k], t[3 * k + 1], t[3 * k + 2]});
      m->tri.push_back(static_cast<std::int32_t>(m->tri.size()));
    }
  return m;  // unwelded: make_setup refuses it as open, so the tests weld through the reader
}

std::shared_ptr<const TriMesh> read(const std::string& path) { return std::make_shared<TriMesh>(read_mesh(path)); }

// A frictional block in a 40 x 40 x 40 cm grid of 1 cm, 8 points per cell, no walls.
Scene open_3d() {
  Scene sc = test::tiny_column(ModelKind::Frictional);
  sc.dim = 3;
  sc.h = 0.01;
  sc.ppc_axis = 2;
  sc.dt = 1e-4;
  sc.origin = {0.0, 0.0, 0.0};
  sc.size = {0.4, 0.4, 0.4};
  sc.gravity = {0.0, -9.81, 0.0};
  sc.walls.clear();
  sc.tracks.clear();
  sc.runout_x = {0.0, 0.4};
  sc.runout_y = {0.0, 0.0};
  sc.output.times.clear();
  test::one_open_stage(sc, "fall", 0.001, 0.0);
  return sc;
}

std::string setup_error(const Scene& sc) {
  try {
    make_setup(sc);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// A sphere of 10 cells' radius (off the lattice's symmetry) and a cube, as ASCII and binary STL
// (and the cube as OBJ and PLY): at 8 points per cell the seeded volume is within 1 % of the
// mesh's own volume and the points' centre within h / 10 of the solid's. The cube's faces lie on
// planes between lattice points (a face between them would move by up to half a spacing).
TEST(MpmMesh, SphereAndCubeSeedTheirOwnVolumeAndCentre) {
  if (!mesh_reader_available()) GTEST_SKIP() << "built without assimp";
  const std::string dir = temp_dir("seed");
  const double c[3] = {0.2013, 0.1987, 0.2041}, lo[3] = {0.125, 0.08, 0.15}, hi[3] = {0.275, 0.2, 0.31};
  struct Shape {
    std::string name;
    std::vector<test::Tri> tris;
    double centre[3];
  };
  std::vector<Shape> shapes = {{"sphere", test::sphere_mesh(c, 0.1, 48, 96), {c[0], c[1], c[2]}},
                               {"cube", test::box_mesh(lo, hi), {(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2}}};
  for (const Shape& s : shapes)
    for (const std::string fmt : {"ascii.stl", "binary.stl", "obj", "ply"}) {
      if (s.name == "sphere" && (fmt == "obj" || fmt == "ply")) continue;
      const std::string path = dir + "/" + s.name + "." + fmt;
      if (fmt == "obj") test::write_obj(path, s.tris);
      else if (fmt == "ply") test::write_ply(path, s.tris);
      else test::write_stl(path, s.tris, fmt == "binary.stl");
      Scene sc = open_3d();
      sc.bodies[0] = Body{};
      sc.bodies[0].mesh = read(path);
      EXPECT_EQ(sc.bodies[0].mesh->triangles(), static_cast<long>(s.tris.size())) << path;
      const SceneSetup su = make_setup(sc);
      const double seeded = su.seeded_volume.at(0), own = su.geometric_volume.at(0);
      const long n = su.particles.n;
      double m[3] = {0, 0, 0};
      for (long i = 0; i < n; ++i)
        for (int d = 0; d < 3; ++d) m[d] += su.particles.x[d * n + i] / double(n);
      const double off = std::hypot(m[0] - s.centre[0], m[1] - s.centre[1], m[2] - s.centre[2]);
      std::printf("%-16s %8ld points: seeded %.6e m^3, mesh %.6e m^3 (%+.3f %%), centre off by %.3f h\n",
                  (s.name + "." + fmt).c_str(), n, seeded, own, 100 * (seeded / own - 1), off / sc.h);
      EXPECT_NEAR(seeded, own, 0.01 * own) << path;
      EXPECT_LT(off, sc.h / 10) << path;
      if (s.name == "cube") {  // the mesh's own volume is the box's
        const double v = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
        EXPECT_NEAR(own, v, 1e-6 * v);
      } else {  // a sphere's, less what the facets cut off
        const double v = 4.0 / 3.0 * M_PI * 1e-3;
        EXPECT_LT(own, v);
        EXPECT_GT(own, 0.995 * v);
      }
    }
}

// Placement: scale, then rotation about x, y, z (in that order), then offset.
TEST(MpmMesh, PlacementScalesThenRotatesXYZThenOffsets) {
  TriMesh m;
  m.xyz = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  m.tri = {0, 1, 2};
  MeshPlacement p;
  p.scale = 2;
  p.rotation = {90, 90, 0};  // x about x: (1,0,0); then about y: (0,0,-1)
  p.offset = {10, 20, 30};
  place_mesh(m, p);
  const double e = 1e-12;
  EXPECT_NEAR(m.xyz[0], 10, e);
  EXPECT_NEAR(m.xyz[1], 20, e);
  EXPECT_NEAR(m.xyz[2], 28, e);  // (2,0,0) -> x: (2,0,0) -> y: (0,0,-2)
  EXPECT_NEAR(m.xyz[3], 12, e);  // (0,2,0) -> x: (0,0,2) -> y: (2,0,0)
  EXPECT_NEAR(m.xyz[4], 20, e);
  EXPECT_NEAR(m.xyz[5], 30, e);
  EXPECT_NEAR(m.xyz[6], 10, e);  // (0,0,2) -> x: (0,-2,0) -> y: (0,-2,0)
  EXPECT_NEAR(m.xyz[7], 18, e);
  EXPECT_NEAR(m.xyz[8], 30, e);
}

namespace {

// mpm_cuda_check's 3D slab (the CI column 8 cm wide between free-slip side walls, released at
// once) with one obstacle.
Scene slab(const Obstacle& ob, double duration) {
  Scene sc = slab_3d_scene(ModelKind::Frictional, ShapeKind::Linear, duration);
  sc.obstacles = {ob};
  return sc;
}

RunSummary run_cpu(const SceneSetup& su) {
  RunOptions opt;
  opt.progress = false;
  auto r = make_cpu_runner(su);
  RunSummary s = run(su, *r, opt);
  EXPECT_TRUE(s.ok) << s.message;
  return s;
}

}  // namespace

// The low box of mpm_cuda_check's slab as an STL of 12 triangles with float32-exact corners:
// the same held nodes, normals, probes and parts as the analytic box, and the same forces and
// final points, bit for bit on the CPU twin.
TEST(MpmMesh, BoxFromStlMatchesTheAnalyticBoxBitForBit) {
  if (!mesh_reader_available()) GTEST_SKIP() << "built without assimp";
  const double lo[3] = {0.203125, 0.0, 0.0}, hi[3] = {0.234375, 0.03125, 0.046875};  // float32-exact, off the nodes
  const std::string path = temp_dir("box") + "/box.stl";
  test::write_stl(path, test::box_mesh(lo, hi), true);
  Obstacle box;
  box.name = "low box";
  box.key = "obstacle[0]";
  box.kind = "box";
  box.shape = Obstacle::Shape::Box;
  box.box_min = {lo[0], lo[1], lo[2]};
  box.box_max = {hi[0], hi[1], hi[2]};
  box.moment_point = {0.22, 0.01, 0.02};  // the mesh's default is its volume centroid
  Obstacle mesh = box;
  mesh.kind = "mesh";
  mesh.shape = Obstacle::Shape::Mesh;
  mesh.mesh = read(path);
  const SceneSetup a = make_setup(slab(box, 0.05)), b = make_setup(slab(mesh, 0.05));
  ASSERT_EQ(a.obstacle_nodes.size(), b.obstacle_nodes.size());
  ASSERT_EQ(a.obstacle_nodes.size(), 3u * 4u * 5u);
  for (size_t i = 0; i < a.obstacle_nodes.size(); ++i) {
    ASSERT_EQ(a.obstacle_nodes[i].node, b.obstacle_nodes[i].node) << i;
    for (int d = 0; d < 3; ++d) ASSERT_EQ(a.obstacle_nodes[i].n[d], b.obstacle_nodes[i].n[d]) << "node " << a.obstacle_nodes[i].node;
  }
  ASSERT_EQ(a.force_parts.size(), b.force_parts.size());
  for (size_t p = 0; p < a.force_parts.size(); ++p) {
    EXPECT_EQ(a.force_parts[p].name, b.force_parts[p].name);
    EXPECT_EQ(a.force_parts[p].count, b.force_parts[p].count) << a.force_parts[p].name;
  }
  ASSERT_EQ(a.probes.size(), b.probes.size());
  for (size_t i = 0; i < a.probes.size(); ++i) {
    ASSERT_EQ(a.probes[i].node, b.probes[i].node);
    ASSERT_EQ(a.probes[i].part, b.probes[i].part);
    for (int d = 0; d < 3; ++d) ASSERT_EQ(a.probes[i].n[d], b.probes[i].n[d]);
  }
  const RunSummary ra = run_cpu(a), rb = run_cpu(b);
  ASSERT_EQ(ra.forces.size(), rb.forces.size());
  ASSERT_EQ(ra.forces[0].boundary, "low box");
  EXPECT_GT(ra.forces[0].impulse, 0.0) << "the flow reaches the box";
  std::printf("low box: impulse %.9g N s analytic, %.9g N s from STL; peak %.9g N, %.9g N\n", ra.forces[0].impulse,
              rb.forces[0].impulse, ra.forces[0].peak, rb.forces[0].peak);
  for (size_t i = 0; i < ra.forces.size(); ++i) {
    EXPECT_EQ(ra.forces[i].impulse, rb.forces[i].impulse) << ra.forces[i].boundary;
    EXPECT_EQ(ra.forces[i].peak, rb.forces[i].peak) << ra.forces[i].boundary;
    EXPECT_EQ(ra.forces[i].step_peak, rb.forces[i].step_peak) << ra.forces[i].boundary;
  }
  ASSERT_EQ(ra.force_rows.size(), rb.force_rows.size());
  for (size_t i = 0; i < ra.force_rows.size(); ++i)
    for (int d = 0; d < 3; ++d) {
      ASSERT_EQ(ra.force_rows[i].sums.impulse[d], rb.force_rows[i].sums.impulse[d]) << "row " << i;
      ASSERT_EQ(ra.force_rows[i].sums.moment[d], rb.force_rows[i].sums.moment[d]) << "row " << i;
    }
  EXPECT_EQ(ra.final.runout, rb.final.runout);
}

// A pier of 2.5 cells' radius as an STL prism of 64 facets (vertices at the radius of equal area),
// mu 0.3, in the slab's first 0.05 s: the same held nodes, and its impulse within 2 % of the
// analytic cylinder's (the facets' normals differ from the radial ones by up to 2.8 degrees).
TEST(MpmMesh, PierOf64FacetsTakesTheCylindersImpulse) {
  if (!mesh_reader_available()) GTEST_SKIP() << "built without assimp";
  const double r = 0.025, cx = 0.23, cz = 0.04, y1 = 0.0625;  // y1 float32-exact: STL stores floats
  const int n = 64;
  const double rv = r * std::sqrt(2 * M_PI / (n * std::sin(2 * M_PI / n)));
  const std::string path = temp_dir("pier") + "/pier.stl";
  test::write_stl(path, test::cylinder_mesh(cx, cz, rv, 0.0, y1, n), false);
  Obstacle cyl = pier_obstacle("pier", "obstacle[0]", {cx, cz}, r, 0.0, y1);
  cyl.mu = 0.3;
  Obstacle mesh;
  mesh.name = "pier";
  mesh.key = "obstacle[0]";
  mesh.kind = "mesh";
  mesh.shape = Obstacle::Shape::Mesh;
  mesh.mesh = read(path);
  mesh.mu = 0.3;
  const SceneSetup a = make_setup(slab(cyl, 0.05)), b = make_setup(slab(mesh, 0.05));
  const RunSummary ra = run_cpu(a), rb = run_cpu(b);
  ASSERT_EQ(ra.forces.at(0).boundary, "pier");
  ASSERT_EQ(rb.forces.at(0).boundary, "pier");
  const double Ia = ra.forces[0].impulse, Ib = rb.forces[0].impulse;
  std::printf("pier: %zu / %zu held nodes; impulse %.6g N s (cylinder), %.6g N s (64 facets), %+.3f %%\n",
              a.obstacle_nodes.size(), b.obstacle_nodes.size(), Ia, Ib, 100 * (Ib / Ia - 1));
  EXPECT_GT(Ia, 0.0) << "the flow reaches the pier";
  EXPECT_EQ(a.obstacle_nodes.size(), b.obstacle_nodes.size());
  EXPECT_NEAR(Ib, Ia, 0.02 * Ia);
}

// What the geometry refuses at set-up, with the count and the first bad place.
TEST(MpmMesh, BadMeshesAreRefusedAtSetUp) {
  if (!mesh_reader_available()) GTEST_SKIP() << "built without assimp";
  const std::string dir = temp_dir("bad");
  const double lo[3] = {0.1, 0.1, 0.1}, hi[3] = {0.2, 0.2, 0.2};
  auto body_error = [&](const std::vector<test::Tri>& tris, const std::string& name) {
    const std::string path = dir + "/" + name + ".stl";
    test::write_stl(path, tris, true);
    Scene sc = open_3d();
    sc.bodies[0] = Body{};
    try {
      sc.bodies[0].mesh = read(path);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return setup_error(sc);
  };
  std::vector<test::Tri> box = test::box_mesh(lo, hi);
  std::vector<test::Tri> open(box.begin(), box.end() - 1);
  std::string e = body_error(open, "open");
  EXPECT_EQ(e.find("body[0].mesh: " + dir + "/open.stl: "), 0u) << e;  // the key, the file
  EXPECT_NE(e.find("is not closed: 3 bad edges"), std::string::npos) << e;
  EXPECT_NE(e.find("from ("), std::string::npos) << e;
  std::vector<test::Tri> flipped = box;
  std::swap(flipped[3][0], flipped[3][3]), std::swap(flipped[3][1], flipped[3][4]), std::swap(flipped[3][2], flipped[3][5]);
  e = body_error(flipped, "flipped");
  EXPECT_NE(e.find("is not consistently oriented: 3 bad edges"), std::string::npos) << e;
  std::vector<test::Tri> two = box;
  const double lo2[3] = {0.15, 0.15, 0.15}, hi2[3] = {0.25, 0.25, 0.25};
  for (const test::Tri& t : test::box_mesh(lo2, hi2)) two.push_back(t);
  e = body_error(two, "crossing");
  EXPECT_NE(e.find("is self-intersecting"), std::string::npos) << e;
  EXPECT_NE(e.find("pairs of triangles cross"), std::string::npos) << e;
  std::vector<test::Tri> flat;
  for (test::Tri t : box) {
    for (int k = 0; k < 3; ++k) t[3 * k + 1] = t[3 * k + 2] = 0.1;  // every triangle squashed onto a line
    flat.push_back(t);
  }
  e = body_error(flat, "flat");
  EXPECT_TRUE(e.find("degenerate") != std::string::npos || e.find("no triangle") != std::string::npos) << e;
  std::vector<test::Tri> nan = box;
  nan[5][4] = std::nan("");
  e = body_error(nan, "nan");
  EXPECT_NE(e.find("not a finite number"), std::string::npos) << e;
  // out of the grid; a mesh in millimetres gets the hint
  std::vector<test::Tri> far = box;
  for (test::Tri& t : far) t[0] += 0.35, t[3] += 0.35, t[6] += 0.35;
  e = body_error(far, "far");
  EXPECT_NE(e.find("lies outside the grid"), std::string::npos) << e;
  std::vector<test::Tri> mm = box;
  for (test::Tri& t : mm)
    for (double& v : t) v *= 1000;
  e = body_error(mm, "mm");
  EXPECT_NE(e.find("scale = 0.001"), std::string::npos) << e;
  // a folder, an empty file, a file above the limit (sparse)
  for (const std::string& p : {dir, dir + "/empty.stl", dir + "/huge.stl"}) {
    if (p != dir) {
      std::ofstream(p).close();
      if (p.find("huge") != std::string::npos) fs::resize_file(p, static_cast<std::uintmax_t>(kMeshMaxBytes) + 1);
    }
    try {
      read_mesh(p);
      ADD_FAILURE() << p << " was read";
    } catch (const std::exception& x) {
      const std::string m = x.what();
      EXPECT_NE(m.find(p), std::string::npos) << m;
      EXPECT_TRUE(m.find("is a folder") != std::string::npos || m.find("empty mesh") != std::string::npos ||
                  m.find("above the limit of 1073741824 bytes") != std::string::npos)
          << m;
    }
  }
}

// Self-intersections without a transversal crossing: a box set on another, the lower's top and
// the upper's bottom coplanar and overlapping, the footprint inside one of the lower top's two
// triangles (no edge of the lower passes under the upper's sides), and a tetrahedron standing on
// that top from one of its corners (the overlapping triangles share that vertex): both are
// refused, with the place on the common plane; the boxes a hair apart, and the lower box alone,
// are accepted.
TEST(MpmMesh, SurfacesLyingOnThemselvesAreSelfIntersecting) {
  if (!mesh_reader_available()) GTEST_SKIP() << "built without assimp";
  const std::string dir = temp_dir("touching");
  auto error_of = [&](const std::vector<test::Tri>& tris, const std::string& name) {
    const std::string path = dir + "/" + name + ".stl";
    test::write_stl(path, tris, true);
    Scene sc = open_3d();
    sc.bodies[0] = Body{};
    sc.bodies[0].mesh = read(path);  // welds the shared corner
    return setup_error(sc);
  };
  const double lo[3] = {0.1, 0.1, 0.1}, hi[3] = {0.2, 0.2, 0.2};
  // the lower top's triangles meet on the diagonal x = z; the footprints lie where x > z
  auto stacked = [&](double x0, double x1, double z0, double z1, double gap) {
    std::vector<test::Tri> m = test::box_mesh(lo, hi);
    const double lo2[3] = {x0, 0.2 + gap, z0}, hi2[3] = {x1, 0.3, z1};
    for (const test::Tri& t : test::box_mesh(lo2, hi2)) m.push_back(t);
    return m;
  };
  std::string e = error_of(stacked(0.15, 0.19, 0.11, 0.14, 0), "inside");
  EXPECT_NE(e.find("is self-intersecting"), std::string::npos) << e;
  EXPECT_NE(e.find("of triangles cross or overlap"), std::string::npos) << e;
  EXPECT_NE(e.find(", 0.2, "), std::string::npos) << e;  // where: on the common plane y = 0.2
  // a tetrahedron standing on the lower top from its corner (0.2, 0.2, 0.1), its other base
  // vertices inside that top: only triangles sharing the corner meet (coplanar)
  const std::array<double, 3> tet[4] = {{0.2, 0.2, 0.1}, {0.17, 0.2, 0.12}, {0.19, 0.2, 0.105}, {0.19, 0.25, 0.11}};
  std::vector<test::Tri> corner = test::box_mesh(lo, hi);
  for (int f = 0; f < 4; ++f) {
    std::array<double, 3> a = tet[(f + 1) % 4], b = tet[(f + 2) % 4], c = tet[(f + 3) % 4];
    const std::array<double, 3>& opposite = tet[f];
    double n[3], ab[3], ac[3], ao[3];
    for (int d = 0; d < 3; ++d) ab[d] = b[d] - a[d], ac[d] = c[d] - a[d], ao[d] = opposite[d] - a[d];
    n[0] = ab[1] * ac[2] - ab[2] * ac[1], n[1] = ab[2] * ac[0] - ab[0] * ac[2], n[2] = ab[0] * ac[1] - ab[1] * ac[0];
    if (n[0] * ao[0] + n[1] * ao[1] + n[2] * ao[2] > 0) std::swap(b, c);  // outward
    corner.push_back({a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]});
  }
  e = error_of(corner, "corner");
  EXPECT_NE(e.find("is self-intersecting"), std::string::npos) << e;
  EXPECT_NE(e.find(", 0.2, "), std::string::npos) << e;
  EXPECT_EQ(error_of(stacked(0.15, 0.19, 0.11, 0.14, 1e-6), "apart"), "");
  EXPECT_EQ(error_of(test::box_mesh(lo, hi), "alone"), "");
}

// The coplanar-overlap test of the self-intersection check, against the separating axis theorem
// (two convex polygons' interiors are disjoint iff their projections on the normal of one of
// their edges overlap in at most a point), exact on triangles of a small integer lattice, where
// shared, touching and collinear vertices and edges are common.
TEST(MpmMesh, CoplanarTrianglesOverlapExactlyWhereTheirInteriorsMeet) {
  using P = std::array<long, 2>;
  auto orient = [](const P& a, const P& b, const P& c) { return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]); };
  auto interiors_meet = [](const P* a, const P* b) {
    for (const P* t : {a, b})
      for (int e = 0; e < 3; ++e) {
        const long nu = t[(e + 1) % 3][1] - t[e][1], nv = t[e][0] - t[(e + 1) % 3][0];
        long alo = LONG_MAX, ahi = LONG_MIN, blo = LONG_MAX, bhi = LONG_MIN;
        for (int k = 0; k < 3; ++k) {
          const long pa = nu * a[k][0] + nv * a[k][1], pb = nu * b[k][0] + nv * b[k][1];
          alo = std::min(alo, pa), ahi = std::max(ahi, pa), blo = std::min(blo, pb), bhi = std::max(bhi, pb);
        }
        if (ahi <= blo || bhi <= alo) return false;
      }
    return true;
  };
  std::mt19937 rng(54);
  std::uniform_int_distribution<long> coord(0, 3);
  int meet = 0, apart = 0;
  for (int n = 0; n < 20000; ++n) {
    P a[3], b[3];
    for (P* t : {a, b})
      do
        for (int k = 0; k < 3; ++k) t[k] = {coord(rng), coord(rng)};
      while (orient(t[0], t[1], t[2]) == 0);
    double da[3][2], db[3][2], at[2];
    for (int k = 0; k < 3; ++k) da[k][0] = a[k][0], da[k][1] = a[k][1], db[k][0] = b[k][0], db[k][1] = b[k][1];
    const double area = mpm::detail::triangle_overlap_area(da, db, at);
    const double smaller = 0.5 * std::min(std::abs(orient(a[0], a[1], a[2])), std::abs(orient(b[0], b[1], b[2])));
    const bool expected = interiors_meet(a, b);
    ASSERT_EQ(area > 1e-9 * smaller, expected) << "pair " << n << ": area " << area;
    double at2[2];
    EXPECT_NEAR(mpm::detail::triangle_overlap_area(db, da, at2), area, 1e-12);
    EXPECT_LE(area, smaller + 1e-12);
    if (expected) {
      ++meet;
      for (const P* t : {a, b}) {  // the reported point lies strictly inside both
        const double s = orient(t[0], t[1], t[2]) > 0 ? 1 : -1;
        for (int e = 0; e < 3; ++e) {
          const P &p = t[e], &q = t[(e + 1) % 3];
          EXPECT_GT(s * ((q[0] - p[0]) * (at[1] - p[1]) - (q[1] - p[1]) * (at[0] - p[0])), 1e-9) << "pair " << n;
        }
      }
    } else {
      ++apart;
    }
  }
  EXPECT_GT(meet, 2000);
  EXPECT_GT(apart, 2000);
}

// Thin plates: an inside run thinner than 2 h across a face is refused, naming where.
TEST(MpmMesh, ThinPlateObstacleIsRefusedNamingTheThinnestPlace) {
  if (!mesh_reader_available()) GTEST_SKIP() << "built without assimp";
  const std::string dir = temp_dir("thin");
  for (const double t : {0.015, 0.025}) {
    const double lo[3] = {0.2, 0.0, 0.1}, hi[3] = {0.2 + t, 0.1, 0.3};
    const std::string path = dir + "/plate.stl";
    test::write_stl(path, test::box_mesh(lo, hi), false);
    Scene sc = open_3d();
    sc.bodies[0].box_min = {0.02, 0.02, 0.02};
    sc.bodies[0].box_max = {0.1, 0.1, 0.1};
    Obstacle ob;
    ob.name = "plate";
    ob.key = "obstacle[0]";
    ob.kind = "mesh";
    ob.shape = Obstacle::Shape::Mesh;
    ob.mesh = read(path);
    sc.obstacles = {ob};
    const std::string e = setup_error(sc);
    if (t < 2 * sc.h) {
      EXPECT_NE(e.find("obstacle[0].mesh: obstacle 'plate' is 0.015 m thick along x at (0.2075"), std::string::npos) << e;
    } else {
      EXPECT_EQ(e, "");
    }
  }
}

// Unwelded triangles (as an STL lists them) are open: the reader welds, make_setup never guesses.
TEST(MpmMesh, UnweldedTrianglesAreOpen) {
  const double lo[3] = {0.1, 0.1, 0.1}, hi[3] = {0.2, 0.2, 0.2};
  Scene sc = open_3d();
  sc.bodies[0] = Body{};
  sc.bodies[0].mesh = mesh_of(test::box_mesh(lo, hi));
  EXPECT_NE(setup_error(sc).find("is not closed: 36 bad edges"), std::string::npos) << setup_error(sc);
}

// The shipped example's CI copy as a user runs it (mpm/scenes/valley_barrier_ci.toml, the barrier
// from scripts/make_slit_barrier.py): the slide reaches the STL barrier, which takes a force
// (x- the upstream faces), and the run writes the force history, the barrier's triangles and
// the maps.
TEST(MpmMesh, ValleyIntoSlitBarrierExampleCi) {
  if (!mesh_reader_available()) GTEST_SKIP() << "built without assimp";
  const Scene sc = load_scene(GRANFLOW_SOURCE_DIR "/mpm/scenes/valley_barrier_ci.toml");
  ASSERT_EQ(sc.obstacles.size(), 1u);
  ASSERT_EQ(sc.obstacles[0].mesh->triangles(), 24);  // two closed boxes
  const SceneSetup su = make_setup_for_file(sc);
  const std::string dir = temp_dir("valley_barrier");
  RunOptions opt;
  opt.progress = false;
  opt.out_dir = dir + "/run";
  auto r = make_cpu_runner(su);
  const RunSummary s = run(su, *r, opt);
  ASSERT_TRUE(s.ok) << s.message;
  ASSERT_EQ(s.forces.at(0).boundary, "slit barrier");
  std::printf("valley into the slit barrier: %ld points, barrier impulse %.4g N s, peak %.4g N at %.3g s\n",
              su.particles.n, s.forces[0].impulse, s.forces[0].peak, s.forces[0].t_peak);
  EXPECT_GT(s.forces[0].impulse, 0.0);
  double upstream = 0;  // Ix of the x- faces (the flow runs along +x into them)
  for (const ForceRow& row : s.force_rows)
    if (row.part >= 0 && su.force_parts[row.part].name == "x-" && su.force_boundaries[row.boundary] == "slit barrier")
      upstream += row.sums.impulse[0];
  EXPECT_GT(upstream, 0.0);
  for (const char* f : {"obstacle_forces.csv", "obstacles.vtu", "maps/deposit_thickness.asc", "maps/max_speed.asc"})
    EXPECT_TRUE(fs::exists(opt.out_dir + "/" + f)) << f;
}
