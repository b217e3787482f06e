// Boundary force rows, their CSVs and the obstacles' geometry (forces.hpp).
#include <granflow/mpm/forces.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include <granflow/io/output.hpp>

namespace granflow::mpm {
namespace {

void write_text(const std::string& path, const std::string& text) {
  io::write_file(path, text, io::Durability::Buffered);
}

double norm3(const double* v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

}  // namespace

ForceRecorder::ForceRecorder(const SceneSetup& su) : su_(&su), active_(!su.probes.empty()) {}

void ForceRecorder::sample(double t, double t_flow, Runner& runner) {
  if (!active_) return;
  BoundaryForces taken;
  runner.take_forces(taken);
  sample(t, t_flow, taken);
}

void ForceRecorder::sample(double t, double t_flow, const BoundaryForces& taken) {
  if (!active_) return;
  last_ = taken;
  const SceneSetup& su = *su_;
  std::vector<int> parts_of(su.force_boundaries.size(), 0);
  for (const ForcePart& p : su.force_parts) ++parts_of[p.boundary];
  for (size_t b = 0; b < su.force_boundaries.size(); ++b) {
    st_.rows.push_back({t, t_flow, static_cast<int>(b), -1, last_.boundaries[b]});
    if (parts_of[b] < 2) continue;
    for (size_t q = 0; q < su.force_parts.size(); ++q)
      if (su.force_parts[q].boundary == static_cast<int>(b))
        st_.rows.push_back({t, t_flow, static_cast<int>(b), static_cast<int>(q), last_.parts[q]});
  }
}

void ForceRecorder::write_csv(const std::string& dir) const {
  if (!active_) return;
  const int D = su_->scene.dim;
  const std::string f = D == 2 ? "N/m" : "N", m = D == 2 ? "N m/m" : "N m", i = D == 2 ? "N s/m" : "N s";
  std::ostringstream os;
  os.precision(9);
  const char* axes = "xyz";
  os << "t [s],t_flow [s],boundary,part";
  for (int d = 0; d < D; ++d) os << ",F" << axes[d] << " [" << f << "]";
  os << ",F_max [" << f << "],Fn [" << f << "],Ft [" << f << "]";
  if (D == 2)
    os << ",Mz [" << m << "]";
  else
    for (int d = 0; d < 3; ++d) os << ",M" << axes[d] << " [" << m << "]";
  for (int d = 0; d < D; ++d) os << ",I" << axes[d] << " [" << i << "]";
  os << '\n';
  for (const ForceRow& r : st_.rows) {
    const ForceSums& s = r.sums;
    const double inv = s.time > 0 ? 1.0 / s.time : 0.0;
    os << r.t << ',' << r.t_flow << ',' << io::csv_field(su_->force_boundaries[r.boundary]) << ','
       << (r.part < 0 ? "total" : io::csv_field(su_->force_parts[r.part].name));
    for (int d = 0; d < D; ++d) os << ',' << s.impulse[d] * inv;
    os << ',' << s.max_force << ',' << s.normal * inv << ',' << s.tangential * inv;
    for (int d = D == 2 ? 2 : 0; d < 3; ++d) os << ',' << s.moment[d] * inv;
    for (int d = 0; d < D; ++d) os << ',' << s.impulse[d];
    os << '\n';
  }
  write_text(dir + "/obstacle_forces.csv", os.str());
}

std::string ForceRecorder::pressure_file(int frame_no) {
  char file[64];
  std::snprintf(file, sizeof file, "obstacle_pressure_%04d.csv", frame_no);
  return file;
}

std::string ForceRecorder::pressure_csv() const {
  const SceneSetup& su = *su_;
  if (!active_ || su.scene.dim != 2 || su.scene.obstacles.empty() || last_.node_impulse.empty()) return "";
  const long np = static_cast<long>(su.probes.size());
  std::ostringstream os;
  os.precision(9);
  os << "obstacle,face,x [m],y [m],s [m],p [Pa],tau [Pa]\n";
  const double h = su.scene.h;
  for (size_t q = 0; q < su.force_parts.size(); ++q) {
    const ForcePart& part = su.force_parts[q];
    const std::string& name = su.force_boundaries[part.boundary];
    const Obstacle* ob = nullptr;
    for (const Obstacle& o : su.scene.obstacles)
      if (o.name == name) ob = &o;
    if (!ob) continue;
    // the face: polygon edge `face`, from its first vertex
    int face = 0;
    for (size_t k = 0; k < q; ++k)
      if (su.force_parts[k].boundary == part.boundary) ++face;
    const size_t nv = ob->poly_x.size(), j = (face + 1) % nv;
    const double x0 = ob->poly_x[face], y0 = ob->poly_y[face];
    const double dx = ob->poly_x[j] - x0, dy = ob->poly_y[j] - y0, len = std::hypot(dx, dy);
    for (long i = part.first; i < part.first + part.count; ++i) {
      const ForceProbe& pr = su.probes[i];
      const double time = last_.parts[q].time;
      if (!(time > 0)) continue;
      const double fx = last_.node_impulse[i] / time, fy = last_.node_impulse[np + i] / time;
      const double fn = fx * pr.n[0] + fy * pr.n[1];
      const double ft = fx * (-pr.n[1]) + fy * pr.n[0];
      const double s = ((pr.x[0] - x0) * dx + (pr.x[1] - y0) * dy) / len;
      os << io::csv_field(name) << ',' << io::csv_field(part.name) << ',' << pr.x[0] << ',' << pr.x[1] << ',' << s << ',' << fn / h << ','
         << ft / h << '\n';
    }
  }
  return os.str();
}

void ForceRecorder::write_geometry(const std::string& dir, const Scene& sc) {
  if (sc.obstacles.empty()) return;
  std::vector<double> pts;               // x y z
  std::vector<std::vector<long>> cells;  // point indices
  std::vector<int> types, ids;
  auto point = [&](double x, double y, double z) {
    pts.insert(pts.end(), {x, y, z});
    return static_cast<long>(pts.size() / 3 - 1);
  };
  for (size_t k = 0; k < sc.obstacles.size(); ++k) {
    const Obstacle& ob = sc.obstacles[k];
    auto cell = [&](std::vector<long> c, int type) {
      cells.push_back(std::move(c));
      types.push_back(type);
      ids.push_back(static_cast<int>(k));
    };
    if (ob.shape == Obstacle::Shape::Polygon) {
      std::vector<long> c;
      for (size_t i = 0; i < ob.poly_x.size(); ++i) c.push_back(point(ob.poly_x[i], ob.poly_y[i], 0));
      cell(c, 7);  // VTK_POLYGON
    } else if (ob.shape == Obstacle::Shape::Box) {
      const auto &a = ob.box_min, &b = ob.box_max;
      std::vector<long> c;
      for (int z = 0; z < 2; ++z)
        for (int i = 0; i < 4; ++i) {
          const bool x1 = i == 1 || i == 2, y1 = i >= 2;
          c.push_back(point(x1 ? b[0] : a[0], y1 ? b[1] : a[1], z ? b[2] : a[2]));
        }
      cell(c, 12);  // VTK_HEXAHEDRON
    } else if (ob.shape == Obstacle::Shape::Mesh) {  // its triangles
      const long base = static_cast<long>(pts.size() / 3);
      pts.insert(pts.end(), ob.mesh->xyz.begin(), ob.mesh->xyz.end());
      for (size_t t = 0; t + 2 < ob.mesh->tri.size(); t += 3)
        cell({base + ob.mesh->tri[t], base + ob.mesh->tri[t + 1], base + ob.mesh->tri[t + 2]}, 5);  // VTK_TRIANGLE
    } else {  // a 48-sided prism: bottom and top polygons and the side quads
      const int n = 48;
      const long base = static_cast<long>(pts.size() / 3);
      for (int lvl = 0; lvl < 2; ++lvl)
        for (int i = 0; i < n; ++i) {
          const double a = 2 * M_PI * i / n;
          point(ob.center[0] + ob.radius * std::cos(a), lvl ? ob.y_max : ob.y_min, ob.center[1] + ob.radius * std::sin(a));
        }
      std::vector<long> bottom, top;
      for (int i = 0; i < n; ++i) {
        bottom.push_back(base + i);
        top.push_back(base + n + i);
        cell({base + i, base + (i + 1) % n, base + n + (i + 1) % n, base + n + i}, 9);  // VTK_QUAD
      }
      cell(bottom, 7);
      cell(top, 7);
    }
  }
  std::ostringstream os;
  os.precision(12);
  os << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
     << "<UnstructuredGrid>\n<Piece NumberOfPoints=\"" << pts.size() / 3 << "\" NumberOfCells=\"" << cells.size()
     << "\">\n<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (size_t i = 0; i < pts.size(); ++i) os << pts[i] << (i % 3 == 2 ? '\n' : ' ');
  os << "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  long off = 0;
  std::ostringstream offsets;
  for (const auto& c : cells) {
    for (long i : c) os << i << ' ';
    os << '\n';
    off += static_cast<long>(c.size());
    offsets << off << ' ';
  }
  os << "</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n" << offsets.str()
     << "\n</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (int t : types) os << t << ' ';
  os << "\n</DataArray>\n</Cells>\n<CellData Scalars=\"obstacle\">\n"
     << "<DataArray type=\"Int32\" Name=\"obstacle\" format=\"ascii\">\n";
  for (int id : ids) os << id << ' ';
  os << "\n</DataArray>\n</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  write_text(dir + "/obstacles.vtu", os.str());
}

std::vector<ForcePeak> ForceRecorder::peaks() const {
  std::vector<ForcePeak> out;
  if (!active_) return out;
  const size_t nb = su_->force_boundaries.size();
  std::vector<double> impulse(3 * nb, 0.0);
  for (size_t b = 0; b < nb; ++b) out.push_back({su_->force_boundaries[b], 0.0, 0.0, 0.0, 0.0});
  for (const ForceRow& r : st_.rows) {
    if (r.part >= 0) continue;
    ForcePeak& p = out[r.boundary];
    const double mean = r.sums.time > 0 ? norm3(r.sums.impulse) / r.sums.time : 0.0;
    if (mean > p.peak) {
      p.peak = mean;
      p.t_peak = r.t;
    }
    p.step_peak = std::max(p.step_peak, r.sums.max_force);
    for (int d = 0; d < 3; ++d) impulse[3 * r.boundary + d] += r.sums.impulse[d];
  }
  for (size_t b = 0; b < nb; ++b) out[b].impulse = norm3(&impulse[3 * b]);
  return out;
}

ForcesState ForceRecorder::state(Runner& runner) const {
  ForcesState s;
  s.rows = st_.rows;
  s.last = last_;
  if (active_) runner.take_forces(s.pending, true);
  return s;
}

void ForceRecorder::restore(const ForcesState& s, Runner& runner) {
  st_.rows = s.rows;
  last_ = s.last;
  if (active_) runner.restore_forces(s.pending);
}

}  // namespace granflow::mpm
