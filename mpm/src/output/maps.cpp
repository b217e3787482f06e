// Maps and deposit measures of 3D terrain runs on the terrain raster's cells (maps.hpp).
#include <granflow/mpm/maps.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <granflow/io/output.hpp>
#include <granflow/io/raster.hpp>

#include "scene/surface.hpp"

namespace granflow::mpm {

namespace {

// The base polyline's height at x, level beyond its ends.
double base_height(const BaseLine& b, double x) {
  if (x <= b.x.front()) return b.y.front();
  if (x >= b.x.back()) return b.y.back();
  const size_t k = static_cast<size_t>(std::upper_bound(b.x.begin(), b.x.end(), x) - b.x.begin());
  const double w = (x - b.x[k - 1]) / (b.x[k] - b.x[k - 1]);
  return b.y[k - 1] + w * (b.y[k] - b.y[k - 1]);
}

double plan_z(const Frame& fr, long i) { return fr.dim == 3 ? fr.x[2 * fr.n + i] : 0.0; }

// Annuli of one sector: per annulus the sum of its cells' distances and thicknesses, and their count.
struct Annuli {
  std::vector<double> sum_r, sum_t, count;
  void add(size_t k, double r, double t) {
    if (k >= count.size()) sum_r.resize(k + 1), sum_t.resize(k + 1), count.resize(k + 1);
    sum_r[k] += r;
    sum_t[k] += t;
    count[k] += 1;
  }
  // Where the annuli's mean thickness, at their mean distance, first falls below `threshold`.
  double crossing(double threshold) const {
    double r_in = 0, t_in = 0;
    bool first = true;
    for (size_t k = 0; k < count.size(); ++k) {
      if (count[k] == 0) continue;
      const double r = sum_r[k] / count[k], t = sum_t[k] / count[k];
      if (t < threshold) return first ? 0.0 : r_in + (r - r_in) * (t_in - threshold) / (t_in - t);
      first = false;
      r_in = r;
      t_in = t;
    }
    return std::numeric_limits<double>::quiet_NaN();
  }
};

}  // namespace

DepositEdges deposit_edges(const std::vector<double>& cx, const std::vector<double>& cz, const std::vector<double>& th,
                           double x0, double z0, double width, double threshold) {
  Annuli all, axes, diagonals;
  for (size_t c = 0; c < th.size(); ++c) {
    const double r = std::hypot(cx[c] - x0, cz[c] - z0);
    const size_t k = static_cast<size_t>(r / width);
    all.add(k, r, th[c]);
    const double deg = std::atan2(std::fabs(cz[c] - z0), std::fabs(cx[c] - x0)) * (180 / 3.14159265358979323846);
    if (deg <= 15 || deg >= 75) axes.add(k, r, th[c]);
    if (std::fabs(deg - 45) <= 15) diagonals.add(k, r, th[c]);
  }
  return {all.crossing(threshold), axes.crossing(threshold), diagonals.crossing(threshold)};
}

TerrainMaps::TerrainMaps(const SceneSetup& su) : su_(&su) {
  const Scene& sc = su.scene;
  if (sc.dim == 2 && sc.base) {  // a profile along the base: bins of output.map_cell (else h) from the grid's left edge
    profile_ = true;
    cellsize_ = sc.output.map_cell > 0 ? sc.output.map_cell : sc.h;
    ncols_ = std::max(1L, static_cast<long>(std::ceil(sc.size[0] / cellsize_ - 1e-9)));
    nrows_ = 1;
    col0 = row0 = row1 = 0;
    col1 = ncols_ - 1;
    point_volume_ = su.spacing * su.spacing;  // per unit width
    st_.max_speed.assign(static_cast<size_t>(ncols_), 0.0);
    st_.max_depth.assign(static_cast<size_t>(ncols_), 0.0);
    active_ = true;
    return;
  }
  if (sc.dim != 3 || !sc.terrain || !sc.terrain->raster) return;
  const io::Raster& r = *sc.terrain->raster;
  east0_ = sc.terrain->origin[0];
  north0_ = sc.terrain->origin[1];
  // The map cells: blocks of block x block raster cells from the raster's south-west corner
  // (output.map_cell); the last column and row of blocks may reach past the raster.
  block_ = sc.output.map_cell > 0 ? std::max(1L, std::lround(sc.output.map_cell / r.cellsize)) : 1;
  cellsize_ = r.cellsize * block_;
  ncols_ = (r.ncols + block_ - 1) / block_;
  nrows_ = (r.nrows + block_ - 1) / block_;
  // cells that overlap the grid's footprint by more than 1e-6 of a cell (the raster covers it: set-up checks)
  const double e0 = east0_ + sc.origin[0], e1 = e0 + sc.size[0];
  const double n0 = north0_ + sc.origin[2], n1 = n0 + sc.size[2];
  const double cs = cellsize_;
  auto clampc = [](double v, long hi) { return std::clamp(static_cast<long>(v), 0L, hi); };
  col0 = clampc(std::floor((e0 - r.west) / cs + 1e-6), ncols_ - 1);
  col1 = std::max(col0, clampc(std::ceil((e1 - r.west) / cs - 1e-6) - 1, ncols_ - 1));
  const long k0 = clampc(std::floor((n0 - r.south) / cs + 1e-6), nrows_ - 1);  // counted from the south
  const long k1 = std::max(k0, clampc(std::ceil((n1 - r.south) / cs - 1e-6) - 1, nrows_ - 1));
  row0 = nrows_ - 1 - k1;
  row1 = nrows_ - 1 - k0;
  point_volume_ = std::pow(su.spacing, 3);
  if (sc.output.deposit_direction.size() == 2) {
    const double dx = sc.output.deposit_direction[0], dz = sc.output.deposit_direction[1], len = std::hypot(dx, dz);
    if (len > 0) {
      dir_x_ = dx / len;
      dir_z_ = dz / len;
    }
  }
  const size_t cells = static_cast<size_t>((row1 - row0 + 1) * (col1 - col0 + 1));
  for (long row = row0; row <= row1; ++row)  // the window cells' plan centres in grid coordinates
    for (long col = col0; col <= col1; ++col) {
      cell_x_.push_back(r.west + (double(col) + 0.5) * cs - east0_);
      cell_z_.push_back(r.south + (double(nrows_ - 1 - row) + 0.5) * cs - north0_);
    }
  st_.max_speed.assign(cells, 0.0);
  st_.max_depth.assign(cells, 0.0);
  active_ = true;
}

long TerrainMaps::cell_of(double x, double z) const {
  if (profile_) {
    double c = std::floor((x - su_->scene.origin[0]) / cellsize_);
    if (std::isnan(c)) c = 0;
    return static_cast<long>(std::clamp(c, 0.0, double(ncols_ - 1)));
  }
  const io::Raster& r = *su_->scene.terrain->raster;
  const double cs = cellsize_;
  double c = std::floor((east0_ + x - r.west) / cs), k = std::floor((north0_ + z - r.south) / cs);
  if (std::isnan(c)) c = -1;  // (a bad point's frame is never sampled; no cast of NaN all the same)
  if (std::isnan(k)) k = -1;
  // clamped: a point on the footprint's edge counts in the edge cell
  const long col = std::clamp(static_cast<long>(std::clamp(c, -1.0, double(ncols_))), col0, col1);
  const long row = std::clamp(nrows_ - 1 - static_cast<long>(std::clamp(k, -1.0, double(nrows_))), row0, row1);
  return (row - row0) * (col1 - col0 + 1) + (col - col0);
}

std::vector<double> TerrainMaps::thickness(const Frame& fr) const {
  std::vector<double> th(st_.max_depth.size(), 0.0);
  if (!active_) return th;
  const long n = fr.n;
  for (long i = 0; i < n; ++i) th[cell_of(fr.x[i], plan_z(fr, i))] += point_volume_;
  for (double& v : th) v /= cell_measure();
  return th;
}

// Points below the terrain (3D): their count and the largest depth along the ground's normal,
// (b - y) cos of the slope at the point's plan position (the raster itself, not the grid).
void TerrainMaps::below_ground(const Frame& fr, double& count, double& deepest) const {
  count = deepest = 0;
  const Terrain& tr = *su_->scene.terrain;
  const detail::Surface ground(*tr.raster, tr.origin);
  const long n = fr.n;
  for (long i = 0; i < n; ++i) {
    const double x = fr.x[i], y = fr.x[n + i], z = fr.x[2 * n + i];
    const double b = ground.height(x, z);
    if (!(y < b)) continue;
    double nrm[3];
    ground.normal(x, z, nrm);
    count += 1;
    deepest = std::max(deepest, (b - y) * -nrm[1]);
  }
}

void TerrainMaps::sample(double t, double t_flow, const Frame& fr) {
  if (!active_) return;
  const std::vector<double> th = thickness(fr);
  const long n = fr.n;
  std::vector<long> cell(n);
  for (long i = 0; i < n; ++i) {
    cell[i] = cell_of(fr.x[i], plan_z(fr, i));
    double v2 = 0;
    for (int d = 0; d < fr.dim; ++d) v2 += fr.v[d * n + i] * fr.v[d * n + i];
    st_.max_speed[cell[i]] = std::max(st_.max_speed[cell[i]], std::sqrt(v2));
  }
  const double a = cell_measure(), s = su_->spacing;
  DepositRow row;
  row.t = t;
  row.t_flow = t_flow;
  std::vector<char> deposit(th.size(), 0);
  for (size_t c = 0; c < th.size(); ++c) {
    st_.max_depth[c] = std::max(st_.max_depth[c], th[c]);
    if (th[c] >= s * (1 - 1e-9)) {  // at least one point spacing thick
      deposit[c] = 1;
      row.area += a;
      row.volume += th[c] * a;
    }
  }
  double lo = std::numeric_limits<double>::max(), hi = -lo;
  for (long i = 0; i < n; ++i) {
    if (!deposit[cell[i]]) continue;
    const double along = fr.x[i] * dir_x_ + plan_z(fr, i) * dir_z_;
    lo = std::min(lo, along);
    hi = std::max(hi, along);
  }
  if (hi >= lo) row.extent = hi - lo + s;  // half a spacing beyond the outermost points each way
  if (!profile_) below_ground(fr, row.ground_points, row.ground_depth);
  const std::vector<double>& centre = su_->scene.output.deposit_centre;
  if (!profile_ && centre.size() == 2) {
    const double thr = su_->scene.output.edge_thickness > 0 ? su_->scene.output.edge_thickness : s;
    const DepositEdges e = deposit_edges(cell_x_, cell_z_, th, centre[0], centre[1], cellsize_, thr);
    row.edge_radius = e.all;
    row.edge_axes = e.axes;
    row.edge_diagonals = e.diagonals;
  }
  st_.deposit.push_back(row);
}

void TerrainMaps::restore(const MapsState& s) {
  if (!active_) {
    if (!s.max_speed.empty() || !s.deposit.empty()) throw std::runtime_error("maps of a scene without terrain");
    return;
  }
  if (s.max_speed.size() != st_.max_speed.size() || s.max_depth.size() != st_.max_depth.size())
    throw std::runtime_error("maps of " + std::to_string(s.max_speed.size()) + " cells, the terrain's window has " +
                             std::to_string(st_.max_speed.size()));
  st_ = s;
}

double TerrainMaps::terrain_mean(long row, long col) const {
  const io::Raster& r = *su_->scene.terrain->raster;
  // map row `row` (from the north) covers raster rows counted from the south [k0, k0 + block)
  const long k0 = (nrows_ - 1 - row) * block_, c0 = col * block_;
  double sum = 0;
  long n = 0;
  for (long k = k0; k < std::min(k0 + block_, r.nrows); ++k)
    for (long c = c0; c < std::min(c0 + block_, r.ncols); ++c) {
      const double z = r.at(r.nrows - 1 - k, c);
      if (std::isnan(z)) continue;
      sum += z;
      ++n;
    }
  return n ? sum / n : std::numeric_limits<double>::quiet_NaN();
}

void TerrainMaps::write_maps(const std::string& dir, const Frame& final_frame) const {
  if (!active_) return;
  if (profile_) {
    const std::vector<double> th = thickness(final_frame);
    const BaseLine& b = *su_->scene.base;
    std::ostringstream os;
    os.precision(9);
    os << "x,base_y,deposit_thickness,max_speed,max_depth\n";
    for (long c = 0; c < ncols_; ++c) {
      const double x = su_->scene.origin[0] + (c + 0.5) * cellsize_;
      const size_t k = static_cast<size_t>(c);
      os << x << ',' << base_height(b, x) << ',' << th[k] << ',' << st_.max_speed[k] << ',' << st_.max_depth[k] << '\n';
    }
    io::write_file(dir + "/deposit_profile.csv", os.str(), io::Durability::Buffered);
    return;
  }
  const io::Raster& terrain = *su_->scene.terrain->raster;
  const std::string folder = dir + "/maps";
  io::make_folder(folder);
  // The window of map cells over the grid's footprint, on the terrain's cell lattice: a cell keeps
  // its position, the cells outside the footprint (NODATA) are left out.
  io::Raster m;
  m.ncols = col1 - col0 + 1;
  m.nrows = row1 - row0 + 1;
  m.west = terrain.west + static_cast<double>(col0) * cellsize_;
  m.south = terrain.south + static_cast<double>(nrows_ - 1 - row1) * cellsize_;
  m.cellsize = cellsize_;
  m.crs = terrain.crs;
  auto write = [&](const std::string& name, const std::vector<double>& window, bool from_terrain) {
    m.values.assign(static_cast<size_t>(m.ncols * m.nrows), 0.0);
    for (long row = row0; row <= row1; ++row)
      for (long col = col0; col <= col1; ++col) {
        const size_t k = static_cast<size_t>((row - row0) * m.ncols + (col - col0));
        m.values[k] = from_terrain ? terrain_mean(row, col) : window[k];
      }
    const std::string base = folder + "/" + name;
    io::write_file(base + ".asc", io::esri_ascii_text(m), io::Durability::Buffered);
    if (!m.crs.empty()) io::write_file(base + ".prj", m.crs + "\n", io::Durability::Buffered);
    if (io::raster_gdal_available()) io::write_file(base + ".tif", io::geotiff_bytes(m), io::Durability::Buffered);
  };
  write("deposit_thickness", thickness(final_frame), false);
  write("max_speed", st_.max_speed, false);
  write("max_depth", st_.max_depth, false);
  write("terrain", {}, true);  // the plot script's hillshade, and the ground under the maps
}

void TerrainMaps::write_deposit_csv(const std::string& dir) const {
  if (!active_) return;
  std::ostringstream os;
  os.precision(8);
  const bool edge = !profile_ && su_->scene.output.deposit_centre.size() == 2;
  os << (profile_ ? "t,t_flow,length,area,extent"
                   : "t,t_flow,area,volume,extent,points_below_ground,max_depth_below_ground")
     << (edge ? ",edge_radius,edge_radius_axes,edge_radius_diagonals\n" : "\n");
  for (const DepositRow& r : st_.deposit) {
    os << r.t << ',' << r.t_flow << ',' << r.area << ',' << r.volume << ',' << r.extent;
    if (!profile_) os << ',' << r.ground_points << ',' << r.ground_depth;
    if (edge)
      for (double v : {r.edge_radius, r.edge_axes, r.edge_diagonals}) {
        os << ',';
        if (std::isfinite(v)) os << v;  // empty: the deposit reaches the map's edge
      }
    os << '\n';
  }
  io::write_file(dir + "/deposit.csv", os.str(), io::Durability::Buffered);
}

}  // namespace granflow::mpm
