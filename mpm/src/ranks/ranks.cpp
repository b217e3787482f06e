// One process as the default ranks; packing of member summaries (ranks.hpp).
#include <granflow/mpm/ranks.hpp>

#include <unistd.h>

#include <cstring>
#include <stdexcept>
#include <type_traits>

namespace granflow::mpm {

namespace {
std::unique_ptr<Ranks>& installed() {
  static std::unique_ptr<Ranks> r = std::make_unique<Ranks>();
  return r;
}
}  // namespace

std::string Ranks::host() const {
  char name[256] = {};
  if (gethostname(name, sizeof name - 1) != 0) return "unknown";
  return name;
}

std::string Ranks::where() const {
  return "rank " + std::to_string(rank()) + " of " + std::to_string(size()) + " on host " + host();
}

const Ranks& ranks() { return *installed(); }
void set_ranks(std::unique_ptr<Ranks> r) { installed() = r ? std::move(r) : std::make_unique<Ranks>(); }

std::pair<long, long> rank_members(long members, int rank, int size) {
  const long base = members / size, extra = members % size;
  const long first = rank * base + std::min<long>(rank, extra);
  return {first, first + base + (rank < extra ? 1 : 0)};
}

void Unpacker::take(void* p, std::size_t n) {
  if (n > b_.size() - at_) throw std::runtime_error("ranks: a message from another rank is truncated");
  if (n) std::memcpy(p, b_.data() + at_, n);
  at_ += n;
}

static_assert(std::is_trivially_copyable_v<SeriesRow> && std::is_trivially_copyable_v<TrackRow> &&
              std::is_trivially_copyable_v<Measures> && std::is_trivially_copyable_v<ConsolidationCheck>);

std::string pack_members(const std::vector<MemberSummary>& ms) {
  Packer p;
  p.pod<std::uint64_t>(ms.size());
  for (const MemberSummary& m : ms) {
    p.pod<char>(m.ok);
    p.str(m.message);
    p.pod(m.steps);
    p.pod(m.t_end);
    p.pod(m.wall_s);
    p.pod(m.final);
    p.pod(m.max_speed);
    p.pods(m.runout_at);
    p.pods(m.series);
    p.pods(m.tracks);
    p.pod(m.consolidation);
    std::vector<double> xy;
    for (const auto& [x, y] : m.profile) xy.insert(xy.end(), {x, y});
    p.pods(xy);
    p.pod<std::uint64_t>(m.forces.size());
    for (const ForcePeak& f : m.forces) {
      p.str(f.boundary);
      for (double v : {f.peak, f.impulse, f.t_peak, f.step_peak}) p.pod(v);
    }
  }
  return p.bytes();
}

std::vector<MemberSummary> unpack_members(const std::string& bytes) {
  Unpacker u(bytes);
  std::vector<MemberSummary> ms(u.pod<std::uint64_t>());
  for (MemberSummary& m : ms) {
    m.ok = u.pod<char>() != 0;
    m.message = u.str();
    m.steps = u.pod<long>();
    m.t_end = u.pod<double>();
    m.wall_s = u.pod<double>();
    m.final = u.pod<Measures>();
    m.max_speed = u.pod<double>();
    m.runout_at = u.pods<double>();
    m.series = u.pods<SeriesRow>();
    m.tracks = u.pods<TrackRow>();
    m.consolidation = u.pod<ConsolidationCheck>();
    const std::vector<double> xy = u.pods<double>();
    for (std::size_t i = 0; i + 1 < xy.size(); i += 2) m.profile.emplace_back(xy[i], xy[i + 1]);
    m.forces.resize(u.pod<std::uint64_t>());
    for (ForcePeak& f : m.forces) {
      f.boundary = u.str();
      f.peak = u.pod<double>();
      f.impulse = u.pod<double>();
      f.t_peak = u.pod<double>();
      f.step_peak = u.pod<double>();
    }
  }
  if (!u.done()) throw std::runtime_error("ranks: a message from another rank has trailing bytes");
  return ms;
}

}  // namespace granflow::mpm
