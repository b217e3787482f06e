// Binary checkpoint: header (magic, version, byte order, payload size, scene hash), payload,
// FNV-1a of everything before it. Host byte order; a file of the other order is refused.
#include <granflow/mpm/checkpoint.hpp>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <type_traits>

#include <granflow/io/output.hpp>

namespace granflow::mpm {
namespace {

constexpr char kMagic[8] = {'G', 'F', 'M', 'P', 'M', 'C', 'K', 'P'};
constexpr std::uint32_t kVersion = 7;  // 2: the maps of terrain runs; 3: boundary forces; 4: gauges, per-material series;
                                       // 5: the last sample's force sums; 6: points below the terrain per deposit row;
                                       // 7: the deposit's edge radius per deposit row
constexpr std::uint32_t kByteOrder = 0x01020304;
constexpr size_t kHeader = 8 + 4 + 4 + 8 + 8;

class Writer {
 public:
  template <class T>
  void pod(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    buf_.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  void doubles(const std::vector<double>& v) {
    pod(static_cast<std::uint64_t>(v.size()));
    if (!v.empty()) buf_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(double));
  }
  void str(const std::string& s) {
    pod(static_cast<std::uint64_t>(s.size()));
    buf_ += s;
  }
  std::string& bytes() { return buf_; }

 private:
  std::string buf_;
};

class Reader {
 public:
  Reader(std::string_view b, size_t at) : b_(b), at_(at) {}
  template <class T>
  T pod() {
    T v;
    need(sizeof v, "a value");
    std::memcpy(&v, b_.data() + at_, sizeof v);
    at_ += sizeof v;
    return v;
  }
  std::vector<double> doubles(const char* what) {
    const std::uint64_t n = pod<std::uint64_t>();
    if (n > (b_.size() - at_) / sizeof(double)) fail(std::string(what) + " claims more values than the file holds");
    std::vector<double> v(n);
    if (n > 0) std::memcpy(v.data(), b_.data() + at_, n * sizeof(double));  // data() may be null when empty
    at_ += n * sizeof(double);
    return v;
  }
  std::string str() {
    const std::uint64_t n = pod<std::uint64_t>();
    need(n, "a string");
    std::string s(b_.data() + at_, n);
    at_ += n;
    return s;
  }
  std::uint64_t count(size_t min_item_bytes, const char* what) {
    const std::uint64_t n = pod<std::uint64_t>();
    if (n > (b_.size() - at_) / min_item_bytes) fail(std::string(what) + " claims more entries than the file holds");
    return n;
  }
  size_t at() const { return at_; }
  [[noreturn]] static void fail(const std::string& m) { throw CheckpointError("corrupt checkpoint: " + m); }

 private:
  void need(size_t n, const char* what) {
    if (n > b_.size() - at_) fail(std::string("ends inside ") + what);
  }
  std::string_view b_;
  size_t at_;
};

std::string num(double v) {
  std::ostringstream os;
  os.precision(10);
  os << v;
  return os.str();
}

std::string hex(std::uint64_t v) {
  std::ostringstream os;
  os << std::hex << v;
  return os.str();
}

void write_frame_light(Writer& w, const Frame& f) {
  w.pod(static_cast<std::int64_t>(f.n));
  w.pod(static_cast<std::int32_t>(f.dim));
  w.doubles(f.x);
  w.doubles(f.v);
  w.doubles(f.T);
}

Frame read_frame_light(Reader& r) {
  Frame f;
  f.n = r.pod<std::int64_t>();
  f.dim = r.pod<std::int32_t>();
  f.x = r.doubles("last_good.x");
  f.v = r.doubles("last_good.v");
  f.T = r.doubles("last_good.T");
  const size_t n = static_cast<size_t>(f.n);
  if (f.n < 0 || f.x.size() != f.dim * n || f.v.size() != f.dim * n || f.T.size() != n)
    Reader::fail("last good frame: array sizes do not match its " + std::to_string(f.n) + " points");
  return f;
}

}  // namespace

std::uint64_t fnv1a(std::string_view bytes, std::uint64_t h) {
  for (const unsigned char c : bytes) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

void write_sums(Writer& w, const ForceSums& f) {
  for (double v : {f.impulse[0], f.impulse[1], f.impulse[2], f.normal, f.tangential, f.moment[0], f.moment[1],
                   f.moment[2], f.max_force, f.time})
    w.pod(v);
  w.pod(static_cast<std::int64_t>(f.steps));
}
ForceSums read_sums(Reader& r) {
  ForceSums f;
  for (double* v : {&f.impulse[0], &f.impulse[1], &f.impulse[2], &f.normal, &f.tangential, &f.moment[0], &f.moment[1],
                    &f.moment[2], &f.max_force, &f.time})
    *v = r.pod<double>();
  f.steps = r.pod<std::int64_t>();
  return f;
}
constexpr std::uint64_t kSumsBytes = 11 * 8;

std::string encode_checkpoint(const Checkpoint& c) {
  Writer w;
  w.bytes().append(kMagic, sizeof kMagic);
  w.pod(kVersion);
  w.pod(kByteOrder);
  w.pod(std::uint64_t{0});  // payload size, filled in below
  w.pod(c.scene_hash);

  const HostParticles& p = c.particles;
  w.pod(static_cast<std::int64_t>(p.n));
  w.pod(static_cast<std::int32_t>(p.dim));
  for (const auto* v : {&p.x, &p.v, &p.m, &p.sig, &p.sigf, &p.L, &p.eps, &p.e, &p.s}) w.doubles(*v);

  const LoopState& s = c.loop;
  w.pod(s.t);
  w.pod(static_cast<std::int64_t>(s.step));
  w.pod(s.dt);
  w.pod(static_cast<std::int32_t>(s.stage));
  w.pod(s.t_stage_end);
  w.pod(s.next_sample);
  w.pod(static_cast<std::int64_t>(s.next_out));
  w.pod(static_cast<std::int32_t>(s.frame_no));
  w.pod(static_cast<std::uint64_t>(s.pvd.size()));
  for (const auto& [t, name] : s.pvd) {
    w.pod(t);
    w.str(name);
  }
  w.pod(static_cast<std::uint64_t>(s.series.size()));
  for (const SeriesRow& r : s.series) {
    w.pod(r.t);
    w.pod(r.t_flow);
    w.pod(static_cast<std::int32_t>(r.stage));
    for (double v : {r.m.runout, r.m.height, r.m.max_speed, r.m.kinetic_energy, r.m.mean_T, r.m.max_T}) w.pod(v);
  }
  w.pod(static_cast<std::uint64_t>(s.material_series.size()));
  for (const Measures& m : s.material_series)
    for (double v : {m.runout, m.height, m.max_speed, m.kinetic_energy, m.mean_T, m.max_T}) w.pod(v);
  w.pod(static_cast<std::uint64_t>(s.tracks.size()));
  for (const TrackRow& r : s.tracks) {
    w.pod(r.t);
    w.pod(r.t_flow);
    w.pod(static_cast<std::uint64_t>(r.track));
    for (double v : {r.x, r.y, r.vx, r.vy, r.p, r.q, r.eps_pd, r.T, r.eta_c, r.K_col}) w.pod(v);
  }
  w.pod(static_cast<std::uint64_t>(s.gauges.size()));
  for (const GaugeRow& r : s.gauges) {
    w.pod(r.t);
    w.pod(r.t_flow);
    w.pod(static_cast<std::uint64_t>(r.gauge));
    for (double v : {r.depth, r.u, r.u_along, r.density, r.mass_flux}) w.pod(v);
    w.pod(static_cast<std::int64_t>(r.points));
  }
  write_frame_light(w, s.last_good);
  w.pod(s.last_good_t);
  w.pod(static_cast<std::uint8_t>(s.consolidation.done));
  w.pod(s.consolidation.max_rel_error);
  w.pod(s.consolidation.base_sigma_v);
  w.pod(s.consolidation.base_rho_g_h);
  for (long v : {s.stats.updates, s.stats.substeps, s.stats.substep_limit, s.stats.tension_cutoff, s.stats.vs_clamped,
                 s.stats.separated})
    w.pod(static_cast<std::int64_t>(v));
  w.pod(s.wall_s);
  w.doubles(s.maps.max_speed);
  w.doubles(s.maps.max_depth);
  w.pod(static_cast<std::uint64_t>(s.maps.deposit.size()));
  for (const DepositRow& r : s.maps.deposit)
    for (double v : {r.t, r.t_flow, r.area, r.volume, r.extent, r.ground_points, r.ground_depth, r.edge_radius, r.edge_axes,
                     r.edge_diagonals})
      w.pod(v);
  w.pod(static_cast<std::uint64_t>(s.forces.rows.size()));
  for (const ForceRow& r : s.forces.rows) {
    w.pod(r.t);
    w.pod(r.t_flow);
    w.pod(static_cast<std::int32_t>(r.boundary));
    w.pod(static_cast<std::int32_t>(r.part));
    write_sums(w, r.sums);
  }
  for (const BoundaryForces* f : {&s.forces.pending, &s.forces.last}) {
    for (const auto* v : {&f->parts, &f->boundaries}) {
      w.pod(static_cast<std::uint64_t>(v->size()));
      for (const ForceSums& x : *v) write_sums(w, x);
    }
    w.doubles(f->node_impulse);
  }

  std::string& b = w.bytes();
  const std::uint64_t payload = b.size() - kHeader;
  std::memcpy(b.data() + 16, &payload, sizeof payload);
  const std::uint64_t sum = fnv1a(b);
  b.append(reinterpret_cast<const char*>(&sum), sizeof sum);
  return b;
}

Checkpoint decode_checkpoint(std::string_view b) {
  if (b.size() < sizeof kMagic || std::memcmp(b.data(), kMagic, sizeof kMagic) != 0)
    throw CheckpointError("not a granflow MPM checkpoint (the file does not start with 'GFMPMCKP')");
  if (b.size() < kHeader + 8)
    throw CheckpointError("truncated checkpoint: " + std::to_string(b.size()) + " bytes, shorter than its header");
  Reader h(b, sizeof kMagic);
  const auto version = h.pod<std::uint32_t>();
  if (version != kVersion)
    throw CheckpointError("checkpoint format version " + std::to_string(version) + "; this granflow reads version " +
                          std::to_string(kVersion));
  if (h.pod<std::uint32_t>() != kByteOrder)
    throw CheckpointError("checkpoint written on a machine of the other byte order");
  const auto payload = h.pod<std::uint64_t>();
  const std::uint64_t expected = kHeader + payload + 8;
  if (payload > b.size() || b.size() != expected)
    throw CheckpointError("truncated checkpoint: " + std::to_string(b.size()) + " bytes, the header says " +
                          std::to_string(expected) + " (the run was killed while writing it?)");
  std::uint64_t stored;
  std::memcpy(&stored, b.data() + b.size() - 8, 8);
  if (fnv1a(b.substr(0, b.size() - 8)) != stored)
    throw CheckpointError("corrupt checkpoint: checksum mismatch (the file was changed after it was written)");

  Checkpoint c;
  c.scene_hash = h.pod<std::uint64_t>();
  Reader r(b.substr(0, b.size() - 8), kHeader);
  HostParticles& p = c.particles;
  p.n = r.pod<std::int64_t>();
  p.dim = r.pod<std::int32_t>();
  const char* names[] = {"x", "v", "m", "sig", "sigf", "L", "eps", "e", "s"};
  std::vector<double>* fields[] = {&p.x, &p.v, &p.m, &p.sig, &p.sigf, &p.L, &p.eps, &p.e, &p.s};
  const size_t sizes[] = {size_t(p.dim), size_t(p.dim), 1, 6, 6, size_t(p.dim * p.dim), 1, 1, 1};
  if (p.n < 0 || (p.dim != 2 && p.dim != 3)) Reader::fail("particle count or dimension out of range");
  for (int k = 0; k < 9; ++k) {
    *fields[k] = r.doubles(names[k]);
    if (fields[k]->size() != sizes[k] * p.n)
      Reader::fail(std::string("particle field ") + names[k] + " has " + std::to_string(fields[k]->size()) +
                   " values for " + std::to_string(p.n) + " particles");
  }

  LoopState& s = c.loop;
  s.t = r.pod<double>();
  s.step = r.pod<std::int64_t>();
  s.dt = r.pod<double>();
  s.stage = r.pod<std::int32_t>();
  s.t_stage_end = r.pod<double>();
  s.next_sample = r.pod<double>();
  s.next_out = r.pod<std::int64_t>();
  s.frame_no = r.pod<std::int32_t>();
  for (std::uint64_t k = 0, n = r.count(16, "frame list"); k < n; ++k) {
    const double t = r.pod<double>();
    s.pvd.emplace_back(t, r.str());
  }
  for (std::uint64_t k = 0, n = r.count(60, "run-out series"); k < n; ++k) {
    SeriesRow row;
    row.t = r.pod<double>();
    row.t_flow = r.pod<double>();
    row.stage = r.pod<std::int32_t>();
    Measures& m = row.m;
    for (double* v : {&m.runout, &m.height, &m.max_speed, &m.kinetic_energy, &m.mean_T, &m.max_T}) *v = r.pod<double>();
    s.series.push_back(row);
  }
  for (std::uint64_t j = 0, nm = r.count(48, "per-material series"); j < nm; ++j) {
    Measures& q = s.material_series.emplace_back();
    for (double* v : {&q.runout, &q.height, &q.max_speed, &q.kinetic_energy, &q.mean_T, &q.max_T}) *v = r.pod<double>();
  }
  for (std::uint64_t k = 0, n = r.count(104, "tracked series"); k < n; ++k) {
    TrackRow row;
    row.t = r.pod<double>();
    row.t_flow = r.pod<double>();
    row.track = r.pod<std::uint64_t>();
    for (double* v : {&row.x, &row.y, &row.vx, &row.vy, &row.p, &row.q, &row.eps_pd, &row.T, &row.eta_c, &row.K_col})
      *v = r.pod<double>();
    s.tracks.push_back(row);
  }
  for (std::uint64_t k = 0, n = r.count(72, "gauge series"); k < n; ++k) {
    GaugeRow row;
    row.t = r.pod<double>();
    row.t_flow = r.pod<double>();
    row.gauge = r.pod<std::uint64_t>();
    for (double* v : {&row.depth, &row.u, &row.u_along, &row.density, &row.mass_flux}) *v = r.pod<double>();
    row.points = r.pod<std::int64_t>();
    s.gauges.push_back(row);
  }
  s.last_good = read_frame_light(r);
  s.last_good_t = r.pod<double>();
  s.consolidation.done = r.pod<std::uint8_t>() != 0;
  s.consolidation.max_rel_error = r.pod<double>();
  s.consolidation.base_sigma_v = r.pod<double>();
  s.consolidation.base_rho_g_h = r.pod<double>();
  for (long* v : {&s.stats.updates, &s.stats.substeps, &s.stats.substep_limit, &s.stats.tension_cutoff,
                  &s.stats.vs_clamped, &s.stats.separated})
    *v = r.pod<std::int64_t>();
  s.wall_s = r.pod<double>();
  s.maps.max_speed = r.doubles("maps.max_speed");
  s.maps.max_depth = r.doubles("maps.max_depth");
  if (s.maps.max_speed.size() != s.maps.max_depth.size()) Reader::fail("the maps have different cell counts");
  for (std::uint64_t k = 0, n = r.count(80, "deposit series"); k < n; ++k) {
    DepositRow row;
    for (double* v : {&row.t, &row.t_flow, &row.area, &row.volume, &row.extent, &row.ground_points, &row.ground_depth,
                      &row.edge_radius, &row.edge_axes, &row.edge_diagonals})
      *v = r.pod<double>();
    s.maps.deposit.push_back(row);
  }
  for (std::uint64_t k = 0, n = r.count(24 + kSumsBytes, "force rows"); k < n; ++k) {
    ForceRow row;
    row.t = r.pod<double>();
    row.t_flow = r.pod<double>();
    row.boundary = r.pod<std::int32_t>();
    row.part = r.pod<std::int32_t>();
    row.sums = read_sums(r);
    s.forces.rows.push_back(row);
  }
  for (BoundaryForces* f : {&s.forces.pending, &s.forces.last}) {
    for (auto* v : {&f->parts, &f->boundaries})
      for (std::uint64_t k = 0, n = r.count(kSumsBytes, "force sums"); k < n; ++k) v->push_back(read_sums(r));
    f->node_impulse = r.doubles("forces.node_impulse");
  }
  if (r.at() != b.size() - 8) Reader::fail(std::to_string(b.size() - 8 - r.at()) + " unread bytes after the state");
  if (s.series.empty()) Reader::fail("no run-out sample (a run samples t = 0 first)");
  return c;
}

void write_checkpoint(const std::string& path, const Checkpoint& c) {
  const std::string bytes = encode_checkpoint(c);
  const io::CriticalWrite critical;  // a second Ctrl-C waits for it: the checkpoint stays usable
  io::write_file(path, bytes, io::Durability::Sync);
}

std::vector<std::string> checkpoint_outputs(const Checkpoint& c) {
  std::vector<std::string> names = {kCheckpointFile, "frames.pvd", "runout.csv", "tracked.csv", "deposit.csv",
                                    "obstacle_forces.csv", "obstacles.vtu"};
  for (const auto& [t, file] : c.loop.pvd) {
    names.push_back(file);
    if (file.rfind("frame_", 0) == 0 && file.size() >= 10)  // its pressure profile (2D obstacles)
      names.push_back("obstacle_pressure_" + file.substr(6, 4) + ".csv");
  }
  return names;
}

Checkpoint read_checkpoint(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CheckpointError("cannot open the checkpoint (" + std::string(std::strerror(errno)) + ")");
  std::ostringstream os;
  os << in.rdbuf();
  return decode_checkpoint(os.str());
}

void check_checkpoint(const Checkpoint& c, const SceneSetup& su, std::uint64_t scene_hash) {
  const Scene& sc = su.scene;
  if (c.scene_hash != scene_hash)
    throw CheckpointError("written for a different scene or parameter set (hash " + hex(c.scene_hash) +
                          ", this scene " + hex(scene_hash) +
                          "): restart with the scene file and parameter set it was written for, or start afresh "
                          "with --force");
  const LoopState& s = c.loop;
  std::string why;
  if (c.particles.n != su.particles.n || c.particles.dim != sc.dim)
    why = std::to_string(c.particles.n) + " particles in " + std::to_string(c.particles.dim) + "D, the scene seeds " +
          std::to_string(su.particles.n) + " in " + std::to_string(sc.dim) + "D";
  else if (s.stage < 0 || s.stage >= static_cast<int>(sc.stages.size()))
    why = "stage " + std::to_string(s.stage) + " of " + std::to_string(sc.stages.size());
  else if (!(s.t >= 0 && s.t <= sc.duration() * (1 + 1e-12)) || !(s.dt > 0))
    why = "t = " + num(s.t) + " s, dt = " + num(s.dt) + " s for a scene of " + num(sc.duration()) + " s";
  else if (s.next_out < 0 || s.next_out > static_cast<long>(sc.output.times.size()))
    why = "frame index " + std::to_string(s.next_out);
  else if (s.last_good.n != su.particles.n)
    why = "last good frame of " + std::to_string(s.last_good.n) + " points";
  for (const TrackRow& r : s.tracks)
    if (why.empty() && r.track >= sc.tracks.size()) why = "tracked point " + std::to_string(r.track);
  for (const GaugeRow& r : s.gauges)
    if (why.empty() && r.gauge >= sc.gauges.size()) why = "gauge " + std::to_string(r.gauge);
  const size_t per_row = sc.material_count() > 1 ? sc.material_count() : 0;
  if (why.empty() && s.material_series.size() != per_row * s.series.size())
    why = std::to_string(s.material_series.size()) + " per-material measures for " + std::to_string(s.series.size()) +
          " samples of " + std::to_string(sc.material_count()) + " materials";
  for (const ForceRow& r : s.forces.rows)
    if (why.empty() && (r.boundary < 0 || size_t(r.boundary) >= su.force_boundaries.size() || r.part < -1 ||
                        r.part >= static_cast<long>(su.force_parts.size())))
      why = "force row of boundary " + std::to_string(r.boundary) + ", part " + std::to_string(r.part);
  const BoundaryForces& last = s.forces.last;
  const bool none = last.parts.empty() && last.boundaries.empty() && last.node_impulse.empty();
  if (why.empty() && !none &&
      (last.parts.size() != su.force_parts.size() || last.boundaries.size() != su.force_boundaries.size() ||
       last.node_impulse.size() != size_t(sc.dim) * su.probes.size()))
    why = "last force sample of " + std::to_string(last.parts.size()) + " parts and " +
          std::to_string(last.node_impulse.size()) + " probe sums";
  if (why.empty()) {
    const TerrainMaps maps(su);
    if (s.maps.max_speed.size() != maps.state().max_speed.size())
      why = "maps of " + std::to_string(s.maps.max_speed.size()) + " terrain cells, the scene's footprint covers " +
            std::to_string(maps.state().max_speed.size());
  }
  if (!why.empty()) throw CheckpointError("does not fit the scene: " + why);
}

}  // namespace granflow::mpm
