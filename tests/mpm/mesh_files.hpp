// Meshes the tests write: triangle soups as STL (ASCII, binary), OBJ and PLY; a UV sphere, a box,
// a faceted vertical cylinder (docs/mpm_meshes.md).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

namespace granflow::mpm::test {

using Tri = std::array<double, 9>;  // three vertices, counter-clockwise from outside

inline std::vector<Tri> box_mesh(const double* lo, const double* hi) {
  auto v = [&](int i, int j, int k) { return std::array<double, 3>{i ? hi[0] : lo[0], j ? hi[1] : lo[1], k ? hi[2] : lo[2]}; };
  const int quads[6][4][3] = {{{0, 0, 0}, {0, 0, 1}, {0, 1, 1}, {0, 1, 0}}, {{1, 0, 0}, {1, 1, 0}, {1, 1, 1}, {1, 0, 1}},
                              {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}}, {{0, 1, 0}, {0, 1, 1}, {1, 1, 1}, {1, 1, 0}},
                              {{0, 0, 0}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}}, {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}}};
  std::vector<Tri> out;
  for (const auto& q : quads) {
    std::array<double, 3> c[4];
    for (int i = 0; i < 4; ++i) c[i] = v(q[i][0], q[i][1], q[i][2]);
    out.push_back({c[0][0], c[0][1], c[0][2], c[1][0], c[1][1], c[1][2], c[2][0], c[2][1], c[2][2]});
    out.push_back({c[0][0], c[0][1], c[0][2], c[2][0], c[2][1], c[2][2], c[3][0], c[3][1], c[3][2]});
  }
  return out;
}

// A UV sphere: nlat bands, nlon sectors, one vertex at each pole.
inline std::vector<Tri> sphere_mesh(const double* c, double r, int nlat, int nlon) {
  auto p = [&](int i, int j) {
    const double th = M_PI * i / nlat, ph = 2 * M_PI * (j % nlon) / nlon;
    if (i == 0) return std::array<double, 3>{c[0], c[1] + r, c[2]};
    if (i == nlat) return std::array<double, 3>{c[0], c[1] - r, c[2]};
    return std::array<double, 3>{c[0] + r * std::sin(th) * std::cos(ph), c[1] + r * std::cos(th), c[2] + r * std::sin(th) * std::sin(ph)};
  };
  std::vector<Tri> out;
  auto add = [&](std::array<double, 3> a, std::array<double, 3> b, std::array<double, 3> d) {
    out.push_back({a[0], a[1], a[2], b[0], b[1], b[2], d[0], d[1], d[2]});
  };
  for (int i = 0; i < nlat; ++i)
    for (int j = 0; j < nlon; ++j) {  // outward: (i, j) -> (i, j+1) -> (i+1, j) seen from outside
      if (i > 0) add(p(i, j), p(i, j + 1), p(i + 1, j));
      if (i < nlat - 1) add(p(i, j + 1), p(i + 1, j + 1), p(i + 1, j));
    }
  return out;
}

// A vertical prism of n facets about (x, z) = (cx, cz) from y0 to y1, vertices at radius rv.
inline std::vector<Tri> cylinder_mesh(double cx, double cz, double rv, double y0, double y1, int n) {
  std::vector<Tri> out;
  auto at = [&](int i) {
    const double a = 2 * M_PI * (i % n) / n;
    return std::array<double, 2>{cx + rv * std::cos(a), cz + rv * std::sin(a)};
  };
  for (int i = 0; i < n; ++i) {
    const auto a = at(i), b = at(i + 1);
    // side (outward normal radial): (a,y0) -> (a,y1) -> (b,y1) has normal along -(tangent x up)...
    out.push_back({a[0], y0, a[1], a[0], y1, a[1], b[0], y1, b[1]});
    out.push_back({a[0], y0, a[1], b[0], y1, b[1], b[0], y0, b[1]});
    out.push_back({cx, y1, cz, b[0], y1, b[1], a[0], y1, a[1]});  // top, normal +y
    out.push_back({cx, y0, cz, a[0], y0, a[1], b[0], y0, b[1]});  // bottom, normal -y
  }
  return out;
}

inline void write_stl(const std::string& path, const std::vector<Tri>& tris, bool binary) {
  std::ofstream f(path, std::ios::binary);
  if (binary) {
    char header[80] = {};
    std::memcpy(header, "granflow test mesh", 18);
    f.write(header, 80);
    const std::uint32_t n = static_cast<std::uint32_t>(tris.size());
    f.write(reinterpret_cast<const char*>(&n), 4);
    for (const Tri& t : tris) {
      float v[12] = {0, 0, 0};
      for (int i = 0; i < 9; ++i) v[3 + i] = static_cast<float>(t[i]);
      f.write(reinterpret_cast<const char*>(v), 48);
      const std::uint16_t attr = 0;
      f.write(reinterpret_cast<const char*>(&attr), 2);
    }
    return;
  }
  f.precision(9);  // float32 round trip
  f << "solid test\n";
  for (const Tri& t : tris) {
    f << "facet normal 0 0 0\n outer loop\n";
    for (int k = 0; k < 3; ++k) f << "  vertex " << float(t[3 * k]) << ' ' << float(t[3 * k + 1]) << ' ' << float(t[3 * k + 2]) << '\n';
    f << " endloop\nendfacet\n";
  }
  f << "endsolid test\n";
}

// OBJ: vertices once per triangle corner (welded by the reader), or indexed faces.
inline void write_obj(const std::string& path, const std::vector<Tri>& tris) {
  std::ofstream f(path);
  f.precision(9);
  f << "o part\n";
  for (const Tri& t : tris)
    for (int k = 0; k < 3; ++k) f << "v " << float(t[3 * k]) << ' ' << float(t[3 * k + 1]) << ' ' << float(t[3 * k + 2]) << '\n';
  for (size_t i = 0; i < tris.size(); ++i) f << "f " << 3 * i + 1 << ' ' << 3 * i + 2 << ' ' << 3 * i + 3 << '\n';
}

// ASCII PLY with an extra vertex property (ignored by the reader).
inline void write_ply(const std::string& path, const std::vector<Tri>& tris) {
  std::ofstream f(path);
  f.precision(9);
  f << "ply\nformat ascii 1.0\nelement vertex " << 3 * tris.size()
    << "\nproperty float x\nproperty float y\nproperty float z\nproperty float quality\nelement face " << tris.size()
    << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const Tri& t : tris)
    for (int k = 0; k < 3; ++k) f << float(t[3 * k]) << ' ' << float(t[3 * k + 1]) << ' ' << float(t[3 * k + 2]) << " 0.5\n";
  for (size_t i = 0; i < tris.size(); ++i) f << "3 " << 3 * i << ' ' << 3 * i + 1 << ' ' << 3 * i + 2 << '\n';
}

}  // namespace granflow::mpm::test
