// What a sample measures on a frame: run-out, height, speeds and energies along the run-out
// polyline, the free surface, the consolidation check (measures.hpp).
#include <granflow/mpm/measures.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace granflow::mpm {
namespace {

struct Polyline {
  std::vector<double> x, y, s0;  // vertices and curvilinear abscissa at each vertex
  explicit Polyline(const Scene& sc) : x(sc.runout_x), y(sc.runout_y) {
    if (x.size() < 2) {  // default: the bottom of the grid box along x
      x = {sc.origin[0], sc.origin[0] + sc.size[0]};
      y = {sc.origin[1], sc.origin[1]};
    }
    s0.assign(x.size(), 0.0);
    for (size_t i = 1; i < x.size(); ++i) s0[i] = s0[i - 1] + std::hypot(x[i] - x[i - 1], y[i] - y[i - 1]);
  }
  // Abscissa of the nearest point and the signed distance above the line.
  void project(double px, double py, double& s, double& above) const {
    double best = std::numeric_limits<double>::max();
    for (size_t i = 1; i < x.size(); ++i) {
      const double dx = x[i] - x[i - 1], dy = y[i] - y[i - 1], len = std::hypot(dx, dy);
      double t = ((px - x[i - 1]) * dx + (py - y[i - 1]) * dy) / (len * len);
      t = std::clamp(t, 0.0, 1.0);
      const double qx = x[i - 1] + t * dx, qy = y[i - 1] + t * dy;
      const double dist = std::hypot(px - qx, py - qy);
      if (dist < best) {
        best = dist;
        s = s0[i - 1] + t * len;
        above = (dx * (py - y[i - 1]) - dy * (px - x[i - 1])) / len;
      }
    }
  }
};

}  // namespace

Measures measure(const Frame& fr, const SceneSetup& su, const std::vector<double>& mass, int material) {
  const Scene& sc = su.scene;
  const Polyline line(sc);
  const long n = fr.n;
  Measures m;
  // one material's points (a scene of several), else all
  auto skip = [&](long i) { return material >= 0 && su.point_material[i] != material; };
  long count = n;
  if (material >= 0) count = std::count(su.point_material.begin(), su.point_material.end(), material);
  if (count == 0) return m;
  std::vector<double> s(n), a(n);
  double smin = std::numeric_limits<double>::max(), smax = -smin;
  for (long i = 0; i < n; ++i) {
    if (skip(i)) continue;
    line.project(fr.x[i], fr.x[n + i], s[i], a[i]);
    smin = std::min(smin, s[i]);
    smax = std::max(smax, s[i]);
    double v2 = 0;
    for (int d = 0; d < fr.dim; ++d) v2 += fr.v[d * n + i] * fr.v[d * n + i];
    m.max_speed = std::max(m.max_speed, std::sqrt(v2));
    m.kinetic_energy += 0.5 * mass[i] * v2;
    if (!fr.T.empty()) {
      m.mean_T += fr.T[i] / count;
      m.max_T = std::max(m.max_T, fr.T[i]);
    }
  }
  // Front of the contiguous deposit: bins of one grid cell along the line; of the runs of
  // occupied bins, the one holding the most points (isolated points thrown ahead do not
  // count, nor does a tail left behind on the slope).
  const double w = sc.h;
  const long nb = static_cast<long>((smax - smin) / w) + 1;
  std::vector<double> occ(nb, 0.0);  // point counts, exact as doubles
  for (long i = 0; i < n; ++i)
    if (!skip(i)) occ[static_cast<long>((s[i] - smin) / w)] += 1;
  const auto [first, last] = heaviest_run(occ);
  const double s_begin = smin + first * w, s_end = smin + (last + 1) * w;
  double front = s_begin;
  for (long i = 0; i < n; ++i)
    if (!skip(i) && s[i] >= s_begin && s[i] < s_end) {
      front = std::max(front, s[i]);
      m.height = std::max(m.height, a[i]);
    }
  m.runout = front + 0.5 * su.spacing;
  m.height += 0.5 * su.spacing;
  return m;
}

std::pair<long, long> heaviest_run(const std::vector<double>& weight) {
  const long nb = static_cast<long>(weight.size());
  long first = 0, last = -1;
  double best = 0;
  for (long b = 0; b < nb;) {
    if (!(weight[b] > 0)) {
      ++b;
      continue;
    }
    long e = b;
    double m = 0;
    while (e < nb && weight[e] > 0) m += weight[e++];
    if (m > best) {
      best = m;
      first = b;
      last = e - 1;
    }
    b = e;
  }
  return {first, last};
}

std::vector<std::pair<double, double>> free_surface(const Frame& fr, const SceneSetup& su) {
  const Scene& sc = su.scene;
  const long n = fr.n;
  const double x0 = sc.origin[0], w = sc.h;
  const long nb = static_cast<long>(sc.size[0] / w) + 1;
  std::vector<double> top(nb, -std::numeric_limits<double>::max());
  for (long i = 0; i < n; ++i) {
    const long b = std::clamp(static_cast<long>((fr.x[i] - x0) / w), 0L, nb - 1);
    top[b] = std::max(top[b], fr.x[n + i] + 0.5 * su.spacing);
  }
  std::vector<std::pair<double, double>> out;
  for (long b = 0; b < nb; ++b)
    if (top[b] > -1e300) out.emplace_back(x0 + (b + 0.5) * w, top[b]);
  return out;
}

ConsolidationCheck check_consolidation(const Frame& fr, const SceneSetup& su) {
  // Middle half of the first body, depth bins of one grid cell; compare the mean -sigma_yy
  // with rho g depth where rho is the current bulk density integrated from the top.
  ConsolidationCheck c;
  const Scene& sc = su.scene;
  if (sc.bodies.empty() || sc.bodies[0].is_polygon() || sc.bodies[0].is_release() || sc.bodies[0].is_mesh()) return c;  // boxes only
  const Body& b = sc.bodies[0];
  const long n = fr.n;
  const double xa = b.box_min[0] + 0.25 * (b.box_max[0] - b.box_min[0]);
  const double xb = b.box_min[0] + 0.75 * (b.box_max[0] - b.box_min[0]);
  const double g = std::fabs(sc.gravity[1]);
  double top = -1e300;
  for (long i = 0; i < n; ++i)
    if (fr.x[i] >= xa && fr.x[i] <= xb) top = std::max(top, fr.x[n + i] + 0.5 * su.spacing);
  const long nb = static_cast<long>((top - b.box_min[1]) / sc.h) + 1;
  std::vector<double> sum(nb, 0), cnt(nb, 0), rho(nb, 0);
  for (long i = 0; i < n; ++i) {
    if (fr.x[i] < xa || fr.x[i] > xb) continue;
    const long k = std::clamp(static_cast<long>((top - fr.x[n + i]) / sc.h), 0L, nb - 1);
    sum[k] += -fr.syy[i];
    const int m = su.point_material.empty() ? 0 : su.point_material[i];
    rho[k] += sc.material_at(m).params.c.rho_p / (1 + fr.e[i]);
    cnt[k] += 1;
  }
  double load = 0;  // rho g integrated over the bins above
  for (long k = 0; k < nb; ++k) {
    if (cnt[k] == 0) continue;
    const double r = rho[k] / cnt[k];
    const double depth_mid = load + r * g * 0.5 * sc.h;
    load += r * g * sc.h;
    const double sv = sum[k] / cnt[k];
    if (k >= 1 && k + 1 < nb) {
      c.max_rel_error = std::max(c.max_rel_error, std::fabs(sv - depth_mid) / depth_mid);
    }
    if (k + 1 == nb || (k + 2 == nb)) {
      c.base_sigma_v = sv;
      c.base_rho_g_h = depth_mid;
    }
  }
  c.done = true;
  return c;
}

}  // namespace granflow::mpm
