// ES-MDA (Emerick & Reynolds 2013): the prior sample, the iterations and the posterior summary.
// Eigen only; every random number comes from std::mt19937_64 through integer or 53-bit
// conversions written here, so a seed gives the same ensemble with every standard library.
#include "granflow/calibration/ensemble_method.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Dense>
#include "common.hpp"

namespace granflow::calibration {

namespace {

using Clock = std::chrono::steady_clock;

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Seed of an independent stream: 0 the prior sample, 1 perturbations, 2 replacements (per iteration).
std::uint64_t stream_seed(std::uint64_t seed, std::uint64_t stream, std::uint64_t iteration) {
  return splitmix64(splitmix64(seed) ^ splitmix64((stream << 32) + iteration + 1));
}

// Uniform integer in [0, n) without modulo bias (rejection below 2^64 mod n).
std::uint64_t bounded(std::mt19937_64& rng, std::uint64_t n) {
  const std::uint64_t threshold = (0 - n) % n;
  for (;;) {
    const std::uint64_t r = rng();
    if (r >= threshold) return r % n;
  }
}

// In (0, 1): the top 53 bits, offset by half a unit.
double unit_open(std::mt19937_64& rng) { return (static_cast<double>(rng() >> 11) + 0.5) * 0x1.0p-53; }

double quantile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return kNaN;
  const double pos = p * static_cast<double>(sorted.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (pos - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

// The iterations on z; members are passed to `forward` and recorded as to_theta(z).
EnsembleResult esmda_core(std::vector<std::vector<double>> z, const std::vector<double>& data,
                          const std::vector<double>& sd, const BatchForward& forward, const EnsembleMethodSpec& spec,
                          const std::function<std::vector<double>(const std::vector<double>&)>& to_theta,
                          const std::function<void(int, const EnsembleResult&)>& progress) {
  const std::size_t N = z.size(), m = data.size();
  if (N < 2) throw std::invalid_argument("ensemble method: at least 2 members are needed");
  if (spec.iterations < 1) throw std::invalid_argument("ensemble method: at least 1 iteration is needed");
  if (sd.size() != m) throw std::invalid_argument("ensemble method: data and sd differ in length");
  if (m == 0) throw std::invalid_argument("ensemble method: no data");
  for (std::size_t k = 0; k < m; ++k)
    if (!std::isfinite(data[k]) || !(sd[k] > 0) || !std::isfinite(sd[k]))
      throw std::invalid_argument("ensemble method: datum " + std::to_string(k) + " has a non-finite value or sd <= 0");
  const std::size_t n = z.front().size();
  for (const auto& zi : z)
    if (zi.size() != n) throw std::invalid_argument("ensemble method: members differ in dimension");

  const Clock::time_point t0 = Clock::now();
  const double alpha = static_cast<double>(spec.iterations);  // sum of 1/alpha over the iterations = 1
  Eigen::Map<const Eigen::VectorXd> d(data.data(), static_cast<Eigen::Index>(m));
  Eigen::Map<const Eigen::VectorXd> s(sd.data(), static_cast<Eigen::Index>(m));
  const Eigen::VectorXd ds = d.cwiseQuotient(s);  // data in units of its sd
  EnsembleResult res;
  int first = 0;
  double before = 0;  // seconds of the iterations a resumed run did not repeat
  if (const EsmdaState* st = spec.resume) {
    if (st->next < 1 || st->next > spec.iterations || st->z.size() != N || st->done.size() != static_cast<std::size_t>(st->next))
      throw std::invalid_argument("ensemble method: the saved state (iteration " + std::to_string(st->next) + ", " +
                                  std::to_string(st->z.size()) + " members) does not fit " +
                                  std::to_string(spec.iterations) + " iterations of " + std::to_string(N) + " members");
    for (const auto& zi : st->z)
      if (zi.size() != n) throw std::invalid_argument("ensemble method: the saved state's members differ in dimension");
    z = st->z;
    res.iterations = st->done;
    res.replaced = st->replaced;
    first = st->next;
    before = st->seconds;
  }

  for (int it = first; it <= spec.iterations; ++it) {
    EnsembleIteration rec;
    std::vector<std::vector<double>> thetas(N);
    for (std::size_t i = 0; i < N; ++i) thetas[i] = to_theta(z[i]);
    const Clock::time_point tb = Clock::now();
    BatchResult b = forward(thetas);
    rec.seconds = std::chrono::duration<double>(Clock::now() - tb).count();
    if (b.predictions.size() != N || b.ok.size() != N)
      throw std::logic_error("ensemble method: the batch returned " + std::to_string(b.predictions.size()) +
                             " predictions for " + std::to_string(N) + " members");
    b.why.resize(N);
    rec.thetas = std::move(thetas);
    rec.misfit.assign(N, kNaN);
    rec.why.assign(N, "");
    std::vector<std::size_t> good;
    double sum = 0, best = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < N; ++i) {
      if (b.ok[i] && b.predictions[i].size() != m) {
        b.ok[i] = 0;
        b.why[i] = "returned " + std::to_string(b.predictions[i].size()) + " values for " + std::to_string(m) + " data";
      }
      double chi2 = 0;
      for (std::size_t k = 0; b.ok[i] && k < m; ++k) {
        const double r = (b.predictions[i][k] - data[k]) / sd[k];
        if (!std::isfinite(r)) {
          b.ok[i] = 0;
          b.why[i] = "non-finite prediction of datum " + std::to_string(k);
        }
        chi2 += r * r;
      }
      if (!b.ok[i]) {
        ++rec.failed;
        rec.why[i] = b.why[i].empty() ? "failed" : b.why[i];
        continue;
      }
      rec.misfit[i] = chi2;
      good.push_back(i);
      sum += chi2;
      best = std::min(best, chi2);
    }
    rec.mean_misfit = good.empty() ? kNaN : sum / static_cast<double>(good.size());
    rec.best_misfit = good.empty() ? kNaN : best;
    res.iterations.push_back(rec);
    res.seconds = before + std::chrono::duration<double>(Clock::now() - t0).count();

    const bool last = it == spec.iterations;
    if (good.size() < (last ? 1u : 2u)) {
      std::string first;
      for (const auto& w : rec.why)
        if (!w.empty()) {
          first = w;
          break;
        }
      throw std::runtime_error("ensemble method: " + std::string(it == 0 ? "prior" : last ? "posterior" : "iteration " +
                               std::to_string(it)) + " batch: " + std::to_string(good.size()) + " of " +
                               std::to_string(N) + " members could be computed" +
                               (first.empty() ? "" : " (e.g. " + first + ")"));
    }
    if (last) {
      res.posterior = res.iterations.back().thetas;
      res.predictions = std::move(b.predictions);
      res.ok = b.ok;
      for (std::size_t i : good)
        if (res.best < 0 || rec.misfit[i] < rec.misfit[static_cast<std::size_t>(res.best)]) res.best = static_cast<long>(i);
      summarise_members(res.posterior, res.ok, res.summary, res.correlation);
      if (progress) progress(it, res);
      break;
    }
    if (progress) progress(it, res);

    // Anomalies of the computed members, predictions scaled by sd.
    const std::size_t K = good.size();
    Eigen::MatrixXd Z(n, K), G(m, K);
    for (std::size_t c = 0; c < K; ++c) {
      const std::size_t i = good[c];
      for (std::size_t j = 0; j < n; ++j) Z(j, c) = z[i][j];
      for (std::size_t k = 0; k < m; ++k) G(k, c) = b.predictions[i][k] / sd[k];
    }
    const double norm = 1.0 / std::sqrt(static_cast<double>(K - 1));
    const Eigen::MatrixXd dZ = (Z.colwise() - Z.rowwise().mean()) * norm;
    const Eigen::MatrixXd dG = (G.colwise() - G.rowwise().mean()) * norm;
    // C_zd (C_dd + alpha C_D)^-1 = dZ dG^T (dG dG^T + alpha I)^-1 S^-1 = dZ V Sigma (Sigma^2 + alpha)^-1 U^T S^-1,
    // with dG = U Sigma V^T truncated to the leading singular values holding `truncation` of sum sigma^2.
    Eigen::BDCSVD<Eigen::MatrixXd> svd(dG, Eigen::ComputeThinU | Eigen::ComputeThinV);
    const Eigen::VectorXd sv = svd.singularValues();
    const double total = sv.squaredNorm();
    Eigen::Index r = 0;
    for (double acc = 0; r < sv.size() && total > 0 && acc < spec.truncation * total; ++r) acc += sv(r) * sv(r);
    Eigen::MatrixXd gain = Eigen::MatrixXd::Zero(n, m);  // acts on innovations in units of sd
    if (r > 0) {
      Eigen::VectorXd f(r);
      for (Eigen::Index k = 0; k < r; ++k) f(k) = sv(k) / (sv(k) * sv(k) + alpha);
      gain = dZ * svd.matrixV().leftCols(r) * f.asDiagonal() * svd.matrixU().leftCols(r).transpose();
    }

    // Failed members become copies of computed ones before the update.
    std::mt19937_64 pick(stream_seed(spec.seed, 2, static_cast<std::uint64_t>(it)));
    std::vector<std::size_t> source(N);
    for (std::size_t i = 0; i < N; ++i) {
      source[i] = i;
      if (!b.ok[i]) {
        source[i] = good[bounded(pick, K)];
        ++res.replaced;
      }
    }
    NormalStream noise(stream_seed(spec.seed, 1, static_cast<std::uint64_t>(it)));
    const double sa = std::sqrt(alpha);
    std::vector<std::vector<double>> next(N);
    Eigen::VectorXd innov(m);
    for (std::size_t i = 0; i < N; ++i) {
      const std::size_t src = source[i];
      for (std::size_t k = 0; k < m; ++k) innov(k) = ds(k) + sa * noise() - b.predictions[src][k] / sd[k];
      const Eigen::VectorXd dz = gain * innov;
      next[i] = z[src];
      for (std::size_t j = 0; j < n; ++j) next[i][j] += dz(j);
    }
    z = std::move(next);
    if (spec.save)
      spec.save(EsmdaState{it + 1, z, res.iterations, res.replaced,
                           before + std::chrono::duration<double>(Clock::now() - t0).count()});
  }
  res.seconds = before + std::chrono::duration<double>(Clock::now() - t0).count();
  return res;
}

// Inverse of the standard normal CDF on (0, 1): Acklam's rational approximation (relative error
// 1.2e-9) refined by one Halley step on erfc, to about 1e-15.
double normal_quantile(double p) {
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                             1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  double x;
  if (p < 0.02425) {
    const double q = std::sqrt(-2 * std::log(p));
    x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  } else if (p > 1 - 0.02425) {
    const double q = std::sqrt(-2 * std::log(1 - p));
    x = -(((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  } else {
    const double q = p - 0.5, r = q * q;
    x = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
        (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
  }
  const double e = 0.5 * std::erfc(-x / std::sqrt(2.0)) - p;
  const double u = e * std::sqrt(2 * 3.14159265358979323846) * std::exp(x * x / 2);
  return x - u / (1 + x * u / 2);
}

}  // namespace

double NormalStream::uniform() { return unit_open(rng_); }

double NormalStream::operator()() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  const double u1 = unit_open(rng_), u2 = unit_open(rng_);
  const double rad = std::sqrt(-2.0 * std::log(u1)), ang = 2.0 * 3.14159265358979323846 * u2;
  spare_ = rad * std::sin(ang);
  has_spare_ = true;
  return rad * std::cos(ang);
}

std::vector<std::vector<double>> latin_hypercube_unit(long members, std::size_t dims, std::uint64_t seed) {
  if (members < 1) throw std::invalid_argument("latin hypercube: members must be positive");
  const std::size_t N = static_cast<std::size_t>(members);
  std::mt19937_64 rng(stream_seed(seed, 0, 0));
  std::vector<std::vector<double>> u(N, std::vector<double>(dims));
  std::vector<std::size_t> perm(N);
  for (std::size_t j = 0; j < dims; ++j) {
    for (std::size_t i = 0; i < N; ++i) perm[i] = i;
    for (std::size_t i = N; i > 1; --i) std::swap(perm[i - 1], perm[bounded(rng, i)]);  // Fisher-Yates
    for (std::size_t i = 0; i < N; ++i) u[i][j] = (static_cast<double>(perm[i]) + unit_open(rng)) / static_cast<double>(N);
  }
  return u;
}

void summarise_members(const std::vector<std::vector<double>>& members, const std::vector<char>& ok,
                       std::vector<ParameterSummary>& summary, std::vector<std::vector<double>>& correlation) {
  std::vector<std::size_t> use;
  for (std::size_t i = 0; i < members.size(); ++i)
    if (ok.empty() || ok[i]) use.push_back(i);
  const std::size_t n = members.empty() ? 0 : members.front().size(), K = use.size();
  summary.assign(n, ParameterSummary{});
  correlation.assign(n, std::vector<double>(n, kNaN));
  std::vector<std::vector<double>> centred(n, std::vector<double>(K));
  for (std::size_t j = 0; j < n; ++j) {
    ParameterSummary& p = summary[j];
    std::vector<double> v(K);
    for (std::size_t c = 0; c < K; ++c) v[c] = members[use[c]][j];
    double mean = 0;
    for (double x : v) mean += x;
    mean = K ? mean / static_cast<double>(K) : kNaN;
    double ss = 0;
    for (std::size_t c = 0; c < K; ++c) {
      centred[j][c] = v[c] - mean;
      ss += centred[j][c] * centred[j][c];
    }
    std::sort(v.begin(), v.end());
    p.mean = mean;
    p.median = quantile(v, 0.5);
    p.q05 = quantile(v, 0.05);
    p.q95 = quantile(v, 0.95);
    p.sd = K > 1 ? std::sqrt(ss / static_cast<double>(K - 1)) : kNaN;
  }
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t k = 0; k < n; ++k) {
      double sjk = 0, sjj = 0, skk = 0;
      for (std::size_t c = 0; c < K; ++c) {
        sjk += centred[j][c] * centred[k][c];
        sjj += centred[j][c] * centred[j][c];
        skk += centred[k][c] * centred[k][c];
      }
      if (K > 1 && sjj > 0 && skk > 0) correlation[j][k] = j == k ? 1.0 : sjk / std::sqrt(sjj * skk);
    }
}

EnsembleResult run_esmda(const std::vector<std::vector<double>>& z0, const std::vector<double>& data,
                         const std::vector<double>& sd, const BatchForward& forward, const EnsembleMethodSpec& spec,
                         const std::function<void(int, const EnsembleResult&)>& progress) {
  return esmda_core(z0, data, sd, forward, spec, [](const std::vector<double>& z) { return z; }, progress);
}

EnsembleResult run_ensemble_method(const std::vector<PriorBound>& prior, const std::vector<double>& data,
                                   const std::vector<double>& sd, const BatchForward& forward,
                                   const EnsembleMethodSpec& spec,
                                   const std::function<void(int, const EnsembleResult&)>& progress) {
  if (prior.empty()) throw std::invalid_argument("ensemble method: no free parameter");
  for (const auto& p : prior)
    if (!(p.lower < p.upper) || (p.log && !(p.lower > 0)))
      throw std::invalid_argument("ensemble method: bad bounds of " + p.key);
  if (spec.members < 2) throw std::invalid_argument("ensemble method: at least 2 members are needed");
  std::vector<std::vector<double>> z = latin_hypercube_unit(spec.members, prior.size(), spec.seed);
  const bool probit = spec.transform == UnitTransform::Probit;
  for (auto& zi : z)
    for (double& v : zi) v = probit ? normal_quantile(v) : std::log(v / (1.0 - v));
  auto to_theta = [&prior, probit](const std::vector<double>& zi) {
    std::vector<double> t(zi.size());
    for (std::size_t j = 0; j < zi.size(); ++j) {
      const PriorBound& p = prior[j];
      // u is 0 or 1 only when z saturates
      const double u = probit ? 0.5 * std::erfc(-zi[j] / std::sqrt(2.0)) : 1.0 / (1.0 + std::exp(-zi[j]));
      t[j] = p.log ? p.lower * std::exp(u * std::log(p.upper / p.lower)) : p.lower + u * (p.upper - p.lower);
      t[j] = std::clamp(t[j], p.lower, p.upper);
    }
    return t;
  };
  return esmda_core(std::move(z), data, sd, forward, spec, to_theta, progress);
}

}  // namespace granflow::calibration
