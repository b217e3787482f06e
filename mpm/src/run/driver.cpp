// Host time loop: stages, step size, sampling of run-out and tracked particles, frames,
// progress line, and the stop on the first bad particle.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include <granflow/io/output.hpp>
#include <granflow/mpm/checkpoint.hpp>
#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/kernels.hpp>
#include <granflow/mpm/forces.hpp>
#include <granflow/mpm/frame_writer.hpp>
#include <granflow/mpm/maps.hpp>

namespace granflow::mpm {
namespace {

struct Polyline {
  std::vector<double> x, y, s0;  // vertices and curvilinear abscissa at each vertex
  explicit Polyline(const Scene& sc) : x(sc.runout_x), y(sc.runout_y) {
    if (x.size() < 2) {  // default: the bottom of the grid box along x
      x = {sc.origin[0], sc.origin[0] + sc.size[0]};
      y = {sc.origin[1], sc.origin[1]};
    }
    s0.assign(x.size(), 0.0);
    for (size_t i = 1; i < x.size(); ++i) s0[i] = s0[i - 1] + std::hypot(x[i] - x[i - 1], y[i] - y[i - 1]);
  }
  // Abscissa of the nearest point and the signed distance above the line.
  void project(double px, double py, double& s, double& above) const {
    double best = std::numeric_limits<double>::max();
    for (size_t i = 1; i < x.size(); ++i) {
      const double dx = x[i] - x[i - 1], dy = y[i] - y[i - 1], len = std::hypot(dx, dy);
      double t = ((px - x[i - 1]) * dx + (py - y[i - 1]) * dy) / (len * len);
      t = std::clamp(t, 0.0, 1.0);
      const double qx = x[i - 1] + t * dx, qy = y[i - 1] + t * dy;
      const double dist = std::hypot(px - qx, py - qy);
      if (dist < best) {
        best = dist;
        s = s0[i - 1] + t * len;
        above = (dx * (py - y[i - 1]) - dy * (px - x[i - 1])) / len;
      }
    }
  }
};

std::string stage_name(const Scene& sc, int i) { return sc.stages[i].name.empty() ? "stage" + std::to_string(i) : sc.stages[i].name; }


}  // namespace

// Steps to queue in a span. Fixed step: exactly those up to the end of the span (the host
// repeats the span's arithmetic). Adaptive: an estimate from the current step, 2 % long; steps
// queued past the end do nothing, and a short span is followed by another.
long span_length(const Span& s, long cap) {
  if (s.adaptive) {
    const double est = (s.t_until - s.t) / s.dt;
    if (!(est < double(cap))) return cap;
    return std::clamp(static_cast<long>(std::ceil(1.02 * std::max(est, 0.0))) + 1, 1L, cap);
  }
  double t = s.t;
  long n = 0;
  while (n < cap) {
    t += span_step_size(t, s.dt, s.t_land);
    ++n;
    if (span_reached(t, s.t_until)) break;
  }
  return n;
}

Measures measure(const Frame& fr, const SceneSetup& su, const std::vector<double>& mass, int material) {
  const Scene& sc = su.scene;
  const Polyline line(sc);
  const long n = fr.n;
  Measures m;
  // one material's points (a scene of several), else all
  auto skip = [&](long i) { return material >= 0 && su.point_material[i] != material; };
  long count = n;
  if (material >= 0) count = std::count(su.point_material.begin(), su.point_material.end(), material);
  if (count == 0) return m;
  std::vector<double> s(n), a(n);
  double smin = std::numeric_limits<double>::max(), smax = -smin;
  for (long i = 0; i < n; ++i) {
    if (skip(i)) continue;
    line.project(fr.x[i], fr.x[n + i], s[i], a[i]);
    smin = std::min(smin, s[i]);
    smax = std::max(smax, s[i]);
    double v2 = 0;
    for (int d = 0; d < fr.dim; ++d) v2 += fr.v[d * n + i] * fr.v[d * n + i];
    m.max_speed = std::max(m.max_speed, std::sqrt(v2));
    m.kinetic_energy += 0.5 * mass[i] * v2;
    if (!fr.T.empty()) {
      m.mean_T += fr.T[i] / count;
      m.max_T = std::max(m.max_T, fr.T[i]);
    }
  }
  // Front of the contiguous deposit: bins of one grid cell along the line; of the runs of
  // occupied bins, the one holding the most points (isolated points thrown ahead do not
  // count, nor does a tail left behind on the slope).
  const double w = sc.h;
  const long nb = static_cast<long>((smax - smin) / w) + 1;
  std::vector<double> occ(nb, 0.0);  // point counts, exact as doubles
  for (long i = 0; i < n; ++i)
    if (!skip(i)) occ[static_cast<long>((s[i] - smin) / w)] += 1;
  const auto [first, last] = heaviest_run(occ);
  const double s_begin = smin + first * w, s_end = smin + (last + 1) * w;
  double front = s_begin;
  for (long i = 0; i < n; ++i)
    if (!skip(i) && s[i] >= s_begin && s[i] < s_end) {
      front = std::max(front, s[i]);
      m.height = std::max(m.height, a[i]);
    }
  m.runout = front + 0.5 * su.spacing;
  m.height += 0.5 * su.spacing;
  return m;
}

std::pair<long, long> heaviest_run(const std::vector<double>& weight) {
  const long nb = static_cast<long>(weight.size());
  long first = 0, last = -1;
  double best = 0;
  for (long b = 0; b < nb;) {
    if (!(weight[b] > 0)) {
      ++b;
      continue;
    }
    long e = b;
    double m = 0;
    while (e < nb && weight[e] > 0) m += weight[e++];
    if (m > best) {
      best = m;
      first = b;
      last = e - 1;
    }
    b = e;
  }
  return {first, last};
}

std::vector<std::pair<double, double>> free_surface(const Frame& fr, const SceneSetup& su) {
  const Scene& sc = su.scene;
  const long n = fr.n;
  const double x0 = sc.origin[0], w = sc.h;
  const long nb = static_cast<long>(sc.size[0] / w) + 1;
  std::vector<double> top(nb, -std::numeric_limits<double>::max());
  for (long i = 0; i < n; ++i) {
    const long b = std::clamp(static_cast<long>((fr.x[i] - x0) / w), 0L, nb - 1);
    top[b] = std::max(top[b], fr.x[n + i] + 0.5 * su.spacing);
  }
  std::vector<std::pair<double, double>> out;
  for (long b = 0; b < nb; ++b)
    if (top[b] > -1e300) out.emplace_back(x0 + (b + 0.5) * w, top[b]);
  return out;
}

ConsolidationCheck check_consolidation(const Frame& fr, const SceneSetup& su) {
  // Middle half of the first body, depth bins of one grid cell; compare the mean -sigma_yy
  // with rho g depth where rho is the current bulk density integrated from the top.
  ConsolidationCheck c;
  const Scene& sc = su.scene;
  if (sc.bodies.empty() || sc.bodies[0].is_polygon() || sc.bodies[0].is_release()) return c;  // boxes only
  const Body& b = sc.bodies[0];
  const long n = fr.n;
  const double xa = b.box_min[0] + 0.25 * (b.box_max[0] - b.box_min[0]);
  const double xb = b.box_min[0] + 0.75 * (b.box_max[0] - b.box_min[0]);
  const double g = std::fabs(sc.gravity[1]);
  double top = -1e300;
  for (long i = 0; i < n; ++i)
    if (fr.x[i] >= xa && fr.x[i] <= xb) top = std::max(top, fr.x[n + i] + 0.5 * su.spacing);
  const long nb = static_cast<long>((top - b.box_min[1]) / sc.h) + 1;
  std::vector<double> sum(nb, 0), cnt(nb, 0), rho(nb, 0);
  for (long i = 0; i < n; ++i) {
    if (fr.x[i] < xa || fr.x[i] > xb) continue;
    const long k = std::clamp(static_cast<long>((top - fr.x[n + i]) / sc.h), 0L, nb - 1);
    sum[k] += -fr.syy[i];
    const int m = su.point_material.empty() ? 0 : su.point_material[i];
    rho[k] += sc.material_at(m).params.c.rho_p / (1 + fr.e[i]);
    cnt[k] += 1;
  }
  double load = 0;  // rho g integrated over the bins above
  for (long k = 0; k < nb; ++k) {
    if (cnt[k] == 0) continue;
    const double r = rho[k] / cnt[k];
    const double depth_mid = load + r * g * 0.5 * sc.h;
    load += r * g * sc.h;
    const double sv = sum[k] / cnt[k];
    if (k >= 1 && k + 1 < nb) {
      c.max_rel_error = std::max(c.max_rel_error, std::fabs(sv - depth_mid) / depth_mid);
    }
    if (k + 1 == nb || (k + 2 == nb)) {
      c.base_sigma_v = sv;
      c.base_rho_g_h = depth_mid;
    }
  }
  c.done = true;
  return c;
}

namespace {

// Series and profiles: synced with the checkpoint or the manifest, like the frames.
void write_text(const std::string& path, const std::string& text) {
  io::write_file(path, text, io::Durability::Buffered);
}

}  // namespace

namespace {


}  // namespace

void write_series_csv(const std::string& dir, const Scene& sc, const std::vector<SeriesRow>& series,
                      const std::vector<TrackRow>& tracks) {
  std::ostringstream a;
  a.precision(8);
  a << "t,t_flow,stage,runout,height,max_speed,kinetic_energy,mean_T,max_T\n";
  for (const auto& r : series)
    a << r.t << ',' << r.t_flow << ',' << r.stage << ',' << r.m.runout << ',' << r.m.height << ',' << r.m.max_speed
      << ',' << r.m.kinetic_energy << ',' << r.m.mean_T << ',' << r.m.max_T << '\n';
  write_text(dir + "/runout.csv", a.str());
  std::ostringstream b;
  b.precision(8);
  b << "t,t_flow,name,x,y,vx,vy,p,q,eps_pd,T,eta_c,K_col\n";
  for (const auto& r : tracks)
    b << r.t << ',' << r.t_flow << ',' << sc.tracks[r.track].name << ',' << r.x << ',' << r.y << ',' << r.vx << ','
      << r.vy << ',' << r.p << ',' << r.q << ',' << r.eps_pd << ',' << r.T << ',' << r.eta_c << ',' << r.K_col << '\n';
  write_text(dir + "/tracked.csv", b.str());
}

void write_profile_csv(const std::string& path, const std::vector<std::pair<double, double>>& surface) {
  std::ostringstream c;
  c.precision(8);
  c << "x,surface_y\n";
  for (const auto& [x, y] : surface) c << x << ',' << y << '\n';
  write_text(path, c.str());
}

namespace {
void write_series_csv(const std::string& dir, const Scene& sc, const RunSummary& sum) {
  write_series_csv(dir, sc, sum.series, sum.tracks);
  write_gauges_csv(dir, sc, sum.gauges);
  const size_t nm = sc.material_count();
  if (nm > 1 && sum.material_series.size() == nm * sum.series.size()) {  // runout.csv's measures per material
    std::ostringstream c;
    c.precision(8);
    c << "t,t_flow,stage,material,runout,height,max_speed,kinetic_energy,mean_T,max_T\n";
    for (size_t i = 0; i < sum.series.size(); ++i)
      for (size_t k = 0; k < nm; ++k) {
        const SeriesRow& r = sum.series[i];
        const Measures& m = sum.material_series[i * nm + k];
        c << r.t << ',' << r.t_flow << ',' << r.stage << ',' << sc.material_at(static_cast<int>(k)).label << ','
          << m.runout << ',' << m.height << ',' << m.max_speed << ',' << m.kinetic_energy << ',' << m.mean_T << ','
          << m.max_T << '\n';
      }
    write_text(dir + "/materials.csv", c.str());
  }
}
}  // namespace

// Where the loop is, for the message of a write that fails.
struct LoopPosition {
  double t = 0;
  long step = 0;
  double checkpoint_t = -1;  // time of the checkpoint on disk (< 0: none)
};

RunSummary run_loop(const SceneSetup& su, Runner& runner, const RunOptions& opt, LoopPosition& at) {
  using Clock = std::chrono::steady_clock;
  const Scene& sc = su.scene;
  RunSummary sum;
  sum.device = runner.device();
  const bool files = !opt.out_dir.empty();
  if (files) io::make_folder(opt.out_dir);
  const std::string ckpt_path = files ? opt.out_dir + "/" + kCheckpointFile : "";
  std::vector<std::pair<double, std::string>> pvd;
  int frame_no = 0;
  const std::vector<double>& mass = su.particles.m;
  TerrainMaps maps(su);  // 3D terrain runs: maps and deposit.csv from the samples
  ForceRecorder forces(su);  // obstacle_forces.csv (output.forces)

  const double t_total = sc.duration();
  double t_release = 0;
  for (size_t i = 0; i + 1 < sc.stages.size(); ++i) t_release += sc.stages[i].duration;
  double t_stop = t_total;
  if (opt.stop_after > 0) t_stop = std::min(t_stop, opt.stop_after);

  // Samples (run-out, tracked points) use light frames: positions, velocities and T for all
  // particles, full diagnostics only for the tracked ones. Frames written to disk are full.
  Frame fr, full, last_good;
  double last_good_t = 0;
  // seconds since t0, added to `into` (the loop's host times, HostTimes)
  auto add_since = [](double& into, Clock::time_point t0) {
    into += std::chrono::duration<double>(Clock::now() - t0).count();
  };
  auto full_frame = [&]() -> const Frame& {
    const auto t0 = Clock::now();
    runner.frame(full, true);
    add_since(sum.host.full_frames, t0);
    if (full.body.empty()) {  // ids per point: the set-up's, the same in every frame
      full.body = su.point_body;
      full.material.assign(su.point_material.begin(), su.point_material.end());
      full.material.resize(su.point_body.size(), 0);
    }
    return full;
  };
  // The measures of a sample (run-out, energies: a pass over every particle) and the copy of
  // the last good frame run on a worker thread while the next span runs (on the GPU the host
  // work of a sample cost as long as 100 steps of the 1 mm column). The row is appended at once
  // with its time; settle() waits for the worker before anything reads its measures, last_good
  // or overwrites fr. Declared after fr, last_good and sum: an exception waits for it too.
  std::future<void> pending;
  auto settle = [&] {
    if (pending.valid()) pending.get();
  };
  auto sample = [&](double t, int stage) {
    const auto t0 = Clock::now();
    settle();
    runner.frame(fr, false, su.tracked);
    forces.sample(t, t - t_release, runner);
    sum.series.push_back({t, t - t_release, stage, Measures{}});
    for (size_t k = 0; k < su.tracked.size(); ++k) {
      const long i = su.tracked[k], n = fr.n;
      const PointDiagnostics& d = fr.subset[k];
      sum.tracks.push_back({t, t - t_release, k, fr.x[i], fr.x[n + i], fr.v[i], fr.v[n + i], d.p, d.q, d.eps_pd, d.T,
                            d.eta_c, d.K_col});
    }
    last_good_t = t;
    const size_t row = sum.series.size() - 1;
    add_since(sum.host.samples, t0);
    pending = std::async(std::launch::async, [&, row, t] {
      const Measures m = measure(fr, su, mass);
      std::vector<Measures> per_material;
      if (sc.material_count() > 1)
        for (int k = 0; k < sc.material_count(); ++k) per_material.push_back(measure(fr, su, mass, k));
      maps.sample(t, t - t_release, fr);
      for (const GaugeRow& g : measure_gauges(fr, su, mass, t, t - t_release)) sum.gauges.push_back(g);
      sum.series[row].m = m;
      // the worker appends in sample order: settle() precedes the next sample
      sum.material_series.insert(sum.material_series.end(), per_material.begin(), per_material.end());  // the main thread touches only .t of this row until settle()
      sum.final = m;
      last_good = fr;
    });
  };
  // Frames go to a thread of their own with a copy of the frame: the VTU, its pressure profile,
  // then the index, in that order, while the loop goes on. A write's error comes back at the
  // next frame or flush(); flush() before a checkpoint and at the end (an exception: its
  // destructor writes what was handed over).
  FrameWriter writer(sc.output.format, sc.output.fields);
  // `spare`: a frame the loop no longer needs, moved to the writer instead of copied
  auto write_frame = [&](const Frame& f, double t, const std::string& tag, Frame* spare = nullptr) {
    if (!files) return;
    const auto t0 = Clock::now();
    char name[64];
    std::snprintf(name, sizeof name, "frame_%04d%s.vtu", frame_no++, tag.c_str());
    pvd.emplace_back(t, name);
    FrameJob job;
    if (spare)
      job.frame = std::move(*spare);
    else
      job.frame = f;
    job.path = opt.out_dir + "/" + name;
    if (std::string csv = forces.pressure_csv(); !csv.empty())
      job.beside.emplace_back(opt.out_dir + "/" + ForceRecorder::pressure_file(frame_no - 1), std::move(csv));
    job.index_path = opt.out_dir + "/frames.pvd";
    job.index = pvd;
    writer.write(std::move(job));
    add_since(sum.host.frame_handover, t0);
  };
  auto flush_writer = [&] {
    const auto t0 = Clock::now();
    writer.flush();
    add_since(sum.host.writer_wait, t0);
  };

  const auto wall0 = Clock::now();
  auto last_print = wall0;
  double t = 0;
  long step = 0;
  double dt = sc.adaptive ? std::min(sc.dt, sc.cfl * su.dt_estimate) : sc.dt;
  int si = 0;
  double t_stage_end = 0;
  long next_out = 0;
  std::vector<double> out_times = sc.output.times;
  std::sort(out_times.begin(), out_times.end());
  double next_sample = sc.output.series_dt;
  UpdateStats stats_before;  // steps before the checkpoint resumed from
  double wall_before = 0;
  bool resumed = false;
  if (opt.resume) {
    const LoopState& ls = opt.resume->loop;
    runner.upload(opt.resume->particles);
    t = ls.t;
    step = ls.step;
    dt = ls.dt;
    si = ls.stage;
    t_stage_end = ls.t_stage_end;
    next_sample = ls.next_sample;
    next_out = ls.next_out;
    frame_no = ls.frame_no;
    pvd = ls.pvd;
    sum.series = ls.series;
    sum.tracks = ls.tracks;
    sum.gauges = ls.gauges;
    sum.material_series = ls.material_series;
    last_good = ls.last_good;
    last_good_t = ls.last_good_t;
    sum.consolidation = ls.consolidation;
    stats_before = ls.stats;
    wall_before = ls.wall_s;
    maps.restore(ls.maps);
    forces.restore(ls.forces, runner);
    sum.final = sum.series.back().m;
    runner.frame(fr, false, su.tracked);  // the current state; a sample at t would have given it
    resumed = true;
    if (files) {  // the index and the series as they were at the checkpoint
      write_pvd(opt.out_dir + "/frames.pvd", pvd);
      write_series_csv(opt.out_dir, sc, sum);
      maps.write_deposit_csv(opt.out_dir);
      forces.write_csv(opt.out_dir);
      sum.checkpoint = ckpt_path;
      at.checkpoint_t = t;
    }
  } else {
    if (files) ForceRecorder::write_geometry(opt.out_dir, sc);
    sample(0.0, 0);
    write_frame(full_frame(), 0.0, "");
  }
  const long step0 = step;
  const double t0 = t;
  auto elapsed = [&] { return std::chrono::duration<double>(Clock::now() - wall0).count(); };

  // Checkpoints land on no particular time (the steps stay those of a run without them).
  const double ck_dt = files ? opt.checkpoint_dt : 0.0;
  auto next_checkpoint_after = [&](double x) {
    return ck_dt > 0 ? (std::floor(x / ck_dt + 1e-9) + 1) * ck_dt : std::numeric_limits<double>::infinity();
  };
  double next_ckpt = next_checkpoint_after(t);
  auto save = [&] {
    flush_writer();  // the frames it lists are on disk before it (the writer syncs each)
    settle();
    Checkpoint c;
    c.scene_hash = opt.scene_hash;
    runner.download(c.particles);
    LoopState& ls = c.loop;
    ls.t = t;
    ls.step = step;
    ls.dt = dt;
    ls.stage = si;
    ls.t_stage_end = t_stage_end;
    ls.next_sample = next_sample;
    ls.next_out = next_out;
    ls.frame_no = frame_no;
    ls.pvd = pvd;
    ls.series = sum.series;
    ls.tracks = sum.tracks;
    ls.gauges = sum.gauges;
    ls.material_series = sum.material_series;
    ls.last_good = last_good;
    ls.last_good.subset.clear();
    ls.last_good_t = last_good_t;
    ls.consolidation = sum.consolidation;
    ls.stats = stats_before + runner.update_stats();
    ls.wall_s = wall_before + elapsed();
    ls.maps = maps.state();
    ls.forces = forces.state(runner);
    write_checkpoint(ckpt_path, c);  // the series and index are rewritten on restart
    sum.checkpoint = ckpt_path;
    at.checkpoint_t = t;
    write_series_csv(opt.out_dir, sc, sum);  // readable series up to the checkpoint
    maps.write_deposit_csv(opt.out_dir);
    forces.write_csv(opt.out_dir);
  };

  bool stop = t >= t_stop - 1e-12;  // a resumed run may already be at --stop-after
  for (; si < static_cast<int>(sc.stages.size()) && !stop; ++si) {
    const Stage& st = sc.stages[si];
    runner.set_stage(si, st.damping, st.flip.value_or(sc.flip));
    if (!resumed) t_stage_end += st.duration;  // a checkpoint holds the end of its stage
    resumed = false;
    while (t < t_stage_end - 1e-12 * t_stage_end && !stop) {
      // Steps land on stage ends, samples and frames exactly. A span runs the steps up to the
      // next one after which this loop has work (sample, frame, stage end, stop) with no host
      // round-trip in between; its conditions are this loop's, so the steps are those of a
      // step-by-step loop (the CPU twin's results are bitwise the same).
      double next_event = std::min(t_stage_end, next_sample);
      if (next_out < static_cast<long>(out_times.size())) next_event = std::min(next_event, t_release + out_times[next_out]);
      double t_until = std::min(next_sample - 1e-12, t_stop - 1e-12);
      if (next_out < static_cast<long>(out_times.size())) t_until = std::min(t_until, t_release + out_times[next_out] - 1e-12);
      t_until = std::min(t_until, t_stage_end - 1e-12 * t_stage_end);
      if (ck_dt > 0) t_until = std::min(t_until, next_ckpt - 1e-9 * ck_dt);  // checkpoint after that step
      Span span;
      span.t = t;
      span.dt = dt;
      span.adaptive = sc.adaptive;
      span.dt_max = sc.dt;  // adaptive: the scene's dt is the largest step
      span.t_land = next_event;
      span.t_until = t_until;
      span.max_steps = span_length(span, std::max(1L, opt.max_span));
      const SpanResult r = runner.advance_span(span);
      step += r.steps;
      at.step = step;
      at.t = r.t;
      if (!r.ok) {
        settle();
        Frame bad;
        runner.frame(bad, false);
        const long n = bad.n, p = r.particle;
        std::ostringstream os;
        os << "particle " << p << " at (" << bad.x[p] << ", " << bad.x[n + p];
        if (bad.dim == 3) os << ", " << bad.x[2 * n + p];
        os << ") m: bad " << status_field(r.status) << " at step " << step << " (t = " << r.t + r.h_last
           << " s, stage '" << stage_name(sc, si) << "'); the last good frame (t = " << last_good_t
           << " s) was written";
        sum.ok = false;
        sum.message = os.str();
        write_frame(last_good, last_good_t, "_last_good");
        stop = true;
        break;
      }
      t = r.t;
      dt = r.dt;
      if (t >= next_sample - 1e-12) {
        sample(t, si);
        next_sample += sc.output.series_dt;
      }
      if (next_out < static_cast<long>(out_times.size()) && t >= t_release + out_times[next_out] - 1e-12) {
        if (sum.series.back().t != t) sample(t, si);
        write_frame(full_frame(), t, "");
        ++next_out;
      }
      if (t >= t_stop - 1e-12) stop = true;
      if (!stop && opt.interrupt && *opt.interrupt) {
        sum.interrupted = *opt.interrupt;
        if (files) save();
        stop = true;
        break;
      }
      if (!stop && t >= next_ckpt - 1e-9 * ck_dt) {
        save();
        next_ckpt = next_checkpoint_after(t);
      }
      if (opt.progress && std::chrono::duration<double>(Clock::now() - last_print).count() > 1.0) {
        last_print = Clock::now();
        const double w = std::chrono::duration<double>(last_print - wall0).count();
        const double rate = (step - step0) / w;
        const double eta = (t_stop - t) / std::max((t - t0) / w, 1e-30);
        std::fprintf(stderr, "\r  t = %.4f / %.4f s  [%s]  step %ld  %.0f steps/s  ETA %.0f s   ", t, t_stop,
                     stage_name(sc, si).c_str(), step, rate, eta);
        std::fflush(stderr);
      }
    }
    if (!sum.ok || sum.interrupted) break;
    if (sum.series.back().t != t) sample(t, si);
    const bool stage_frame = si + 1 < static_cast<int>(sc.stages.size()) && sc.output.frames_in_stages;
    const bool check = si == 0 && sc.stages.size() > 1 && t >= t_stage_end * (1 - 1e-12);
    if (stage_frame || check) full_frame();
    if (check) sum.consolidation = check_consolidation(full, su);
    if (stage_frame) write_frame(full, t, "_" + stage_name(sc, si));
  }
  settle();
  if (opt.progress) std::fprintf(stderr, "\n");
  const bool complete = sum.ok && !sum.interrupted;
  if (complete && (pvd.empty() || pvd.back().first != t)) write_frame(full_frame(), t, "_final", &full);
  sum.steps = step;
  sum.t_end = t;
  sum.wall_s = wall_before + elapsed();
  sum.times = runner.times();
  sum.stats = stats_before + runner.update_stats();

  sum.forces = forces.peaks();
  sum.force_rows = forces.rows();
  if (files) {
    write_series_csv(opt.out_dir, sc, sum);
    maps.write_deposit_csv(opt.out_dir);
    forces.write_csv(opt.out_dir);
    if (!sum.interrupted) {
      write_profile_csv(opt.out_dir + "/profile_final.csv", free_surface(sum.ok ? fr : last_good, su));
      maps.write_maps(opt.out_dir, sum.ok ? fr : last_good);  // the last sample's frame: maxima include it
    }
    flush_writer();  // before the checkpoint goes: a frame that fails leaves it to restart from
    if (complete && t >= t_total * (1 - 1e-12)) {  // nothing left to continue
      std::error_code ec;
      std::filesystem::remove(ckpt_path, ec);
      sum.checkpoint.clear();
    }
  }
  return sum;
}

RunSummary run(const SceneSetup& su, Runner& runner, const RunOptions& opt) {
  LoopPosition at;
  try {
    return run_loop(su, runner, opt, at);
  } catch (const io::OutputError& e) {
    std::ostringstream os;
    os << e.what() << "; the run stopped at t = " << at.t << " s (step " << at.step << ")";
    if (at.checkpoint_t >= 0)
      os << "; its checkpoint of t = " << at.checkpoint_t << " s (" << opt.out_dir << "/" << kCheckpointFile
         << ") is intact";
    else
      os << "; no checkpoint had been written";
    throw io::OutputError(os.str(), e.os_error());
  }
}

BenchResult bench(const SceneSetup& su, Runner& r, const BenchOptions& o) {
  using Clock = std::chrono::steady_clock;
  const Scene& sc = su.scene;
  r.set_stage(0, sc.stages[0].damping, sc.stages[0].flip.value_or(sc.flip));
  double dt = sc.adaptive ? std::min(sc.dt, sc.cfl * su.dt_estimate) : sc.dt;
  auto go = [&](long n, bool timing, bool per_step) {
    long done = 0;
    if (per_step) {
      for (; done < n; ++done) {
        const StepResult s = r.step(dt, sc.adaptive);
        if (!s.ok)
          throw std::runtime_error("benchmark step " + std::to_string(done + 1) + " failed at particle " +
                                   std::to_string(s.particle) + ": " + status_field(s.status));
        if (sc.adaptive) dt = span_next_dt(s.dt_limit, sc.dt);
      }
      return done;
    }
    Span sp;
    sp.max_steps = n;
    sp.dt = dt;
    sp.adaptive = sc.adaptive;
    sp.dt_max = sc.dt;
    sp.timing = timing;
    const SpanResult s = r.advance_span(sp);
    if (!s.ok)
      throw std::runtime_error("benchmark step " + std::to_string(s.steps) + " failed at particle " +
                               std::to_string(s.particle) + ": " + status_field(s.status));
    dt = s.dt;
    return s.steps;
  };
  go(o.warmup, false, o.step_by_step);
  r.reset_times();
  BenchResult res;
  const auto t0 = Clock::now();
  res.steps = go(o.steps, false, o.step_by_step);
  res.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  res.run = r.times();
  if (res.run.steps > 0) {
    res.split = res.run;  // the backend timed its phases in the run itself (CPU twin)
  } else if (o.split_steps > 0) {
    r.reset_times();
    go(o.split_steps, true, false);
    res.split = r.times();
  }
  return res;
}

std::string bench_report(const SceneSetup& su, const Runner& r, const BenchOptions& o, const BenchResult& b) {
  const Scene& sc = su.scene;
  char buf[512];
  std::string out;
  auto line = [&](const char* fmt, auto... a) {
    std::snprintf(buf, sizeof buf, fmt, a...);
    out += buf;
  };
  const double n = double(std::max(1L, b.steps));
  line("scene: %s\ndevice: %s\nparticles: %ld\ngrid nodes: %ld\n", sc.name.c_str(), r.device().c_str(),
       r.particles(), r.nodes());
  line("steps: %ld (after %ld warm-up), %s\n", b.steps, o.warmup,
       o.step_by_step ? "step by step (a host round-trip per step)" : "one span (no host round-trip)");
  out += r.config();
  line("wall: %.4f s\nparticle-updates/s: %.4g\ntime per step: %.2f us\n", b.wall_s, r.particles() * n / b.wall_s,
       1e6 * b.wall_s / n);
  if (b.run.span_steps > 0)
    line("  device time per step (span events): %.2f us\n", 1e6 * b.run.device / double(b.run.span_steps));
  if (b.run.deferred > 0)
    line("  plastic returns (second G2P pass): %.1f %% of the updates\n", 100.0 * b.run.deferred_share(r.particles()));
  if (b.split.steps > 0) {
    const double m = double(b.split.steps);
    const bool same = b.run.steps > 0;
    line("phase split (%s, %ld steps):\n", same ? "same steps" : "separate timed span, a sync per step", b.split.steps);
    line("  P2G: %.2f us\n  grid update: %.2f us\n  G2P + constitutive: %.2f us\n", 1e6 * b.split.p2g / m,
         1e6 * b.split.grid / m, 1e6 * b.split.g2p / m);
    if (b.split.sort > 0) line("  sort (amortised): %.2f us\n", 1e6 * b.split.sort / m);
    line("  sum of phases: %.2f us\n", 1e6 * (b.split.p2g + b.split.grid + b.split.g2p + b.split.sort) / m);
  }
  return out;
}

}  // namespace granflow::mpm
