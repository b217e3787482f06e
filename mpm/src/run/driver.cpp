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

// A stable step below this fraction of the at-rest P-wave step is a blow-up, not a stiff
// material (impacts lower it to about a third: issue 52's slide into a wall).
constexpr double kCollapsedStep = 1e-3;

// "(x, y)" or "(x, y, z)" of point p of a frame.
std::string point_at(const Frame& f, long p) {
  std::ostringstream os;
  os << "(" << f.x[p];
  for (int d = 1; d < f.dim; ++d) os << ", " << f.x[d * f.n + p];
  os << ")";
  return os.str();
}

// The point of a frame that moves fastest, and its speed.
long fastest_point(const Frame& f, double& speed) {
  long fast = 0;
  double v2max = 0;
  for (long i = 0; i < f.n; ++i) {
    double v2 = 0;
    for (int d = 0; d < f.dim; ++d) v2 += f.v[d * f.n + i] * f.v[d * f.n + i];
    if (v2 > v2max) v2max = v2, fast = i;
  }
  speed = std::sqrt(v2max);
  return fast;
}

std::string stage_name(const Scene& sc, int i) { return sc.stages[i].name.empty() ? "stage" + std::to_string(i) : sc.stages[i].name; }

}  // namespace

double rest_since(const std::vector<SeriesRow>& rows, size_t settled, double t_from, double ratio, double hold) {
  settled = std::min(settled, rows.size());
  double peak = 0;
  for (size_t i = 0; i < settled; ++i)
    if (rows[i].t >= t_from - 1e-12) peak = std::max(peak, rows[i].m.kinetic_energy);
  if (!(peak > 0)) return -1;
  size_t first = settled;
  while (first > 0 && rows[first - 1].t >= t_from - 1e-12 && rows[first - 1].m.kinetic_energy < ratio * peak) --first;
  if (first == settled || rows[settled - 1].t - rows[first].t < hold - 1e-9) return -1;
  return rows[first].t;
}

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
        c << r.t << ',' << r.t_flow << ',' << r.stage << ',' << io::csv_field(sc.material_at(static_cast<int>(k)).label) << ','
          << m.runout << ',' << m.height << ',' << m.max_speed << ',' << m.kinetic_energy << ',' << m.mean_T << ','
          << m.max_T << '\n';
      }
    io::write_file(dir + "/materials.csv", c.str(), io::Durability::Buffered);  // synced with the checkpoint or the manifest
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
    const std::string name = frame_file_name(frame_no++, tag);
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
      span.adaptive = sc.limited_steps();
      span.dt_max = sc.dt;  // adaptive: the scene's dt is the largest step
      span.t_land = next_event;
      span.t_until = t_until;
      span.max_steps = span_length(span, std::max(1L, opt.max_span));
      const SpanResult r = runner.advance_span(span);
      step += r.steps;
      sum.shortened_steps += r.shortened;
      sum.dt_min = std::min(sum.dt_min, r.dt_min);
      at.step = step;
      at.t = r.t;
      // The stable step collapsed: a point's speed or stiffness ran away, a blow-up that the
      // next steps would only crawl through.
      const bool collapsed = r.ok && sc.limited_steps() && r.dt < kCollapsedStep * su.dt_estimate;
      if (!r.ok || collapsed) {
        settle();
        Frame now;
        runner.frame(now, false);
        std::ostringstream os;
        if (!r.ok) {
          os << "particle " << r.particle << " at " << point_at(now, r.particle) << " m: bad " << status_field(r.status)
             << " at step " << step << " (t = " << r.t + r.h_last << " s, stage '" << stage_name(sc, si) << "')";
        } else {
          t = r.t;
          double speed = 0;
          const long fast = fastest_point(now, speed);
          os << "the stable step fell to " << r.dt << " s (the at-rest P-wave step is " << su.dt_estimate
             << " s) at step " << step << " (t = " << t << " s, stage '" << stage_name(sc, si)
             << "'): a blown-up velocity field; the fastest point, particle " << fast << " at " << point_at(now, fast)
             << " m, moves at " << speed << " m/s";
        }
        os << "; the last good frame (t = " << last_good_t << " s) was written";
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
        // the newest row's measures are still on the worker: the rows before it are settled
        if (sc.stop_at_rest > 0 && si + 1 == static_cast<int>(sc.stages.size())) {
          const double from = rest_since(sum.series, sum.series.size() - 1, t_release, sc.stop_at_rest, sc.rest_hold);
          if (from >= 0) {
            sum.at_rest_since = from;
            stop = true;
          }
        }
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
    if (complete && (t >= t_total * (1 - 1e-12) || sum.at_rest_since >= 0)) {  // nothing left to continue
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
        const StepResult s = r.step(dt, sc.limited_steps());
        if (!s.ok)
          throw std::runtime_error("benchmark step " + std::to_string(done + 1) + " failed at particle " +
                                   std::to_string(s.particle) + ": " + status_field(s.status));
        if (sc.limited_steps()) dt = span_next_dt(s.dt_limit, sc.dt);
      }
      return done;
    }
    Span sp;
    sp.max_steps = n;
    sp.dt = dt;
    sp.adaptive = sc.limited_steps();
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
