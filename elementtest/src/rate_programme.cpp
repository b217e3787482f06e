// Rate programmes as segments (rate_programme.hpp).
#include "rate_programme.hpp"

#include <algorithm>

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
  }
  return s;
}

}  // namespace granflow::elementtest::detail
