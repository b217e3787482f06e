// A closed triangle mesh as a solid: checks, exact line crossings, nearest faces (mesh_geometry.hpp).
#include "scene/mesh_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "scene/setup_common.hpp"

namespace granflow::mpm {

void place_mesh(TriMesh& m, const MeshPlacement& p) {
  const double deg = M_PI / 180;
  const bool turn = p.rotation[0] != 0 || p.rotation[1] != 0 || p.rotation[2] != 0;
  const double cx = std::cos(p.rotation[0] * deg), sx = std::sin(p.rotation[0] * deg);
  const double cy = std::cos(p.rotation[1] * deg), sy = std::sin(p.rotation[1] * deg);
  const double cz = std::cos(p.rotation[2] * deg), sz = std::sin(p.rotation[2] * deg);
  for (size_t i = 0; i < m.xyz.size(); i += 3) {
    double x = m.xyz[i] * p.scale, y = m.xyz[i + 1] * p.scale, z = m.xyz[i + 2] * p.scale;
    if (turn) {  // about x, then y, then z
      double t = cx * y - sx * z;
      z = sx * y + cx * z;
      y = t;
      t = cy * x + sy * z;
      z = -sy * x + cy * z;
      x = t;
      t = cz * x - sz * y;
      y = sz * x + cz * y;
      x = t;
    }
    m.xyz[i] = x + p.offset[0];
    m.xyz[i + 1] = y + p.offset[1];
    m.xyz[i + 2] = z + p.offset[2];
  }
}

namespace detail {
namespace {

using i128 = __int128;

void sub(const double* a, const double* b, double* c) {
  for (int d = 0; d < 3; ++d) c[d] = a[d] - b[d];
}
void cross(const double* a, const double* b, double* c) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}
double dot(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm(const double* a) { return std::sqrt(dot(a, a)); }
void normalize(double* a) {
  const double l = norm(a);
  if (l > 0)
    for (int d = 0; d < 3; ++d) a[d] /= l;
}

// Twice the signed area of the plane triangle (a, b, c): positive when counter-clockwise.
double orient2(const double* a, const double* b, const double* c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

std::string point(const double* p) { return "(" + fmt(p[0]) + ", " + fmt(p[1]) + ", " + fmt(p[2]) + ")"; }

// Sign of the edge function of edge i -> j at q in 2D, exact; zero counts as the perturbed
// point's side: the canonical (lexicographically increasing) edge's left (see crossings).
int edge_sign(std::int64_t iu, std::int64_t iv, std::int64_t ju, std::int64_t jv, std::int64_t qu, std::int64_t qv) {
  const bool swap = iu > ju || (iu == ju && iv > jv);
  if (swap) {
    std::swap(iu, ju);
    std::swap(iv, jv);
  }
  const i128 w = i128(ju - iu) * i128(qv - iv) - i128(jv - iv) * i128(qu - iu);
  const int s = w >= 0 ? 1 : -1;
  return swap ? -s : s;
}

}  // namespace

std::int64_t MeshSolid::snap(int d, double x) const { return std::llround((x - lo_[d]) / res_); }

MeshSolid::MeshSolid(const TriMesh& m, const std::string& key) : key_(key), file_(m.file), x_(m.xyz) {
  const std::string who = (file_.empty() ? "the mesh" : file_) + ": ";
  const long nv = m.vertices();
  for (long i = 0; i < nv; ++i)
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(x_[3 * i + d])) fail(key, who + "vertex " + std::to_string(i) + " is not finite (NaN or infinite)");
  for (int d = 0; d < 3; ++d) {
    lo_[d] = std::numeric_limits<double>::max();
    hi_[d] = -lo_[d];
  }
  // triangles with a repeated vertex are dropped (they cover nothing and cancel their edges)
  for (size_t k = 0; k + 2 < m.tri.size(); k += 3) {
    const std::int32_t a = m.tri[k], b = m.tri[k + 1], c = m.tri[k + 2];
    if (a < 0 || b < 0 || c < 0 || a >= nv || b >= nv || c >= nv)
      fail(key, who + "triangle " + std::to_string(k / 3) + " names a vertex the mesh does not have");
    if (a == b || b == c || a == c) continue;
    t_.insert(t_.end(), {a, b, c});
    for (const std::int32_t v : {a, b, c})
      for (int d = 0; d < 3; ++d) {
        lo_[d] = std::min(lo_[d], x_[3 * v + d]);
        hi_[d] = std::max(hi_[d], x_[3 * v + d]);
      }
  }
  if (t_.empty()) fail(key, who + "has no triangle (an empty mesh)");
  for (int d = 0; d < 3; ++d) extent_ = std::max(extent_, hi_[d] - lo_[d]);
  const long nt = triangles();
  // normals, degenerate triangles, volume about the box's centre (divergence theorem)
  n_.assign(3 * nt, 0.0);
  double c0[3];
  for (int d = 0; d < 3; ++d) c0[d] = 0.5 * (lo_[d] + hi_[d]);
  long degenerate = 0;
  for (long t = 0; t < nt; ++t) {
    const double *a = &x_[3 * t_[3 * t]], *b = &x_[3 * t_[3 * t + 1]], *c = &x_[3 * t_[3 * t + 2]];
    double ab[3], ac[3], nn[3], ra[3], rb[3], rc[3], bc[3];
    sub(b, a, ab);
    sub(c, a, ac);
    cross(ab, ac, nn);
    if (!(norm(nn) > 1e-14 * extent_ * extent_)) {
      ++degenerate;
      continue;
    }
    normalize(nn);
    std::copy(nn, nn + 3, &n_[3 * t]);
    sub(a, c0, ra);
    sub(b, c0, rb);
    sub(c, c0, rc);
    cross(rb, rc, bc);
    volume_ += dot(ra, bc) / 6;
  }
  if (degenerate == nt) fail(key, who + "all " + std::to_string(nt) + " triangles are degenerate (no area)");
  check_edges();
  if (!(std::fabs(volume_) > 1e-12 * extent_ * extent_ * extent_)) fail(key, who + "encloses no volume");
  if (volume_ < 0) {  // closed and consistent, but facing inward: turned outward
    volume_ = -volume_;
    for (long t = 0; t < nt; ++t) {
      std::swap(t_[3 * t + 1], t_[3 * t + 2]);
      for (int d = 0; d < 3; ++d) n_[3 * t + d] = -n_[3 * t + d];
    }
    check_edges();  // the edge pseudo-normals again, of the turned triangles
  }
  part_.resize(nt);
  for (long t = 0; t < nt; ++t) {
    const double* nn = &n_[3 * t];
    int d = 0;
    for (int e = 1; e < 3; ++e)
      if (std::fabs(nn[e]) > std::fabs(nn[d])) d = e;
    part_[t] = static_cast<std::int8_t>(2 * d + (nn[d] > 0 ? 1 : 0));
  }
  // vertex pseudo-normals: the normals of the triangles about the vertex weighted by their angle there
  vn_.assign(3 * nv, 0.0);
  for (long t = 0; t < nt; ++t)
    for (int e = 0; e < 3; ++e) {
      const double *p = &x_[3 * t_[3 * t + e]], *q = &x_[3 * t_[3 * t + (e + 1) % 3]], *r = &x_[3 * t_[3 * t + (e + 2) % 3]];
      double u[3], w[3];
      sub(q, p, u);
      sub(r, p, w);
      const double c = dot(u, w) / (norm(u) * norm(w));
      const double angle = std::acos(std::clamp(std::isfinite(c) ? c : 1.0, -1.0, 1.0));
      for (int d = 0; d < 3; ++d) vn_[3 * t_[3 * t + e] + d] += angle * n_[3 * t + d];
    }
  for (long v = 0; v < nv; ++v) normalize(&vn_[3 * v]);
  // snapped vertices: 2^-50 of the extent (coordinates below 2^51, products below 2^103)
  res_ = extent_ * std::ldexp(1.0, -50);
  q_.resize(3 * nv);
  for (long v = 0; v < nv; ++v)
    for (int d = 0; d < 3; ++d) q_[3 * v + d] = snap(d, x_[3 * v + d]);
  // projections' bins along each axis
  const int side = static_cast<int>(std::clamp(std::sqrt(double(nt) / 2), 1.0, 2048.0));
  for (int a = 0; a < 3; ++a) {
    Bins2& b = bins_[a];
    const int u = (a + 1) % 3, v = (a + 2) % 3;
    b.nu = b.nv = side;
    b.u0 = lo_[u];
    b.v0 = lo_[v];
    b.du = std::max(hi_[u] - lo_[u], extent_ * 1e-9) / side;
    b.dv = std::max(hi_[v] - lo_[v], extent_ * 1e-9) / side;
    auto range = [&](long t, int& i0, int& i1, int& j0, int& j1) {
      double mu = std::numeric_limits<double>::max(), Mu = -mu, mv = mu, Mv = -mu;
      for (int c = 0; c < 3; ++c) {
        const double* p = &x_[3 * t_[3 * t + c]];
        mu = std::min(mu, p[u]), Mu = std::max(Mu, p[u]), mv = std::min(mv, p[v]), Mv = std::max(Mv, p[v]);
      }
      const double g = 4 * res_;  // the snapped triangle may reach that far beyond
      i0 = std::clamp(static_cast<int>(std::floor((mu - g - b.u0) / b.du)), 0, b.nu - 1);
      i1 = std::clamp(static_cast<int>(std::floor((Mu + g - b.u0) / b.du)), 0, b.nu - 1);
      j0 = std::clamp(static_cast<int>(std::floor((mv - g - b.v0) / b.dv)), 0, b.nv - 1);
      j1 = std::clamp(static_cast<int>(std::floor((Mv + g - b.v0) / b.dv)), 0, b.nv - 1);
    };
    b.start.assign(size_t(b.nu) * b.nv + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<std::int32_t> fill;
      if (pass == 1) {
        for (size_t k = 1; k < b.start.size(); ++k) b.start[k] += b.start[k - 1];
        b.item.resize(b.start.back());
        fill.assign(b.start.begin(), b.start.end() - 1);
      }
      for (long t = 0; t < nt; ++t) {
        int i0, i1, j0, j1;
        range(t, i0, i1, j0, j1);
        for (int j = j0; j <= j1; ++j)
          for (int i = i0; i <= i1; ++i) {
            const size_t cell = size_t(j) * b.nu + i;
            if (pass == 0) ++b.start[cell + 1];
            else b.item[fill[cell]++] = static_cast<std::int32_t>(t);
          }
      }
    }
  }
  build_grid();
  check_crossing_triangles();
}

void MeshSolid::check_edges() {
  struct Rec {
    std::uint64_t key;
    std::int32_t tri;
    std::int8_t slot, fwd;
  };
  const long nt = triangles();
  std::vector<Rec> recs;
  recs.reserve(3 * nt);
  for (long t = 0; t < nt; ++t)
    for (int e = 0; e < 3; ++e) {
      const std::uint32_t a = t_[3 * t + e], b = t_[3 * t + (e + 1) % 3];
      recs.push_back({(std::uint64_t(std::min(a, b)) << 32) | std::max(a, b), static_cast<std::int32_t>(t),
                      static_cast<std::int8_t>(e), static_cast<std::int8_t>(a < b)});
    }
  std::sort(recs.begin(), recs.end(), [](const Rec& x, const Rec& y) { return x.key < y.key || (x.key == y.key && x.tri < y.tri); });
  en_.assign(9 * nt, 0.0);
  long open = 0, many = 0, same = 0;
  const Rec* first = nullptr;
  std::string first_what;
  for (size_t i = 0; i < recs.size();) {
    size_t j = i;
    while (j < recs.size() && recs[j].key == recs[i].key) ++j;
    const size_t k = j - i;
    const char* what = nullptr;
    if (k == 1) ++open, what = "belongs to one triangle only (a hole)";
    else if (k > 2) ++many, what = "is shared by more than two triangles";
    else if (recs[i].fwd == recs[i + 1].fwd) ++same, what = "is traversed the same way by both its triangles (a flipped face)";
    if (what && (!first || recs[i].tri < first->tri)) {
      first = &recs[i];
      first_what = what;
    }
    if (!what) {  // the edge's pseudo-normal: the mean of its two faces' normals
      double e[3];
      for (int d = 0; d < 3; ++d) e[d] = n_[3 * recs[i].tri + d] + n_[3 * recs[i + 1].tri + d];
      normalize(e);
      for (size_t r = i; r < j; ++r) std::copy(e, e + 3, &en_[9 * recs[r].tri + 3 * recs[r].slot]);
    }
    i = j;
  }
  if (!first) return;
  const long bad = open + many + same;
  std::string counts;
  auto add = [&](long c, const char* s) {
    if (c) counts += (counts.empty() ? "" : ", ") + std::to_string(c) + " " + s;
  };
  add(open, "open (one triangle)");
  add(many, "shared by more than two triangles");
  add(same, "traversed the same way by both triangles (flipped faces)");
  const std::int32_t a = static_cast<std::int32_t>(first->key >> 32), b = static_cast<std::int32_t>(first->key & 0xffffffffu);
  const std::string why = open || many ? "is not closed" : "is not consistently oriented";
  fail(key_, (file_.empty() ? "the mesh" : file_) + ": " + why + ": " + std::to_string(bad) + " bad edge" +
                 (bad > 1 ? "s" : "") + " of " + std::to_string(recs.size() / 2) + " (" + counts +
                 "); the first, of triangle " + std::to_string(first->tri) + ", from " + point(&x_[3 * a]) + " to " +
                 point(&x_[3 * b]) + ", " + first_what +
                 ". A body or obstacle needs a closed surface, every edge shared by two triangles that traverse it in "
                 "opposite directions");
}

void MeshSolid::build_grid() {
  const long nt = triangles();
  double vol = 1;
  for (int d = 0; d < 3; ++d) vol *= std::max(hi_[d] - lo_[d], extent_ * 1e-3);
  const double c = std::cbrt(vol / (2.0 * double(nt)));
  for (int d = 0; d < 3; ++d) {
    g0_[d] = lo_[d];
    gn_[d] = static_cast<int>(std::clamp(std::ceil((hi_[d] - lo_[d]) / c), 1.0, 256.0));
    gc_[d] = std::max(hi_[d] - lo_[d], extent_ * 1e-9) / gn_[d];
  }
  gstart_.assign(size_t(gn_[0]) * gn_[1] * gn_[2] + 1, 0);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<std::int32_t> fill;
    if (pass == 1) {
      for (size_t k = 1; k < gstart_.size(); ++k) gstart_[k] += gstart_[k - 1];
      gitem_.resize(gstart_.back());
      fill.assign(gstart_.begin(), gstart_.end() - 1);
    }
    for (long t = 0; t < nt; ++t) {
      int i0[3], i1[3];
      for (int d = 0; d < 3; ++d) {
        double a = std::numeric_limits<double>::max(), b = -a;
        for (int k = 0; k < 3; ++k) a = std::min(a, x_[3 * t_[3 * t + k] + d]), b = std::max(b, x_[3 * t_[3 * t + k] + d]);
        i0[d] = std::clamp(static_cast<int>(std::floor((a - g0_[d]) / gc_[d])), 0, gn_[d] - 1);
        i1[d] = std::clamp(static_cast<int>(std::floor((b - g0_[d]) / gc_[d])), 0, gn_[d] - 1);
      }
      for (int k = i0[2]; k <= i1[2]; ++k)
        for (int j = i0[1]; j <= i1[1]; ++j)
          for (int i = i0[0]; i <= i1[0]; ++i) {
            const size_t cell = (size_t(k) * gn_[1] + j) * gn_[0] + i;
            if (pass == 0) ++gstart_[cell + 1];
            else gitem_[fill[cell]++] = static_cast<std::int32_t>(t);
          }
    }
  }
}

void MeshSolid::check_crossing_triangles() const {
  const double eps = 1e-10 * extent_;
  const std::int32_t* T = t_.data();
  // does edge p-q pierce triangle t's interior? then at x
  auto pierces = [&](const double* p, const double* q, int t, double* x) {
    const double *a = &x_[3 * T[3 * t]], *b = &x_[3 * T[3 * t + 1]], *c = &x_[3 * T[3 * t + 2]];
    const double* n = &n_[3 * t];
    double ap[3], aq[3];
    sub(p, a, ap);
    sub(q, a, aq);
    const double dp = dot(ap, n), dq = dot(aq, n);
    if (!((dp > eps && dq < -eps) || (dp < -eps && dq > eps))) return false;
    const double s = dp / (dp - dq);
    for (int d = 0; d < 3; ++d) x[d] = p[d] + s * (q[d] - p[d]);
    const double* v[3] = {a, b, c};
    for (int e = 0; e < 3; ++e) {
      double ev[3], w[3], cw[3];
      sub(v[(e + 1) % 3], v[e], ev);
      sub(x, v[e], w);
      cross(ev, w, cw);
      if (!(dot(cw, n) >= -eps * norm(ev))) return false;  // on its edges too: non-adjacent triangles never meet
    }
    return true;
  };
  // Coplanar triangles s and t whose interiors overlap (a surface lying on itself, as where two
  // solids touch face to face): their intersection, projected on the plane of the normal's two
  // smaller components, has an area above round-off (1e-9 of the smaller triangle's). Exact up
  // to that threshold: every configuration of shared, touching or collinear vertices and edges.
  auto overlaps = [&](int s, int t, double* x) {
    const double* ns = &n_[3 * s];
    const double* nt = &n_[3 * t];
    if (std::fabs(dot(ns, nt)) < 1 - 1e-9) return false;
    for (int k = 0; k < 3; ++k) {
      double r[3];
      sub(&x_[3 * T[3 * s + k]], &x_[3 * T[3 * t]], r);
      if (std::fabs(dot(r, nt)) > eps) return false;
    }
    int drop = 0;
    for (int d = 1; d < 3; ++d)
      if (std::fabs(nt[d]) > std::fabs(nt[drop])) drop = d;
    const int u = (drop + 1) % 3, w = (drop + 2) % 3;
    double ps[3][2], pt[3][2];
    for (int k = 0; k < 3; ++k) {
      ps[k][0] = x_[3 * T[3 * s + k] + u], ps[k][1] = x_[3 * T[3 * s + k] + w];
      pt[k][0] = x_[3 * T[3 * t + k] + u], pt[k][1] = x_[3 * T[3 * t + k] + w];
    }
    double c[2];
    const double common = triangle_overlap_area(ps, pt, c);
    const double smaller2 = std::min(std::fabs(orient2(ps[0], ps[1], ps[2])), std::fabs(orient2(pt[0], pt[1], pt[2])));
    if (!(common > 0.5e-9 * smaller2)) return false;
    const double* a = &x_[3 * T[3 * t]];
    x[u] = c[0], x[w] = c[1];
    x[drop] = a[drop] - (nt[u] * (c[0] - a[u]) + nt[w] * (c[1] - a[w])) / nt[drop];  // on t's plane
    return true;
  };
  long pairs = 0;
  int fa = -1, fb = -1;
  double at[3] = {0, 0, 0};
  const size_t cells = gstart_.size() - 1;
  for (size_t cell = 0; cell < cells; ++cell) {
    const int ci = static_cast<int>(cell % gn_[0]), cj = static_cast<int>(cell / gn_[0] % gn_[1]),
              ck = static_cast<int>(cell / (size_t(gn_[0]) * gn_[1]));
    const int cc[3] = {ci, cj, ck};
    for (std::int32_t x = gstart_[cell]; x < gstart_[cell + 1]; ++x)
      for (std::int32_t y = x + 1; y < gstart_[cell + 1]; ++y) {
        const int s = gitem_[x], t = gitem_[y];
        if (n_[3 * s] == 0 && n_[3 * s + 1] == 0 && n_[3 * s + 2] == 0) continue;
        if (n_[3 * t] == 0 && n_[3 * t + 1] == 0 && n_[3 * t + 2] == 0) continue;
        bool apart = false, here = true;
        for (int d = 0; d < 3 && !apart; ++d) {
          double as = std::numeric_limits<double>::max(), bs = -as, at_ = as, bt = -as;
          for (int k = 0; k < 3; ++k) {
            as = std::min(as, x_[3 * T[3 * s + k] + d]), bs = std::max(bs, x_[3 * T[3 * s + k] + d]);
            at_ = std::min(at_, x_[3 * T[3 * t + k] + d]), bt = std::max(bt, x_[3 * T[3 * t + k] + d]);
          }
          if (bs < at_ || bt < as) apart = true;
          const int owner = std::clamp(static_cast<int>(std::floor((std::max(as, at_) - g0_[d]) / gc_[d])), 0, gn_[d] - 1);
          here = here && owner == cc[d];  // each pair once: in the cell of its boxes' common corner
        }
        if (apart || !here) continue;
        // shared vertices; slot_s, slot_t: where the (last) shared one sits in s and in t
        int nshared = 0, slot_s = -1, slot_t = -1;
        for (int k = 0; k < 3; ++k) {
          bool in_t = false, in_s = false;
          for (int j = 0; j < 3; ++j) {
            in_t = in_t || T[3 * s + k] == T[3 * t + j];
            in_s = in_s || T[3 * t + k] == T[3 * s + j];
          }
          nshared += in_t;
          if (in_t) slot_s = k;
          if (in_s) slot_t = k;
        }
        if (nshared == 3) continue;  // the same triangle twice: check_edges counts its edges
        double p[3];
        bool hit = false;
        if (nshared == 0) {
          for (int e = 0; e < 3 && !hit; ++e)
            hit = pierces(&x_[3 * T[3 * s + e]], &x_[3 * T[3 * s + (e + 1) % 3]], t, p) ||
                  pierces(&x_[3 * T[3 * t + e]], &x_[3 * T[3 * t + (e + 1) % 3]], s, p);
        } else if (nshared == 1) {
          // a crossing that starts at the common vertex leaves through the edge of one of them
          // opposite it (the other edges meet the other's plane only at that vertex)
          hit = pierces(&x_[3 * T[3 * s + (slot_s + 1) % 3]], &x_[3 * T[3 * s + (slot_s + 2) % 3]], t, p) ||
                pierces(&x_[3 * T[3 * t + (slot_t + 1) % 3]], &x_[3 * T[3 * t + (slot_t + 2) % 3]], s, p);
        }
        // two shared vertices: not coplanar, they meet only on their common edge
        hit = hit || overlaps(s, t, p);
        if (!hit) continue;
        if (pairs++ == 0 || std::min(s, t) < std::min(fa, fb)) {
          fa = std::min(s, t), fb = std::max(s, t);
          std::copy(p, p + 3, at);
        }
      }
  }
  if (pairs)
    fail(key_, (file_.empty() ? "the mesh" : file_) + ": is self-intersecting: " + std::to_string(pairs) +
                   " pair" + (pairs > 1 ? "s" : "") + " of triangles cross or overlap; the first, triangles " +
                   std::to_string(fa) + " and " + std::to_string(fb) + ", at " + point(at) +
                   ". Separate or merge the parts (a body or obstacle needs one surface without crossings)");
}

double triangle_overlap_area(const double a[3][2], const double b[3][2], double at[2]) {
  // b counter-clockwise
  const bool ccw = orient2(b[0], b[1], b[2]) >= 0;
  const int order[3] = {0, ccw ? 1 : 2, ccw ? 2 : 1};
  double poly[9][2], next[9][2];  // a triangle clipped by three half-planes has at most 6 vertices
  int n = 3;
  for (int k = 0; k < 3; ++k) poly[k][0] = a[k][0], poly[k][1] = a[k][1];
  for (int e = 0; e < 3 && n > 0; ++e) {
    const double* p = b[order[e]];
    const double* q = b[order[(e + 1) % 3]];
    int m = 0;
    for (int k = 0; k < n; ++k) {
      const double* r0 = poly[k];
      const double* r1 = poly[(k + 1) % n];
      const double s0 = orient2(p, q, r0), s1 = orient2(p, q, r1);
      if (s0 >= 0) next[m][0] = r0[0], next[m][1] = r0[1], ++m;
      if ((s0 > 0 && s1 < 0) || (s0 < 0 && s1 > 0)) {
        const double f = s0 / (s0 - s1);
        next[m][0] = r0[0] + f * (r1[0] - r0[0]), next[m][1] = r0[1] + f * (r1[1] - r0[1]), ++m;
      }
    }
    n = m;
    for (int k = 0; k < n; ++k) poly[k][0] = next[k][0], poly[k][1] = next[k][1];
  }
  double area = 0, cu = 0, cv = 0;
  for (int k = 0; k < n; ++k) {
    const double* r0 = poly[k];
    const double* r1 = poly[(k + 1) % n];
    const double cr = r0[0] * r1[1] - r1[0] * r0[1];
    area += cr, cu += (r0[0] + r1[0]) * cr, cv += (r0[1] + r1[1]) * cr;
  }
  area *= 0.5;
  if (area != 0) at[0] = cu / (6 * area), at[1] = cv / (6 * area);
  else if (n > 0) at[0] = poly[0][0], at[1] = poly[0][1];
  return std::fabs(area);
}

void MeshSolid::centroid(double* c) const {
  double c0[3], s[3] = {0, 0, 0}, v = 0;
  for (int d = 0; d < 3; ++d) c0[d] = 0.5 * (lo_[d] + hi_[d]);
  for (long t = 0; t < triangles(); ++t) {
    double r[3][3], bc[3];
    for (int k = 0; k < 3; ++k) sub(&x_[3 * t_[3 * t + k]], c0, r[k]);
    cross(r[1], r[2], bc);
    const double w = dot(r[0], bc) / 6;
    v += w;
    for (int d = 0; d < 3; ++d) s[d] += w * (r[0][d] + r[1][d] + r[2][d]) / 4;
  }
  for (int d = 0; d < 3; ++d) c[d] = c0[d] + s[d] / v;
}

// The line is perturbed by (-delta, 1) epsilon in (u, v), delta << 1: every canonical edge
// direction (u increasing, or u equal and v increasing) then has the line strictly on its left
// when it passes exactly through the edge, so edge_sign's zero rule is one consistent position.
void MeshSolid::crossings(int a, double pu, double pv, std::vector<MeshCrossing>& out) const {
  out.clear();
  const int u = (a + 1) % 3, v = (a + 2) % 3;
  const double g = 4 * res_;
  if (pu < lo_[u] - g || pu > hi_[u] + g || pv < lo_[v] - g || pv > hi_[v] + g) return;
  const Bins2& b = bins_[a];
  const int i = std::clamp(static_cast<int>(std::floor((pu - b.u0) / b.du)), 0, b.nu - 1);
  const int j = std::clamp(static_cast<int>(std::floor((pv - b.v0) / b.dv)), 0, b.nv - 1);
  const size_t cell = size_t(j) * b.nu + i;
  const std::int64_t qu = snap(u, pu), qv = snap(v, pv);
  for (std::int32_t k = b.start[cell]; k < b.start[cell + 1]; ++k) {
    const int t = b.item[k];
    const std::int64_t* A = &q_[3 * t_[3 * t]];
    const std::int64_t* B = &q_[3 * t_[3 * t + 1]];
    const std::int64_t* C = &q_[3 * t_[3 * t + 2]];
    const int s0 = edge_sign(A[u], A[v], B[u], B[v], qu, qv);
    if (edge_sign(B[u], B[v], C[u], C[v], qu, qv) != s0 || edge_sign(C[u], C[v], A[u], A[v], qu, qv) != s0) continue;
    const double *x0 = &x_[3 * t_[3 * t]], *x1 = &x_[3 * t_[3 * t + 1]], *x2 = &x_[3 * t_[3 * t + 2]];
    const double* n = &n_[3 * t];
    const double tmin = std::min({x0[a], x1[a], x2[a]}), tmax = std::max({x0[a], x1[a], x2[a]});
    double tt = (x0[a] + x1[a] + x2[a]) / 3;
    if (n[a] != 0) tt = x0[a] - (n[u] * (pu - x0[u]) + n[v] * (pv - x0[v])) / n[a];
    out.push_back({std::clamp(tt, tmin, tmax), s0, t});
  }
  std::sort(out.begin(), out.end(), [](const MeshCrossing& x, const MeshCrossing& y) { return x.t < y.t || (x.t == y.t && x.tri < y.tri); });
}

bool MeshSolid::inside(const double* p) const {
  for (int d = 0; d < 3; ++d)
    if (p[d] < lo_[d] || p[d] > hi_[d]) return false;
  thread_local std::vector<MeshCrossing> cr;
  crossings(1, p[2], p[0], cr);
  int w = 0;
  for (const MeshCrossing& c : cr) {
    if (!(c.t < p[1])) break;
    w -= c.sign;
  }
  return w != 0;
}

// feature: 0 the face, 1 + e edge e, 4 + k vertex k
double MeshSolid::face_key(int tri, const double* p, double tol, int& feature) const {
  const double* v[3] = {&x_[3 * t_[3 * tri]], &x_[3 * t_[3 * tri + 1]], &x_[3 * t_[3 * tri + 2]]};
  const double* n = &n_[3 * tri];
  const double nin[3] = {-n[0], -n[1], -n[2]};
  double w[3];
  sub(p, v[0], w);
  const double sd = w[0] * nin[0] + w[1] * nin[1] + w[2] * nin[2];  // into the solid
  bool in = true;
  double best = std::numeric_limits<double>::max();
  feature = 0;
  for (int e = 0; e < 3 && in; ++e) {
    double ev[3], we[3], c[3];
    sub(v[(e + 1) % 3], v[e], ev);
    sub(p, v[e], we);
    cross(ev, we, c);
    in = dot(c, n) >= -tol * norm(ev);
  }
  if (in) return sd >= -tol ? sd : -sd;
  for (int e = 0; e < 3; ++e) {
    double ev[3], we[3], r[3];
    sub(v[(e + 1) % 3], v[e], ev);
    sub(p, v[e], we);
    const double s = std::clamp(dot(we, ev) / dot(ev, ev), 0.0, 1.0);
    for (int d = 0; d < 3; ++d) r[d] = we[d] - s * ev[d];
    const double dist = norm(r);
    if (dist < best) {
      best = dist;
      feature = s == 0 ? 4 + e : (s == 1 ? 4 + (e + 1) % 3 : 1 + e);
    }
  }
  return best;
}

bool MeshSolid::nearest(const double* p, double tol, double limit, double& key, double* n, int& part) const {
  int c[3];
  for (int d = 0; d < 3; ++d) c[d] = std::clamp(static_cast<int>(std::floor((p[d] - g0_[d]) / gc_[d])), 0, gn_[d] - 1);
  const double cmin = std::min({gc_[0], gc_[1], gc_[2]});
  int best = -1, best_feature = 0, best_part = 0;
  double best_key = std::numeric_limits<double>::max();
  const int rmax = std::max({gn_[0], gn_[1], gn_[2]});
  for (int r = 0; r <= rmax; ++r) {
    for (int k = c[2] - r; k <= c[2] + r; ++k)
      for (int j = c[1] - r; j <= c[1] + r; ++j)
        for (int i = c[0] - r; i <= c[0] + r; ++i) {
          if (std::max({std::abs(i - c[0]), std::abs(j - c[1]), std::abs(k - c[2])}) != r) continue;
          if (i < 0 || j < 0 || k < 0 || i >= gn_[0] || j >= gn_[1] || k >= gn_[2]) continue;
          const size_t cell = (size_t(k) * gn_[1] + j) * gn_[0] + i;
          for (std::int32_t x = gstart_[cell]; x < gstart_[cell + 1]; ++x) {
            const int t = gitem_[x];
            if (n_[3 * t] == 0 && n_[3 * t + 1] == 0 && n_[3 * t + 2] == 0) continue;
            int f = 0;
            const double kk = face_key(t, p, tol, f);
            const int pt = part_[t];
            if (kk < best_key || (kk == best_key && (pt < best_part || (pt == best_part && t < best)))) {
              best_key = kk, best = t, best_feature = f, best_part = pt;
            }
          }
        }
    // every triangle not yet seen lies at least r cmin away (p in its clamped cell or beyond the
    // box), its key at least that less tol
    if (best >= 0 && best_key < r * cmin - tol) break;
    if (r * cmin - tol > limit) break;
  }
  if (best < 0 || !(best_key <= limit)) return false;
  key = best_key;
  part = best_part;
  const double* src = best_feature == 0 ? &n_[3 * best]
                      : best_feature < 4 ? &en_[9 * best + 3 * (best_feature - 1)]
                                         : &vn_[3 * t_[3 * best + best_feature - 4]];
  for (int d = 0; d < 3; ++d) n[d] = -src[d];
  return true;
}

void MeshSolid::deep(const double* p, double& key, double* n, int& part) const {
  thread_local std::vector<MeshCrossing> cr;
  crossings(1, p[2], p[0], cr);
  key = std::numeric_limits<double>::max();
  n[0] = n[2] = 0;
  n[1] = 1;
  part = 2;
  for (const MeshCrossing& c : cr)
    if (std::fabs(c.t - p[1]) < key) {
      key = std::fabs(c.t - p[1]);
      part = part_[c.tri];
      for (int d = 0; d < 3; ++d) n[d] = -n_[3 * c.tri + d];
    }
}

double MeshSolid::thinnest_run(const double* g, double h, double* at, int& axis) const {
  double thin = std::numeric_limits<double>::max();
  std::vector<MeshCrossing> cr;
  for (int a = 0; a < 3; ++a) {
    const int u = (a + 1) % 3, v = (a + 2) % 3;
    const long i0 = static_cast<long>(std::ceil((lo_[u] - g[u]) / h - 0.5)), i1 = static_cast<long>(std::floor((hi_[u] - g[u]) / h - 0.5));
    const long j0 = static_cast<long>(std::ceil((lo_[v] - g[v]) / h - 0.5)), j1 = static_cast<long>(std::floor((hi_[v] - g[v]) / h - 0.5));
    for (long j = j0; j <= j1; ++j)
      for (long i = i0; i <= i1; ++i) {
        const double pu = g[u] + (i + 0.5) * h, pv = g[v] + (j + 0.5) * h;
        crossings(a, pu, pv, cr);
        int w = 0;
        const MeshCrossing* entry = nullptr;
        for (const MeshCrossing& c : cr) {
          const int before = w;
          w -= c.sign;
          if (before == 0 && w != 0) entry = &c;
          if (before != 0 && w == 0 && entry) {
            const double run = c.t - entry->t;
            if ((part_[entry->tri] / 2 == a || part_[c.tri] / 2 == a) && run < thin) {
              thin = run;
              axis = a;
              at[a] = 0.5 * (c.t + entry->t);
              at[u] = pu;
              at[v] = pv;
            }
          }
        }
      }
  }
  return thin;
}

void mesh_in_grid(const MeshSolid& m, const Scene& sc, const std::string& key) {
  double ratio = 0;
  bool out = false;
  for (int d = 0; d < 3; ++d) {
    ratio = std::max(ratio, (m.hi()[d] - m.lo()[d]) / sc.size[d]);
    // float32 files: a vertex at the grid's edge may come back 6e-8 of its coordinate beyond it
    const double slack = 1e-12 + 2e-7 * std::max(std::fabs(sc.origin[d]), std::fabs(sc.origin[d] + sc.size[d]));
    out = out || m.lo()[d] < sc.origin[d] - slack || m.hi()[d] > sc.origin[d] + sc.size[d] + slack;
  }
  if (!out) return;
  std::string box = "x [" + fmt(m.lo()[0]) + ", " + fmt(m.hi()[0]) + "], y [" + fmt(m.lo()[1]) + ", " + fmt(m.hi()[1]) +
                    "], z [" + fmt(m.lo()[2]) + ", " + fmt(m.hi()[2]) + "]";
  std::string grid;
  for (int d = 0; d < 3; ++d)
    grid += std::string(d ? ", " : "") + char('x' + d) + " [" + fmt(sc.origin[d]) + ", " + fmt(sc.origin[d] + sc.size[d]) + "]";
  std::string hint = "; move it (offset) or enlarge the grid (grid.origin, grid.size)";
  if (ratio > 200 && ratio < 5000)
    hint = "; it is about " + fmt(std::round(ratio)) + " times the grid's size: a mesh in millimetres needs scale = 0.001";
  fail(key, "the placed mesh (" + box + ") lies outside the grid (" + grid + ")" + hint);
}

}  // namespace detail
}  // namespace granflow::mpm
