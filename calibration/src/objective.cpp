#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "granflow/calibration/experiment.hpp"
#include "granflow/calibration/fit.hpp"
#include "granflow/calibration/parameters.hpp"
#include <granflow/io/input_error.hpp>

namespace granflow::calibration {

// ---- thread pool ---------------------------------------------------------------------

ThreadPool::ThreadPool(unsigned threads) {
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  for (unsigned i = 1; i < threads; ++i) workers_.emplace_back([this] { work(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lk(m_);
    stop_ = true;
  }
  cv_.notify_all();
  for (auto& w : workers_) w.join();
}

void ThreadPool::work() {
  unsigned long seen = 0;
  for (;;) {
    const std::function<void(std::size_t)>* job;
    std::size_t n;
    {
      std::unique_lock<std::mutex> lk(m_);
      cv_.wait(lk, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      job = job_;
      n = n_;
      ++busy_;
    }
    if (job)  // null: woke after its batch had finished
      for (std::size_t i = next_++; i < n; i = next_++) (*job)(i);
    {
      std::lock_guard<std::mutex> lk(m_);
      --busy_;
    }
    done_cv_.notify_all();
  }
}

void ThreadPool::parallel_for(std::size_t n, const std::function<void(std::size_t)>& f) {
  if (workers_.empty() || n <= 1) {
    for (std::size_t i = 0; i < n; ++i) f(i);
    return;
  }
  {
    std::lock_guard<std::mutex> lk(m_);
    job_ = &f;
    n_ = n;
    next_ = 0;
    ++generation_;
  }
  cv_.notify_all();
  for (std::size_t i = next_++; i < n; i = next_++) f(i);
  std::unique_lock<std::mutex> lk(m_);
  // every index has been taken; wait until the workers that took one are done
  done_cv_.wait(lk, [&] { return busy_ == 0; });
  job_ = nullptr;
}

// ---- objective -----------------------------------------------------------------------

Objective::Objective(const CalibrationJob& job, unsigned threads) : job_(job), pool_(threads) {
  for (std::size_t e = 0; e < job.experiments.size(); ++e)
    for (std::size_t c = 0; c < job.experiments[e]->curves.size(); ++c) {
      const Curve& cv = job.experiments[e]->curves[c];
      curves_.push_back({e, c});
      n_residuals_ += cv.x.size();
      double s = 1.0;
      if (job.misfit.scale == MisfitScale::Log) {
        for (std::size_t i = 0; i < cv.y.size(); ++i)
          if (!(cv.y[i] > 0))
            throw io::InputError(io::where(job.experiments[e]->data_file, cv.lines[i]) + "column '" + cv.data_column +
                                 "': value " + std::to_string(cv.y[i]) + " is not positive; a log misfit (misfit.scale = " +
                                 "\"log\") needs positive data");
      } else if (job.misfit.normalise == Normalise::Rms) {
        double ss = 0;
        for (double y : cv.y) ss += y * y;
        s = std::sqrt(ss / cv.y.size());
      } else if (job.misfit.normalise == Normalise::Range) {
        const auto [lo, hi] = std::minmax_element(cv.y.begin(), cv.y.end());
        s = *hi - *lo;
      }
      if (!(s > 0))
        throw io::InputError(io::where(job.experiments[e]->data_file) + "curve '" + cv.label() +
                             "' has zero " + (job.misfit.normalise == Normalise::Rms ? "RMS" : "range") +
                             ": it cannot be normalised (use misfit.normalise = \"none\")");
      scale_.push_back(s);
    }
}

const Curve& Objective::curve(std::size_t c) const {
  return job_.experiments[curves_[c].experiment]->curves[curves_[c].curve];
}

std::vector<double> Objective::to_unit(const std::vector<double>& theta) const {
  std::vector<double> u(theta.size());
  for (std::size_t j = 0; j < theta.size(); ++j) {
    const FreeParameter& p = job_.free[j];
    u[j] = p.log ? std::log(theta[j] / p.lower) / std::log(p.upper / p.lower) : (theta[j] - p.lower) / (p.upper - p.lower);
    u[j] = std::clamp(u[j], 0.0, 1.0);
  }
  return u;
}

std::vector<double> Objective::from_unit(const std::vector<double>& u) const {
  std::vector<double> theta(u.size());
  for (std::size_t j = 0; j < u.size(); ++j) {
    const FreeParameter& p = job_.free[j];
    const double v = std::clamp(u[j], 0.0, 1.0);
    theta[j] = p.log ? p.lower * std::exp(v * std::log(p.upper / p.lower)) : p.lower + v * (p.upper - p.lower);
    if (v == 1.0) theta[j] = p.upper;  // exact bounds despite rounding
    if (v == 0.0) theta[j] = p.lower;
  }
  return theta;
}

std::vector<double> Objective::start_values() const {
  std::vector<double> t;
  for (const auto& p : job_.free) t.push_back(p.start ? *p.start : get_parameter(job_.start, p.key));
  return t;
}

io::ParameterSet Objective::parameters_at(const std::vector<double>& theta) const {
  io::ParameterSet s = job_.start;
  for (std::size_t j = 0; j < theta.size(); ++j) set_parameter(s, job_.free[j].key, theta[j]);
  return s;
}

Evaluation Objective::evaluate(const std::vector<double>& theta) const {
  const io::ParameterSet set = parameters_at(theta);
  const auto& exps = job_.experiments;
  std::vector<Prediction> pred(exps.size());
  // Each experiment writes only its own slot: the reduction below runs in a fixed order, so the
  // misfit is bitwise the same whatever the number of threads.
  pool_.parallel_for(exps.size(), [&](std::size_t e) {
    try {
      pred[e] = exps[e]->predict(set);
    } catch (const std::exception& ex) {
      pred[e].ok = false;
      pred[e].error = ex.what();
    }
  });
  return assess(pred);
}

std::vector<std::vector<Prediction>> Objective::predict_many(const std::vector<std::vector<double>>& thetas) const {
  const auto& exps = job_.experiments;
  const std::size_t N = thetas.size(), E = exps.size();
  std::vector<io::ParameterSet> sets;
  sets.reserve(N);
  for (const auto& t : thetas) sets.push_back(parameters_at(t));
  std::vector<std::vector<Prediction>> pred(N, std::vector<Prediction>(E));
  std::vector<std::size_t> unbatched;
  for (std::size_t e = 0; e < E; ++e) {
    if (!exps[e]->batched()) {
      unbatched.push_back(e);
      continue;
    }
    std::vector<Prediction> b;
    std::string error;
    try {
      b = exps[e]->predict_batch(sets);
      if (b.size() != N) error = "predicted " + std::to_string(b.size()) + " of " + std::to_string(N) + " sets";
    } catch (const std::exception& ex) {
      error = ex.what();
    }
    for (std::size_t i = 0; i < N; ++i) {
      if (error.empty()) {
        pred[i][e] = std::move(b[i]);
      } else {
        pred[i][e].ok = false;
        pred[i][e].error = error;
      }
    }
  }
  // One task per set x experiment, each writing its own slot.
  const std::size_t U = unbatched.size();
  pool_.parallel_for(N * U, [&](std::size_t k) {
    const std::size_t i = k / U, e = unbatched[k % U];
    try {
      pred[i][e] = exps[e]->predict(sets[i]);
    } catch (const std::exception& ex) {
      pred[i][e].ok = false;
      pred[i][e].error = ex.what();
    }
  });
  return pred;
}

Evaluation Objective::assess(const std::vector<Prediction>& pred) const {
  Evaluation ev;
  ev.residuals.reserve(n_residuals_);
  const bool logm = job_.misfit.scale == MisfitScale::Log;
  const double pen = job_.misfit.failure_penalty;
  for (std::size_t c = 0; c < curves_.size(); ++c) {
    const Curve& cv = curve(c);
    const Prediction& p = pred[curves_[c].experiment];
    CurveEvaluation ce;
    const std::size_t n = cv.x.size();
    const double f = std::sqrt(cv.weight / static_cast<double>(n));
    const std::size_t k = curves_[c].curve;
    if (!p.ok || p.values.size() <= k || p.values[k].size() != n) {
      ce.failure = !p.ok ? p.error : "the experiment returned no values for this curve's " + std::to_string(n) + " points";
      ce.model.assign(n, std::numeric_limits<double>::quiet_NaN());
    } else {
      ce.model = p.values[k];
    }
    double ss_res = 0, ss_tot = 0, mean = 0, used = 0;
    for (double y : cv.y) mean += y;
    mean /= static_cast<double>(n);
    for (std::size_t i = 0; i < n; ++i) {
      const double m = ce.model[i], y = cv.y[i];
      double r;
      if (!std::isfinite(m) || (logm && !(m > 0))) {
        r = pen;
        if (ce.failure.empty())
          ce.failure = "model undefined at some abscissae (e.g. " + cv.abscissa + " = " + std::to_string(cv.x[i]) +
                       (cv.file.empty() || i >= cv.lines.size() ? ""
                                                                : " of " + cv.file + " line " + std::to_string(cv.lines[i])) +
                       ")";
      } else {
        r = logm ? std::log(m) - std::log(y) : (m - y) / scale_[c];
        ss_res += (m - y) * (m - y);
        ss_tot += (y - mean) * (y - mean);
        used += 1;
      }
      r *= f;
      ev.residuals.push_back(r);
      ce.misfit += r * r;
    }
    ce.rmse = used > 0 ? std::sqrt(ss_res / used) : std::numeric_limits<double>::quiet_NaN();
    ce.r2 = ss_tot > 0 ? 1.0 - ss_res / ss_tot : std::numeric_limits<double>::quiet_NaN();
    ev.misfit += ce.misfit;
    ev.curves.push_back(std::move(ce));
  }
  return ev;
}

}  // namespace granflow::calibration
