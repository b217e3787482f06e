// Obstacles (their nodes and normals) and the probes of the boundary forces.
#include "scene/boundaries.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "scene/mesh_geometry.hpp"
#include "scene/setup_common.hpp"

namespace granflow::mpm::detail {
namespace {

// An obstacle's solid for node and point tests: whether x lies inside or on the surface (within
// tol), and then the nearest face, its normal into the solid and its index (the part).
struct Solid {
  const Obstacle& ob;
  int dim;
  const MeshSolid* mesh;  // Shape::Mesh
  double orient = 1;  // polygons: +1 counter-clockwise, -1 clockwise (normals flip)

  double deep = 0;        // Shape::Mesh: nodes deeper than this take MeshSolid::deep's normal

  Solid(const Obstacle& o, int D, const MeshSolid* m, double h = 0) : ob(o), dim(D), mesh(m), deep(4 * h) {
    if (ob.shape == Obstacle::Shape::Polygon) {
      double a = 0;
      const size_t n = ob.poly_x.size();
      for (size_t i = 0, j = n - 1; i < n; j = i++) a += ob.poly_x[j] * ob.poly_y[i] - ob.poly_x[i] * ob.poly_y[j];
      orient = a >= 0 ? 1.0 : -1.0;
    }
  }

  int faces() const {
    switch (ob.shape) {
      case Obstacle::Shape::Polygon: return static_cast<int>(ob.poly_x.size());
      case Obstacle::Shape::Box:
      case Obstacle::Shape::Mesh: return 6;  // a mesh's triangles by their outward normal's axis and sign
      default: return 3;
    }
  }
  std::string face_name(int f) const {
    if (ob.shape == Obstacle::Shape::Box || ob.shape == Obstacle::Shape::Mesh)
      return std::string(1, static_cast<char>('x' + f / 2)) + (f % 2 ? "+" : "-");
    if (ob.shape == Obstacle::Shape::Cylinder) return f == 0 ? "side" : (f == 1 ? "bottom" : "top");
    if (ob.kind == "box") return std::vector<std::string>{"y-", "x+", "y+", "x-"}[f];
    if (ob.kind == "segment") return std::vector<std::string>{"right", "to", "left", "from"}[f];
    return "face" + std::to_string(f);
  }

  // Distance of (x, y) from polygon edge i and the edge's normal into the solid.
  double edge_distance(int i, double x, double y, double* n) const {
    const size_t m = ob.poly_x.size(), j = (i + 1) % m;
    const double x0 = ob.poly_x[i], y0 = ob.poly_y[i], dx = ob.poly_x[j] - x0, dy = ob.poly_y[j] - y0;
    const double len2 = dx * dx + dy * dy, len = std::sqrt(len2);
    const double s = std::clamp(((x - x0) * dx + (y - y0) * dy) / len2, 0.0, 1.0);
    n[0] = -orient * dy / len;
    n[1] = orient * dx / len;
    n[2] = 0;
    return std::hypot(x - (x0 + s * dx), y - (y0 + s * dy));
  }

  bool inside_polygon(double x, double y) const {
    bool in = false;
    const auto& px = ob.poly_x;
    const auto& py = ob.poly_y;
    for (size_t i = 0, j = px.size() - 1; i < px.size(); j = i++)
      if ((py[i] > y) != (py[j] > y) && x < (px[j] - px[i]) * (y - py[i]) / (py[j] - py[i]) + px[i]) in = !in;
    return in;
  }

  // depth: the distance to that face.
  bool hold(const double* x, double tol, double* n, int& face, double* depth = nullptr) const {
    double best = std::numeric_limits<double>::max();
    if (ob.shape == Obstacle::Shape::Mesh) {  // inside (winding number), or within tol of a triangle
      const bool in = mesh->inside(x);
      if (tol < 0) return in;
      // the nearest face within 4 h (beyond a stencil's reach and the force probes' 3 h): a
      // search to the middle of a large solid would visit most of its triangle grid per node
      double key = 0;
      if (!mesh->nearest(x, tol, in ? deep : tol, key, n, face)) {
        if (!in) return false;
        mesh->deep(x, key, n, face);
      }
      if (depth) *depth = key;
      return true;
    }
    if (ob.shape == Obstacle::Shape::Polygon) {
      double nn[3];
      bool near = false;
      for (int i = 0; i < faces(); ++i) {
        const double d = edge_distance(i, x[0], x[1], nn);
        if (d < best) {
          best = d;
          face = i;
          std::copy(nn, nn + 3, n);
        }
        near = near || d <= tol;
      }
      if (depth) *depth = best;
      return near || inside_polygon(x[0], x[1]);
    }
    if (ob.shape == Obstacle::Shape::Box) {
      for (int d = 0; d < 3; ++d)
        if (x[d] < ob.box_min[d] - tol || x[d] > ob.box_max[d] + tol) return false;
      for (int f = 0; f < 6; ++f) {
        const int d = f / 2;
        const double dist = f % 2 ? ob.box_max[d] - x[d] : x[d] - ob.box_min[d];
        if (dist < best) {
          best = dist;
          face = f;
          n[0] = n[1] = n[2] = 0;
          n[d] = f % 2 ? -1.0 : 1.0;  // into the box
        }
      }
      if (depth) *depth = best;
      return true;
    }
    const double rx = x[0] - ob.center[0], rz = x[2] - ob.center[1], r = std::hypot(rx, rz);
    if (r > ob.radius + tol || x[1] < ob.y_min - tol || x[1] > ob.y_max + tol) return false;
    const double side = ob.radius - r, bottom = x[1] - ob.y_min, top = ob.y_max - x[1];
    if (depth) *depth = std::min({side, bottom, top});
    n[0] = n[1] = n[2] = 0;
    if (side <= bottom && side <= top) {
      face = 0;
      n[0] = r > 0 ? -rx / r : -1.0;
      n[2] = r > 0 ? -rz / r : 0.0;
    } else if (bottom <= top) {
      face = 1;
      n[1] = 1;
    } else {
      face = 2;
      n[1] = -1;
    }
    return true;
  }

  // Narrowest width (a polygon: the smallest over its edges of the farthest vertex from the
  // edge's line, exact for convex ones) and the key that sets it.
  double thickness(std::string& key) const {
    if (ob.shape == Obstacle::Shape::Mesh) return std::numeric_limits<double>::max();  // mesh_solids' runs
    if (ob.shape == Obstacle::Shape::Box) {
      key = ob.key + ".max";
      double t = std::numeric_limits<double>::max();
      for (int d = 0; d < 3; ++d) t = std::min(t, ob.box_max[d] - ob.box_min[d]);
      return t;
    }
    if (ob.shape == Obstacle::Shape::Cylinder) {
      key = 2 * ob.radius <= ob.y_max - ob.y_min ? ob.key + ".radius" : ob.key + ".y";
      return std::min(2 * ob.radius, ob.y_max - ob.y_min);
    }
    key = ob.key + (ob.kind == "segment" ? ".thickness" : (ob.kind == "box" ? ".max" : ".x"));
    double t = std::numeric_limits<double>::max();
    const size_t m = ob.poly_x.size();
    for (size_t i = 0; i < m; ++i) {
      const size_t j = (i + 1) % m;
      const double dx = ob.poly_x[j] - ob.poly_x[i], dy = ob.poly_y[j] - ob.poly_y[i], len = std::hypot(dx, dy);
      if (!(len > 0)) continue;
      double far = 0;
      for (size_t k = 0; k < m; ++k)
        far = std::max(far, std::fabs((ob.poly_x[k] - ob.poly_x[i]) * dy - (ob.poly_y[k] - ob.poly_y[i]) * dx) / len);
      t = std::min(t, far);
    }
    return t;
  }

  // The default point of the moments: the centroid.
  void centroid(double* c) const {
    c[0] = c[1] = c[2] = 0;
    if (ob.shape == Obstacle::Shape::Mesh) {
      mesh->centroid(c);
    } else if (ob.shape == Obstacle::Shape::Box) {
      for (int d = 0; d < 3; ++d) c[d] = 0.5 * (ob.box_min[d] + ob.box_max[d]);
    } else if (ob.shape == Obstacle::Shape::Cylinder) {
      c[0] = ob.center[0];
      c[1] = 0.5 * (ob.y_min + ob.y_max);
      c[2] = ob.center[1];
    } else {
      double a = 0;
      const size_t n = ob.poly_x.size();
      for (size_t i = 0, j = n - 1; i < n; j = i++) {
        const double w = ob.poly_x[j] * ob.poly_y[i] - ob.poly_x[i] * ob.poly_y[j];
        a += w;
        c[0] += (ob.poly_x[j] + ob.poly_x[i]) * w;
        c[1] += (ob.poly_y[j] + ob.poly_y[i]) * w;
      }
      c[0] /= 3 * a;
      c[1] /= 3 * a;
    }
  }

  // Node index ranges per axis of the solid's bounding box (grown by tol).
  void node_range(const SceneSetup& su, double h, double tol, int* lo, int* hi) const {
    double bmin[3], bmax[3];
    if (ob.shape == Obstacle::Shape::Polygon) {
      bmin[0] = *std::min_element(ob.poly_x.begin(), ob.poly_x.end());
      bmax[0] = *std::max_element(ob.poly_x.begin(), ob.poly_x.end());
      bmin[1] = *std::min_element(ob.poly_y.begin(), ob.poly_y.end());
      bmax[1] = *std::max_element(ob.poly_y.begin(), ob.poly_y.end());
    } else if (ob.shape == Obstacle::Shape::Box) {
      for (int d = 0; d < 3; ++d) {
        bmin[d] = ob.box_min[d];
        bmax[d] = ob.box_max[d];
      }
    } else if (ob.shape == Obstacle::Shape::Mesh) {
      std::copy(mesh->lo(), mesh->lo() + 3, bmin);
      std::copy(mesh->hi(), mesh->hi() + 3, bmax);
    } else {
      bmin[0] = ob.center[0] - ob.radius;
      bmax[0] = ob.center[0] + ob.radius;
      bmin[1] = ob.y_min;
      bmax[1] = ob.y_max;
      bmin[2] = ob.center[1] - ob.radius;
      bmax[2] = ob.center[1] + ob.radius;
    }
    for (int d = 0; d < dim; ++d) {
      lo[d] = std::max(0, static_cast<int>(std::ceil((bmin[d] - tol - su.origin[d]) / h)));
      hi[d] = std::min(su.nodes[d] - 1, static_cast<int>(std::floor((bmax[d] + tol - su.origin[d]) / h)));
    }
  }
};

// Calls f(node, x) for every node of the index box [lo, hi].
template <class F>
void for_nodes(const SceneSetup& su, int D, const int* lo, const int* hi, double h, F&& f) {
  if (D == 2) {
    for (int j = lo[1]; j <= hi[1]; ++j)
      for (int i = lo[0]; i <= hi[0]; ++i) {
        const double x[3] = {su.origin[0] + i * h, su.origin[1] + j * h, 0.0};
        f(i + static_cast<long>(su.nodes[0]) * j, x);
      }
    return;
  }
  for (int k = lo[2]; k <= hi[2]; ++k)
    for (int j = lo[1]; j <= hi[1]; ++j)
      for (int i = lo[0]; i <= hi[0]; ++i) {
        const double x[3] = {su.origin[0] + i * h, su.origin[1] + j * h, su.origin[2] + k * h};
        f(i + static_cast<long>(su.nodes[0]) * (j + static_cast<long>(su.nodes[1]) * k), x);
      }
}

}  // namespace

ObstacleMeshes obstacle_meshes(const Scene& sc, const SceneSetup& su) {
  ObstacleMeshes out(sc.obstacles.size());
  for (size_t k = 0; k < sc.obstacles.size(); ++k) {
    const Obstacle& ob = sc.obstacles[k];
    if (ob.shape != Obstacle::Shape::Mesh) continue;
    const std::string key = ob.key + ".mesh";
    if (sc.dim != 3 || !ob.mesh) fail(key, "a mesh obstacle needs grid.dim = 3 and a mesh");
    auto m = std::make_shared<const MeshSolid>(*ob.mesh, key);
    mesh_in_grid(*m, sc, key);
    double at[3] = {0, 0, 0};
    int axis = 0;
    const double t = m->thinnest_run(su.origin.data(), sc.h, at, axis);
    if (t < 2 * sc.h * (1 - 1e-9))
      fail(key, "obstacle '" + ob.name + "' is " + fmt(t) + " m thick along " + std::string(1, char('x' + axis)) +
                    " at (" + fmt(at[0]) + ", " + fmt(at[1]) + ", " + fmt(at[2]) +
                    "), less than two grid cells (2 h = " + fmt(2 * sc.h) +
                    " m): material on both sides would share its nodes (the rule: docs/mpm_meshes.md)");
    out[k] = std::move(m);
  }
  return out;
}

// The nodes of [lo, hi] a mesh obstacle holds, in node order, the queries in parallel (each
// node's winding number and nearest face are independent; MeshSolid's scratch is thread_local).
std::vector<MeshHeldNode> mesh_held_nodes(const Solid& solid, const SceneSetup& su, int D, const int* lo, const int* hi,
                                          double h, double tol) {
  std::vector<long> nodes;
  std::vector<double> xs;
  for_nodes(su, D, lo, hi, h, [&](long I, const double* x) {
    nodes.push_back(I);
    xs.insert(xs.end(), x, x + 3);
  });
  const long n = static_cast<long>(nodes.size());
  std::vector<MeshHeldNode> rec(n);
  std::vector<char> in(n, 0);
#pragma omp parallel for schedule(dynamic, 256)
  for (long c = 0; c < n; ++c) {
    MeshHeldNode& r = rec[c];
    r.node = nodes[c];
    in[c] = solid.hold(&xs[3 * c], tol, r.n, r.part, &r.depth) ? 1 : 0;
  }
  std::vector<MeshHeldNode> out;
  for (long c = 0; c < n; ++c)
    if (in[c]) out.push_back(rec[c]);
  return out;
}

void setup_obstacles(const Scene& sc, SceneSetup& su, const ObstacleMeshes& meshes, MeshHeldNodes& held) {
  const int D = sc.dim;
  const double h = sc.h, tol = 1e-9 * h;
  const HostParticles& hp = su.particles;
  held.assign(sc.obstacles.size(), {});
  for (size_t k = 0; k < sc.obstacles.size(); ++k) {
    const Obstacle& ob = sc.obstacles[k];
    const Solid solid(ob, D, meshes.empty() ? nullptr : meshes[k].get(), h);
    std::string key;
    const double t = solid.thickness(key);
    if (t < 2 * h * (1 - 1e-9))
      fail(key, "obstacle '" + ob.name + "' is " + fmt(t) + " m thick at its narrowest, less than two grid cells (2 h = " +
                    fmt(2 * h) + " m): material on both sides would share its nodes");
    if (!ob.moment_point.empty() && static_cast<int>(ob.moment_point.size()) != D)
      fail(ob.key + ".moment_point", "needs " + std::to_string(D) + " components");
    // material inside it at the start (the first such point in point order)
    long inside = hp.n;
#pragma omp parallel for reduction(min : inside) schedule(static)
    for (long i = 0; i < hp.n; ++i) {
      double x[3] = {0, 0, 0}, n[3];
      for (int d = 0; d < D; ++d) x[d] = hp.x[d * hp.n + i];
      int face = 0;
      if (i < inside && solid.hold(x, -1e-12 * h, n, face)) inside = i;
    }
    if (inside < hp.n) {
      const long i = inside;
      double x[3] = {0, 0, 0};
      for (int d = 0; d < D; ++d) x[d] = hp.x[d * hp.n + i];
      std::string at = "(" + fmt(x[0]) + ", " + fmt(x[1]) + (D == 3 ? ", " + fmt(x[2]) : "") + ")";
      const int body = su.point_body.empty() ? 0 : su.point_body[i];
      fail(ob.key, "material point at " + at + " of body[" + std::to_string(body) + "] lies inside obstacle '" +
                       ob.name + "': move the body or the obstacle");
    }
    int lo[3] = {0, 0, 0}, hi[3] = {-1, -1, -1};
    solid.node_range(su, h, tol, lo, hi);
    const size_t before = su.obstacle_nodes.size();
    auto add = [&](long I, const double* n) {
      ObstacleNode o;
      o.node = I;
      std::copy(n, n + 3, o.n);
      o.mu = ob.mu ? *ob.mu : -1.0;
      su.obstacle_nodes.push_back(o);
    };
    if (ob.shape == Obstacle::Shape::Mesh) {
      held[k] = mesh_held_nodes(solid, su, D, lo, hi, h, tol);
      for (const MeshHeldNode& r : held[k]) add(r.node, r.n);
    } else {
      for_nodes(su, D, lo, hi, h, [&](long I, const double* x) {
        double n[3];
        int face = 0;
        if (solid.hold(x, tol, n, face)) add(I, n);
      });
    }
    if (su.obstacle_nodes.size() == before)
      fail(ob.key, "obstacle '" + ob.name + "' holds no grid node: it lies outside the grid (grid.origin, grid.size)");
  }
  std::stable_sort(su.obstacle_nodes.begin(), su.obstacle_nodes.end(),
                   [](const ObstacleNode& a, const ObstacleNode& b) { return a.node < b.node; });
}

void setup_force_probes(const Scene& sc, SceneSetup& su, const std::vector<TerrainNode>& ground,
                        const ObstacleMeshes& meshes, const MeshHeldNodes& held) {
  const int D = sc.dim;
  const double h = sc.h, tol = 1e-9 * h;
  if (!sc.output.moment_point.empty() && static_cast<int>(sc.output.moment_point.size()) != D)
    fail("output.moment_point", "needs " + std::to_string(D) + " components");
  double about[3] = {0, 0, 0};
  for (size_t d = 0; d < sc.output.moment_point.size(); ++d) about[d] = sc.output.moment_point[d];

  // Parts in this order: each obstacle's faces, the walls, the base, the terrain.
  struct Owner {
    int part = -1;
    double n[3] = {0, 0, 0};
  };
  std::vector<Owner> owner(su.n_nodes);
  // Only nodes material can reach carry mass: a stencil reaches 1.5 h per axis, and under a
  // slope a node that far aside lies up to as much again below the surface. Deeper nodes are
  // held but never measured (their dp is zero): 3 h.
  const double reach = 3 * h;
  auto add_part = [&](const std::string& boundary, const std::string& name, const double* point) {
    if (su.force_boundaries.empty() || su.force_boundaries.back() != boundary) su.force_boundaries.push_back(boundary);
    ForcePart p;
    p.boundary = static_cast<int>(su.force_boundaries.size()) - 1;
    p.name = name;
    std::copy(point, point + 3, p.moment_point);
    su.force_parts.push_back(p);
    return static_cast<int>(su.force_parts.size()) - 1;
  };
  auto claim = [&](long I, int part, const double* n) {
    if (owner[I].part >= 0) return;
    owner[I].part = part;
    std::copy(n, n + 3, owner[I].n);
  };
  const int lo[3] = {0, 0, 0};
  int hi[3] = {0, 0, 0};
  for (int d = 0; d < D; ++d) hi[d] = su.nodes[d] - 1;
  for (size_t k = 0; k < sc.obstacles.size(); ++k) {
    const Obstacle& ob = sc.obstacles[k];
    const Solid solid(ob, D, meshes.empty() ? nullptr : meshes[k].get(), h);
    double point[3] = {0, 0, 0};
    solid.centroid(point);
    for (size_t d = 0; d < ob.moment_point.size(); ++d) point[d] = ob.moment_point[d];
    const int first = static_cast<int>(su.force_parts.size());
    for (int f = 0; f < solid.faces(); ++f) add_part(ob.name, solid.face_name(f), point);
    if (ob.shape == Obstacle::Shape::Mesh && k < held.size()) {  // setup_obstacles' nodes
      for (const MeshHeldNode& r : held[k])
        if (r.depth <= reach) claim(r.node, first + r.part, r.n);
      continue;
    }
    int nlo[3] = {0, 0, 0}, nhi[3] = {-1, -1, -1};
    solid.node_range(su, h, tol, nlo, nhi);
    for_nodes(su, D, nlo, nhi, h, [&](long I, const double* x) {
      double n[3];
      int face = 0;
      double depth = 0;
      if (solid.hold(x, tol, n, face, &depth) && depth <= reach) claim(I, first + face, n);
    });
  }
  for (size_t w = 0; w < sc.walls.size(); ++w) {
    const Wall& wall = sc.walls[w];
    const std::string side = std::string(1, static_cast<char>('x' + wall.axis)) + (wall.at_max ? "+" : "-");
    const int part = add_part("wall[" + std::to_string(w) + "]", side, about);
    double n[3] = {0, 0, 0};
    n[wall.axis] = wall.at_max ? 1.0 : -1.0;
    for_nodes(su, D, lo, hi, h, [&](long I, const double* x) {
      if (beyond_wall(wall.axis, wall.at_max, wall.position, x, tol) && std::fabs(x[wall.axis] - wall.position) <= reach)
        claim(I, part, n);
    });
  }
  if (sc.base) {
    const int part = add_part("base", "base", about);
    std::vector<BaseSegment> seg;  // the contact table's segments (boundary.hpp), as contact_node reads them
    for (size_t i = 1; i < sc.base->x.size(); ++i)
      seg.push_back({sc.base->x[i - 1], sc.base->y[i - 1], sc.base->x[i], sc.base->y[i]});
    const int ns = static_cast<int>(seg.size());
    for_nodes(su, D, lo, hi, h, [&](long I, const double* x) {
      const int i = base_segment_at(seg.data(), ns, x[0]);
      const double y = base_height(seg.data(), ns, i, x[0]);
      if (x[1] > y + tol || x[1] < y - reach) return;
      double n[3] = {0, -1, 0};  // level beyond the ends; else the segment's normal into the base
      if (i >= 0 && i < ns) {
        const double dx = seg[i].x1 - seg[i].x0, dy = seg[i].y1 - seg[i].y0, len = std::hypot(dx, dy);
        n[0] = dy / len;
        n[1] = -dx / len;
      }
      claim(I, part, n);
    });
  }
  if (!ground.empty()) {
    const int part = add_part("terrain", "ground", about);
    for (const TerrainNode& g : ground) claim(g.node, part, g.n);
  }
  // probes grouped by part, each part's in node order
  std::vector<long> count(su.force_parts.size() + 1, 0);
  for (long I = 0; I < su.n_nodes; ++I)
    if (owner[I].part >= 0) ++count[owner[I].part + 1];
  for (size_t p = 0; p < su.force_parts.size(); ++p) {
    su.force_parts[p].first = count[p];
    su.force_parts[p].count = count[p + 1];
    count[p + 1] += count[p];
  }
  su.probes.resize(count.back());
  std::vector<long> fill(count.begin(), count.end() - 1);
  for (long I = 0; I < su.n_nodes; ++I) {
    const int p = owner[I].part;
    if (p < 0) continue;
    ForceProbe& pr = su.probes[fill[p]++];
    pr.node = I;
    pr.part = p;
    std::copy(owner[I].n, owner[I].n + 3, pr.n);
    long k = I;
    for (int d = 0; d < D; ++d) {
      pr.x[d] = su.origin[d] + static_cast<double>(k % su.nodes[d]) * h;
      k /= su.nodes[d];
    }
  }
}

}  // namespace granflow::mpm::detail
