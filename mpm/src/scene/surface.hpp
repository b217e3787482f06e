// A raster surface (the terrain, a release volume's top or bottom) in scene coordinates.
#pragma once

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <granflow/io/raster.hpp>

namespace granflow::mpm::detail {

// Georeferenced coordinates (easting 512345.678) need more digits than fmt's six.
inline std::string fmt_geo(double v) {
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

}  // namespace granflow::mpm::detail
