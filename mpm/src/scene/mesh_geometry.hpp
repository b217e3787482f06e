// A closed triangle mesh as a solid (make_setup's helper, library-free): the checks a mesh must
// pass, the crossings of axis-aligned lines (seeding, inside test, thickness), and the nearest
// face of a point (held nodes' normals). docs/mpm_meshes.md.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <granflow/mpm/mesh.hpp>
#include <granflow/mpm/scene.hpp>

namespace granflow::mpm::detail {

// Where a line along an axis crosses the surface: at t along that axis, leaving the solid
// (sign +1, the outward normal along +axis) or entering it (-1), through triangle tri.
struct MeshCrossing {
  double t;
  int sign;
  int tri;
};

class MeshSolid {
 public:
  // Checks the mesh (SceneError at `key`, naming its file): finite vertices, not every triangle
  // degenerate, every edge shared by exactly two triangles that traverse it in opposite
  // directions, no two triangles without a common vertex crossing, a volume; orients it outward.
  MeshSolid(const TriMesh& m, const std::string& key);

  double volume() const { return volume_; }
  const double* lo() const { return lo_; }
  const double* hi() const { return hi_; }
  void centroid(double* c) const;
  long triangles() const { return static_cast<long>(t_.size() / 3); }
  const std::vector<double>& vertices() const { return x_; }
  const std::vector<std::int32_t>& triangle_list() const { return t_; }
  // Part of a triangle: 2 d + (outward normal's d component > 0) for the axis d of its largest
  // component (0 x-, 1 x+, 2 y-, ..., 5 z+: an analytic box's faces).
  int part(int tri) const { return part_[tri]; }

  // Crossings of the line along axis a through (u, v) = coordinates (a + 1) % 3 and (a + 2) % 3,
  // sorted by t. Exact: snapped vertices, integer orientation, ties broken by one consistent
  // perturbation of the line, so a closed mesh gives an even count and a winding of 0 or 1.
  void crossings(int a, double u, double v, std::vector<MeshCrossing>& out) const;
  // Whether p lies inside (winding number of the line along y; points on the surface either way).
  bool inside(const double* p) const;
  // The nearest triangle of p with key <= limit: key is the distance, signed (positive into the
  // solid, from -tol) where p projects into the triangle (within tol); n the normal into the
  // solid there: the face's, else the angle-weighted pseudo-normal of the nearest edge or
  // corner. Ties go to the lower part, then the lower triangle. False when none is that near.
  bool nearest(const double* p, double tol, double limit, double& key, double* n, int& part) const;
  // For a point deep inside (no triangle within nearest's limit): the triangle of the crossing
  // of the line along y nearest to it, its normal into the solid and the distance along y.
  void deep(const double* p, double& key, double* n, int& part) const;

  // The thinnest inside run of the lines along x, y and z through the centres of the cells of a
  // grid (origin g, spacing h) that enters or leaves through a face whose normal lies nearest
  // that axis; its length (a huge number when none) and its midpoint `at`, along `axis`.
  double thinnest_run(const double* g, double h, double* at, int& axis) const;

 private:
  struct Bins2 {  // triangles by their projection along one axis
    double u0 = 0, v0 = 0, du = 1, dv = 1;
    int nu = 1, nv = 1;
    std::vector<std::int32_t> start, item;
  };
  std::string key_, file_;
  std::vector<double> x_;            // vertices
  std::vector<std::int32_t> t_;      // triangles, outward
  std::vector<double> n_;            // unit outward normal per triangle (0: degenerate)
  std::vector<double> en_, vn_;      // pseudo-normals: per triangle edge (v_e -> v_e+1), per vertex
  std::vector<std::int8_t> part_;
  std::vector<std::int64_t> q_;      // snapped vertices (exact crossings)
  double lo_[3], hi_[3], res_ = 1, volume_ = 0, extent_ = 0;
  Bins2 bins_[3];
  double g0_[3], gc_[3];             // uniform grid of triangles (nearest face, self-intersection)
  int gn_[3];
  std::vector<std::int32_t> gstart_, gitem_;

  void check_edges();
  void build_grid();
  void check_crossing_triangles() const;
  std::int64_t snap(int d, double x) const;
  double face_key(int tri, const double* p, double tol, int& feature) const;
};

// Area of the intersection of two triangles of the plane (three (u, v) vertices each, either
// orientation), by clipping a against b's three half-planes, and that intersection's centroid in
// `at`. Zero (to round-off) where they meet only on their boundaries.
double triangle_overlap_area(const double a[3][2], const double b[3][2], double at[2]);

// Refuses (at `key`) a placed mesh whose bounding box leaves the grid; one about 1000 times the
// grid's size is probably in millimetres (the message suggests scale = 0.001).
void mesh_in_grid(const MeshSolid& m, const Scene& sc, const std::string& key);

}  // namespace granflow::mpm::detail
