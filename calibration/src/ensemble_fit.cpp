// granflow calibrate with algorithm.method = "ensemble": the job's curves as the data vector of
// ES-MDA, the members evaluated on the objective's pool (batched experiments once per
// iteration), the best final member polished with BOBYQA and reported like a fit.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "granflow/calibration/fit.hpp"
#include <granflow/io/input_error.hpp>
#include <granflow/io/output.hpp>
#include <granflow/io/sha256.hpp>
#include <granflow/mpm/ranks.hpp>

#include <filesystem>
#include <fstream>
#include "common.hpp"

namespace granflow::calibration {

namespace {

// ---- the saved ES-MDA state (FitOptions::state_file) ------------------------------------
// Format (host byte order): "GFESMDA1", the job's key, the state, then the SHA-256 of what
// precedes it. The key is the SHA-256 of the job file's bytes, the ensemble settings, the prior
// and the data vector with its sd: a state of another job, or of an edited one, is refused.

constexpr const char* kStateMagic = "GFESMDA1";

std::string state_key(const CalibrationJob& job, const EnsembleMethodSpec& spec, const std::vector<PriorBound>& prior,
                      const std::vector<double>& data, const std::vector<double>& sd) {
  mpm::Packer p;
  std::ifstream in(job.file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  p.str(text.str());
  p.pod(spec.members);
  p.pod(spec.iterations);
  p.pod(spec.seed);
  p.pod(spec.truncation);
  p.pod(static_cast<int>(spec.transform));
  for (const PriorBound& b : prior) {
    p.str(b.key);
    p.pod(b.lower);
    p.pod(b.upper);
    p.pod<char>(b.log);
  }
  p.pods(data);
  p.pods(sd);
  return io::sha256_hex(p.bytes());
}

std::string pack_state(const std::string& key, const EsmdaState& st) {
  mpm::Packer p;
  p.str(kStateMagic);
  p.str(key);
  p.pod(st.next);
  p.pod(st.replaced);
  p.pod(st.seconds);
  p.pod<std::uint64_t>(st.z.size());
  for (const auto& z : st.z) p.pods(z);
  p.pod<std::uint64_t>(st.done.size());
  for (const EnsembleIteration& it : st.done) {
    p.pod<std::uint64_t>(it.thetas.size());
    for (const auto& t : it.thetas) p.pods(t);
    p.pod<std::uint64_t>(it.why.size());
    for (const auto& w : it.why) p.str(w);
    p.pods(it.misfit);
    p.pod(it.failed);
    p.pod(it.mean_misfit);
    p.pod(it.best_misfit);
    p.pod(it.seconds);
  }
  mpm::Packer out;
  out.str(p.bytes());
  out.str(io::sha256_hex(p.bytes()));
  return out.bytes();
}

// The state in `file` for `key`; throws InputError naming the file when it is damaged or of
// another job.
EsmdaState unpack_state(const std::string& file, const std::string& bytes, const std::string& key) {
  const std::string again = " (remove it to start the calibration afresh)";
  try {
    mpm::Unpacker outer(bytes);
    const std::string payload = outer.str(), digest = outer.str();
    if (!outer.done() || io::sha256_hex(payload) != digest) throw std::runtime_error("checksum");
    mpm::Unpacker u(payload);
    if (u.str() != kStateMagic) throw std::runtime_error("magic");
    if (u.str() != key)
      throw io::InputError(file + ": the saved ensemble state is of another job, or the job, its data or settings " +
                           "changed since" + again);
    EsmdaState st;
    st.next = u.pod<int>();
    st.replaced = u.pod<long>();
    st.seconds = u.pod<double>();
    st.z.resize(u.pod<std::uint64_t>());
    for (auto& z : st.z) z = u.pods<double>();
    st.done.resize(u.pod<std::uint64_t>());
    for (EnsembleIteration& it : st.done) {
      it.thetas.resize(u.pod<std::uint64_t>());
      for (auto& t : it.thetas) t = u.pods<double>();
      it.why.resize(u.pod<std::uint64_t>());
      for (auto& w : it.why) w = u.str();
      it.misfit = u.pods<double>();
      it.failed = u.pod<long>();
      it.mean_misfit = u.pod<double>();
      it.best_misfit = u.pod<double>();
      it.seconds = u.pod<double>();
    }
    if (!u.done()) throw std::runtime_error("trailing bytes");
    return st;
  } catch (const io::InputError&) {
    throw;
  } catch (const std::exception&) {
    throw io::InputError(file + ": not a readable saved ensemble state (truncated or damaged)" + again);
  }
}

}  // namespace

void likelihood_data(const Objective& obj, std::vector<double>& data, std::vector<double>& sd) {
  const CalibrationJob& job = obj.job();
  const bool logm = job.misfit.scale == MisfitScale::Log;
  data.clear();
  sd.clear();
  for (std::size_t c = 0; c < obj.curves().size(); ++c) {
    const Curve& cv = obj.curve(c);
    double rms = 0;
    for (double y : cv.y) rms += y * y;
    rms = std::sqrt(rms / static_cast<double>(cv.y.size()));
    const bool given = std::isfinite(cv.sd);
    if (!given && !logm && !(rms > 0))
      throw io::InputError(io::where(job.experiments[obj.curves()[c].experiment]->data_file) + "curve '" + cv.label() +
                           "' has zero RMS, so likelihood.relative_sd gives it no standard deviation: set its " +
                           "target_sd (data units) in the job");
    for (double y : cv.y) {
      data.push_back(logm ? std::log(y) : y);  // log data are positive (checked by the objective)
      sd.push_back(given ? (logm ? cv.sd / y : cv.sd) : job.likelihood.relative_sd * (logm ? 1.0 : rms));
    }
  }
}

bool prediction_vector(const Objective& obj, const std::vector<Prediction>& pred, std::vector<double>& out,
                       std::string& why) {
  const bool logm = obj.job().misfit.scale == MisfitScale::Log;
  out.clear();
  out.reserve(obj.residual_count());
  for (std::size_t c = 0; c < obj.curves().size(); ++c) {
    const auto [e, k] = obj.curves()[c];
    const Curve& cv = obj.curve(c);
    const Prediction& p = pred[e];
    if (!p.ok) {
      why = obj.job().experiments[e]->name + ": " + p.error;
      return false;
    }
    if (p.values.size() <= k || p.values[k].size() != cv.x.size()) {
      why = cv.label() + ": the experiment returned no values for its points";
      return false;
    }
    for (std::size_t i = 0; i < cv.x.size(); ++i) {
      const double m = p.values[k][i];
      if (!std::isfinite(m) || (logm && !(m > 0))) {
        why = (cv.file.empty() ? "" : io::where(cv.file, i < cv.lines.size() ? cv.lines[i] : 0)) + cv.label() +
              ": model undefined at " + cv.abscissa + " = " + num(cv.x[i]);
        return false;
      }
      out.push_back(logm ? std::log(m) : m);
    }
  }
  return true;
}

FitResult fit_ensemble(const Objective& obj, const FitOptions& options) {
  const CalibrationJob& job = obj.job();
  const EnsembleSpec& es = job.ensemble;
  const std::size_t n = obj.dimension();
  FitResult res;
  res.threads = obj.threads();
  res.start = obj.start_values();
  res.at_start = obj.evaluate(res.start);
  const auto t0 = std::chrono::steady_clock::now();
  auto rep = std::make_shared<EnsembleReport>();
  likelihood_data(obj, rep->data, rep->sd);

  std::vector<PriorBound> prior;
  for (const auto& p : job.free) prior.push_back({p.key, p.lower, p.upper, p.log});
  EnsembleMethodSpec spec;
  spec.members = es.members;
  spec.iterations = es.iterations;
  spec.seed = es.seed;
  spec.transform = es.transform == "logit" ? UnitTransform::Logit : UnitTransform::Probit;

  std::vector<std::vector<Prediction>> last;  // the latest batch's predictions, per member and experiment
  const BatchForward forward = [&](const std::vector<std::vector<double>>& thetas) {
    last = obj.predict_many(thetas);
    BatchResult b;
    b.predictions.resize(thetas.size());
    b.ok.resize(thetas.size());
    b.why.resize(thetas.size());
    for (std::size_t i = 0; i < thetas.size(); ++i)
      b.ok[i] = prediction_vector(obj, last[i], b.predictions[i], b.why[i]) ? 1 : 0;
    return b;
  };
  const auto progress = [&](int it, const EnsembleResult& r) {
    if (!options.progress) return;
    const EnsembleIteration& x = r.iterations.back();
    std::fprintf(stderr, "calibrate: ensemble %s %d/%d  members %ld  failed %ld  misfit mean %.4e best %.4e  elapsed %6.1f s\n",
                 it == es.iterations ? "posterior" : "iteration", it, es.iterations, es.members, x.failed,
                 x.mean_misfit, x.best_misfit, r.seconds);
    std::fflush(stderr);
  };
  EsmdaState resume;
  std::string key;
  if (!options.state_file.empty()) {
    key = state_key(job, spec, prior, rep->data, rep->sd);
    std::error_code ec;
    if (std::filesystem::exists(options.state_file, ec)) {
      std::ifstream in(options.state_file, std::ios::binary);
      std::ostringstream bytes;
      bytes << in.rdbuf();
      resume = unpack_state(options.state_file, bytes.str(), key);
      spec.resume = &resume;
      std::fprintf(stderr, "calibrate: resuming the ensemble at iteration %d/%d from %s\n", resume.next,
                   es.iterations, options.state_file.c_str());
    }
    spec.save = [&](const EsmdaState& st) { io::write_file(options.state_file, pack_state(key, st)); };
  }
  rep->result = run_ensemble_method(prior, rep->data, rep->sd, forward, spec, progress);
  const EnsembleResult& er = rep->result;

  rep->members.resize(er.posterior.size());
  for (std::size_t i = 0; i < er.posterior.size(); ++i)
    if (er.ok[i]) rep->members[i] = obj.assess(last[i]);
  rep->best = er.posterior[static_cast<std::size_t>(er.best)];
  rep->best_misfit = er.iterations.back().misfit[static_cast<std::size_t>(er.best)];

  // chi-square of one set (the polish's objective: the likelihood the ensemble used)
  const auto chi2 = [&](const std::vector<double>& theta) {
    const auto p = obj.predict_many({theta});
    std::vector<double> g;
    std::string why;
    if (!prediction_vector(obj, p[0], g, why)) return std::numeric_limits<double>::infinity();
    double s = 0;
    for (std::size_t k = 0; k < g.size(); ++k) s += std::pow((g[k] - rep->data[k]) / rep->sd[k], 2);
    return s;
  };
  std::vector<double> u = obj.to_unit(rep->best);
  double fu = rep->best_misfit;
  if (!es.polish) {
    rep->polish = "skipped: ensemble.polish = false";
  } else {
    // initial step: a quarter of the 5-95 % width of each parameter in the unit cube, within [1e-3, 0.1]
    std::vector<double> step(n);
    for (std::size_t j = 0; j < n; ++j) {
      std::vector<double> a = rep->best, b = rep->best;
      a[j] = er.summary[j].q05;
      b[j] = er.summary[j].q95;
      step[j] = std::clamp(0.25 * (obj.to_unit(b)[j] - obj.to_unit(a)[j]), 1e-3, 0.1);
    }
    long before = 0;
    const std::function<double(const std::vector<double>&)> f = [&](const std::vector<double>& x) {
      ++before;
      return chi2(obj.from_unit(x));
    };
    detail::polish_bobyqa(f, u, fu, es.polish_evaluations, step, job.algorithm.xtol_rel, rep->polish);
    rep->polish_evaluations = before;
  }
  rep->fitted_misfit = fu;

  res.theta = obj.from_unit(u);
  if (fu == rep->best_misfit) res.theta = rep->best;  // exactly the member when the polish found nothing better
  res.at_best = obj.evaluate(res.theta);
  res.evaluations = static_cast<long>(er.iterations.size()) * es.members + rep->polish_evaluations;
  res.global_evaluations = static_cast<long>(er.iterations.size()) * es.members;
  res.local_evaluations = rep->polish_evaluations;
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();  // with the polish
  const std::vector<double> ub = obj.to_unit(res.theta);
  for (std::size_t j = 0; j < n; ++j) res.on_bound.push_back(ub[j] <= 1e-3 ? -1 : ub[j] >= 1.0 - 1e-3 ? 1 : 0);
  const bool batched = std::any_of(job.experiments.begin(), job.experiments.end(),
                                   [](const auto& e) { return e->batched(); });
  if (batched) {  // a Jacobian would cost 2n scene runs: leave it out
    Identifiability& id = res.identifiability;
    id.sensitivity = Eigen::MatrixXd::Constant(static_cast<Eigen::Index>(obj.curves().size()), static_cast<Eigen::Index>(n), kNaN);
    id.correlation = Eigen::MatrixXd::Constant(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n), kNaN);
    id.rel_sd.assign(n, kNaN);
    id.undefined.assign(n, "not computed: the job has batched (MPM scene) experiments; see the ensemble's posterior");
    id.sd_range.assign(n, kNaN);
    id.condition = kNaN;
    id.status.assign(n, "not computed");
  } else {
    res.identifiability = identifiability(obj, res.theta, job.algorithm.fd_step);
  }
  res.fitted = obj.parameters_at(res.theta);
  res.stop_reason = "ensemble: " + std::to_string(es.members) + " members, " + std::to_string(es.iterations) +
                    " iterations; polish " + rep->polish;
  res.ensemble = rep;
  return res;
}

}  // namespace granflow::calibration
