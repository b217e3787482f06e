// The ensemble method (ES-MDA): the update against the closed-form posterior of a linear-Gaussian
// problem, the prior sample, failed members, coverage of the 5-95 % intervals on steady-shear
// flow curves, independence of the thread count and the run folder.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <set>
#include <sstream>

#include <Eigen/Dense>

#include <granflow/calibration/ensemble_method.hpp>
#include <granflow/calibration/fit.hpp>
#include <granflow/calibration/job.hpp>
#include <granflow/constitutive.hpp>

#include "helpers.hpp"
#include <granflow/io/parameter_set.hpp>

namespace granflow::calibration::test {

namespace {

std::size_t index_of(const CalibrationJob& job, const std::string& key) {
  for (std::size_t j = 0; j < job.free.size(); ++j)
    if (job.free[j].key == key) return j;
  ADD_FAILURE() << "no free parameter " << key;
  return 0;
}

// p, tau, T against solid fraction from a known set, each multiplied by exp(sd_log * N(0,1)):
// exactly the noise the log likelihood with relative_sd = sd_log assumes.
std::string lognormal_flow_curves(const CollisionalParams<double>& c, double sd_log, std::uint64_t seed) {
  NormalStream n01(seed);
  std::ostringstream os;
  os.precision(12);
  os << "nu,p,s,T\n";
  for (int k = 0; k <= 16; ++k) {
    const double nu = 0.10 + 0.025 * k;
    const auto kc = kinetic_coefficients(c, nu);
    const auto ss = steady_simple_shear(c, kc, 1.0);
    os << nu << "," << ss.p / c.rho_p * std::exp(sd_log * n01()) << "," << ss.tau / c.rho_p * std::exp(sd_log * n01())
       << "," << ss.T * std::exp(sd_log * n01()) << "\n";
  }
  return os.str();
}

CollisionalParams<double> flow_truth() {
  CollisionalParams<double> t;
  t.rho_p = 1;
  t.d = 1;
  t.V_sd = 1.0 / (1.0 + 0.60);  // e_sd = 0.60
  t.V_m = 0.35;
  t.eps_n = 0.80;
  t.mu_p = 0.0;
  return t;
}

// Two free parameters (e_sd, eps_n), V_m fixed at the truth, log likelihood with relative_sd.
std::string flow_job(long members, unsigned long seed, double relative_sd, bool polish) {
  std::ostringstream os;
  os << "params = \"start.toml\"\n"
     << "[[free]]\nkey = \"collisional.e_sd\"\nlower = 0.3\nupper = 0.9\n"
     << "[[free]]\nkey = \"collisional.eps_n\"\nlower = 0.3\nupper = 0.99\n"
     << "[misfit]\nscale = \"log\"\n[algorithm]\nmethod = \"ensemble\"\n"
     << "[ensemble]\nmembers = " << members << "\niterations = 4\nseed = " << seed
     << "\npolish = " << (polish ? "true" : "false") << "\n[likelihood]\nrelative_sd = " << relative_sd << "\n"
     << "[[experiments]]\nname = \"synthetic\"\nkind = \"steady_shear\"\ndata = \"flow.csv\"\nabscissa = \"nu\"\n"
     << "quantity = \"solid_fraction\"\ntargets = { p = \"p\", s = \"tau\", T = \"T\" }\n"
     << "[experiments.steady_shear]\nunits = \"dimensionless\"\n";
  return os.str();
}

const char* kFlowStart = "[collisional]\nrho_p = 1\nd = 1\ne_sd = 0.6\nV_m = 0.35\neps_n = 0.8\nmu_p = 0\n";

FitResult run(const CalibrationJob& job, unsigned threads) {
  Objective obj(job, threads);
  FitOptions fo;
  fo.progress = false;
  return fit(obj, fo);
}

}  // namespace

// Linear forward model g = A z with a Gaussian prior on z and Gaussian noise: the posterior is
// Gaussian with P = (P0^-1 + A^T C_D^-1 A)^-1, mu = P (P0^-1 mu0 + A^T C_D^-1 d), and ES-MDA
// samples it exactly as the ensemble grows. 4000 members: mean within 4 standard errors, s.d.
// within 8 % (its standard error is ~1.1 %), correlation within 0.05.
TEST(CalibrationEnsemble, LinearGaussianPosteriorMatchesClosedForm) {
  const int n = 2, m = 5;
  const long N = 4000;
  Eigen::MatrixXd A(m, n);
  A << 1.0, 0.5, -0.3, 2.0, 0.8, 0.8, 1.5, -1.0, 0.2, 0.1;
  const Eigen::Vector2d mu0(0.5, -1.0);
  Eigen::Matrix2d P0;
  P0 << 1.0, 0.3, 0.3, 2.0;
  const Eigen::VectorXd sd = (Eigen::VectorXd(m) << 0.5, 0.8, 0.4, 1.0, 0.3).finished();
  const Eigen::VectorXd d = (Eigen::VectorXd(m) << 1.2, -2.5, 0.3, 2.2, 0.05).finished();
  const Eigen::MatrixXd CDi = sd.cwiseProduct(sd).cwiseInverse().asDiagonal();
  const Eigen::Matrix2d P = (P0.inverse() + A.transpose() * CDi * A).inverse();
  const Eigen::Vector2d mu = P * (P0.inverse() * mu0 + A.transpose() * CDi * d);

  const Eigen::Matrix2d L = P0.llt().matrixL();
  NormalStream n01(11);
  std::vector<std::vector<double>> z0(N);
  for (auto& z : z0) {
    const Eigen::Vector2d e(n01(), n01());
    const Eigen::Vector2d v = mu0 + L * e;
    z = {v(0), v(1)};
  }
  const BatchForward forward = [&](const std::vector<std::vector<double>>& zs) {
    BatchResult b;
    for (const auto& z : zs) {
      const Eigen::VectorXd g = A * Eigen::Vector2d(z[0], z[1]);
      b.predictions.emplace_back(g.data(), g.data() + m);
      b.ok.push_back(1);
    }
    b.why.resize(zs.size());
    return b;
  };
  EnsembleMethodSpec spec;
  spec.iterations = 4;
  spec.seed = 5;
  const EnsembleResult r = run_esmda(z0, std::vector<double>(d.data(), d.data() + m),
                                     std::vector<double>(sd.data(), sd.data() + m), forward, spec);
  ASSERT_EQ(r.iterations.size(), 5u);
  for (int j = 0; j < n; ++j) {
    const double s = std::sqrt(P(j, j));
    EXPECT_NEAR(r.summary[j].mean, mu(j), 4.0 * s / std::sqrt(double(N))) << j;
    EXPECT_NEAR(r.summary[j].sd / s, 1.0, 0.08) << j;
    EXPECT_NEAR(r.summary[j].median, mu(j), 5.0 * s / std::sqrt(double(N))) << j;
    EXPECT_NEAR(r.summary[j].q95 - r.summary[j].q05, 2 * 1.6449 * s, 0.12 * 2 * 1.6449 * s) << j;
  }
  EXPECT_NEAR(r.correlation[0][1], P(0, 1) / std::sqrt(P(0, 0) * P(1, 1)), 0.05);
  // the misfit falls from the prior to the posterior
  EXPECT_LT(r.iterations.back().mean_misfit, r.iterations.front().mean_misfit);
}

// One ES-MDA update of g = z (one datum, sd 1, prior N(0, 1)) with inflation alpha = iterations:
// the gain is K = 1 / (1 + alpha) and the data perturbed by sqrt(alpha) sd, so the members after
// it have variance (1 - K)^2 + K^2 alpha = alpha / (1 + alpha) and mean K d (K and the mean from
// the sample's own prior moments). At alpha = 4 that is 0.8; perturbations of sd instead of
// sqrt(alpha) sd would give 0.68, of alpha sd 1.28 (standard error of the estimate: 1 %).
TEST(CalibrationEnsemble, PerturbationScalesWithTheInflationFactor) {
  const long N = 20000;
  NormalStream n01(3);
  std::vector<std::vector<double>> z0(N);
  for (auto& z : z0) z = {n01()};
  const double d = 0.7;
  const BatchForward identity = [](const std::vector<std::vector<double>>& zs) {
    BatchResult b;
    b.predictions = zs;
    b.ok.assign(zs.size(), 1);
    b.why.resize(zs.size());
    return b;
  };
  for (int iterations : {1, 4, 9}) {
    EnsembleMethodSpec spec;
    spec.iterations = iterations;
    spec.seed = 7;
    const EnsembleResult r = run_esmda(z0, {d}, {1.0}, identity, spec);
    ASSERT_GE(r.iterations.size(), 2u);
    const auto& after = r.iterations[1].thetas;  // the members after the first update
    double mean = 0, var = 0, mean0 = 0, var0 = 0;
    for (long i = 0; i < N; ++i) {
      mean += after[i][0] / N;
      mean0 += z0[i][0] / N;
    }
    for (long i = 0; i < N; ++i) {
      var += std::pow(after[i][0] - mean, 2) / (N - 1);
      var0 += std::pow(z0[i][0] - mean0, 2) / (N - 1);
    }
    const double alpha = iterations, K = var0 / (var0 + alpha);  // the sample's own prior variance
    const double want = (1 - K) * (1 - K) * var0 + K * K * alpha;
    EXPECT_NEAR(var / want, 1.0, 0.03) << "alpha = " << alpha << ": variance " << var << ", expected " << want;
    EXPECT_NEAR(mean, (1 - K) * mean0 + K * d, 0.03) << "alpha = " << alpha;
  }
}

TEST(CalibrationEnsemble, LatinHypercubeHasOnePointPerStratumAndIsReproducible) {
  const long N = 37;
  const auto u = latin_hypercube_unit(N, 3, 42);
  for (std::size_t j = 0; j < 3; ++j) {
    std::set<long> strata;
    for (const auto& p : u) {
      ASSERT_GT(p[j], 0.0);
      ASSERT_LT(p[j], 1.0);
      strata.insert(static_cast<long>(std::floor(p[j] * N)));
    }
    EXPECT_EQ(static_cast<long>(strata.size()), N);
  }
  EXPECT_EQ(u, latin_hypercube_unit(N, 3, 42));
  EXPECT_NE(u, latin_hypercube_unit(N, 3, 43));
  NormalStream a(3), b(3);
  double s = 0, s2 = 0;
  for (int i = 0; i < 20000; ++i) {
    const double x = a();
    EXPECT_EQ(x, b());
    s += x;
    s2 += x * x;
  }
  EXPECT_NEAR(s / 20000, 0.0, 0.03);
  EXPECT_NEAR(s2 / 20000, 1.0, 0.04);
}

// The prior handed to the model is the Latin hypercube in the unit cube, whichever transform the
// update uses: one member per 1/N stratum of every parameter (linear or log bounds).
TEST(CalibrationEnsemble, PriorIsTheLatinHypercubeWithinTheBounds) {
  const std::vector<PriorBound> prior = {{"a", -2.0, 3.0, false}, {"b", 1e-3, 10.0, true}};
  for (UnitTransform tr : {UnitTransform::Probit, UnitTransform::Logit}) {
    EnsembleMethodSpec spec;
    spec.members = 40;
    spec.iterations = 1;
    spec.seed = 9;
    spec.transform = tr;
    std::vector<std::vector<double>> first;
    const BatchForward forward = [&](const std::vector<std::vector<double>>& t) {
      if (first.empty()) first = t;
      BatchResult b;
      for (const auto& th : t) b.predictions.push_back({th[0], std::log(th[1])});
      b.ok.assign(t.size(), 1);
      b.why.resize(t.size());
      return b;
    };
    run_ensemble_method(prior, {0.5, 0.0}, {10.0, 10.0}, forward, spec);
    const auto u = latin_hypercube_unit(40, 2, 9);
    ASSERT_EQ(first.size(), 40u);
    for (std::size_t i = 0; i < 40; ++i) {
      EXPECT_NEAR(first[i][0], -2.0 + 5.0 * u[i][0], 1e-12);
      EXPECT_NEAR(std::log(first[i][1] / 1e-3) / std::log(1e4), u[i][1], 1e-12);
    }
  }
}

namespace {
// The "model" (a, log10 b + 1) of the failure tests, which cannot compute a > 0.8; counts its calls.
BatchForward failing_above_08(long& calls) {
  return [&calls](const std::vector<std::vector<double>>& t) {
    ++calls;
    BatchResult b;
    for (const auto& th : t) {
      const bool fails = th[0] > 0.8;
      b.predictions.push_back(fails ? std::vector<double>() : std::vector<double>{th[0], std::log10(th[1]) + 1.0});
      b.ok.push_back(fails ? 0 : 1);
      b.why.push_back(fails ? "a > 0.8" : "");
    }
    return b;
  };
}
}  // namespace

// Members the model cannot compute are replaced by copies of computed ones and stay within the
// bounds; a batch without two computed members is an error naming the reason.
TEST(CalibrationEnsemble, FailedMembersAreReplacedAndAllFailingIsAnError) {
  const std::vector<PriorBound> prior = {{"a", 0.0, 1.0, false}, {"b", 0.1, 10.0, true}};
  const std::vector<double> data = {0.3, 1.0}, sd = {0.05, 0.1};
  long calls = 0;
  const BatchForward forward = failing_above_08(calls);
  EnsembleMethodSpec spec;
  spec.members = 50;
  spec.iterations = 3;
  const EnsembleResult r = run_ensemble_method(prior, data, sd, forward, spec);
  EXPECT_EQ(calls, 4);
  EXPECT_GT(r.iterations[0].failed, 5);  // ~20 % of the prior
  EXPECT_EQ(r.replaced, r.iterations[0].failed + r.iterations[1].failed + r.iterations[2].failed);
  EXPECT_EQ(r.iterations[0].why[0].empty(), r.iterations[0].misfit[0] == r.iterations[0].misfit[0]);
  for (const auto& th : r.posterior) {
    EXPECT_GE(th[0], 0.0);
    EXPECT_LE(th[0], 1.0);
    EXPECT_GE(th[1], 0.1);
    EXPECT_LE(th[1], 10.0);
  }
  EXPECT_NEAR(r.summary[0].median, 0.3, 0.05);
  EXPECT_NEAR(r.summary[1].median, 1.0, 0.3);
  ASSERT_GE(r.best, 0);
  EXPECT_TRUE(r.ok[static_cast<std::size_t>(r.best)]);

  const BatchForward none = [](const std::vector<std::vector<double>>& t) {
    BatchResult b;
    b.predictions.resize(t.size());
    b.ok.assign(t.size(), 0);
    b.why.assign(t.size(), "solver diverged");
    return b;
  };
  try {
    run_ensemble_method(prior, data, sd, none, spec);
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("0 of 50 members"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("solver diverged"), std::string::npos) << e.what();
  }
}

// Resume (issue 27): the state saved after iteration k, given back, continues to the result of
// an uninterrupted run bit for bit, with failed members and their replacements on the way; a
// state that does not fit the spec is refused.
TEST(CalibrationEnsemble, ResumedRunEqualsAnUninterruptedOne) {
  const std::vector<PriorBound> prior = {{"a", 0.0, 1.0, false}, {"b", 0.1, 10.0, true}};
  const std::vector<double> data = {0.3, 1.0}, sd = {0.05, 0.1};
  long calls = 0;
  const BatchForward forward = failing_above_08(calls);
  EnsembleMethodSpec spec;
  spec.members = 20;
  spec.iterations = 3;
  std::vector<EsmdaState> saved;
  spec.save = [&](const EsmdaState& st) { saved.push_back(st); };
  const EnsembleResult full = run_ensemble_method(prior, data, sd, forward, spec);
  ASSERT_EQ(saved.size(), 3u);  // after each of the 3 updates
  EXPECT_GT(full.replaced, 0);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(saved[k].next, k + 1);
    spec.save = nullptr;
    spec.resume = &saved[k];
    calls = 0;
    const EnsembleResult r = run_ensemble_method(prior, data, sd, forward, spec);
    EXPECT_EQ(calls, 3 - k) << "resumed after update " << k + 1;  // only the batches not yet run
    EXPECT_EQ(r.posterior, full.posterior);
    EXPECT_EQ(r.replaced, full.replaced);
    ASSERT_EQ(r.iterations.size(), full.iterations.size());
    for (std::size_t i = 0; i < r.iterations.size(); ++i) EXPECT_EQ(r.iterations[i].thetas, full.iterations[i].thetas);
  }
  EsmdaState bad = saved[0];
  bad.z.pop_back();
  spec.resume = &bad;
  EXPECT_THROW(run_ensemble_method(prior, data, sd, forward, spec), std::invalid_argument);
}

// The data vector: ln y with relative_sd for a log misfit; y with relative_sd x RMS for a linear
// one; target_sd (data units) where given, divided by y for a log misfit; curves in job order.
TEST(CalibrationEnsemble, LikelihoodDataFollowTheCurvesAndTheirSd) {
  Scratch dir;
  dir.write("data.csv", "nu,p,s\n0.3,1.0,3.0\n0.4,2.0,4.0\n");
  std::string job = flow_job(8, 1, 0.1, false);
  const std::string targets = "targets = { p = \"p\", s = \"tau\", T = \"T\" }";
  job.replace(job.find(targets), targets.size(), "targets = { p = \"p\", s = \"tau\" }\ntarget_sd = { s = 0.5 }");
  job.replace(job.find("flow.csv"), 8, "data.csv");
  dir.write("start.toml", kFlowStart);
  const CalibrationJob logj = load_job(dir.write("job.toml", job));
  std::vector<double> d, sd;
  {
    Objective obj(logj, 1);
    likelihood_data(obj, d, sd);
  }
  ASSERT_EQ(d.size(), 4u);
  EXPECT_DOUBLE_EQ(d[0], std::log(1.0));
  EXPECT_DOUBLE_EQ(d[1], std::log(2.0));
  EXPECT_DOUBLE_EQ(d[3], std::log(4.0));
  EXPECT_DOUBLE_EQ(sd[0], 0.1);
  EXPECT_DOUBLE_EQ(sd[2], 0.5 / 3.0);
  EXPECT_DOUBLE_EQ(sd[3], 0.5 / 4.0);
  job.replace(job.find("scale = \"log\""), 13, "scale = \"linear\"");
  const CalibrationJob linj = load_job(dir.write("job.toml", job));
  Objective obj(linj, 1);
  likelihood_data(obj, d, sd);
  EXPECT_DOUBLE_EQ(d[1], 2.0);
  EXPECT_DOUBLE_EQ(sd[0], 0.1 * std::sqrt(2.5));
  EXPECT_DOUBLE_EQ(sd[1], 0.1 * std::sqrt(2.5));
  EXPECT_DOUBLE_EQ(sd[2], 0.5);
}

// Synthetic flow curves from a known set with the noise the likelihood assumes (log-normal,
// relative_sd = 0.05), 20 noise seeds: a calibrated 90 % interval covers the truth in 14 to 20 of
// them (binomial(20, 0.9): 14 or fewer has probability 1 %).
TEST(CalibrationEnsemble, IntervalsCoverTheTruthOnSteadyShear) {
  const CollisionalParams<double> truth = flow_truth();
  const double t_esd = 1.0 / truth.V_sd - 1.0, t_eps = truth.eps_n;
  int cover_esd = 0, cover_eps = 0;
  std::ostringstream log;
  for (unsigned long seed = 1; seed <= 20; ++seed) {
    Scratch dir;
    dir.write("flow.csv", lognormal_flow_curves(truth, 0.05, 1000 + seed));
    dir.write("start.toml", kFlowStart);
    const CalibrationJob job = load_job(dir.write("job.toml", flow_job(100, seed, 0.05, false)));
    const FitResult r = run(job, 2);
    ASSERT_TRUE(r.ensemble);
    const auto& s = r.ensemble->result.summary;
    const auto& a = s[index_of(job, "collisional.e_sd")];
    const auto& b = s[index_of(job, "collisional.eps_n")];
    cover_esd += a.q05 <= t_esd && t_esd <= a.q95;
    cover_eps += b.q05 <= t_eps && t_eps <= b.q95;
    log << "seed " << seed << ": e_sd [" << a.q05 << ", " << a.q95 << "], eps_n [" << b.q05 << ", " << b.q95
        << "], best misfit " << r.ensemble->best_misfit << "\n";
  }
  std::cout << log.str() << "covered: e_sd " << cover_esd << ", eps_n " << cover_eps << " of 20\n";
  EXPECT_GE(cover_esd, 14) << log.str();
  EXPECT_GE(cover_eps, 14) << log.str();
}

TEST(CalibrationEnsemble, ResultDoesNotDependOnTheThreadCount) {
  Scratch dir;
  dir.write("flow.csv", lognormal_flow_curves(flow_truth(), 0.05, 7));
  dir.write("start.toml", kFlowStart);
  const CalibrationJob job = load_job(dir.write("job.toml", flow_job(32, 3, 0.05, true)));
  const FitResult a = run(job, 1), b = run(job, 3);
  EXPECT_EQ(a.ensemble->result.posterior, b.ensemble->result.posterior);  // bitwise
  EXPECT_EQ(a.theta, b.theta);
}

// The polish: the misfit at the written set, computed here from the closed forms and the data
// file (chi-square of the log data with sd = relative_sd), is the reported fitted misfit and
// lies below the best final member's.
TEST(CalibrationEnsemble, PolishedSetHasTheReportedMisfitBelowTheBestMember) {
  Scratch dir;
  const std::string data = lognormal_flow_curves(flow_truth(), 0.05, 9);
  dir.write("flow.csv", data);
  dir.write("start.toml", kFlowStart);
  const CalibrationJob job = load_job(dir.write("job.toml", flow_job(24, 2, 0.05, true)));
  Objective obj(job, 2);
  FitOptions fo;
  fo.progress = false;
  const FitResult r = fit(obj, fo);
  write_outputs(obj, r, dir.path("out"), false, false);
  const io::ParameterSet s = io::load_parameter_set(dir.path("out/fitted.toml"));
  ASSERT_TRUE(s.collisional);
  double chi2 = 0;
  long points = 0;
  std::istringstream in(data);
  std::string line;
  std::getline(in, line);  // header nu,p,s,T
  for (char sep; std::getline(in, line); ++points) {
    std::istringstream row(line);
    double nu, p, tau, T;
    row >> nu >> sep >> p >> sep >> tau >> sep >> T;
    const auto kc = kinetic_coefficients(*s.collisional, nu);
    const auto ss = steady_simple_shear(*s.collisional, kc, 1.0);  // d = rho_p = gammadot = 1
    for (const auto& [model, measured] : {std::pair{ss.p, p}, std::pair{ss.tau, tau}, std::pair{ss.T, T}})
      chi2 += std::pow(std::log(model / measured) / 0.05, 2);
  }
  EXPECT_EQ(points, 17);
  ASSERT_TRUE(r.ensemble);
  EXPECT_NE(r.ensemble->polish.rfind("skipped", 0), 0u) << r.ensemble->polish;
  EXPECT_NEAR(chi2, r.ensemble->fitted_misfit, 1e-9 * chi2);
  EXPECT_LT(chi2, r.ensemble->best_misfit * (1 - 1e-6));
}

// The run folder: the fitted set is the best member (polished) and loads; the posterior files
// have one row per member and per parameter.
TEST(CalibrationEnsemble, OutputsHoldThePosteriorAndTheFittedSetLoads) {
  Scratch dir;
  dir.write("flow.csv", lognormal_flow_curves(flow_truth(), 0.05, 9));
  dir.write("start.toml", kFlowStart);
  const CalibrationJob job = load_job(dir.write("job.toml", flow_job(24, 2, 0.05, true)));
  Objective obj(job, 2);
  FitOptions fo;
  fo.progress = false;
  const FitResult r = fit(obj, fo);
  write_outputs(obj, r, dir.path("out"), false, false);
  const io::ParameterSet s = io::load_parameter_set(dir.path("out/fitted.toml"));
  EXPECT_DOUBLE_EQ(s.collisional->eps_n, r.theta[index_of(job, "collisional.eps_n")]);
  EXPECT_LE(r.ensemble->fitted_misfit, r.ensemble->best_misfit);
  auto lines = [&](const std::string& f) {
    std::ifstream in(dir.path("out/" + f));
    long k = 0;
    for (std::string l; std::getline(in, l);) ++k;
    return k;
  };
  EXPECT_EQ(lines("posterior.csv"), 25);
  EXPECT_EQ(lines("posterior_summary.csv"), 3);
  EXPECT_EQ(lines("iterations.csv"), 6);
  EXPECT_EQ(lines("ensemble_curves.csv"), 1 + 17 * 3);
  EXPECT_EQ(lines("posterior_correlation.csv"), 3);
  const std::string report = format_report(obj, r);
  for (const char* f : {"ensemble method: ES-MDA", "posterior over the 24 computed final members", "posterior correlation",
                        "best final member"})
    EXPECT_NE(report.find(f), std::string::npos) << f << "\n" << report;
}

}  // namespace granflow::calibration::test
