// The time loop of an ensemble: run_loop's stages, spans and samples (driver.cpp), with the
// samples measured per member and a failed step retiring the members that failed in it.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <future>
#include <limits>
#include <memory>
#include <sstream>
#include <thread>

#include <granflow/io/output.hpp>
#include <granflow/mpm/ensemble.hpp>
#include <granflow/mpm/kernels.hpp>

namespace granflow::mpm {

namespace {

std::string stage_label(const Scene& sc, int i) {
  return sc.stages[i].name.empty() ? "stage" + std::to_string(i) : sc.stages[i].name;
}

std::string member_dir(const std::string& out, int k) {
  char name[32];
  std::snprintf(name, sizeof name, "/member_%04d", k);
  return out + name;
}

}  // namespace

EnsembleSummary run_ensemble(const SceneSetup& su, const std::vector<SceneSetup>& ms, Runner& runner,
                             const EnsembleOptions& opt) {
  using Clock = std::chrono::steady_clock;
  const Scene& sc = su.scene;
  const int nm = su.members;
  const long np = su.particles.n / nm;
  EnsembleSummary sum;
  sum.device = runner.device();
  sum.members.resize(nm);
  const bool files = !opt.out_dir.empty();
  auto interrupted = [&] { return opt.interrupt && *opt.interrupt; };
  if (files) {
    io::make_folder(opt.out_dir);
    for (int k = 0; k < nm; ++k) {
      if (interrupted()) {  // nothing run yet: no member files
        sum.interrupted = *opt.interrupt;
        return sum;
      }
      io::make_folder(member_dir(opt.out_dir, opt.first_member + k));
    }
  }

  double t_release = 0;
  for (size_t i = 0; i + 1 < sc.stages.size(); ++i) t_release += sc.stages[i].duration;
  std::vector<double> out_times = sc.output.times;
  std::sort(out_times.begin(), out_times.end());
  for (auto& m : sum.members) m.runout_at.assign(out_times.size(), std::nan(""));

  // Tracked points of every member (member k's copy of member 0's tracked particle).
  std::vector<long> tracked;
  for (int k = 0; k < nm; ++k)
    for (long i : ms[k].tracked) tracked.push_back(k * np + i);
  const size_t nt = ms[0].tracked.size();

  std::vector<char> alive(nm, 1);
  std::vector<int> pvd_count(nm, 0);
  std::vector<std::vector<std::pair<double, std::string>>> pvd(nm);
  const auto wall0 = Clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(Clock::now() - wall0).count(); };

  // Boundary forces (output.forces): each member's share of the runner's sums, in a recorder of
  // its own set-up (make_ensemble_setup lists the members' parts and probes one after another).
  std::vector<std::unique_ptr<ForceRecorder>> forces;
  for (int k = 0; k < nm && !su.probes.empty(); ++k) forces.push_back(std::make_unique<ForceRecorder>(ms[k]));
  auto sample_forces = [&](double t) {
    if (forces.empty()) return;
    BoundaryForces all;
    runner.take_forces(all);
    const size_t nq = ms[0].force_parts.size(), nb = ms[0].force_boundaries.size(), npr = ms[0].probes.size();
    const int D = sc.dim;
    for (int k = 0; k < nm; ++k) {
      if (!alive[k]) continue;
      BoundaryForces f;
      f.parts.assign(all.parts.begin() + k * nq, all.parts.begin() + (k + 1) * nq);
      f.boundaries.assign(all.boundaries.begin() + k * nb, all.boundaries.begin() + (k + 1) * nb);
      f.node_impulse.resize(D * npr);
      for (int d = 0; d < D; ++d)
        std::copy(all.node_impulse.begin() + d * nm * npr + k * npr,
                  all.node_impulse.begin() + d * nm * npr + (k + 1) * npr, f.node_impulse.begin() + d * npr);
      forces[k]->sample(t, t - t_release, f);
    }
  };


  // Samples: a snapshot of all members (queued behind the steps; Runner::snapshot), collected
  // and measured on a worker thread while the next span runs, the members split over a few
  // threads; settle() before anything reads the rows or takes the next snapshot.
  const int workers = std::clamp(static_cast<int>(std::thread::hardware_concurrency()) - 1, 1, 8);
  Frame fr;
  double last_sample_t = -1;
  std::future<void> pending;
  auto settle = [&] {
    if (pending.valid()) pending.get();
  };
  auto sample = [&](double t, int stage, long out_index) {
    settle();
    last_sample_t = t;
    sample_forces(t);
    std::vector<int> todo;
    for (int k = 0; k < nm; ++k) {
      if (!alive[k]) continue;
      MemberSummary& m = sum.members[k];
      m.series.push_back({t, t - t_release, stage, Measures{}});
      m.t_end = t;
      todo.push_back(k);
    }
    runner.snapshot(tracked);
    const bool released = stage + 1 >= static_cast<int>(sc.stages.size());
    auto measure_members = [&, out_index, released](const std::vector<int>& ks) {
      for (const int k : ks) {
        MemberSummary& m = sum.members[k];
        const Frame f = member_frame(fr, k, np);
        const Measures me = measure(f, ms[k], ms[k].particles.m);
        m.series.back().m = me;
        m.final = me;
        if (released) m.max_speed = std::max(m.max_speed, me.max_speed);
        if (out_index >= 0) m.runout_at[out_index] = me.runout;
        m.profile = free_surface(f, ms[k]);
      }
    };
    pending = std::async(std::launch::async, [&, todo, t, measure_members] {
      runner.collect(fr);
      for (const int k : todo) {
        MemberSummary& m = sum.members[k];
        for (size_t j = 0; j < nt; ++j) {
          const long i = ms[k].tracked[j] + k * np, n = fr.n;
          const PointDiagnostics& d = fr.subset[k * nt + j];
          m.tracks.push_back({t, t - t_release, j, fr.x[i], fr.x[n + i], fr.v[i], fr.v[n + i], d.p, d.q, d.eps_pd,
                              d.T, d.eta_c, d.K_col});
        }
      }
      // Threads of their own, no OpenMP team: a team made for each new worker thread cost more
      // than the measures (64 members of the 5 mm column on an H100: 12.5 ms a sample).
      const int nw = std::min<int>(workers, static_cast<int>(todo.size()));
      std::vector<std::vector<int>> parts(std::max(nw, 1));
      for (size_t j = 0; j < todo.size(); ++j) parts[j % parts.size()].push_back(todo[j]);
      std::vector<std::future<void>> done;
      for (size_t w = 1; w < parts.size(); ++w)
        done.push_back(std::async(std::launch::async, measure_members, parts[w]));
      measure_members(parts[0]);
      for (auto& d : done) d.get();
    });
  };
  auto write_frames = [&](double t, const std::string& tag) {
    if (!files || !opt.frames) return;
    settle();
    Frame full;
    runner.frame(full, true);
    full.body = su.point_body;
    full.material.assign(su.point_material.begin(), su.point_material.end());
    full.material.resize(su.point_body.size(), 0);
    for (int k = 0; k < nm; ++k) {
      if (!alive[k]) continue;
      const std::string name = frame_file_name(pvd_count[k]++, tag);
      const std::string dir = member_dir(opt.out_dir, opt.first_member + k);
      write_vtu(dir + "/" + name, member_frame(full, k, np), sc.output.format, sc.output.fields);
      pvd[k].emplace_back(t, name);
      write_pvd(dir + "/frames.pvd", pvd[k]);
    }
  };

  double t = 0;
  long step = 0;
  double dt = sc.adaptive ? std::min(sc.dt, sc.cfl * su.dt_estimate) : sc.dt;
  double t_stage_end = 0;
  long next_out = 0;
  double next_sample = sc.output.series_dt;
  sample(0.0, 0, -1);
  write_frames(0.0, "");
  auto last_print = wall0;
  int n_alive = nm;
  bool stop = interrupted();
  if (stop) sum.interrupted = *opt.interrupt;
  // Spans of about kSpanWall seconds at most (from the last span's wall time per step): an
  // interrupt is seen within that however many members run. Spans only group the steps.
  constexpr double kSpanWall = 0.2;
  double step_wall = 0;
  for (int si = 0; si < static_cast<int>(sc.stages.size()) && !stop; ++si) {
    const Stage& st = sc.stages[si];
    runner.set_stage(si, st.damping, st.flip.value_or(sc.flip));
    t_stage_end += st.duration;
    while (t < t_stage_end - 1e-12 * t_stage_end && !stop) {
      double next_event = std::min(t_stage_end, next_sample);
      double t_until = next_sample - 1e-12;
      if (next_out < static_cast<long>(out_times.size())) {
        next_event = std::min(next_event, t_release + out_times[next_out]);
        t_until = std::min(t_until, t_release + out_times[next_out] - 1e-12);
      }
      t_until = std::min(t_until, t_stage_end - 1e-12 * t_stage_end);
      Span span;
      span.t = t;
      span.dt = dt;
      span.adaptive = sc.adaptive;  // no cap_to_stable: a member's steps must not depend on the others'
      span.dt_max = sc.dt;
      span.t_land = next_event;
      span.t_until = t_until;
      const long cap = std::max(1L, opt.max_span);
      span.max_steps = span_length(
          span, step_wall > 0 ? std::clamp(static_cast<long>(kSpanWall / step_wall), 1L, cap) : std::min(cap, 4L));
      const auto span_start = Clock::now();
      const SpanResult r = runner.advance_span(span);
      if (r.steps > 0) step_wall = std::chrono::duration<double>(Clock::now() - span_start).count() / double(r.steps);
      step += r.steps;
      if (!r.ok) {
        // The failed step is complete for the members that did not fail in it.
        settle();
        const std::vector<MemberFailure> failed = runner.retire_failed_members();
        if (failed.empty()) throw std::logic_error("ensemble: a failed step named no member");
        for (const MemberFailure& f : failed) {
          MemberSummary& m = sum.members[f.member];
          const long p = f.particle - f.member * np;
          std::ostringstream os;
          os << "particle " << p << ": bad " << status_field(f.status) << " at step " << step << " (t = "
             << r.t + r.h_last << " s, stage '" << stage_label(sc, si) << "'); last good sample t = " << m.t_end
             << " s";
          m.ok = false;
          m.message = os.str();
          m.steps = step;
          m.wall_s = elapsed();
          alive[f.member] = 0;
          --n_alive;
        }
        t = r.t + r.h_last;
        if (n_alive == 0) {
          stop = true;
          break;
        }
      } else {
        t = r.t;
        dt = r.dt;
      }
      if (t >= next_sample - 1e-12) {
        sample(t, si, -1);
        next_sample += sc.output.series_dt;
      }
      if (next_out < static_cast<long>(out_times.size()) && t >= t_release + out_times[next_out] - 1e-12) {
        if (last_sample_t == t) {
          settle();
          for (int k = 0; k < nm; ++k)
            if (alive[k]) sum.members[k].runout_at[next_out] = sum.members[k].final.runout;
        } else {
          sample(t, si, next_out);
        }
        write_frames(t, "");
        ++next_out;
      }
      if (interrupted()) {
        sum.interrupted = *opt.interrupt;
        stop = true;
        break;
      }
      if (opt.progress && std::chrono::duration<double>(Clock::now() - last_print).count() > 1.0) {
        last_print = Clock::now();
        const double w = elapsed();
        const double eta = (sc.duration() - t) / std::max(t / w, 1e-30);
        std::fprintf(stderr, "\r  members: %d running, %d failed  t = %.4f / %.4f s  [%s]  step %ld  ETA %.0f s   ",
                     n_alive, nm - n_alive, t, sc.duration(), stage_label(sc, si).c_str(), step, eta);
        std::fflush(stderr);
      }
    }
    if (stop) break;
    if (last_sample_t != t) sample(t, si, -1);
    if (si == 0 && sc.stages.size() > 1) {
      settle();
      Frame full;
      runner.frame(full, true);
      for (int k = 0; k < nm; ++k)
        if (alive[k]) sum.members[k].consolidation = check_consolidation(member_frame(full, k, np), ms[k]);
    }
  }
  settle();
  if (opt.progress) std::fprintf(stderr, "\n");
  const bool complete = !sum.interrupted;
  if (complete) write_frames(t, "_final");
  sum.steps = step;
  sum.t_end = t;
  sum.wall_s = elapsed();
  sum.times = runner.times();
  sum.stats = runner.update_stats();
  // The members' files on all cores (formatting 256 members' series took 4-5 s on one): the
  // error of the lowest failing member is the one reported, as one after the other.
  const auto files0 = Clock::now();
  std::vector<std::exception_ptr> failed(nm);
#pragma omp parallel for schedule(dynamic, 1)
  for (int k = 0; k < nm; ++k) {
    try {
      MemberSummary& m = sum.members[k];
      if (alive[k]) {
        m.steps = step;
        m.wall_s = sum.wall_s;
      }
      if (k < static_cast<int>(forces.size())) m.forces = forces[k]->peaks();
      if (!files) continue;
      const std::string dir = member_dir(opt.out_dir, opt.first_member + k);
      write_series_csv(dir, ms[k].scene, m.series, m.tracks);
      write_profile_csv(dir + "/profile_final.csv", m.profile);
      if (k < static_cast<int>(forces.size())) forces[k]->write_csv(dir);
    } catch (...) {
      failed[k] = std::current_exception();
    }
  }
  for (const auto& e : failed)
    if (e) std::rethrow_exception(e);
  sum.files_s = std::chrono::duration<double>(Clock::now() - files0).count();
  return sum;
}

}  // namespace granflow::mpm
