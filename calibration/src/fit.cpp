#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <random>

#include <unistd.h>

#ifdef GRANFLOW_HAVE_NLOPT
#include <nlopt.hpp>
#endif

#include "granflow/calibration/fit.hpp"
#include <granflow/io/input_error.hpp>

namespace granflow::calibration {

namespace {

using Clock = std::chrono::steady_clock;

#ifdef GRANFLOW_HAVE_NLOPT
nlopt::algorithm algorithm_of(const std::string& name) {
  static const std::map<std::string, nlopt::algorithm> m = {
      {"GN_CRS2_LM", nlopt::GN_CRS2_LM}, {"GN_ISRES", nlopt::GN_ISRES},     {"GN_DIRECT_L", nlopt::GN_DIRECT_L},
      {"GN_MLSL_LDS", nlopt::GN_MLSL_LDS}, {"GN_ESCH", nlopt::GN_ESCH},     {"LN_BOBYQA", nlopt::LN_BOBYQA},
      {"LN_SBPLX", nlopt::LN_SBPLX},     {"LN_NELDERMEAD", nlopt::LN_NELDERMEAD}, {"LN_COBYLA", nlopt::LN_COBYLA}};
  return m.at(name);
}

#endif

// Counts evaluations, keeps the best point, prints the progress line.
struct Tracker {
  const Objective& obj;
  bool progress;
  Clock::time_point t0 = Clock::now(), last_print = Clock::now();
  long evaluations = 0;
  double best = std::numeric_limits<double>::infinity();
  std::vector<double> best_u;
  std::string phase;
  bool tty = isatty(STDERR_FILENO) != 0;

  double operator()(const std::vector<double>& u) {
    const double f = obj.misfit(obj.from_unit(u));
    ++evaluations;
    const double v = std::isfinite(f) ? f : 1e300;
    if (v < best) {
      best = v;
      best_u = u;
    }
    print(false);
    return v;
  }
  double elapsed() const { return std::chrono::duration<double>(Clock::now() - t0).count(); }
  void print(bool final_line) {
    if (!progress) return;
    const auto now = Clock::now();
    const double since = std::chrono::duration<double>(now - last_print).count();
    if (!final_line && since < (tty ? 0.2 : 2.0)) return;
    last_print = now;
    std::fprintf(stderr, "%scalibrate: %-6s evaluations %6ld  best misfit %.6e  elapsed %6.1f s%s", tty ? "\r" : "",
                 phase.c_str(), evaluations, best, elapsed(), (tty && !final_line) ? "" : "\n");
    std::fflush(stderr);
  }
};

#ifdef GRANFLOW_HAVE_NLOPT
double nlopt_callback(unsigned, const double* x, double*, void* data) {
  auto* t = static_cast<Tracker*>(data);
  return (*t)(std::vector<double>(x, x + t->obj.dimension()));
}

// Runs one NLopt optimisation from u0 within the remaining time; returns its stop reason.
std::string run(nlopt::opt& opt, Tracker& tr, std::vector<double> u0, double deadline_s) {
  const std::size_t n = u0.size();
  opt.set_lower_bounds(std::vector<double>(n, 0.0));
  opt.set_upper_bounds(std::vector<double>(n, 1.0));
  opt.set_min_objective(nlopt_callback, &tr);
  if (deadline_s > 0) opt.set_maxtime(std::max(1e-3, deadline_s - tr.elapsed()));
  double f = 0;
  try {
    const nlopt::result r = opt.optimize(u0, f);
    switch (r) {
      case nlopt::MAXEVAL_REACHED: return "evaluation budget";
      case nlopt::MAXTIME_REACHED: return "time budget";
      case nlopt::XTOL_REACHED: return "xtol";
      case nlopt::FTOL_REACHED: return "ftol";
      case nlopt::STOPVAL_REACHED: return "stopval";
      default: return "converged";
    }
  } catch (const nlopt::roundoff_limited&) {
    return "roundoff limited";
  } catch (const nlopt::forced_stop&) {
    return "forced stop";
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("NLopt rejected the problem: ") + e.what());
  }
}

double function_callback(unsigned n, const double* x, double*, void* data) {
  const auto* f = static_cast<const std::function<double(const std::vector<double>&)>*>(data);
  const double v = (*f)(std::vector<double>(x, x + n));
  return std::isfinite(v) ? v : 1e300;
}
#endif

}  // namespace

namespace detail {

bool polish_bobyqa(const std::function<double(const std::vector<double>&)>& f, std::vector<double>& u, double& fu,
                   long max_evaluations, const std::vector<double>& step, double xtol_rel, std::string& note) {
#ifdef GRANFLOW_HAVE_NLOPT
  const std::size_t n = u.size();
  long evaluations = 0;
  std::vector<double> best = u;
  double fbest = fu;
  const std::function<double(const std::vector<double>&)> counted = [&](const std::vector<double>& x) {
    const double v = f(x);
    ++evaluations;
    if (std::isfinite(v) && v < fbest) {
      fbest = v;
      best = x;
    }
    return v;
  };
  nlopt::opt l(nlopt::LN_BOBYQA, static_cast<unsigned>(n));
  l.set_lower_bounds(std::vector<double>(n, 0.0));
  l.set_upper_bounds(std::vector<double>(n, 1.0));
  l.set_min_objective(function_callback, const_cast<std::function<double(const std::vector<double>&)>*>(&counted));
  l.set_maxeval(static_cast<int>(max_evaluations));
  l.set_xtol_rel(xtol_rel);
  l.set_initial_step(step);
  std::string reason = "converged";
  std::vector<double> x = u;
  double fx = 0;
  try {
    const nlopt::result r = l.optimize(x, fx);
    if (r == nlopt::MAXEVAL_REACHED) reason = "evaluation budget";
  } catch (const nlopt::roundoff_limited&) {
    reason = "roundoff limited";
  } catch (const std::invalid_argument& e) {
    reason = std::string("NLopt rejected the problem: ") + e.what();
  }
  note = "LN_BOBYQA from the best member, " + std::to_string(evaluations) + " evaluations (" + reason + ")";
  u = best;
  fu = fbest;
  return true;
#else
  (void)f, (void)u, (void)fu, (void)max_evaluations, (void)step, (void)xtol_rel;
  note = "skipped: this build has no NLopt";
  return false;
#endif
}

}  // namespace detail

FitResult fit(const Objective& obj, const FitOptions& options) {
  const CalibrationJob& job = obj.job();
  const AlgorithmSpec& a = job.algorithm;
  if (!options.evaluate_only && a.method == "ensemble") return fit_ensemble(obj, options);
#ifndef GRANFLOW_HAVE_NLOPT
  if (!options.evaluate_only)
    throw io::InputError(io::where(job.file, a.method_line) +
                         "this build has no NLopt: use [algorithm] method = \"ensemble\"");
#endif
  const std::size_t n = obj.dimension();
  FitResult res;
  res.threads = obj.threads();
  res.start = obj.start_values();
  res.at_start = obj.evaluate(res.start);

  Tracker tr{obj, options.progress};
  const std::vector<double> u_start = obj.to_unit(res.start);
  tr.best = res.at_start.misfit;
  tr.best_u = u_start;
  std::string reason;

  if (options.evaluate_only) {
    reason = "evaluation only (--evaluate)";
  }
#ifdef GRANFLOW_HAVE_NLOPT
  else if (a.global != "none") {
    nlopt::srand(a.seed);  // the stochastic global methods draw from NLopt's generator
    nlopt::opt g(algorithm_of(a.global), static_cast<unsigned>(n));
    g.set_maxeval(static_cast<int>(a.global_evaluations));
    g.set_xtol_rel(a.xtol_rel);
    g.set_ftol_rel(a.ftol_rel);
    if (a.global == "GN_MLSL_LDS") {
      nlopt::opt l(algorithm_of(a.local == "none" ? "LN_BOBYQA" : a.local), static_cast<unsigned>(n));
      l.set_xtol_rel(1e-4);
      l.set_maxeval(static_cast<int>(std::max<long>(20, a.global_evaluations / 10)));
      g.set_local_optimizer(l);
    }
    tr.phase = "global";
    reason = "global: " + run(g, tr, u_start, a.max_time_s);
    res.global_evaluations = tr.evaluations;
  }
  if (a.local != "none" && !options.evaluate_only) {
    std::mt19937_64 rng(a.seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    tr.phase = "local";
    for (long s = 0; s < a.starts; ++s) {
      if (a.max_time_s > 0 && tr.elapsed() >= a.max_time_s) break;
      std::vector<double> u0 = tr.best_u;
      if (s > 0)
        for (auto& v : u0) v = uni(rng);
      nlopt::opt l(algorithm_of(a.local), static_cast<unsigned>(n));
      l.set_maxeval(static_cast<int>(a.local_evaluations));
      l.set_xtol_rel(a.xtol_rel);
      l.set_ftol_rel(a.ftol_rel);
      l.set_initial_step(std::vector<double>(n, s == 0 && a.global != "none" ? 0.02 : 0.1));
      reason += std::string(reason.empty() ? "" : "; ") + "local " + std::to_string(s + 1) + ": " +
                run(l, tr, u0, a.max_time_s);
    }
    res.local_evaluations = tr.evaluations - res.global_evaluations;
  }
#endif
  tr.phase = "done";
  tr.print(true);
  res.evaluations = tr.evaluations;
  res.seconds = tr.elapsed();
  res.stop_reason = reason;
  res.theta = obj.from_unit(tr.best_u);
  res.at_best = obj.evaluate(res.theta);
  for (std::size_t j = 0; j < n; ++j)
    res.on_bound.push_back(tr.best_u[j] <= 1e-3 ? -1 : tr.best_u[j] >= 1.0 - 1e-3 ? 1 : 0);
  res.identifiability = identifiability(obj, res.theta, a.fd_step);
  res.fitted = obj.parameters_at(res.theta);
  return res;
}

Identifiability identifiability(const Objective& obj, const std::vector<double>& theta, double step) {
  const CalibrationJob& job = obj.job();
  const std::size_t n = obj.dimension(), N = obj.residual_count(), nc = obj.curves().size();
  Identifiability id;
  const std::vector<double> u = obj.to_unit(theta);
  Eigen::MatrixXd S(N, n);  // d residual / d ln(theta)
  Eigen::MatrixXd Ju(N, n);  // d residual / d u (the unit cube of the search)
  for (std::size_t j = 0; j < n; ++j) {
    const FreeParameter& p = job.free[j];
    std::vector<double> up = u, um = u;
    up[j] = std::min(1.0, u[j] + step);
    um[j] = std::max(0.0, u[j] - step);
    const Evaluation ep = obj.evaluate(obj.from_unit(up)), em = obj.evaluate(obj.from_unit(um));
    id.evaluations += 2;
    const double du_dlnt = p.log ? 1.0 / std::log(p.upper / p.lower) : theta[j] / (p.upper - p.lower);
    for (std::size_t i = 0; i < N; ++i) {
      Ju(i, j) = (ep.residuals[i] - em.residuals[i]) / (up[j] - um[j]);
      S(i, j) = Ju(i, j) * du_dlnt;
    }
  }
  id.sensitivity = Eigen::MatrixXd::Zero(nc, n);
  std::size_t row = 0;
  for (std::size_t c = 0; c < nc; ++c) {
    const std::size_t m = obj.curve(c).x.size();
    // residuals carry sqrt(w/m): undo it so the figure is the RMS change of the normalised curve
    const double f = std::sqrt(static_cast<double>(m) / obj.curve(c).weight);
    for (std::size_t j = 0; j < n; ++j) id.sensitivity(c, j) = S.block(row, j, m, 1).norm() * f / std::sqrt(double(m));
    row += m;
  }
  const Eigen::MatrixXd A = S.transpose() * S;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(A);
  const double lmax = es.eigenvalues().cwiseAbs().maxCoeff();
  Eigen::VectorXd inv = Eigen::VectorXd::Zero(n);
  std::vector<bool> in_null(n, false);  // a direction that changes no curve moves this parameter
  for (std::size_t k = 0; k < n; ++k) {
    const double l = es.eigenvalues()(k);
    if (l > 1e-12 * lmax && l > 0) {
      inv(k) = 1.0 / l;
      continue;
    }
    id.singular = true;
    for (std::size_t j = 0; j < n; ++j)
      if (std::fabs(es.eigenvectors()(j, k)) > 1e-6) in_null[j] = true;
  }
  const Eigen::MatrixXd C = es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose();
  const Evaluation e0 = obj.evaluate(theta);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double s2 = N > n ? e0.misfit / static_cast<double>(N - n) : nan;
  std::vector<bool> covaries(n);  // the correlations of j are defined (rel_sd also needs s2)
  for (std::size_t j = 0; j < n; ++j) {
    std::string why;
    if (S.col(j).cwiseAbs().maxCoeff() == 0.0)
      why = "no curve changes with it at these parameter values (zero sensitivity; e.g. a packing fraction beyond "
            "the data's range)";
    else if (in_null[j])
      why = "the Jacobian is rank-deficient: it trades off with other free parameters without changing any curve";
    else if (!(C(j, j) > 0))
      why = "its variance from the Jacobian is not positive";
    covaries[j] = why.empty();
    if (why.empty() && N <= n) why = "as many free parameters as data points: no residual to estimate a spread from";
    id.undefined.push_back(why);
    id.rel_sd.push_back(why.empty() ? std::sqrt(s2 * C(j, j)) : nan);
  }
  id.correlation = Eigen::MatrixXd::Constant(n, n, nan);
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t k = 0; k < n; ++k)
      if (covaries[j] && covaries[k]) id.correlation(j, k) = C(j, k) / std::sqrt(C(j, j) * C(k, k));
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t k = j + 1; k < n; ++k)
      if (std::isfinite(id.correlation(j, k)) && std::fabs(id.correlation(j, k)) > 0.95) id.correlated.emplace_back(j, k);
  const UnitSpread spread = gauss_newton_spread(Ju, e0.misfit);
  id.sd_range = spread.sd;
  id.condition = spread.condition;
  for (std::size_t j = 0; j < n; ++j) {
    bool paired = false;
    for (const auto& [a, b] : id.correlated) paired = paired || a == j || b == j;
    const double sd = id.sd_range[j];
    id.status.push_back(!id.undefined[j].empty() || !std::isfinite(sd) ? "not identified"
                        : sd > kPoorlyIdentified                       ? "poorly identified"
                        : paired                                       ? "correlated"
                                                                       : "identified");
  }
  return id;
}

UnitSpread gauss_newton_spread(const Eigen::MatrixXd& J, double misfit) {
  const Eigen::Index N = J.rows(), n = J.cols();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  UnitSpread out;
  out.sd.assign(static_cast<std::size_t>(n), nan);
  if (n == 0) return out;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(J.transpose() * J);
  const Eigen::VectorXd l = es.eigenvalues();  // ascending
  const double lmax = l.cwiseAbs().maxCoeff();
  out.condition = l(0) > 1e-12 * lmax && l(0) > 0 ? lmax / l(0) : std::numeric_limits<double>::infinity();
  if (N <= n || !(lmax > 0)) return out;
  const double s2 = misfit / static_cast<double>(N - n);
  for (Eigen::Index j = 0; j < n; ++j) {
    double var = 0;
    bool defined = true;
    for (Eigen::Index k = 0; k < n; ++k) {
      const double v = es.eigenvectors()(j, k);
      if (l(k) > 1e-12 * lmax && l(k) > 0)
        var += v * v / l(k);
      else if (std::fabs(v) > 1e-6)
        defined = false;  // a direction the residuals do not see moves this parameter
    }
    if (defined) out.sd[static_cast<std::size_t>(j)] = std::sqrt(s2 * var);
  }
  return out;
}

}  // namespace granflow::calibration
