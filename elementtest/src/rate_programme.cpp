// Rate programmes as segments (rate_programme.hpp).
#include "rate_programme.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <granflow/io/input_error.hpp>

namespace granflow::elementtest::detail {

std::vector<Segment> segments_of(const RateProgramme& g) {
  std::vector<Segment> s;
  switch (g.kind) {
    case ProgrammeKind::Constant:
    case ProgrammeKind::Sweep:
      s.push_back({0.0, g.duration, g.rate, g.rate});
      break;
    case ProgrammeKind::Acceleration:
      if (g.hold > 0) s.push_back({0.0, g.hold, g.rate, g.rate});
      s.push_back({g.hold, g.duration, g.rate, g.rate + g.acceleration * (g.duration - g.hold)});
      break;
    case ProgrammeKind::Table:
      for (std::size_t i = 0; i + 1 < g.table_time.size(); ++i) {
        const double a = g.table_time[i], b = std::min(g.table_time[i + 1], g.duration);
        if (!(b > a)) continue;
        const double rb = g.table_rate[i] + (g.table_rate[i + 1] - g.table_rate[i]) * (b - a) /
                                                (g.table_time[i + 1] - g.table_time[i]);
        s.push_back({a, b, g.table_rate[i], rb});
        if (b >= g.duration) break;
      }
      break;
    case ProgrammeKind::Data:
      break;  // data_schedule
  }
  for (Segment& sg : s) {
    sg.r0 *= g.direction;
    sg.r1 *= g.direction;
  }
  return s;
}

DataSchedule data_schedule(const RateProgramme& g, double sigma_v0, const std::string& file) {
  DataSchedule d;
  const bool stress = g.control == Control::Stress;
  auto target = [&](double c) { return stress ? std::max(c, sigma_v0) : c; };
  if (g.data_control.empty())
    throw io::InputError(io::where(file) + "programme 'data' has no data: give data_file (and control_column)");
  d.start = stress ? sigma_v0 : g.data_control.front();
  double t = 0, prev = d.start, seg_t0 = 0;
  int dir = 0;
  for (std::size_t i = 0; i < g.data_control.size(); ++i) {
    const double c = g.data_control[i];
    const double v = target(c), dv = v - prev;
    const int sign = dv > 0 ? 1 : dv < 0 ? -1 : 0;
    if (sign != 0 && dir != 0 && sign != dir) {  // a reversal ends the run
      d.segments.push_back({seg_t0, t, dir * g.rate, dir * g.rate});
      seg_t0 = t;
    }
    if (sign != 0) dir = sign;
    t += std::fabs(dv) / g.rate;
    if (!std::isfinite(t)) {  // e.g. a stray 1e300: say so, not "never changes"
      std::ostringstream os;
      os << "programme 'data': column '" << g.control_column << "' reaches " << c << " here; at rate = " << g.rate
         << " the time to get there is not finite: a stray value?";
      const bool own = !g.data_file.empty() && i < g.data_lines.size();
      throw io::InputError(io::where(own ? g.data_file : file, own ? g.data_lines[i] : 0) + os.str());
    }
    d.out_times.push_back(t);
    prev = v;
  }
  if (!(t > seg_t0))
    throw io::InputError(io::where(file) + "programme 'data': column '" + g.control_column + "' never changes" +
                         (stress ? " above sigma_v0" : ""));
  d.segments.push_back({seg_t0, t, dir * g.rate, dir * g.rate});
  return d;
}

}  // namespace granflow::elementtest::detail
