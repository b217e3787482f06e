// Particle seeding: bodies, release volumes between surfaces, the points' fields and initial stress.
#include "scene/seeding.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <numeric>
#include <string>

#include <unistd.h>

#include "scene/mesh_geometry.hpp"
#include "scene/setup_common.hpp"

namespace granflow::mpm::detail {
namespace {

double physical_memory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), size = ::sysconf(_SC_PAGE_SIZE);
  return pages > 0 && size > 0 ? double(pages) * double(size) : 0.0;
}

bool inside_polygon(const std::vector<double>& px, const std::vector<double>& py, double x, double y) {
  bool in = false;
  for (size_t i = 0, j = px.size() - 1; i < px.size(); j = i++) {
    if ((py[i] > y) != (py[j] > y) && x < (px[j] - px[i]) * (y - py[i]) / (py[j] - py[i]) + px[i]) in = !in;
  }
  return in;
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

// Points of a mesh body on the grid's lattice of spacing l (points at origin + (i + 1/2) l): one
// line along y per lattice column, its sorted crossings of the surface, the points strictly
// between where the winding number is not zero. `geometric`: the mesh's own volume.
void seed_mesh(const Scene& sc, const Body& body, const std::string& key, double l, double ram, double n_nodes,
               std::vector<std::vector<double>>& pos, double& geometric, double& points_wanted) {
  if (sc.dim != 3) fail(key + ".mesh", "meshes need grid.dim = 3");
  const MeshSolid m(*body.mesh, key + ".mesh");
  mesh_in_grid(m, sc, key + ".mesh");
  geometric = m.volume();
  points_wanted += m.volume() / (l * l * l);
  const double need = memory_bytes(3, n_nodes, points_wanted, sc.stages.size());
  if (ram > 0 && need > ram)
    fail("grid.h", "the scene needs about " + gb(need) + " of memory (" + fmt(points_wanted) +
                       " material points), more than this machine's " + gb(ram) +
                       ": use a larger grid.h or fewer particles.per_cell");
  auto first = [&](int d) { return static_cast<long>(std::ceil((m.lo()[d] - sc.origin[d]) / l - 0.5)); };
  auto last = [&](int d) { return static_cast<long>(std::floor((m.hi()[d] - sc.origin[d]) / l - 0.5)); };
  std::vector<MeshCrossing> cr;
  for (long k = first(2); k <= last(2); ++k)
    for (long i = first(0); i <= last(0); ++i) {
      const double x = sc.origin[0] + (i + 0.5) * l, z = sc.origin[2] + (k + 0.5) * l;
      m.crossings(1, z, x, cr);
      int w = 0;
      double from = 0;
      for (const MeshCrossing& c : cr) {
        const int before = w;
        w -= c.sign;
        if (before == 0 && w != 0) from = c.t;
        if (before == 0 || w != 0) continue;
        for (long j = static_cast<long>(std::floor((from - sc.origin[1]) / l - 0.5)); ; ++j) {
          const double y = sc.origin[1] + (j + 0.5) * l;
          if (y >= c.t) break;
          if (y <= from) continue;
          pos[0].push_back(x);
          pos[1].push_back(y);
          pos[2].push_back(z);
        }
      }
    }
}

// K0 of the geostatic state: initial_stress.K0, else Jaky's 1 - sin(phi_c) of material m.
double K0_of(const Scene& sc, int m) {
  return sc.initial.K0 >= 0 ? sc.initial.K0 : 1.0 - std::sin(sc.material_at(m).params.f.phi_c);
}

}  // namespace

std::vector<double> rest_densities(const Scene& sc) {
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
  return rho0s;
}

void seed_particles(const Scene& sc, SceneSetup& su, const std::vector<double>& rho0s,
                    const std::optional<Surface>& ground) {
  const int D = sc.dim;
  const double l = su.spacing;
  const int nmat = sc.material_count();
  // Particles on a lattice of spacing h / ppc_axis, aligned with each body's lower corner.
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
    if (body.is_release() || body.is_mesh()) {
      const long before = static_cast<long>(pos[0].size());
      double geometric = 0;
      if (body.is_mesh())
        seed_mesh(sc, body, key, l, ram, double(su.n_nodes), pos, geometric, points_wanted);
      else
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
}

double initial_stress(const Scene& sc, SceneSetup& su, const std::vector<double>& rho0s) {
  const int D = sc.dim;
  const double l = su.spacing;
  const int nmat = sc.material_count();
  HostParticles& hp = su.particles;
  const long n = hp.n;
  auto material_of = [&](long i) { return nmat > 1 ? static_cast<int>(su.point_material[i]) : 0; };
  const double g = std::sqrt(std::inner_product(sc.gravity.begin(), sc.gravity.end(), sc.gravity.begin(), 0.0));
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
      const double K0 = K0_of(sc, m);
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
  return depth_max;
}

void step_estimate(const Scene& sc, SceneSetup& su, const std::vector<double>& rho0s, double depth_max) {
  const int nmat = sc.material_count();
  const double g = std::sqrt(std::inner_product(sc.gravity.begin(), sc.gravity.end(), sc.gravity.begin(), 0.0));
  // Stability of a fixed step: P-wave speed at the deepest point of the at-rest column (of
  // each material's density and stiffness; the smallest limit).
  const double rho_max = *std::max_element(rho0s.begin(), rho0s.end());
  for (int m = 0; m < nmat; ++m) {
    const Material& mat = sc.material_at(m);
    const FrictionalParams<double>& fp = mat.params.f;
    const double rho0 = rho0s[m];
    const double p = std::max((nmat > 1 ? rho_max : rho0) * g * depth_max * (1 + 2 * K0_of(sc, m)) / 3, fp.p_min);
    const ElasticModuli<double> c = elastic_moduli(fp, p, mat.e0);
    const double wave = std::sqrt((c.K + 4.0 / 3.0 * c.G) / rho0);
    const double limit = sc.h / wave;
    if (m > 0 && limit >= su.dt_estimate) continue;
    su.dt_estimate = limit;
    if (!sc.adaptive && sc.dt > limit)
      fail("time.dt", fmt(sc.dt) + " s is above the stability limit h / c_p = " + fmt(limit) +
                          " s (P-wave speed " + fmt(wave) + " m/s at the base of the consolidated material)");
  }
}

}  // namespace granflow::mpm::detail
