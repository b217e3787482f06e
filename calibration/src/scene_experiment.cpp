// MPM scenes as calibration experiments (kind = "mpm_scene"; docs/calibration_scenes.md). A
// batch of parameter sets is one ensemble run (mpm/ensemble.hpp): member i runs the scene with
// set i's frictional and collisional parameters. What is compared with the data:
//   surface  the final free surface y(x) (free_surface of the last sample: the top of each cell-wide
//            bin, at the bin's centre, interpolated linearly; before the first centre the first
//            bin's top); beyond the simulated deposit the surface is the run-out polyline (the floor)
//   front    the run-out against the time since the release (the last stage's start)
//   track    a tracked point's x and y against the time since the release
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>
#include <sstream>
#include <type_traits>

#include <granflow/calibration/experiment.hpp>
#include <granflow/io/csv_table.hpp>
#include <granflow/io/input_error.hpp>
#include <granflow/io/toml_reader.hpp>
#include <granflow/mpm/ensemble.hpp>
#include <granflow/mpm/ranks.hpp>
#include <granflow/mpm/scene_file.hpp>

namespace granflow::calibration {

namespace {

// Linear interpolation of y(x) at x (x increasing); beyond the ends: `outside` (NaN: the end value).
double interpolate(const std::vector<double>& xs, const std::vector<double>& ys, double x, double outside) {
  if (xs.empty()) return std::nan("");
  if (x <= xs.front()) return std::isnan(outside) ? ys.front() : (x < xs.front() ? outside : ys.front());
  if (x >= xs.back()) return std::isnan(outside) ? ys.back() : (x > xs.back() ? outside : ys.back());
  const auto it = std::upper_bound(xs.begin(), xs.end(), x);
  const size_t i = static_cast<size_t>(it - xs.begin());
  const double w = (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
  return ys[i - 1] + w * (ys[i] - ys[i - 1]);
}

enum class Measured { SurfaceY, Front, TrackX, TrackY };

struct SceneCurve {
  Measured what;
  std::string track;  // Track* only
};

class SceneExperiment final : public Experiment {
 public:
  std::string scene_file;
  mpm::SceneOverrides fixed;
  std::string backend = "auto";
  std::vector<SceneCurve> measured;  // one per curve
  int material = 0;                  // the scene's material the calibrated set replaces (material = "NAME")
  bool progress = true;

  std::size_t index = 0;  // of its [[experiments]] table: names it to the other ranks

  bool batched() const override { return true; }
  Prediction predict(const io::ParameterSet& params) const override { return predict_batch({params}).front(); }

  // Under several MPI ranks a batch of more than one set is split over them (share below); a
  // single set runs here.
  std::vector<Prediction> predict_batch(const std::vector<io::ParameterSet>& sets) const override;

  // The sets as one ensemble run in this process.
  std::vector<Prediction> predict_here(const std::vector<io::ParameterSet>& sets) const {
    const mpm::Scene base = mpm::load_scene(scene_file, fixed);
    std::vector<Prediction> out(sets.size());
    std::vector<mpm::SceneSetup> ms;
    std::vector<size_t> member_of_set(sets.size(), SIZE_MAX);
    for (size_t i = 0; i < sets.size(); ++i) {
      mpm::Scene sc = base;
      mpm::Material& mat = sc.material_at(material);
      const double rho_p = mat.params.c.rho_p;  // the scene's grain density stays
      if (sets[i].frictional) mat.params.f = *sets[i].frictional;
      if (sets[i].collisional) mat.params.c = *sets[i].collisional;
      mat.params.c.rho_p = rho_p;
      try {
        io::check_initial_void_ratio(sets[i], mat.e0, mat.label.empty() ? "the scene's material.e0"
                                                                      : "the e0 of the scene's material " + mat.label);
        ms.push_back(mpm::make_setup(sc));
        member_of_set[i] = ms.size() - 1;
      } catch (const std::exception& e) {
        out[i].ok = false;
        out[i].error = e.what();
      }
    }
    if (ms.empty()) return out;
    const mpm::SceneSetup su = mpm::make_ensemble_setup(ms);
    const bool gpu = backend == "cuda" || (backend == "auto" && mpm::cuda_backend_available());
    auto runner = gpu ? mpm::make_cuda_runner(su) : mpm::make_cpu_runner(su);
    mpm::EnsembleOptions eo;
    eo.progress = progress && mpm::ranks().rank() == 0;
    const mpm::EnsembleSummary es = mpm::run_ensemble(su, ms, *runner, eo);
    for (size_t i = 0; i < sets.size(); ++i) {
      if (member_of_set[i] == SIZE_MAX) continue;
      const size_t k = member_of_set[i];
      const mpm::MemberSummary& m = es.members[k];
      Prediction& p = out[i];
      if (!m.ok) {
        p.ok = false;
        p.error = "MPM member failed: " + m.message;
        continue;
      }
      for (size_t c = 0; c < curves.size(); ++c) p.values.push_back(model_values(c, m, ms[k]));
    }
    return out;
  }

 private:
  std::vector<double> model_values(size_t c, const mpm::MemberSummary& m, const mpm::SceneSetup& su) const {
    const Curve& cv = curves[c];
    std::vector<double> v;
    if (measured[c].what == Measured::SurfaceY) {
      std::vector<double> px, py;
      for (const auto& [x, y] : m.profile) {
        px.push_back(x);
        py.push_back(y);
      }
      const std::vector<double>& lx = su.scene.runout_x;
      const std::vector<double>& ly = su.scene.runout_y;
      for (double x : cv.x) {
        const double floor = lx.size() >= 2 ? interpolate(lx, ly, x, std::nan("")) : su.scene.origin[1];
        // before the first bin's centre: that bin's top (the wall side); beyond the last: the floor
        v.push_back(x > px.back() ? floor : std::max(floor, interpolate(px, py, x, std::nan(""))));
      }
      return v;
    }
    std::vector<double> t, q;
    if (measured[c].what == Measured::Front) {
      for (const auto& r : m.series)
        if (r.t_flow >= 0) {
          t.push_back(r.t_flow);
          q.push_back(r.m.runout);
        }
    } else {
      size_t track = 0;
      for (; track < su.scene.tracks.size(); ++track)
        if (su.scene.tracks[track].name == measured[c].track) break;
      for (const auto& r : m.tracks)
        if (r.track == track && r.t_flow >= 0 && (t.empty() || r.t_flow > t.back())) {
          t.push_back(r.t_flow);
          q.push_back(measured[c].what == Measured::TrackX ? r.x : r.y);
        }
    }
    for (double x : cv.x) v.push_back(x > t.back() + 1e-12 ? std::nan("") : interpolate(t, q, x, std::nan("")));
    return v;
  }
};

// ---- batches over MPI ranks (mpm/ranks.hpp) -------------------------------------------------
// Rank 0 runs the calibration; the other ranks wait in serve_scene_batches. For a batch, rank 0
// broadcasts a request (the experiment's table index and the sets), every rank runs its
// contiguous share of the sets as one ensemble, and the predictions are gathered in set order.

static_assert(std::is_trivially_copyable_v<FrictionalParams<double>> &&
              std::is_trivially_copyable_v<CollisionalParams<double>>);

std::string pack_request(std::size_t index, const std::vector<io::ParameterSet>& sets) {
  mpm::Packer p;
  p.pod<std::uint8_t>(1);
  p.pod<std::uint64_t>(index);
  p.pod<std::uint64_t>(sets.size());
  for (const io::ParameterSet& s : sets) {  // what predict_here reads of a set
    p.str(s.file);
    p.pod<char>(s.frictional.has_value());
    if (s.frictional) p.pod(*s.frictional);
    p.pod<char>(s.collisional.has_value());
    if (s.collisional) p.pod(*s.collisional);
  }
  return p.bytes();
}

std::vector<io::ParameterSet> unpack_sets(mpm::Unpacker& u) {
  std::vector<io::ParameterSet> sets(u.pod<std::uint64_t>());
  for (io::ParameterSet& s : sets) {
    s.file = u.str();
    if (u.pod<char>()) s.frictional = u.pod<FrictionalParams<double>>();
    if (u.pod<char>()) s.collisional = u.pod<CollisionalParams<double>>();
  }
  return sets;
}

// Every rank: its share of `sets`, then all predictions (rank 0 uses them; a rank whose share
// threw makes rank 0 throw naming that rank and host).
std::vector<Prediction> share(const SceneExperiment& e, const std::vector<io::ParameterSet>& sets) {
  const mpm::Ranks& rk = mpm::ranks();
  const auto [a, b] = mpm::rank_members(static_cast<long>(sets.size()), rk.rank(), rk.size());
  mpm::Packer p;
  try {
    const std::vector<Prediction> mine =
        b > a ? e.predict_here(std::vector<io::ParameterSet>(sets.begin() + a, sets.begin() + b))
              : std::vector<Prediction>{};
    p.pod<char>(1);
    p.pod<std::uint64_t>(mine.size());
    for (const Prediction& q : mine) {
      p.pod<char>(q.ok);
      p.str(q.error);
      p.pod<std::uint64_t>(q.values.size());
      for (const auto& v : q.values) p.pods(v);
    }
  } catch (const std::exception& ex) {
    p = mpm::Packer();
    p.pod<char>(0);
    p.str(ex.what());
  }
  const std::vector<std::string> all = rk.allgather(p.bytes());
  std::vector<Prediction> out;
  for (int r = 0; r < rk.size(); ++r) {
    mpm::Unpacker u(all[r]);
    if (!u.pod<char>())
      throw std::runtime_error("rank " + std::to_string(r) + " of " + std::to_string(rk.size()) + ": " + u.str());
    for (auto n = u.pod<std::uint64_t>(); n > 0; --n) {
      Prediction q;
      q.ok = u.pod<char>() != 0;
      q.error = u.str();
      q.values.resize(u.pod<std::uint64_t>());
      for (auto& v : q.values) v = u.pods<double>();
      out.push_back(std::move(q));
    }
  }
  if (out.size() != sets.size())
    throw std::runtime_error("ranks returned " + std::to_string(out.size()) + " predictions for " +
                             std::to_string(sets.size()) + " sets");
  return out;
}

std::mutex g_request;  // rank 0: one request at a time (the objective's threads may call)

std::vector<Prediction> SceneExperiment::predict_batch(const std::vector<io::ParameterSet>& sets) const {
  const mpm::Ranks& rk = mpm::ranks();
  if (rk.size() < 2 || sets.size() < 2) return predict_here(sets);
  std::lock_guard<std::mutex> lock(g_request);
  std::string request = pack_request(index, sets);
  rk.broadcast(request);
  return share(*this, sets);
}

// A data table of an experiment: its file (relative to the job), two columns, the sd. A time
// series (t_end finite: the last stage's duration) must end by the end of the run.
Curve read_curve(io::TomlTable& t, const std::string& job_file, const std::string& xkey, const std::string& ykey,
                 const std::string& experiment, const std::string& model_output, double default_sd,
                 double t_end = std::numeric_limits<double>::infinity()) {
  std::string file = t.string("data");
  if (!file.empty() && file[0] != '/') {
    const auto slash = job_file.find_last_of('/');
    if (slash != std::string::npos) file = job_file.substr(0, slash + 1) + file;
  }
  const std::string xc = t.string_or(xkey, xkey), yc = t.string_or(ykey, ykey);
  Curve c;
  c.experiment = experiment;
  c.data_column = yc;
  c.abscissa = xc;
  c.model_output = model_output;
  c.sd = t.number_or("sd", default_sd, io::Bounds::positive());
  c.weight = 1.0;
  const io::CsvColumns cols = io::read_csv_columns(file, {xc, yc});
  c.x = cols.column(xc);
  c.y = cols.column(yc);
  c.lines = cols.lines;
  c.file = file;
  for (size_t i = 1; i < c.x.size(); ++i)
    if (!(c.x[i] > c.x[i - 1]))
      throw io::InputError(io::where(file, cols.lines[i]) + "column '" + xc + "' must increase strictly");
  if (c.x.empty()) throw io::InputError(io::where(file) + "no data rows");
  for (size_t i = 0; i < c.x.size(); ++i)
    if (c.x[i] > t_end * (1 + 1e-9)) {
      std::ostringstream os;
      os << xc << " = " << c.x[i] << " s lies past the end of the run: the scene's last stage ends " << t_end
         << " s after the release (the data's time origin); drop the later rows or lengthen the stage";
      throw io::InputError(io::where(file, cols.lines[i]) + os.str());
    }
  return c;
}

}  // namespace

// Default standard deviations of the data (docs/calibration_scenes.md).
inline constexpr double kSurfaceSd = 0.003;  // m: a digitised free surface
inline constexpr double kFrontSd = 0.01;     // m: a front position read from video frames
inline constexpr double kTrackSd = 0.005;    // m

std::shared_ptr<const Experiment> make_scene_experiment(io::TomlTable& t, const std::string& job_file,
                                                        std::size_t index) {
  auto e = std::make_shared<SceneExperiment>();
  e->index = index;
  e->name = t.string_or("name", "experiment" + std::to_string(index + 1));
  e->kind = t.choice("kind", {"mpm_scene"}, "mpm_scene");
  std::string scene = t.string("scene");
  if (!scene.empty() && scene[0] != '/') {
    const auto slash = job_file.find_last_of('/');
    if (slash != std::string::npos) scene = job_file.substr(0, slash + 1) + scene;
  }
  e->scene_file = scene;
  e->data_file = scene;
  if (t.has("set")) e->fixed.sets = t.strings("set");
  e->backend = t.choice("backend", {"auto", "cpu", "cuda"}, "auto");
  e->progress = t.boolean_or("progress", true);
  mpm::Scene sc;
  try {
    sc = mpm::load_scene(scene, e->fixed);
  } catch (const io::InputError& err) {
    t.fail("scene", err.what());
  }
  // Scenes of several materials: the one the calibrated set replaces (the others keep theirs,
  // `set` may change them with NAME:KEY).
  if (t.has("material")) {
    const std::string name = t.string("material");
    e->material = sc.material_index(name);
    if (sc.material.label.empty()) t.fail("material", "the scene has one unnamed [material]: leave material out");
    if (e->material < 0) {
      std::string list;
      for (int i = 0; i < sc.material_count(); ++i) list += (list.empty() ? "" : ", ") + sc.material_at(i).label;
      t.fail("material", "the scene has no [[material]] named '" + name + "' (its materials: " + list + ")");
    }
  } else if (sc.material_count() > 1) {
    t.fail_missing("material", "the [[material]] the calibrated set replaces: the scene has " +
                                   std::to_string(sc.material_count()) + " materials");
  }
  e->abscissa_quantity = "time";
  if (auto s = t.optional_table("surface")) {
    e->curves.push_back(read_curve(*s, job_file, "x", "y", e->name, "surface_y", kSurfaceSd));
    e->measured.push_back({Measured::SurfaceY, ""});
    s->finish();
  }
  const double t_end = sc.stages.empty() ? 0.0 : sc.stages.back().duration;  // since the release
  if (auto f = t.optional_table("front")) {
    e->curves.push_back(read_curve(*f, job_file, "t", "x", e->name, "runout", kFrontSd, t_end));
    e->measured.push_back({Measured::Front, ""});
    f->finish();
  }
  for (io::TomlTable& tr : t.array_of_tables("track")) {
    const std::string name = tr.string("name");
    if (std::none_of(sc.tracks.begin(), sc.tracks.end(), [&](const mpm::Track& k) { return k.name == name; }))
      tr.fail("name", "the scene tracks no point '" + name + "'");
    e->curves.push_back(read_curve(tr, job_file, "t", "x", e->name + "[" + name + "]", "track_x", kTrackSd, t_end));
    e->measured.push_back({Measured::TrackX, name});
    e->curves.push_back(read_curve(tr, job_file, "t", "y", e->name + "[" + name + "]", "track_y", kTrackSd, t_end));
    e->measured.push_back({Measured::TrackY, name});
    tr.finish();
  }
  if (e->curves.empty()) t.fail("surface", "an mpm_scene experiment needs [surface], [front] or [[track]] data");
  return e;
}

void serve_scene_batches(const std::vector<std::shared_ptr<const Experiment>>& experiments) {
  const mpm::Ranks& rk = mpm::ranks();
  if (rk.size() < 2 || rk.rank() == 0) return;
  for (;;) {
    std::string request;
    rk.broadcast(request);
    mpm::Unpacker u(request);
    if (u.pod<std::uint8_t>() == 0) return;
    const auto index = u.pod<std::uint64_t>();
    const std::vector<io::ParameterSet> sets = unpack_sets(u);
    const SceneExperiment* e = nullptr;
    for (const auto& x : experiments)
      if (const auto* s = dynamic_cast<const SceneExperiment*>(x.get()); s && s->index == index) e = s;
    if (!e)  // the same job on every rank gives the same experiments
      throw std::runtime_error("the job as read by this rank has no mpm_scene experiment in table " +
                               std::to_string(index + 1) + ": every rank must read the same job file");
    try {
      share(*e, sets);
    } catch (const std::exception&) {  // rank 0 reports it
    }
  }
}

void end_scene_batches() {
  const mpm::Ranks& rk = mpm::ranks();
  if (rk.size() < 2 || rk.rank() != 0) return;
  std::lock_guard<std::mutex> lock(g_request);
  mpm::Packer p;
  p.pod<std::uint8_t>(0);
  std::string done = p.bytes();
  rk.broadcast(done);
}

}  // namespace granflow::calibration
