#include "granflow/calibration/job.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <set>

#include "granflow/calibration/experiment.hpp"
#include "granflow/calibration/parameters.hpp"
#include "granflow/calibration/synthesize.hpp"
#include <granflow/io/input_error.hpp>
#include <granflow/io/output.hpp>
#include <granflow/io/toml_reader.hpp>

namespace granflow::calibration {

namespace fs = std::filesystem;

namespace {

const std::vector<std::string> kGlobal = {"none", "GN_CRS2_LM", "GN_ISRES", "GN_DIRECT_L", "GN_MLSL_LDS", "GN_ESCH"};
const std::vector<std::string> kLocal = {"none", "LN_BOBYQA", "LN_SBPLX", "LN_NELDERMEAD", "LN_COBYLA"};

std::string resolve(const std::string& job_file, const std::string& path) {
  if (fs::path(path).is_absolute()) return path;
  return (fs::path(job_file).parent_path() / path).lexically_normal().string();
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "'" : ", '") + x + "'";
  return s;
}

// Reads a table of string values (data column -> model output) in file order.
std::vector<std::pair<std::string, std::string>> string_map(io::TomlTable& t, const std::vector<std::string>& allowed) {
  std::vector<std::pair<std::string, std::string>> out;
  std::vector<std::pair<std::size_t, std::string>> keys;  // (line, key) to keep the file's order
  for (const auto& [k, node] : t.raw()) keys.emplace_back(node.source().begin.line, std::string(k.str()));
  std::sort(keys.begin(), keys.end());
  for (const auto& [line, k] : keys) {
    const std::string v = t.string(k);
    if (std::find(allowed.begin(), allowed.end(), v) == allowed.end())
      t.fail(k, "model output must be one of " + join(allowed) + ", got '" + v + "'");
    out.emplace_back(k, v);
  }
  t.finish();
  return out;
}

FreeParameter read_free(io::TomlTable& t, const io::ParameterSet& start) {
  FreeParameter p;
  p.key = t.string("key");
  p.experiment = t.string_or("experiment", "");  // a per-test parameter (only test.e0)
  if (t.has("experiment") && p.key != "test.e0") t.fail("key", "a per-test parameter ('experiment') must be 'test.e0'");
  if (!t.has("experiment") && p.key == "test.e0") t.fail("experiment", "'test.e0' needs the name of its experiment");
  if (!p.experiment.empty()) p.key += "@" + p.experiment;
  std::string why;
  if (!parameter_addressable(start, p.key, why)) t.fail("key", why);
  p.lower = t.number("lower");
  p.upper = t.number("upper");
  p.log = t.boolean_or("log", false);
  p.start = t.optional_number("start");
  if (!(p.lower < p.upper)) t.fail("upper", "must exceed lower = " + std::to_string(p.lower));
  if (p.log && !(p.lower > 0)) t.fail("lower", "must be > 0 with log = true");
  if (!p.experiment.empty() && !p.start) {  // from the experiment's test, once it is read (parse_job)
    t.finish();
    return p;
  }
  const double s = p.start ? *p.start : get_parameter(start, p.key);
  if (!(s >= p.lower && s <= p.upper))
    t.fail(p.start ? "start" : "lower", "start value " + std::to_string(s) + (p.start ? "" : " (from the parameter set)") +
                                            " lies outside [lower, upper] = [" + std::to_string(p.lower) + ", " +
                                            std::to_string(p.upper) + "]");
  t.finish();
  return p;
}

struct Parsed {
  DataSelection sel;
  std::string kind, name, model_abscissa;
  SteadyShearSpec ss;
  bool predict = false;  // role = "predict": held out
};

// The part of an [[experiments]] entry shared by both kinds; leaves 'test' unread.
Parsed read_experiment_common(io::TomlTable& t, const std::string& job_file, std::size_t index, bool need_file) {
  Parsed p;
  p.name = t.string_or("name", "experiment" + std::to_string(index + 1));
  p.kind = t.choice("kind", {"steady_shear", "element", "mpm_scene"}, "");
  DataSelection& s = p.sel;
  s.file = resolve(job_file, t.string("data"));
  if (need_file && !fs::exists(s.file)) t.fail("data", "no such file: " + s.file);
  s.abscissa = t.string("abscissa");
  s.quantity = t.choice("quantity", {"time", "strain", "shear_rate", "solid_fraction"}, "");
  if (p.kind == "steady_shear" && s.quantity != "solid_fraction" && s.quantity != "shear_rate")
    t.fail("quantity", "a steady_shear experiment needs quantity = 'solid_fraction' or 'shear_rate'");
  if (p.kind == "element" && s.quantity == "solid_fraction")
    t.fail("quantity", "an element test has no solid-fraction abscissa; use time, strain or shear_rate");
  if (t.has("range")) {
    const auto r = t.numbers("range", io::Bounds::any(), false);
    if (r.size() != 2 || !(r[0] < r[1])) t.fail("range", "expected [low, high] with low < high");
    s.x_lo = r[0];
    s.x_hi = r[1];
  }
  s.average_duplicates = t.choice("duplicates", {"error", "average"}, "error") == "average";
  s.reverses = t.boolean_or("abscissa_reverses", false);
  s.reversal_tolerance = t.number_or("reversal_tolerance", 0.0, io::Bounds::non_negative());
  if (t.has("reversal_tolerance") && !s.reverses) t.fail("reversal_tolerance", "only with abscissa_reverses = true");
  p.predict = t.choice("role", {"fit", "predict"}, "fit") == "predict";
  if (auto f = t.optional_table("filter")) {
    std::vector<std::pair<std::size_t, std::string>> keys;
    for (const auto& [k, node] : f->raw()) keys.emplace_back(node.source().begin.line, std::string(k.str()));
    std::sort(keys.begin(), keys.end());
    for (const auto& [line, k] : keys) s.filter.emplace_back(k, f->number(k));
    f->finish();
  }
  if (t.has("split_by")) s.split_by = t.strings("split_by");
  s.weight = t.number_or("weight", 1.0, io::Bounds::positive());
  const auto& outputs = p.kind == "steady_shear" ? steady_shear_outputs() : element_test_outputs();
  io::TomlTable targets = t.table("targets");
  s.targets = string_map(targets, outputs);
  if (s.targets.empty()) t.fail("targets", "map at least one data column to a model output");
  s.target_weights.assign(s.targets.size(), 1.0);
  if (auto w = t.optional_table("target_weights")) {
    for (const auto& [k, node] : w->raw()) {
      const std::string key(k.str());
      auto it = std::find_if(s.targets.begin(), s.targets.end(), [&](const auto& tg) { return tg.first == key; });
      if (it == s.targets.end()) w->fail(key, "not a target column of this experiment");
      s.target_weights[it - s.targets.begin()] = w->number(key, io::Bounds::positive());
    }
    w->finish();
  }
  s.target_sd.assign(s.targets.size(), std::numeric_limits<double>::quiet_NaN());
  if (auto w = t.optional_table("target_sd")) {  // the ensemble method's likelihood, data units
    for (const auto& [k, node] : w->raw()) {
      const std::string key(k.str());
      auto it = std::find_if(s.targets.begin(), s.targets.end(), [&](const auto& tg) { return tg.first == key; });
      if (it == s.targets.end()) w->fail(key, "not a target column of this experiment");
      s.target_sd[it - s.targets.begin()] = w->number(key, io::Bounds::positive());
    }
    w->finish();
  }
  if (p.kind == "steady_shear") {
    if (auto ss = t.optional_table("steady_shear")) {
      p.ss.dimensionless = ss->choice("units", {"dimensionless", "si"}, "dimensionless") == "dimensionless";
      p.ss.shear_rate = ss->number_or("shear_rate", 1.0, io::Bounds::positive());
      if (s.quantity == "shear_rate")
        p.ss.solid_fraction = ss->number("solid_fraction", io::Bounds::open(0.0, 1.0));
      p.ss.restitution_column = ss->string_or("restitution_column", "");
      p.ss.friction_column = ss->string_or("friction_column", "");
      ss->finish();
    } else if (s.quantity == "shear_rate") {
      t.fail("steady_shear", "a flow curve against shear rate needs [experiments.steady_shear] solid_fraction");
    }
  } else {
    const std::string def = s.quantity == "time" ? "time" : s.quantity == "strain" ? "gamma" : "shear_rate";
    p.model_abscissa = t.string_or("model_abscissa", def);
    s.model_abscissa = p.model_abscissa;
    const auto& o = element_test_outputs();
    if (std::find(o.begin(), o.end(), p.model_abscissa) == o.end())
      t.fail("model_abscissa", "must be one of " + join(o));
  }
  return p;
}

}  // namespace

namespace detail {

// Parses a job; with `synth` set, element experiments write synthetic data instead of reading it.
CalibrationJob parse_job(const std::string& path, const SynthesisOptions* synth) {
  const toml::table doc = io::TomlTable::parse_file(path);
  io::TomlTable root(doc, path);
  CalibrationJob job;
  job.file = path;
  job.name = root.string_or("name", fs::path(path).stem().string());
  const std::string params = root.string("params");
  const std::string local = resolve(path, params);
  try {
    job.start = io::load_parameter_set(fs::exists(local) ? local : params);
  } catch (const io::InputError& e) {
    root.fail("params", e.what());
  }
  job.output_name = root.string_or("output", "fitted");

  for (auto& t : root.array_of_tables("free")) {
    FreeParameter p = read_free(t, job.start);
    for (const auto& q : job.free)
      if (q.key == p.key) t.fail("key", "'" + p.key + "' is freed twice");
    if ((p.key == "collisional.V_sd" || p.key == "collisional.e_sd") &&
        std::any_of(job.free.begin(), job.free.end(),
                    [](const FreeParameter& q) { return q.key == "collisional.V_sd" || q.key == "collisional.e_sd"; }))
      t.fail("key", "free either collisional.V_sd or collisional.e_sd, not both (e_sd = 1/V_sd - 1)");
    job.free.push_back(p);
  }
  if (job.free.empty() && !synth) root.fail("free", "a job needs at least one [[free]] parameter");

  if (auto m = root.optional_table("misfit")) {
    job.misfit.scale = m->choice("scale", {"linear", "log"}, "linear") == "log" ? MisfitScale::Log : MisfitScale::Linear;
    const std::string n = m->choice("normalise", {"rms", "range", "none"}, "rms");
    job.misfit.normalise = n == "rms" ? Normalise::Rms : n == "range" ? Normalise::Range : Normalise::None;
    job.misfit.failure_penalty = m->number_or("failure_penalty", job.misfit.failure_penalty, io::Bounds::positive());
    m->finish();
  }
  if (auto a = root.optional_table("algorithm")) {
    AlgorithmSpec& g = job.algorithm;
    g.method = a->choice("method", {"nlopt", "ensemble"}, g.method);
    g.method_line = a->line(a->has("method") ? "method" : "");
    g.global = a->choice("global", kGlobal, g.global);
    g.local = a->choice("local", kLocal, g.local);
    g.global_evaluations = a->integer_or("global_evaluations", g.global_evaluations, 1, 100000000);
    g.local_evaluations = a->integer_or("local_evaluations", g.local_evaluations, 1, 100000000);
    g.max_time_s = a->number_or("max_time_s", g.max_time_s, io::Bounds::non_negative());
    g.seed = static_cast<unsigned long>(a->integer_or("seed", static_cast<long>(g.seed), 0, 4294967295L));
    g.starts = a->integer_or("starts", g.starts, 1, 1000);
    g.xtol_rel = a->number_or("xtol_rel", g.xtol_rel, io::Bounds::open(0.0, 1.0));
    g.ftol_rel = a->number_or("ftol_rel", g.ftol_rel, io::Bounds::open(0.0, 1.0));
    g.fd_step = a->number_or("fd_step", g.fd_step, io::Bounds::open(0.0, 0.1));
    if (g.method == "nlopt" && g.global == "none" && g.local == "none")
      a->fail("local", "global and local cannot both be 'none'");
    a->finish();
  }
  if (auto e = root.optional_table("ensemble")) {
    EnsembleSpec& s = job.ensemble;
    s.members = e->integer_or("members", s.members, 2, 1000000);
    s.iterations = static_cast<int>(e->integer_or("iterations", s.iterations, 1, 100));
    s.seed = static_cast<unsigned long>(e->integer_or("seed", static_cast<long>(s.seed), 0, 4294967295L));
    s.polish = e->boolean_or("polish", s.polish);
    s.polish_evaluations = e->integer_or("polish_evaluations", s.polish_evaluations, 1, 100000000);
    s.transform = e->choice("transform", {"probit", "logit"}, s.transform);
    e->finish();
  }
  if (auto l = root.optional_table("likelihood")) {
    job.likelihood.relative_sd = l->number_or("relative_sd", job.likelihood.relative_sd, io::Bounds::positive());
    l->finish();
  }

  if (auto cv = root.optional_table("cross_validation")) {
    CrossValidationSpec& c = job.cross_validation;
    c.present = true;
    if (cv->has("windows_lo") != cv->has("windows_hi"))
      cv->fail(cv->has("windows_lo") ? "windows_hi" : "windows_lo", "give both windows_lo and windows_hi");
    if (cv->has("windows_lo")) {
      const auto lo = cv->numbers("windows_lo", io::Bounds::closed(0.0, 1.0), false);
      const auto hi = cv->numbers("windows_hi", io::Bounds::closed(0.0, 1.0), false);
      if (lo.size() != hi.size()) cv->fail("windows_hi", "needs as many values as windows_lo");
      for (std::size_t i = 0; i < lo.size(); ++i) {
        if (!(lo[i] < hi[i])) cv->fail("windows_hi", "each window needs lo < hi");
        c.windows.emplace_back(lo[i], hi[i]);
      }
    } else {
      c.windows = {{0.0, 0.57}};
    }
    c.bands = cv->has("bands") ? cv->numbers("bands", io::Bounds::closed(0.0, 1.0), false)
                               : std::vector<double>{0.0, 0.1, 0.5, 0.57};
    if (c.bands.size() < 2 || !std::is_sorted(c.bands.begin(), c.bands.end()))
      cv->fail("bands", "expected at least two increasing band edges");
    c.leave_one_group = cv->boolean_or("leave_one_group", true);
    c.leave_one_friction = cv->boolean_or("leave_one_friction", true);
    if (auto h = cv->optional_table("friction_held")) {  // "0.5" = ["collisional.V_sd", ...]
      for (const auto& [k, node] : h->raw()) {
        const std::string key(k.str());
        char* end = nullptr;
        const double mu = std::strtod(key.c_str(), &end);
        if (key.empty() || *end != '\0' || !(mu >= 0)) h->fail(key, "expected a friction level such as \"0.5\"");
        c.friction_held.emplace_back(mu, h->strings(key));
      }
      h->finish();
    }
    cv->finish();
  }

  for (const auto& [mu, keys] : job.cross_validation.friction_held)
    for (const auto& k : keys)
      if (std::none_of(job.free.begin(), job.free.end(), [&](const FreeParameter& p) { return p.key == k; }))
        throw io::InputError(io::where(path) + "cross_validation.friction_held: '" + k + "' is not a [[free]] key of the job");

  auto exps = root.array_of_tables("experiments");
  if (exps.empty()) root.fail("experiments", "a job needs at least one [[experiments]] entry");
  std::set<std::string> names;
  std::vector<std::pair<std::string, std::string>> synthetic;  // file, text: written once all are made
  for (std::size_t i = 0; i < exps.size(); ++i) {
    io::TomlTable& t = exps[i];
    const std::string kind_of = t.raw().get("kind") ? t.raw().get("kind")->value_or(std::string()) : "";
    if (kind_of == "mpm_scene") {  // its own table format (scene_experiment.cpp)
      auto e = make_scene_experiment(t, path, i);
      if (!names.insert(e->name).second) t.fail("name", "experiment name '" + e->name + "' is used twice");
      if (!synth) job.experiments.push_back(e);
      t.finish();
      continue;
    }
    const bool synth_this = synth && kind_of == "element";
    Parsed p = read_experiment_common(t, path, i, !synth_this);
    if (!names.insert(p.name).second) t.fail("name", "experiment name '" + p.name + "' is used twice");
    if (p.kind == "element") {
      io::TomlTable test = t.table("test");
      if (synth_this) {
        std::error_code ec;
        if (!synth->force && fs::exists(p.sel.file, ec))
          t.fail("data", p.sel.file + " exists; pass --force to replace it with synthetic data");
        synthetic.emplace_back(p.sel.file, synthesize_element_data(p.sel, test, p.model_abscissa, synth->truth,
                                                                   synth->noise, synth->seed + i, synth->stride));
        t.finish();
        continue;
      }
      for (auto& e : make_element_experiments(p.name, p.sel, test, p.model_abscissa))
        (p.predict ? job.predictions : job.experiments).push_back(e);
    } else {
      if (synth) {
        t.finish();
        continue;
      }
      for (auto& e : make_steady_shear_experiments(p.name, p.sel, p.ss))
        (p.predict ? job.predictions : job.experiments).push_back(e);
      job.steady_shear_sources.push_back({p.name, std::make_shared<const DataSelection>(p.sel),
                                          std::make_shared<const SteadyShearSpec>(p.ss), p.predict});
    }
    t.finish();
  }
  root.finish();
  if (job.experiments.empty() && !synth) root.fail("experiments", "every experiment has role = \"predict\": nothing to fit");
  // Per-test e0: a fitted element experiment; start from its test's e0 unless given.
  for (auto& p : job.free) {
    if (p.experiment.empty() || synth) continue;
    auto named = [&](const auto& list) {
      return std::find_if(list.begin(), list.end(), [&](const auto& e) { return e->base_name == p.experiment; });
    };
    if (named(job.predictions) != job.predictions.end())
      throw io::InputError(io::where(path) + "free 'test.e0' of experiment '" + p.experiment +
                           "': a held-out (role = \"predict\") test takes its e0 from its data, never from a fit");
    const auto it = named(job.experiments);
    if (it == job.experiments.end() || !std::isfinite((*it)->initial_void_ratio()))
      throw io::InputError(io::where(path) + "free 'test.e0': no element experiment named '" + p.experiment + "'");
    const double s = p.start.value_or((*it)->initial_void_ratio());
    if (!(s >= p.lower && s <= p.upper))
      throw io::InputError(io::where(path) + "free 'test.e0' of experiment '" + p.experiment + "': start " +
                           std::to_string(s) + " lies outside [" + std::to_string(p.lower) + ", " +
                           std::to_string(p.upper) + "]");
    p.start = s;
  }
  if (synth) {
    for (const auto& [file, text] : synthetic) io::write_file(file, text);
    return job;
  }

  // Steady shear: the closed forms exist only below V_sd; no data point may reach the lowest V_sd the fit may try.
  double vsd_min = job.start.collisional ? job.start.collisional->V_sd - job.start.collisional->vs_gap : 1.0;
  for (const auto& p : job.free) {
    const double gap = job.start.collisional ? job.start.collisional->vs_gap : 0.0;
    if (p.key == "collisional.V_sd") vsd_min = p.lower - gap;
    if (p.key == "collisional.e_sd") vsd_min = 1.0 / (1.0 + p.upper) - gap;
  }
  // With V_sd(mu_p) the limit depends on each group's friction: points beyond it get the failure
  // penalty instead (the fit moves away from them), so there is no check here.
  const bool vsd_of_friction = job.start.collisional && job.start.collisional->jamming_friction;
  for (const auto& e : job.experiments) {
    if (vsd_of_friction) break;
    if (e->kind != "steady_shear" || e->abscissa_quantity != "solid_fraction") continue;
    if (e->x_max() >= vsd_min)
      throw io::InputError(io::where(path) + "experiment '" + e->name + "' has data up to solid fraction " +
                           std::to_string(e->x_max()) + ", but the fit may take V_sd down to " + std::to_string(vsd_min) +
                           " (less vs_gap) where the closed forms do not exist: restrict its 'range' or raise the " +
                           "lower bound of V_sd (upper bound of e_sd)");
  }
  return job;
}

}  // namespace detail

CalibrationJob load_job(const std::string& path) { return detail::parse_job(path, nullptr); }

void synthesize_job_data(const std::string& job_path, const SynthesisOptions& options) {
  detail::parse_job(job_path, &options);
}

}  // namespace granflow::calibration
