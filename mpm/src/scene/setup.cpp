// Scene -> set-up: particle seeding, initial stress, node masks, consistency checks.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <sstream>

#include <unistd.h>

#include <granflow/io/raster.hpp>
#include <granflow/mpm/boundary.hpp>
#include <granflow/mpm/runner.hpp>

#include "scene/boundaries.hpp"

namespace granflow::mpm {
namespace {

constexpr int kPad = 3;  // grid cells added around the scene box (walls sit inside the grid)
constexpr double kMaxNodes = 4e8;

// Host memory of a run, roughly: grid fields, masks and bins per node; the packed particle
// buffer, its host copy and the per-particle work arrays.
double memory_bytes(int D, double nodes, double particles, size_t stages) {
  const double per_node = 8.0 * (1 + 4 * D) + 24 + static_cast<double>(stages);
  const double per_particle = 2 * 8.0 * (2 * D + 1 + 6 + D * D + 6 + 3) + 32;
  return nodes * per_node + particles * per_particle;
}

double physical_memory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), size = ::sysconf(_SC_PAGE_SIZE);
  return pages > 0 && size > 0 ? double(pages) * double(size) : 0.0;
}

[[noreturn]] void fail(const std::string& key, const std::string& msg) { throw SceneError(key, msg); }

bool inside_polygon(const std::vector<double>& px, const std::vector<double>& py, double x, double y) {
  bool in = false;
  for (size_t i = 0, j = px.size() - 1; i < px.size(); j = i++) {
    if ((py[i] > y) != (py[j] > y) && x < (px[j] - px[i]) * (y - py[i]) / (py[j] - py[i]) + px[i]) in = !in;
  }
  return in;
}

double polyline(const std::vector<double>& xs, const std::vector<double>& ys, double x) {
  if (x <= xs.front()) return ys.front();
  if (x >= xs.back()) return ys.back();
  for (size_t i = 1; i < xs.size(); ++i)
    if (x <= xs[i]) return ys[i - 1] + (ys[i] - ys[i - 1]) * (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
  return ys.back();
}

std::string fmt(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// Georeferenced coordinates (easting 512345.678) need more digits than fmt's six.
std::string fmt_geo(double v) {
  std::ostringstream os;
  os.precision(12);
  os << v;
  return os.str();
}

// A raster surface in scene coordinates: x, z = easting, northing minus origin[0, 1] (the
// terrain's), y = elevation minus origin[2].
class Surface {
 public:
  Surface(const io::Raster& r, const std::vector<double>& origin) : r_(r), o_(origin) {}
  double height(double x, double z) const { return r_.elevation(x + o_[0], z + o_[1]) - o_[2]; }
  // Unit normal into the ground at (x, z) from the raster's slope; returns the slope's magnitude.
  double normal(double x, double z, double n[3]) const {
    double de = 0, dn = 0;
    r_.slope(x + o_[0], z + o_[1], de, dn);
    const double len = std::sqrt(1 + de * de + dn * dn);
    n[0] = de / len;
    n[1] = -1 / len;
    n[2] = dn / len;
    return std::sqrt(de * de + dn * dn);
  }
  // "row R, column C of FILE (centre at easting E, northing N)"
  std::string cell(long row, long col) const {
    std::ostringstream os;
    os.precision(12);
    os << "row " << row << ", column " << col << " of " << r_.file << " (centre at easting " << r_.centre_east(col)
       << ", northing " << r_.centre_north(row) << ")";
    return os.str();
  }
  std::string cell_at(double x, double z) const { return cell(r_.row_of(z + o_[1]), r_.col_of(x + o_[0])); }
  // Empty when the raster covers x in [x0, x1], z in [z0, z1]; else what it covers and what is needed.
  std::string uncovered(double x0, double x1, double z0, double z1) const {
    const double e0 = x0 + o_[0], e1 = x1 + o_[0], n0 = z0 + o_[1], n1 = z1 + o_[1];
    const double slack = 1e-9 * r_.cellsize;
    if (e0 >= r_.west - slack && e1 <= r_.east() + slack && n0 >= r_.south - slack && n1 <= r_.north() + slack)
      return "";
    return r_.file + " covers easting [" + fmt_geo(r_.west) + ", " + fmt_geo(r_.east()) + "] and northing [" +
           fmt_geo(r_.south) + ", " + fmt_geo(r_.north()) + "], not easting [" + fmt_geo(e0) + ", " + fmt_geo(e1) +
           "], northing [" + fmt_geo(n0) + ", " + fmt_geo(n1) + "]";
  }
  // Empty when no cell the interpolation reads for that box is NODATA; else that cell.
  std::string nodata_in(double x0, double x1, double z0, double z1) const {
    long r0, r1, c0, c1;
    r_.cells_read(x0 + o_[0], x1 + o_[0], z0 + o_[1], z1 + o_[1], r0, r1, c0, c1);
    for (long row = r0; row <= r1; ++row)
      for (long col = c0; col <= c1; ++col)
        if (std::isnan(r_.at(row, col))) return cell(row, col);
    return "";
  }

 private:
  const io::Raster& r_;
  const std::vector<double>& o_;
};

std::string gb(double bytes) {
  std::ostringstream os;
  os.precision(3);
  os << bytes / 1e9 << " GB";
  return os.str();
}

// Points of a release volume (Body::is_release) on the lattice of spacing l: x and z aligned
// with the lower corner of the plan polygon's box (else of the grid's footprint), y with the
// grid's bottom; a point is kept where bottom < y < top inside the plan. `geometric`: the
// integral of max(0, top - bottom) over the plan, sampled at l / 4.
void seed_release(const Scene& sc, const Body& body, const std::string& key, double l,
                  std::vector<std::vector<double>>& pos, double& geometric, double& points_wanted) {
  if (sc.dim != 3) fail(key + ".top", "a body between surfaces needs grid.dim = 3");
  if (!sc.terrain || !sc.terrain->raster)
    fail(key + ".top", "a body between surfaces needs [terrain] (its origin georeferences the surfaces)");
  const std::vector<double>& origin = sc.terrain->origin;
  const Surface top(*body.top, origin), bottom(body.bottom ? *body.bottom : *sc.terrain->raster, origin);
  const std::string bottom_key = key + (body.bottom ? ".bottom" : ".top");
  const bool plan = !body.plan_x.empty();
  if (plan && (body.plan_x.size() != body.plan_z.size() || body.plan_x.size() < 3))
    fail(key + ".plan_z", "plan_x and plan_z need the same number (>= 3) of vertices");
  double x0 = sc.origin[0], x1 = x0 + sc.size[0], z0 = sc.origin[2], z1 = z0 + sc.size[2];
  if (plan) {
    const auto [ax, bx] = std::minmax_element(body.plan_x.begin(), body.plan_x.end());
    const auto [az, bz] = std::minmax_element(body.plan_z.begin(), body.plan_z.end());
    if (*ax < x0 - 1e-12 || *bx > x1 + 1e-12 || *az < z0 - 1e-12 || *bz > z1 + 1e-12)
      fail(key + ".plan_x", "the plan polygon (x [" + fmt(*ax) + ", " + fmt(*bx) + "], z [" + fmt(*az) + ", " +
                                fmt(*bz) + "]) leaves the grid's footprint (x [" + fmt(x0) + ", " + fmt(x1) +
                                "], z [" + fmt(z0) + ", " + fmt(z1) + "])");
    x0 = *ax, x1 = *bx, z0 = *az, z1 = *bz;
  }
  for (const auto& [s, k] : {std::pair<const Surface*, std::string>{&top, key + ".top"}, {&bottom, bottom_key}}) {
    const std::string miss = s->uncovered(x0, x1, z0, z1);
    if (!miss.empty()) fail(k, miss + ", the body's plan extent");
  }
  const double y0 = sc.origin[1], y_top = y0 + sc.size[1];
  auto inside = [&](double x, double z) { return !plan || inside_polygon(body.plan_x, body.plan_z, x, z); };
  // top and bottom where the plan needs them: NODATA there is an error
  auto heights = [&](double x, double z, double& b, double& t) {
    b = bottom.height(x, z);
    t = top.height(x, z);
    if (std::isnan(b)) fail(bottom_key, "a NODATA cell under the body: " + bottom.cell_at(x, z));
    if (std::isnan(t)) fail(key + ".top", "a NODATA cell under the body: " + top.cell_at(x, z));
  };
  const long cx = static_cast<long>(std::floor((x1 - x0) / l + 1e-9)), cz = static_cast<long>(std::floor((z1 - z0) / l + 1e-9));
  points_wanted += double(cx) * double(cz);  // a lower bound: one point per column
  for (long k = 0; k < cz; ++k)
    for (long i = 0; i < cx; ++i) {
      const double x = x0 + (i + 0.5) * l, z = z0 + (k + 0.5) * l;
      for (int a = 0; a < 4; ++a)  // the volume, sampled at l / 4 in plan
        for (int c = 0; c < 4; ++c) {
          const double xs = x0 + (i + (a + 0.5) / 4) * l, zs = z0 + (k + (c + 0.5) / 4) * l;
          if (!inside(xs, zs)) continue;
          double b, t;
          heights(xs, zs, b, t);
          geometric += std::max(0.0, t - b) * l * l / 16;
        }
      if (!inside(x, z)) continue;
      double b, t;
      heights(x, z, b, t);
      if (!(t > b)) continue;
      if (t > y_top + 1e-9 * l)
        fail(key + ".top", "the body reaches y = " + fmt(t) + " at x = " + fmt(x) + ", z = " + fmt(z) +
                               ", above the grid (up to y = " + fmt(y_top) + "): raise grid.size[1]");
      if (b < y0 - 1e-9 * l)
        fail(bottom_key, "the body reaches down to y = " + fmt(b) + " at x = " + fmt(x) + ", z = " + fmt(z) +
                             ", below the grid (from y = " + fmt(y0) + "): lower grid.origin[1]");
      for (long j = std::max(0L, static_cast<long>(std::floor((b - y0) / l - 0.5))); ; ++j) {
        const double y = y0 + (j + 0.5) * l;
        if (y >= t) break;
        if (y <= b) continue;
        pos[0].push_back(x);
        pos[1].push_back(y);
        pos[2].push_back(z);
      }
    }
}

}  // namespace

SceneSetup make_setup(const Scene& sc) {
  SceneSetup su;
  su.scene = sc;
  const int D = sc.dim;
  if (D != 2 && D != 3) fail("grid.dim", "must be 2 or 3");
  if (!(sc.h > 0)) fail("grid.h", "must be positive");
  if (sc.ppc_axis < 1) fail("particles.per_cell", "must be at least 1");
  if (sc.stages.empty()) fail("stage", "at least one [[stage]] is required");
  if (sc.pic_speed < 0) fail("solver.pic_speed", "must not be negative");
  if (sc.pic_speed > 0)
    for (size_t i = 0; i < sc.stages.size(); ++i)
      if (sc.stages[i].flip)
        fail("stage[" + std::to_string(i) + "].flip",
             "a FLIP fraction per step cannot be combined with solver.pic_speed (a rate)");
  if (static_cast<int>(sc.gravity.size()) != D) fail("gravity", "needs " + std::to_string(D) + " components");
  const double l = sc.h / sc.ppc_axis;
  su.spacing = l;

  // Grid, padded by kPad cells on every side.
  su.origin.resize(D);
  su.nodes.resize(D);
  su.n_nodes = 1;
  double nodes_wanted = 1;
  for (int d = 0; d < D; ++d) nodes_wanted *= sc.size[d] / sc.h + 1 + 2 * kPad;
  if (!(nodes_wanted <= kMaxNodes))
    fail("grid.h", "h = " + fmt(sc.h) + " m gives a grid of " + fmt(nodes_wanted) + " nodes (about " +
                       gb(memory_bytes(D, nodes_wanted, 0, sc.stages.size())) + "); at most " +
                       std::to_string(static_cast<long>(kMaxNodes)) +
                       " nodes are allowed (grid.size / grid.h + 7 per axis): use a larger grid.h or a smaller "
                       "grid.size");
  for (int d = 0; d < D; ++d) {
    const double cells = sc.size[d] / sc.h;
    if (std::fabs(cells - std::round(cells)) > 1e-6)
      fail("grid.size", "each extent must be a whole number of cells of grid.h = " + fmt(sc.h));
    su.origin[d] = sc.origin[d] - kPad * sc.h;
    su.nodes[d] = static_cast<int>(std::lround(cells)) + 1 + 2 * kPad;
    su.n_nodes *= su.nodes[d];
  }

  // Terrain (3D): the raster covers the grid's footprint in plan (x, z).
  std::optional<Surface> ground;
  if (sc.terrain) {
    const Terrain& t = *sc.terrain;
    if (D != 3) fail("terrain", "needs grid.dim = 3 (a 2D scene takes its ground as base)");
    if (!t.raster) fail("terrain.file", "no raster was read");
    if (t.origin.size() != 3) fail("terrain.origin", "needs 3 components (easting, northing, elevation)");
    if (t.mu && !(*t.mu >= 0)) fail("terrain.mu", "must be >= 0, got " + fmt(*t.mu));
    ground.emplace(*t.raster, t.origin);
    const std::string miss = ground->uncovered(sc.origin[0], sc.origin[0] + sc.size[0], sc.origin[2],
                                               sc.origin[2] + sc.size[2]);
    if (!miss.empty())
      fail("terrain.file", miss + ", the grid's footprint (grid.origin and grid.size in x and z, plus terrain.origin)");
  }

  // Particles on a lattice of spacing h / ppc_axis, aligned with each body's lower corner.
  // Materials: one model, a body's material one of them; bulk density at rest per material.
  const int nmat = sc.material_count();
  if (nmat > 255) fail("material", "at most 255 materials, got " + std::to_string(nmat));
  std::vector<double> rho0s(nmat);
  for (int m = 0; m < nmat; ++m) {
    const Material& mm = sc.material_at(m);
    if (mm.model != sc.material.model)
      fail("material[" + std::to_string(m) + "].model",
           "differs from material[0].model: every material of a scene has the same model");
    rho0s[m] = mm.params.c.rho_p / (1.0 + mm.e0);
  }
  std::vector<int> pos_body;  // body of each point, as pos
  std::vector<std::vector<double>> pos(D);
  double points_wanted = 0;
  const double ram = physical_memory();
  for (size_t b = 0; b < sc.bodies.size(); ++b) {
    const Body& body = sc.bodies[b];
    const std::string key = "body[" + std::to_string(b) + "]";
    if (body.material < 0 || body.material >= nmat)
      fail(key + ".material", "material " + std::to_string(body.material) + " does not exist (the scene has " +
                                  std::to_string(nmat) + ")");
    if (body.is_release()) {
      const long before = static_cast<long>(pos[0].size());
      double geometric = 0;
      seed_release(sc, body, key, l, pos, geometric, points_wanted);
      pos_body.resize(pos[0].size(), static_cast<int>(b));
      su.seeded_volume.push_back(double(static_cast<long>(pos[0].size()) - before) * std::pow(l, D));
      su.geometric_volume.push_back(geometric);
      continue;
    }
    std::vector<double> lo(D), hi(D);
    if (body.is_polygon()) {
      if (D != 2) fail(key + ".polygon_x", "polygons are 2D only");
      lo = {*std::min_element(body.poly_x.begin(), body.poly_x.end()),
            *std::min_element(body.poly_y.begin(), body.poly_y.end())};
      hi = {*std::max_element(body.poly_x.begin(), body.poly_x.end()),
            *std::max_element(body.poly_y.begin(), body.poly_y.end())};
    } else {
      lo = body.box_min;
      hi = body.box_max;
    }
    for (int d = 0; d < D; ++d) {
      if (!(hi[d] > lo[d])) fail(key, "is empty along axis " + std::to_string(d));
      const bool below = lo[d] < sc.origin[d] - 1e-12;
      if (below || hi[d] > sc.origin[d] + sc.size[d] + 1e-12)
        fail(key + (body.is_polygon() ? (d == 0 ? ".polygon_x" : ".polygon_y") : below ? ".min" : ".max"),
             "material [" + fmt(lo[d]) + ", " + fmt(hi[d]) + "] along axis " + std::to_string(d) +
                 " lies outside the grid [" + fmt(sc.origin[d]) + ", " + fmt(sc.origin[d] + sc.size[d]) +
                 "] (grid.origin, grid.size)");
    }
    std::vector<long> cnt(D);
    long total = 1;
    for (int d = 0; d < D; ++d) {
      cnt[d] = static_cast<long>(std::floor((hi[d] - lo[d]) / l + 1e-9));
      total *= cnt[d];
    }
    points_wanted += double(total);
    const double need = memory_bytes(D, double(su.n_nodes), points_wanted, sc.stages.size());
    if (ram > 0 && need > ram)
      fail("grid.h", "the scene needs about " + gb(need) + " of memory (" + std::to_string(su.n_nodes) + " nodes, " +
                         fmt(points_wanted) + " material points), more than this machine's " + gb(ram) +
                         ": use a larger grid.h or fewer particles.per_cell");
    const long before = static_cast<long>(pos[0].size());
    for (long k = 0; k < total; ++k) {
      long kk = k;
      double x[3];
      for (int d = 0; d < D; ++d) {
        x[d] = lo[d] + (kk % cnt[d] + 0.5) * l;
        kk /= cnt[d];
      }
      if (body.is_polygon() && !inside_polygon(body.poly_x, body.poly_y, x[0], x[1])) continue;
      for (int d = 0; d < D; ++d) pos[d].push_back(x[d]);
    }
    pos_body.resize(pos[0].size(), static_cast<int>(b));
    su.seeded_volume.push_back(double(static_cast<long>(pos[0].size()) - before) * std::pow(l, D));
    double geometric = 1;
    if (body.is_polygon()) {
      geometric = 0;  // shoelace
      for (size_t i = 0, j = body.poly_x.size() - 1; i < body.poly_x.size(); j = i++)
        geometric += (body.poly_x[j] - body.poly_x[i]) * (body.poly_y[j] + body.poly_y[i]);
      geometric = std::fabs(geometric) / 2;
    } else {
      for (int d = 0; d < D; ++d) geometric *= hi[d] - lo[d];
    }
    su.geometric_volume.push_back(geometric);
  }
  const long n = static_cast<long>(pos[0].size());
  if (n == 0) fail("body", "no material point was seeded");

  // Material must not start inside a held region.
  for (long i = 0; i < n; ++i) {
    for (const Wall& w : sc.walls) {
      const double x = pos[w.axis][i];
      if (w.at_max ? x >= w.position : x <= w.position)
        fail(w.key, "material point at " + fmt(pos[0][i]) + ", " + fmt(pos[1][i]) + " lies beyond this wall (" +
                        std::string(1, char('x' + w.axis)) + (w.at_max ? " >= " : " <= ") + fmt(w.position) +
                        " is held): move the wall or the material");
    }
    if (sc.base && pos[1][i] <= polyline(sc.base->x, sc.base->y, pos[0][i]))
      fail("base", "material point at " + fmt(pos[0][i]) + ", " + fmt(pos[1][i]) + " lies below the base");
  }
  if (ground) {
    for (long i = 0; i < n; ++i) {
      const double x = pos[0][i], y = pos[1][i], z = pos[2][i], b = ground->height(x, z);
      const std::string at = fmt(x) + ", " + fmt(y) + ", " + fmt(z);
      if (std::isnan(b))
        fail("terrain.file", "a NODATA cell under material: the material point at " + at + " lies over " +
                                 ground->cell_at(x, z) + " or a neighbour it interpolates from");
      if (y <= b)
        fail("terrain", "material point at " + at + " lies on or below the terrain (ground at y = " + fmt(b) +
                            "): move the body up or lower terrain.origin[2]");
    }
    const std::string cell =
        ground->nodata_in(sc.origin[0], sc.origin[0] + sc.size[0], sc.origin[2], sc.origin[2] + sc.size[2]);
    if (!cell.empty())
      fail("terrain.file", "a NODATA cell inside the grid's footprint: " + cell +
                               "; fill it (e.g. gdal_fillnodata.py) or move the grid off it");
  }

  HostParticles& hp = su.particles;
  hp.n = n;
  hp.dim = D;
  hp.x.resize(D * n);
  for (int d = 0; d < D; ++d) std::copy(pos[d].begin(), pos[d].end(), hp.x.begin() + d * n);
  hp.v.assign(D * n, 0.0);
  hp.sig.assign(6 * n, 0.0);
  hp.sigf.assign(6 * n, 0.0);
  hp.L.assign(D * D * n, 0.0);
  hp.eps.assign(n, 0.0);
  su.point_body = std::move(pos_body);
  if (nmat > 1) {
    su.point_material.resize(n);
    for (long i = 0; i < n; ++i) su.point_material[i] = static_cast<std::uint8_t>(sc.bodies[su.point_body[i]].material);
  }
  auto material_of = [&](long i) { return nmat > 1 ? static_cast<int>(su.point_material[i]) : 0; };
  hp.m.resize(n);
  hp.e.resize(n);
  hp.s.resize(n);
  for (long i = 0; i < n; ++i) {
    const int m = material_of(i);
    hp.m[i] = rho0s[m] * std::pow(l, D);
    hp.e[i] = sc.material_at(m).e0;
    hp.s[i] = std::sqrt(sc.material_at(m).T0);
  }

  const double g = std::sqrt(std::inner_product(sc.gravity.begin(), sc.gravity.end(), sc.gravity.begin(), 0.0));
  auto K0_of = [&](int m) { return sc.initial.K0 >= 0 ? sc.initial.K0 : 1.0 - std::sin(sc.material_at(m).params.f.phi_c); };
  double depth_max = 0;
  // Several materials: the overburden of a point differs from rho g depth (its own density) by
  // (rho_m - rho) g l for every point of another material m above it in its column.
  std::vector<double> overburden_fix;
  if (nmat > 1 && sc.initial.geostatic) {
    overburden_fix.assign(n, 0.0);
    std::map<long, std::vector<long>> columns;
    for (long i = 0; i < n; ++i) {
      long key = std::lround(hp.x[i] / l * 2);
      if (D == 3) key = key * 1000003L + std::lround(hp.x[2 * n + i] / l * 2);
      columns[key].push_back(i);
    }
    for (auto& [key, pts] : columns) {
      std::stable_sort(pts.begin(), pts.end(), [&](long a, long b) { return hp.x[n + a] > hp.x[n + b]; });
      std::vector<long> above(nmat, 0);
      for (long i : pts) {
        const int mi = material_of(i);
        double fix = 0;
        for (int m = 0; m < nmat; ++m)
          if (m != mi && above[m] > 0) fix += (rho0s[m] - rho0s[mi]) * l * double(above[m]);
        overburden_fix[i] = fix;
        ++above[mi];
      }
    }
  }
  {
    // Free surface above each lattice column: highest particle plus half a spacing.
    std::map<long, double> top;
    for (long i = 0; i < n; ++i) {
      long key = std::lround(hp.x[i] / l * 2);
      if (D == 3) key = key * 1000003L + std::lround(hp.x[2 * n + i] / l * 2);
      auto it = top.find(key);
      const double y = hp.x[n + i];
      if (it == top.end()) top[key] = y; else it->second = std::max(it->second, y);
    }
    for (long i = 0; i < n; ++i) {
      long key = std::lround(hp.x[i] / l * 2);
      if (D == 3) key = key * 1000003L + std::lround(hp.x[2 * n + i] / l * 2);
      const double depth = top[key] + 0.5 * l - hp.x[n + i];
      depth_max = std::max(depth_max, depth);
      if (!sc.initial.geostatic) continue;
      const int m = material_of(i);
      const Material& mat = sc.material_at(m);
      const double K0 = K0_of(m);
      double sv = -rho0s[m] * g * depth;
      if (!overburden_fix.empty()) sv -= g * overburden_fix[i];
      Mat3<double> s = Mat3<double>::Zero();
      s(0, 0) = s(2, 2) = K0 * sv;
      s(1, 1) = sv;
      const double eps0 = initial_plastic_strain<LodeShape::SmoothMohrCoulomb>(mat.params.f, s, mat.e0);
      if (!(eps0 >= 0))
        fail("initial_stress.K0", "the geostatic state with K0 = " + fmt(K0) + " lies outside the yield surface");
      const double v6[6] = {s(0, 0), s(1, 1), s(2, 2), 0, 0, 0};
      for (int c = 0; c < 6; ++c) hp.sig[c * n + i] = hp.sigf[c * n + i] = v6[c];
      hp.eps[i] = eps0;
    }
  }

  // Stability of a fixed step: P-wave speed at the deepest point of the at-rest column (of
  // each material's density and stiffness; the smallest limit).
  const double rho_max = *std::max_element(rho0s.begin(), rho0s.end());
  for (int m = 0; m < nmat; ++m) {
    const Material& mat = sc.material_at(m);
    const FrictionalParams<double>& fp = mat.params.f;
    const double rho0 = rho0s[m];
    const double p = std::max((nmat > 1 ? rho_max : rho0) * g * depth_max * (1 + 2 * K0_of(m)) / 3, fp.p_min);
    const ElasticModuli<double> c = elastic_moduli(fp, p, mat.e0);
    const double wave = std::sqrt((c.K + 4.0 / 3.0 * c.G) / rho0);
    const double limit = sc.h / wave;
    if (m > 0 && limit >= su.dt_estimate) continue;
    su.dt_estimate = limit;
    if (!sc.adaptive && sc.dt > limit)
      fail("time.dt", fmt(sc.dt) + " s is above the stability limit h / c_p = " + fmt(limit) +
                          " s (P-wave speed " + fmt(wave) + " m/s at the base of the consolidated material)");
  }

  // Node masks per stage.
  for (const Wall& w : sc.walls)
    for (const Wall& o : sc.walls)
      if (w.axis == o.axis && !w.at_max && o.at_max && !(w.position < o.position))
        fail(o.key, "this wall and " + w.key + " leave no room between them");
  su.has_boundary = !sc.walls.empty() || sc.base.has_value() || sc.terrain.has_value() || !sc.obstacles.empty();
  // Wall node rows for the boundary-modified quadratic B-splines: the last held node row of
  // each axis-aligned wall (the flume's inclined base and the gates keep truncated splines).
  su.walls.assign(D, AxisWalls{});
  if (sc.shape == ShapeKind::QuadraticBSpline && sc.modified_boundary_splines) {
    for (const Wall& w : sc.walls) {
      const double c = (w.position - su.origin[w.axis]) / sc.h;
      AxisWalls& a = su.walls[w.axis];
      if (w.at_max) {
        a.hi = static_cast<int>(std::ceil(c - 1e-9));
        a.has_hi = true;
      } else {
        a.lo = static_cast<int>(std::floor(c + 1e-9));
        a.has_lo = true;
      }
    }
  }
  for (const Stage& st : sc.stages) su.has_boundary = su.has_boundary || st.gate.has_value();
  // Several materials run the ensembles' kernels (kernels.hpp, Members), compiled only with
  // boundary code: a scene of several materials without a wall, a base or a gate gets masks
  // that hold no node (and no contact table), which its update reads as no boundary.
  const bool masks = su.has_boundary || nmat > 1;
  // Friction and lifting gates: their nodes are flagged (kContactNode) and a ContactTable
  // follows the stage's masks (boundary.hpp).
  const bool friction = std::any_of(sc.walls.begin(), sc.walls.end(), [](const Wall& w) { return w.mu.has_value(); }) ||
                        (sc.base && sc.base->mu);
  int frictional_walls = 0;
  for (const Wall& w : sc.walls) {
    if (!w.mu) continue;
    const std::string key = w.key.substr(0, w.key.rfind('.')) + ".mu";
    if (!(*w.mu >= 0)) fail(key, "must be >= 0, got " + fmt(*w.mu));
    if (++frictional_walls > static_cast<int>(std::size(ContactTable{}.walls)))
      fail(key, "at most one frictional wall per side of the grid");
  }
  if (sc.base && sc.base->mu && !(*sc.base->mu >= 0)) fail("base.mu", "must be >= 0, got " + fmt(*sc.base->mu));
  const double tol = 1e-9 * sc.h;
  // Terrain: nodes on or below the ground (evaluated at the nearest point of the footprint) are
  // held, the same in every stage. No-slip: all components, by the masks. Frictional: the nodes
  // a point on or above the ground can reach (quadratic stencils reach 1.5 h per axis; on a
  // slope |grad b| a node that far aside lies up to 1.5 h (1 + sqrt 2 |grad b|) below the
  // ground) go through the terrain pass with the ground's normal there; deeper nodes are held
  // whole by the masks.
  std::vector<std::uint8_t> ground_mask;
  const bool forces = sc.output.forces_on(!sc.obstacles.empty());
  std::vector<TerrainNode> ground_nodes;  // every node on or below the ground (force probes)
  if (ground) {
    ground_mask.assign(su.n_nodes, 0);
    const std::uint8_t all = static_cast<std::uint8_t>((1u << D) - 1);
    const bool frictional = sc.terrain->mu.has_value();
    const bool floored = std::any_of(sc.walls.begin(), sc.walls.end(), [](const Wall& w) { return w.axis == 1 && !w.at_max; });
    const int* nd = su.nodes.data();
    double low = std::numeric_limits<double>::max(), high = -low;  // the ground's range over the footprint
    for (int kz = 0; kz < nd[2]; ++kz)
      for (int kx = 0; kx < nd[0]; ++kx) {
        const double x = su.origin[0] + kx * sc.h, z = su.origin[2] + kz * sc.h;
        const double xc = std::clamp(x, sc.origin[0], sc.origin[0] + sc.size[0]);
        const double zc = std::clamp(z, sc.origin[2], sc.origin[2] + sc.size[2]);
        const double b = ground->height(xc, zc);
        low = std::min(low, b);
        high = std::max(high, b);
        if (!floored && b < sc.origin[1] - tol)
          fail("grid.origin", "the terrain at x = " + fmt(xc) + ", z = " + fmt(zc) + " (y = " + fmt(b) +
                                  ") lies below the grid (y from " + fmt(sc.origin[1]) +
                                  "): lower grid.origin[1] or raise terrain.origin[2]");
        double nrm[3] = {0, -1, 0};
        const double slope = frictional || forces ? ground->normal(xc, zc, nrm) : 0.0;
        const double band = 2 * sc.h * (1 + std::sqrt(2.0) * slope);  // reach of a stencil (frictional ground, force probes)
        for (int ky = 0; ky < nd[1]; ++ky) {
          const double y = su.origin[1] + ky * sc.h;
          if (y > b + tol) break;
          const long I = kx + static_cast<long>(nd[0]) * (ky + static_cast<long>(nd[1]) * kz);
          if (forces && b - y <= band) ground_nodes.push_back({I, {nrm[0], nrm[1], nrm[2]}});
          if (frictional && b - y <= band)
            su.terrain.push_back({I, {nrm[0], nrm[1], nrm[2]}});
          else
            ground_mask[I] = all;
        }
      }
    std::sort(su.terrain.begin(), su.terrain.end(), [](const TerrainNode& a, const TerrainNode& b) { return a.node < b.node; });
    // A level ground is an axis-aligned floor: boundary-modified quadratic B-splines there, as at
    // a y- wall at its height (any other terrain keeps truncated splines; docs/mpm_terrain.md).
    if (sc.shape == ShapeKind::QuadraticBSpline && sc.modified_boundary_splines && high - low <= tol) {
      AxisWalls& a = su.walls[1];
      const int row = static_cast<int>(std::floor((high - su.origin[1]) / sc.h + 1e-9));
      a.lo = a.has_lo ? std::max(a.lo, row) : row;
      a.has_lo = true;
    }
    su.terrain_mu = frictional ? *sc.terrain->mu : 0.0;
  }
  double stage_start = 0;  // as the driver sums the stage durations
  for (size_t si = 0; si < sc.stages.size(); ++si) {
    const Stage& st = sc.stages[si];
    int gate_axis = -1;
    const bool lifting = st.gate && st.gate->lift_speed != 0;
    if (st.gate) {
      int nz = 0;
      for (int d = 0; d < D; ++d)
        if (st.gate->normal[d] != 0) { ++nz; gate_axis = d; }
      if (nz == 0) fail("stage[" + std::to_string(si) + "].gate.normal", "must not be zero");
      if (st.gate->normal_only && nz != 1)
        fail("stage[" + std::to_string(si) + "].gate.hold",
             "\"normal\" needs an axis-aligned normal; use \"all\" for an inclined gate");
      if (!(st.gate->lift_speed >= 0))
        fail("stage[" + std::to_string(si) + "].gate.lift_speed", "must be >= 0 (0: held whole while the stage lasts), got " + fmt(st.gate->lift_speed));
      if (lifting && st.gate->normal[1] != 0)
        fail("stage[" + std::to_string(si) + "].gate.lift_speed",
             "a gate is lifted along y: its normal must have no y component (a vertical gate)");
    }
    std::vector<std::uint8_t> mask;
    if (masks) {
      mask.assign(su.n_nodes, 0);
      const std::uint8_t all = static_cast<std::uint8_t>((1u << D) - 1);
      const std::uint8_t gate_bits =
          st.gate ? (st.gate->normal_only ? static_cast<std::uint8_t>(1u << gate_axis) : all) : 0;
      for (long k = 0; k < su.n_nodes; ++k) {
        long kk = k;
        double x[3];
        for (int d = 0; d < D; ++d) {
          x[d] = su.origin[d] + (kk % su.nodes[d]) * sc.h;
          kk /= su.nodes[d];
        }
        std::uint8_t m = 0;
        bool contact = false;
        for (const Wall& w : sc.walls) {
          if (!beyond_wall(w.axis, w.at_max, w.position, x, tol)) continue;
          if (w.mu)
            contact = true;
          else
            m |= w.no_slip ? all : static_cast<std::uint8_t>(1u << w.axis);
        }
        if (sc.base && x[1] <= polyline(sc.base->x, sc.base->y, x[0]) + tol) {
          if (sc.base->mu)
            contact = true;
          else
            m |= all;
        }
        if (st.gate) {
          double s = 0;
          for (int d = 0; d < D; ++d) s += (x[d] - st.gate->point[d]) * st.gate->normal[d];
          if (s >= -tol) {
            if (lifting)
              contact = true;
            else
              m |= gate_bits;
          }
        }
        if (!ground_mask.empty()) m |= ground_mask[k];
        if (contact && m != all) m |= kContactNode;
        mask[k] = m;
      }
      if (friction || lifting) {
        ContactTable c;
        for (int d = 0; d < D; ++d) c.origin[d] = su.origin[d];
        c.h = sc.h;
        c.tol = tol;
        for (const Wall& w : sc.walls)
          if (w.mu) c.walls[c.n_walls++] = FrictionWall{w.axis, w.at_max ? 1 : 0, w.position, *w.mu};
        std::vector<BaseSegment> segments;
        if (sc.base && sc.base->mu) {
          for (size_t i = 1; i < sc.base->x.size(); ++i)
            segments.push_back({sc.base->x[i - 1], sc.base->y[i - 1], sc.base->x[i], sc.base->y[i]});
          c.n_segments = static_cast<int>(segments.size());
          c.base_mu = *sc.base->mu;
        }
        if (lifting) {
          c.gate_lifting = 1;
          c.gate_bits = gate_bits;
          for (int d = 0; d < D; ++d) {
            c.gate_point[d] = st.gate->point[d];
            c.gate_normal[d] = st.gate->normal[d];
          }
          c.lift_speed = st.gate->lift_speed;
          c.lift_start = stage_start;
        }
        const size_t at = static_cast<size_t>(contact_table_offset(su.n_nodes));
        const size_t seg_bytes = segments.size() * sizeof(BaseSegment);
        mask.resize(at + sizeof c + seg_bytes, 0);
        std::memcpy(mask.data() + at, &c, sizeof c);
        if (seg_bytes) std::memcpy(mask.data() + at + sizeof c, segments.data(), seg_bytes);
      }
    }
    su.stage_masks.push_back(std::move(mask));
    stage_start += st.duration;
  }

  if (!sc.obstacles.empty()) detail::setup_obstacles(sc, su);
  if (forces) {
    std::sort(ground_nodes.begin(), ground_nodes.end(), [](const TerrainNode& a, const TerrainNode& b) { return a.node < b.node; });
    detail::setup_force_probes(sc, su, ground_nodes);
  }

  // Tracked particles: nearest to the requested points.
  for (const Track& t : sc.tracks) {
    long best = 0;
    double bd = std::numeric_limits<double>::max();
    for (long i = 0; i < n; ++i) {
      double d2 = 0;
      for (int d = 0; d < D; ++d) d2 += (hp.x[d * n + i] - t.x[d]) * (hp.x[d * n + i] - t.x[d]);
      if (d2 < bd) { bd = d2; best = i; }
    }
    su.tracked.push_back(best);
  }
  return su;
}

namespace {

void column_collapse_params(Material& m) {  // data/params/column_collapse.toml (Table 3)
  auto& c = m.params.c;
  c.rho_p = 2650; c.d = 1.25e-3; c.V_sd = 1.0 / 1.62; c.V_m = 0.4; c.eps_n = 0.6; c.mu_p = 0.2;
  auto& f = m.params.f;
  f.K0 = 120; f.nu = 0.2; f.n = 0.5; f.phi_c = 19.8 * M_PI / 180; f.e_ref = 0.977; f.lambda_c = 0.0596;
  f.xi = 0.365; f.A_d = 0.7; f.k_p = 0.0044; f.n_p = 2.4; f.n_d = 2.9; f.p_at = 101.3e3;
}

void flume_params(Material& m) {  // data/params/flume.toml (Table 3)
  auto& c = m.params.c;
  c.rho_p = 2500; c.d = 1.0e-3; c.V_sd = 1.0 / 1.60; c.V_m = 0.4; c.eps_n = 0.6; c.mu_p = 0.2;
  auto& f = m.params.f;
  f.K0 = 130; f.nu = 0.2; f.n = 0.5; f.phi_c = 38.0 * M_PI / 180; f.e_ref = 0.977; f.lambda_c = 0.0596;
  f.xi = 0.365; f.A_d = 0.4; f.k_p = 0.0044; f.n_p = 2.4; f.n_d = 2.9; f.p_at = 101.3e3;
}

const char* model_name(ModelKind m) { return m == ModelKind::PhaseTransition ? "phase transition" : "frictional only"; }

}  // namespace

namespace {

// What the paper's two plane-strain scenes share: grid of whole cells from the origin, 2 x 2
// points per cell, gravity, the step, the material's model and initial state.
Scene paper_scene(const char* title, double width, double height, double h, double dt, ModelKind model,
                  ShapeKind shape, const char* material, double e0) {
  Scene sc;
  std::ostringstream os;
  os << title << " (" << h * 1e3 << " mm), " << model_name(model);
  sc.name = os.str();
  sc.dim = 2;
  sc.origin = {0.0, 0.0};
  sc.size = {width, std::ceil(height / h - 1e-9) * h};  // whole cells
  sc.h = h;
  sc.ppc_axis = 2;
  sc.shape = shape;
  sc.gravity = {0.0, -9.81};
  sc.dt = dt;
  sc.pic_speed = 1.0;  // PIC part as a rate: flip 0.99 per step at 1 mm and 1e-5 s
  // Quadratic B-splines: Taylor PIC (affine momentum in P2G), which moves the deposit on and
  // brings it to rest without FLIP noise; linear hats (the CI scenes) keep FLIP, their velocity
  // gradient jumps at cell faces and its affine transfer tears points off (docs/mpm.md).
  if (shape == ShapeKind::QuadraticBSpline) {
    sc.transfer = Scene::Transfer::TaylorPic;
    sc.flip = 0.0;  // not used with pic_speed; the TOML default of "tpic"
  }
  Material& m = sc.material;
  m.name = material;
  m.model = model;
  m.e0 = e0;
  m.T0 = 1e-15;
  return sc;
}

}  // namespace

Scene column_scene(double h, double dt, ModelKind model, ShapeKind shape, double collapse_time) {
  Scene sc = paper_scene("column collapse", 0.60, 0.15, h, dt, model, shape,
                         "column_collapse (Table 3, as data/params/column_collapse.toml)", 0.95);
  column_collapse_params(sc.material);
  Body b;
  b.box_min = {0.0, 0.0};
  b.box_max = {0.2, 0.1};
  sc.bodies.push_back(b);
  sc.walls.push_back({0, false, 0.0, false, "wall[0].side"});
  sc.walls.push_back({0, true, 0.60, false, "wall[1].side"});
  sc.walls.push_back({1, false, 0.0, true, "wall[2].side"});
  Stage s1;
  s1.name = "consolidation";
  s1.duration = 0.1;
  s1.damping = 0.5;
  s1.gate = Gate{{0.2, 0.0}, {1.0, 0.0}, true};
  Stage s2;
  s2.name = "collapse";
  s2.duration = collapse_time;
  sc.stages = {s1, s2};
  sc.runout_x = {0.0, 0.6};
  sc.runout_y = {0.0, 0.0};
  sc.tracks = {{"A", {0.15, 0.095}}, {"B", {0.10, 0.05}}, {"C", {0.05, 0.01}}};
  for (double t : {0.05, 0.25, 0.5, 1.0})
    if (t <= collapse_time) sc.output.times.push_back(t);
  sc.output.series_dt = h >= 0.005 ? 5e-3 : 1e-3;
  return sc;
}

Scene small_column_scene(ModelKind model, ShapeKind shape) { return column_scene(0.01, 5e-5, model, shape, 0.4); }

Scene flume_scene(double h, double dt, ModelKind model, ShapeKind shape, double flow_time) {
  const double c45 = std::cos(M_PI / 4);
  const double H = 2.30 * c45, run = 0.5 * c45, thick = 0.30 / c45;
  Scene sc = paper_scene("flume", 3.20, H + thick + 0.1, h, dt, model, shape,
                         "flume (Table 3, as data/params/flume.toml)", 0.90);
  flume_params(sc.material);
  Body b;
  b.poly_x = {0.0, run, run, 0.0};
  b.poly_y = {H, H - run, H - run + thick, H + thick};
  sc.bodies.push_back(b);
  sc.walls.push_back({0, false, 0.0, false, "wall[0].side"});
  sc.walls.push_back({0, true, 3.20, false, "wall[1].side"});
  sc.base = BaseLine{{0.0, H, 3.20}, {H, 0.0, 0.0}};
  Stage s1;
  s1.name = "consolidation";
  s1.duration = 0.1;
  s1.damping = 0.5;
  s1.gate = Gate{{run, 0.0}, {1.0, 0.0}, true};
  Stage s2;
  s2.name = "flow";
  s2.duration = flow_time;
  sc.stages = {s1, s2};
  sc.runout_x = {0.0, H, 3.20};
  sc.runout_y = {H, 0.0, 0.0};
  sc.tracks = {{"A", {0.25, H - 0.25 + thick - 0.02}}, {"B", {0.18, H - 0.18 + thick / 2}}, {"C", {0.02, H + 0.01}}};
  for (double t : {0.1, 0.4, 0.8, 3.0})
    if (t <= flow_time) sc.output.times.push_back(t);
  sc.output.series_dt = 2e-3;
  return sc;
}

}  // namespace granflow::mpm
