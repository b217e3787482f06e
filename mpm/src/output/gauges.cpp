// Gauges: depth, depth-averaged velocity and density of the flow across a line (gauges.csv).
#include <algorithm>
#include <cmath>
#include <sstream>

#include <granflow/io/output.hpp>
#include <granflow/mpm/measures.hpp>

namespace granflow::mpm {

std::vector<GaugeRow> measure_gauges(const Frame& fr, const SceneSetup& su, const std::vector<double>& mass,
                                     double t, double t_flow) {
  const Scene& sc = su.scene;
  std::vector<GaugeRow> rows;
  const long n = fr.n;
  for (size_t g = 0; g < sc.gauges.size(); ++g) {
    const Gauge& ga = sc.gauges[g];
    const double ax = ga.to[0] - ga.from[0], ay = ga.to[1] - ga.from[1], len = std::hypot(ax, ay);
    const double ex = ax / len, ey = ay / len, nx = ey, ny = -ex;  // along; right-hand normal
    // Bins of one grid cell along the line; a run of occupied bins is one body of flow, so a
    // grain thrown above the flow or a tail on the far side does not count.
    const double w = sc.h;
    const long nb = std::max(1L, static_cast<long>(std::ceil(len / w)));
    std::vector<double> bin_mass(nb, 0.0);
    std::vector<std::pair<long, double>> in;  // point and its distance along the line
    for (long i = 0; i < n; ++i) {
      const double dx = fr.x[i] - ga.from[0], dy = fr.x[n + i] - ga.from[1];
      const double s = dx * ex + dy * ey, d = dx * nx + dy * ny;
      if (std::abs(d) > 0.5 * ga.width || s < 0 || s > len) continue;
      bin_mass[std::min(nb - 1, static_cast<long>(s / w))] += mass[i];
      in.emplace_back(i, s);
    }
    const auto [first, last] = heaviest_run(bin_mass);
    GaugeRow r{t, t_flow, g, 0, 0, 0, 0, 0, 0};
    double s_lo = len, s_hi = 0, m_sum = 0, pn = 0, pa = 0;
    for (const auto& [i, s] : in) {
      const long b = std::min(nb - 1, static_cast<long>(s / w));
      if (b < first || b > last) continue;
      s_lo = std::min(s_lo, s);
      s_hi = std::max(s_hi, s);
      m_sum += mass[i];
      pn += mass[i] * (fr.v[i] * nx + fr.v[n + i] * ny);
      pa += mass[i] * (fr.v[i] * ex + fr.v[n + i] * ey);
      ++r.points;
    }
    if (r.points > 0) {  // each point stands for a square of one spacing
      r.depth = std::min(len, s_hi + 0.5 * su.spacing) - std::max(0.0, s_lo - 0.5 * su.spacing);
      r.u = pn / m_sum;
      r.u_along = pa / m_sum;
      r.density = m_sum / (r.depth * ga.width);
      r.mass_flux = pn / ga.width;
    }
    rows.push_back(r);
  }
  return rows;
}

void write_gauges_csv(const std::string& dir, const Scene& sc, const std::vector<GaugeRow>& rows) {
  if (sc.gauges.empty()) return;
  std::ostringstream a;
  a.precision(8);
  a << "t [s],t_flow [s],gauge,depth [m],u [m/s],u_along [m/s],density [kg/m^3],mass_flux [kg/(m s)],points\n";
  for (const GaugeRow& r : rows)
    a << r.t << ',' << r.t_flow << ',' << io::csv_field(sc.gauges[r.gauge].name) << ',' << r.depth << ',' << r.u << ',' << r.u_along
      << ',' << r.density << ',' << r.mass_flux << ',' << r.points << '\n';
  io::write_file(dir + "/gauges.csv", a.str(), io::Durability::Buffered);
}

}  // namespace granflow::mpm
