// granflow ensemble SCENE DESIGN: the members of a design (mpm/ensemble_design.hpp) advanced
// together by one runner; per member the series and final profile granflow mpm writes, a
// summary CSV and PNGs of the final profiles and of each summary quantity against each
// varied value (scripts/plot_ensemble.py).
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <exception>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <new>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <granflow/io/output.hpp>
#include <granflow/io/run_folder.hpp>
#include <granflow/mpm/checkpoint.hpp>
#include <granflow/mpm/ensemble.hpp>
#include <granflow/mpm/ensemble_design.hpp>
#include <granflow/mpm/memory.hpp>
#include <granflow/mpm/ranks.hpp>

#include "commands.hpp"
#include "mpm_common.hpp"

namespace granflow::cli {

namespace {

namespace fs = std::filesystem;

struct EnsembleCmd {
  std::string scene, design, out, backend = "cpu", precision;
  bool force = false, no_png = false, quiet = false, frames = false;
  long span = 10000;
  int devices = 0;  // at most this many GPUs (0: all visible)
  CudaFlags cuda;
  mpm::SceneOverrides overrides;
};

// make_ensemble_setup's refusals: a key the scene gives (time.stop_at_rest, a mesh) is named at
// the scene's line or --set; the others (members that differ) are the design's.
io::InputError ensemble_setup_error(const EnsembleCmd& o, const std::vector<mpm::SceneSetup>& members,
                                    const mpm::SceneError& e) {
  if (!members.empty())
    if (auto located = mpm::scene_error_at(members[0].scene, e)) return *located;
  return io::InputError(io::where(o.design) + e.what());
}

// Memory the platform has for the runner's buffers: the GPU's free memory, or the host's
// available memory (MemAvailable) for the CPU twin. 0: unknown.
double available_bytes(const std::string& backend) {
  if (backend == "cuda") {
    std::size_t free = 0, total = 0;
    return mpm::cuda_memory_info(free, total) ? double(free) : 0.0;
  }
  std::ifstream in("/proc/meminfo");
  std::string key;
  double kib = 0;
  std::string unit;
  while (in >> key >> kib >> unit)
    if (key == "MemAvailable:") return kib * 1024.0;
  return 0.0;
}

// Each varied key tried alone on member 0's value, so that a key the scene does not have is
// named with the design file's line.
void check_vary_keys(const EnsembleCmd& o, const mpm::EnsembleDesign& d) {
  for (size_t j = 0; j < d.vary.size(); ++j) {
    mpm::SceneOverrides ov = o.overrides;
    ov.sets.push_back(mpm::member_overrides(d, 0)[j]);
    try {
      mpm::load_scene(o.scene, ov);
    } catch (const std::exception& e) {
      throw io::InputError(io::where(d.file, d.vary[j].line) + "vary key '" + d.vary[j].key + "': " + e.what());
    }
  }
}

// Member k's scene: the design's values over the command line's --set.
mpm::SceneSetup member_setup(const EnsembleCmd& o, const mpm::EnsembleDesign& d, long k) {
  mpm::SceneOverrides ov = o.overrides;
  for (const std::string& s : mpm::member_overrides(d, k)) ov.sets.push_back(s);
  try {
    return setup_from_file(o.scene, ov, o.precision);
  } catch (const io::InputError& e) {
    std::string values;
    for (const std::string& s : mpm::member_overrides(d, k)) values += " " + s;
    throw io::InputError(io::where(d.file) + "member " + std::to_string(k) + " (" + values.substr(1) + "): " +
                         e.what());
  }
}

// Members [first, last) after `first`'s set-up (given), on the host's cores: each set-up reads
// the scene and seeds its points (about 25 ms for a 5 mm column: 6 s for 256 members one after
// the other). A failing member's error is the lowest failing member's, as one after the other.
std::vector<mpm::SceneSetup> setup_members(const EnsembleCmd& o, const mpm::EnsembleDesign& d, long first, long last,
                                           mpm::SceneSetup first_su) {
  std::vector<mpm::SceneSetup> ms(static_cast<std::size_t>(last - first));
  ms[0] = std::move(first_su);
  std::vector<std::exception_ptr> errors(ms.size());
  std::atomic<long> next{first + 1};
  auto work = [&] {
    for (long k = next++; k < last; k = next++) {
      try {
        ms[k - first] = member_setup(o, d, k);
      } catch (...) {
        errors[k - first] = std::current_exception();
        next = last;  // the others stop at their current member
      }
    }
  };
  const long threads = std::max(1L, std::min<long>(std::thread::hardware_concurrency(), last - first - 1));
  std::vector<std::thread> pool;
  for (long t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
  return ms;
}

// Refuses, before the other members are set up, a design that does not fit 90 % of what is
// available: the runners' buffers in the GPUs' free memory (CUDA), and in the host's available
// memory what the host holds (mpm::estimate_ensemble_memory: the set-ups, samples and summaries,
// and the CPU twin's buffers). Returns the host's estimate, for an out-of-memory message.
std::string check_memory(const EnsembleCmd& o, const mpm::EnsembleDesign& d, const mpm::SceneSetup& first,
                         int devices) {
  const mpm::EnsembleMemory m = mpm::estimate_ensemble_memory(first);
  const bool gpu = o.backend == "cuda";
  char said[160] = "";
  auto check = [&](double per, double have, const char* where) {
    const double need = per * double(d.members);
    std::snprintf(said, sizeof said, "estimated %.2f GiB of the %s's %.2f GiB", need / 1073741824.0, where,
                  have / 1073741824.0);  // the host's, checked last, stays
    if (!(have > 0) || need <= 0.9 * have) return;
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "%ld members need %.2f GiB (%.4f GiB each) and the %s has %.2f GiB available: at most %ld members "
                  "fit; lower design.members or use a coarser grid",
                  d.members, need / 1073741824.0, per / 1073741824.0, where, have / 1073741824.0,
                  static_cast<long>(0.9 * have / per));
    throw io::InputError(io::where(d.file) + buf);
  };
  if (gpu) check(m.runner_per_member, available_bytes("cuda") * devices, devices > 1 ? "GPUs" : "GPU");
  check(m.host_per_member + (gpu ? 0.0 : m.runner_per_member), available_bytes("cpu"), "host");
  return said;
}

// An allocation that fails says what it was for and what the memory check estimated.
template <class F>
auto allocating(const std::string& what, const std::string& estimate, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const std::bad_alloc&) {
    throw std::runtime_error("out of memory while " + what + " (the memory check " + estimate +
                             "): lower design.members or use a coarser grid");
  }
}

std::string summary_csv(const mpm::EnsembleDesign& d, const mpm::Scene& sc, const mpm::EnsembleSummary& s) {
  std::ostringstream os;
  os.precision(10);
  os << "member";
  for (const auto& v : d.vary) os << ',' << v.key;
  os << ",status,runout,height";
  std::vector<double> times = sc.output.times;
  std::sort(times.begin(), times.end());
  for (double t : times) os << ",runout_t" << t;
  // the obstacles' peak force and impulse (docs/mpm_obstacles.md), as the members report them
  std::vector<std::string> obstacles;
  for (const auto& o : sc.obstacles) obstacles.push_back(o.name);
  const char* f_unit = sc.dim == 2 ? "N/m" : "N";
  const char* i_unit = sc.dim == 2 ? "N s/m" : "N s";
  for (const std::string& o : obstacles)
    os << ',' << io::csv_field(o + " peak [" + f_unit + "]", true) << ','
       << io::csv_field(o + " impulse [" + i_unit + "]", true) << ','
       << io::csv_field(o + " step peak [" + f_unit + "]", true);
  os << ",max_speed,steps,t_end,wall_s,message\n";
  for (size_t k = 0; k < s.members.size(); ++k) {
    const mpm::MemberSummary& m = s.members[k];
    os << k;
    for (double v : d.values[k]) os << ',' << mpm::format_exact(v);  // as the members got them
    os << ',' << (m.ok ? "ok" : "failed") << ',' << m.final.runout << ',' << m.final.height;
    for (double r : m.runout_at) {
      os << ',';
      if (std::isfinite(r)) os << r;
    }
    for (const std::string& o : obstacles) {
      const mpm::ForcePeak* f = nullptr;
      for (const auto& x : m.forces)
        if (x.boundary == o) f = &x;
      if (f)
        os << ',' << f->peak << ',' << f->impulse << ',' << f->step_peak;
      else
        os << ",,,";
    }
    os << ',' << m.max_speed << ',' << m.steps << ',' << m.t_end << ',' << m.wall_s << ',' << io::csv_field(m.message, true)
       << '\n';
  }
  return os.str();
}

// Where the command's time outside the run goes (seconds; printed as one line).
struct OutsideRun {
  using Clock = std::chrono::steady_clock;
  Clock::time_point start = Clock::now();
  double members = 0, combining = 0, runners = 0;
  static double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
};

// What one process writes and prints once every member has run: summary.csv, design.toml, the
// report on stdout, the PNGs, the manifest.
void finish(const EnsembleCmd& o, const mpm::EnsembleDesign& design, const mpm::Scene& sc,
            const mpm::EnsembleSummary& s, const std::string& out, io::RunFolder& folder, long particles,
            long nodes, const std::string& device, const OutsideRun& outside = {}) {
  const auto t_summary = OutsideRun::Clock::now();
  io::write_file(out + "/summary.csv", summary_csv(design, sc, s));
  {
    std::ifstream in(o.design, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    io::write_file(out + "/design.toml", text.str());
  }
  long failed = 0;
  for (const auto& m : s.members) failed += m.ok ? 0 : 1;
  const double updates = double(particles) * double(s.steps);
  std::printf("scene: %s\nmembers: %ld (%ld failed)\nparticles: %ld\nsteps: %ld\nsimulated: %.6g s\nwall: %.3f s\n",
              sc.name.c_str(), design.members, failed, particles, s.steps, s.t_end, s.wall_s);
  std::printf("device: %s\ngrid nodes: %ld\n", device.c_str(), nodes);
  std::printf("particle-updates/s: %.4g\nwall per step: %.2f us\n", s.wall_s > 0 ? updates / s.wall_s : 0.0,
              s.steps > 0 ? 1e6 * s.wall_s / s.steps : 0.0);
  if (s.times.span_steps > 0)  // CUDA: kernel time of the spans (first device), the rest is the host's
    std::printf("device time of spans: %.3f s (%.2f us per step)\n", s.times.device,
                1e6 * s.times.device / s.times.span_steps);
  print_plastic_returns(s.stats);
  for (size_t k = 0; k < s.members.size(); ++k)
    if (!s.members[k].ok) std::printf("member %zu failed: %s\n", k, s.members[k].message.c_str());
  std::printf("output: %s (summary.csv, member_NNNN/{runout,tracked,profile_final}.csv)\n", out.c_str());
  std::printf("outside the run: set-up %.2f s (members %.2f, combining %.2f), runners %.2f s, member files %.2f s, "
              "summary %.2f s; command so far %.2f s\n",
              outside.members + outside.combining, outside.members, outside.combining, outside.runners, s.files_s,
              OutsideRun::since(t_summary), OutsideRun::since(outside.start));
  if (s.interrupted) {
    std::fprintf(stderr, "granflow: interrupted at t = %.6g s; wrote the series so far\n", s.t_end);
    throw ExitStatus{128 + s.interrupted};
  }
  if (!o.no_png) {
    const std::string script = locate_script("plot_ensemble.py");
    if (script.empty()) {
      std::fprintf(stderr, "PNGs skipped: scripts/plot_ensemble.py not found\n");
    } else {
      const std::string py = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
      const std::string cmd = py + " " + shell_word(script) + " " + shell_word(out);
      if (std::system(cmd.c_str()) != 0) {
        std::error_code ec;
        fs::remove_all(out + "/png", ec);
        std::fprintf(stderr, "PNGs skipped: '%s' failed\n", cmd.c_str());
      }
    }
  }
  folder.complete(failed == 0 ? "complete" : "complete; " + std::to_string(failed) + " members failed (summary.csv)");
  // Exit status (docs/mpm_ensembles.md): every member failed: 1, as a failed single run; some: 0
  // with a warning, the others' results stand.
  if (failed == 0) return;
  long first = 0;
  while (s.members[first].ok) ++first;
  const std::string why = "member " + std::to_string(first) + ": " + s.members[first].message;
  if (failed == static_cast<long>(s.members.size()))
    throw std::runtime_error("all " + std::to_string(failed) + " members failed (" + why + "); " + out +
                             "/summary.csv has each member's message");
  std::fprintf(stderr, "granflow: warning: %ld of %zu members failed (%s); %s/summary.csv has each member's status\n",
               failed, s.members.size(), why.c_str(), out.c_str());
}

// Several MPI ranks (docs/mpm_ensembles.md, "Several processes (MPI)"): rank r runs the
// contiguous members rank_members gives it as one ensemble on its host's GPU number local rank
// (or the CPU twin) and writes their member folders; rank 0 owns the output folder, gathers
// every member's summary and writes what one process writes.
void run_ensemble_ranks(const EnsembleCmd& o) {
  const mpm::Ranks& rk = mpm::ranks();
  if (o.devices > 1)
    throw io::InputError("--devices " + std::to_string(o.devices) +
                         ": under mpirun/srun each rank drives one GPU (the one of its local rank); start one rank "
                         "per GPU instead");
  const mpm::EnsembleDesign design = mpm::load_design(o.design);
  check_vary_keys(o, design);
  const auto [first, last] = mpm::rank_members(design.members, rk.rank(), rk.size());
  std::string out = o.out;
  if (out.empty()) out = "ensemble_out/" + fs::path(o.design).stem().string();
  mpm::SceneSetup su;  // this rank's members as one ensemble (none where members < ranks)
  std::vector<mpm::SceneSetup> ms;
  if (last > first) {
    mpm::SceneSetup su0 = member_setup(o, design, first);
    mpm::EnsembleDesign mine = design;
    mine.members = last - first;
    if (o.backend == "cuda") mpm::cuda_select_device(rk.local_rank() % std::max(1, mpm::cuda_device_count()));
    const std::string estimate = check_memory(o, mine, su0, 1);
    allocating("setting up this rank's members", estimate, [&] {
      ms = setup_members(o, design, first, last, std::move(su0));
      try {
        su = mpm::make_ensemble_setup(ms);
      } catch (const mpm::SceneError& e) {
        throw ensemble_setup_error(o, ms, e);
      }
    });
  } else {
    su = member_setup(o, design, 0);  // the scene, for rank 0's summary
  }
  // The folder exists and is locked before any rank writes into it.
  std::unique_ptr<io::RunFolder> folder;
  if (rk.rank() == 0)
    folder = std::make_unique<io::RunFolder>(out, o.force ? io::FolderUse::Force : io::FolderUse::Fresh,
                                             mpm::kCheckpointFile);
  rk.barrier();
  mpm::EnsembleSummary part;
  std::string device = "-";
  long particles = 0, nodes = 0;
  {
    SignalGuard guard;
    if (last > first) {
      auto runner = make_runner(su, o.backend, o.cuda);
      device = runner->device();
      if (rk.rank() == 0)
        std::fprintf(stderr, "granflow ensemble: %s, %ld members (%s design of %s) over %d ranks\n  rank 0: %s; %s\n",
                     su.scene.name.c_str(), design.members, design.method.c_str(), o.design.c_str(), rk.size(),
                     device.c_str(), mpm::memory_line(su).c_str());
      mpm::EnsembleOptions eo;
      eo.out_dir = out;
      eo.progress = !o.quiet && rk.rank() == 0;
      eo.frames = o.frames;
      eo.max_span = o.span;
      eo.interrupt = &g_signal;
      eo.first_member = static_cast<int>(first);
      part = mpm::run_ensemble(su, ms, *runner, eo);
      particles = su.particles.n;
      nodes = su.n_nodes * su.members;
    }
  }
  mpm::Packer p;
  p.str(rk.host());
  p.str(device);
  p.pod(first);
  p.pod(particles);
  p.pod(nodes);
  p.pod(part.steps);
  p.pod(part.t_end);
  p.pod(part.wall_s);
  p.pod(part.interrupted);
  p.str(mpm::pack_members(part.members));
  const std::vector<std::string> all = rk.allgather(p.bytes());
  if (rk.rank() != 0) return;

  mpm::EnsembleSummary s;
  s.times = part.times;
  particles = nodes = 0;
  device.clear();
  std::vector<std::pair<long, std::string>> written;  // first member of each rank, its host
  for (int r = 0; r < rk.size(); ++r) {
    mpm::Unpacker u(all[r]);
    const std::string host = u.str(), dev = u.str();
    const long f = u.pod<long>();
    particles += u.pod<long>();
    nodes += u.pod<long>();
    s.steps = std::max(s.steps, u.pod<long>());
    s.t_end = std::max(s.t_end, u.pod<double>());
    s.wall_s = std::max(s.wall_s, u.pod<double>());
    const int interrupted = u.pod<int>();
    s.interrupted = s.interrupted ? s.interrupted : interrupted;
    const std::vector<mpm::MemberSummary> ms_r = mpm::unpack_members(u.str());
    for (size_t k = 0; k < ms_r.size(); ++k) {
      // every rank's member folders must be visible here: --out on a file system the hosts share
      char name[32];
      std::snprintf(name, sizeof name, "/member_%04ld", f + static_cast<long>(k));
      if (!fs::exists(out + name + "/runout.csv"))
        throw io::OutputError(out + name + "/runout.csv: written by rank " + std::to_string(r) + " on host " + host +
                              " but not found by rank 0 on host " + rk.host() +
                              ": --out must be a folder every host shares (docs/mpm_ensembles.md)",
                              ENOENT);
    }
    s.members.insert(s.members.end(), ms_r.begin(), ms_r.end());
    if (device.empty() && dev != "-") device = dev + " x " + std::to_string(rk.size()) + " ranks";
  }
  finish(o, design, su.scene, s, out, *folder, particles, nodes, device);
}

void run_ensemble_cmd(const EnsembleCmd& o) {
  OutsideRun outside;
  require_backend(o.backend);
  if (o.backend != "cuda" && o.devices > 0)
    io::warn("--devices " + std::to_string(o.devices) +
             ": the CPU twin runs every member in this process (--devices spreads them over GPUs with --backend cuda)");
  if (mpm::ranks().size() > 1) return run_ensemble_ranks(o);
  const mpm::EnsembleDesign design = mpm::load_design(o.design);
  check_vary_keys(o, design);
  // Members spread over the visible GPUs: contiguous groups, one runner (context) and one host
  // thread per device.
  int groups = 1;
  if (o.backend == "cuda") groups = std::max(1, mpm::cuda_device_count());
  if (o.devices > 0) groups = std::min(groups, o.devices);
  groups = static_cast<int>(std::min<long>(groups, design.members));
  std::vector<mpm::SceneSetup> ms;
  mpm::SceneSetup su0 = member_setup(o, design, 0);
  const std::string estimate = check_memory(o, design, su0, groups);
  // Set-up: a Ctrl-C here stops at once (the handlers come with the run), nothing is written yet.
  auto t0 = OutsideRun::Clock::now();
  allocating("setting up the " + std::to_string(design.members) + " members", estimate,
             [&] { ms = setup_members(o, design, 0, design.members, std::move(su0)); });
  outside.members = OutsideRun::since(t0);
  t0 = OutsideRun::Clock::now();
  const long per = (design.members + groups - 1) / groups;
  std::vector<std::vector<mpm::SceneSetup>> group_ms(groups);
  std::vector<mpm::SceneSetup> group_su(groups);
  allocating("combining the members' set-ups", estimate, [&] {
    for (int g = 0; g < groups; ++g) {
      const long a = g * per, b = std::min<long>(design.members, a + per);
      group_ms[g].assign(std::make_move_iterator(ms.begin() + a), std::make_move_iterator(ms.begin() + b));
      try {
        group_su[g] = mpm::make_ensemble_setup(group_ms[g]);
      } catch (const mpm::SceneError& e) {
        throw ensemble_setup_error(o, group_ms[g], e);
      }
    }
  });
  ms = {};
  outside.combining = OutsideRun::since(t0);
  std::vector<double> runner_s(groups, 0.0);
  std::string out = o.out;
  if (out.empty()) out = "ensemble_out/" + fs::path(o.design).stem().string();
  io::RunFolder folder(out, o.force ? io::FolderUse::Force : io::FolderUse::Fresh, mpm::kCheckpointFile);
  const mpm::Scene& sc = group_su[0].scene;
  std::vector<mpm::EnsembleSummary> parts(groups);
  std::vector<std::exception_ptr> errors(groups);
  long particles = 0, nodes = 0;
  std::string device;
  {
    SignalGuard guard;
    auto run_group = [&](int g) {
      try {
        const auto tr = OutsideRun::Clock::now();
        if (o.backend == "cuda") mpm::cuda_select_device(g);
        auto runner = allocating("allocating the runner's buffers", estimate,
                                 [&] { return make_runner(group_su[g], o.backend, o.cuda); });
        runner_s[g] = OutsideRun::since(tr);
        if (g == 0) {
          device = runner->device() + (groups > 1 ? " (and " + std::to_string(groups - 1) + " more)" : "");
          std::fprintf(stderr, "granflow ensemble: %s, %ld members (%s design of %s) on %d device%s\n  %s; %s\n",
                       sc.name.c_str(), design.members, design.method.c_str(), o.design.c_str(), groups,
                       groups > 1 ? "s" : "", runner->device().c_str(), mpm::memory_line(group_su[0]).c_str());
        }
        mpm::EnsembleOptions eo;
        eo.out_dir = out;
        eo.progress = !o.quiet && g == 0;
        eo.frames = o.frames;
        eo.max_span = o.span;
        eo.interrupt = &g_signal;
        eo.first_member = static_cast<int>(g * per);
        parts[g] = allocating("running the members", estimate,
                              [&] { return mpm::run_ensemble(group_su[g], group_ms[g], *runner, eo); });
      } catch (...) {
        errors[g] = std::current_exception();
      }
    };
    std::vector<std::thread> threads;
    for (int g = 1; g < groups; ++g) threads.emplace_back(run_group, g);
    run_group(0);
    for (auto& t : threads) t.join();
  }
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
  mpm::EnsembleSummary s = parts[0];
  for (int g = 1; g < groups; ++g) {
    s.members.insert(s.members.end(), parts[g].members.begin(), parts[g].members.end());
    s.wall_s = std::max(s.wall_s, parts[g].wall_s);
    s.files_s = std::max(s.files_s, parts[g].files_s);
    s.interrupted = s.interrupted ? s.interrupted : parts[g].interrupted;
    s.stats = s.stats + parts[g].stats;
  }
  for (const auto& su : group_su) {
    particles += su.particles.n;
    nodes += su.n_nodes * su.members;
  }
  for (double r : runner_s) outside.runners = std::max(outside.runners, r);
  finish(o, design, sc, s, out, folder, particles, nodes, device, outside);
}

}  // namespace

void register_ensemble(CLI::App& app) {
  auto o = std::make_shared<EnsembleCmd>();
  auto* cmd = app.add_subcommand("ensemble", "Run the members of a design over one MPM scene together");
  cmd->add_option("scene", o->scene, "scene file (mpm/scenes/*.toml)")->required()->check(CLI::ExistingFile);
  cmd->add_option("design", o->design, "design file (docs/mpm_ensemble_design.md)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", o->out, "output directory (default ensemble_out/<design>)");
  cmd->add_flag("--force", o->force, "replace the output folder of an earlier granflow run");
  cmd->add_option("--backend", o->backend, "cpu (OpenMP twin) or cuda")->check(CLI::IsMember({"cpu", "cuda"}));
  cmd->add_option("--precision", o->precision, "fp64, mixed or fp32: overrides the scene's solver.precision")
      ->check(CLI::IsMember({"fp64", "mixed", "fp32"}));
  add_override_options(cmd, o->overrides);
  cmd->add_flag("--frames", o->frames, "VTU frames per member at the scene's output times (default: none)");
  cmd->add_flag("--no-png", o->no_png, "do not call scripts/plot_ensemble.py");
  cmd->add_flag("--quiet", o->quiet, "no progress line");
  cmd->add_option("--span", o->span, "most steps queued without a host round-trip")->check(CLI::PositiveNumber);
  cmd->add_option("--devices", o->devices, "CUDA: spread the members over at most N visible GPUs (default: all)")
      ->check(CLI::PositiveNumber);
  o->cuda.add(cmd);
  cmd->callback([o] { run_ensemble_cmd(*o); });
}

}  // namespace granflow::cli
