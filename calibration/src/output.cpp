// Outputs of a fit: the fitted parameter set, reports, curves for plotting and the PNG.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <sstream>

#include "granflow/calibration/experiment.hpp"
#include "granflow/calibration/fit.hpp"
#include <granflow/io/input_error.hpp>
#include <granflow/io/output.hpp>
#include <granflow/io/run_folder.hpp>
#include <granflow/io/share.hpp>
#include <granflow/io/toml_reader.hpp>
#include "common.hpp"


namespace granflow::calibration {

namespace fs = std::filesystem;

namespace {

// A number in the report; "-" where the quantity is undefined (the reason is printed below it).
std::string shown(double v, int prec = 6) { return std::isfinite(v) ? num(v, prec) : "-"; }

// A number cell of a CSV: empty where the quantity is undefined, never nan or inf.
struct Cell {
  double v;
};
std::ostream& operator<<(std::ostream& os, Cell c) {
  if (std::isfinite(c.v)) os << c.v;
  return os;
}

std::string csv_quote(const std::string& s) {
  if (s.find_first_of(",\"") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

// Synced with the others when the manifest is written.
void write_file(const fs::path& p, const std::string& text) { io::write_file(p.string(), text, io::Durability::Buffered); }

std::string fitted_toml(const CalibrationJob& job, const FitResult& r) {
  io::ParameterSet s = r.fitted;
  s.name = (job.start.name.empty() ? job.name : job.start.name) + " -- calibrated by job " + job.name;
  s.source = "granflow calibrate " + job.file + " (misfit " + num(r.at_start.misfit) + " -> " + num(r.at_best.misfit) +
             "); started from " + (job.start.file.empty() ? job.start.name : job.start.file);
  std::string text = "# Fitted parameter set written by granflow calibrate; loads as it is in granflow element.\n# Free: ";
  for (std::size_t j = 0; j < job.free.size(); ++j) text += (j ? ", " : "") + job.free[j].key;
  text += "\n";
  bool first = true;
  for (const auto& e : job.experiments)
    if (!e->data_parameters().empty()) {
      if (first) text += "# The fit took these from the data, per curve; the values below are the start set's:\n";
      first = false;
      text += "#   " + e->name + ": " + e->data_parameters() + "\n";
    }
  text += io::format_parameter_set(s);
  // The file must load unchanged: parse it back with the same validation as any parameter file.
  const toml::table doc = toml::parse(std::string_view(text), std::string_view("fitted parameter set"));
  io::TomlTable root(doc, "fitted parameter set");
  (void)io::parse_parameter_set(root);
  return text;
}

}  // namespace

std::string python_with_matplotlib() {
  for (const char* cand : {"python3", "/usr/bin/python3"}) {
    const std::string cmd = std::string(cand) + " -c 'import matplotlib' >/dev/null 2>&1";
    if (std::system(cmd.c_str()) == 0) return cand;
  }
  return "";
}

std::string format_report(const Objective& obj, const FitResult& r) {
  const CalibrationJob& job = obj.job();
  std::ostringstream os;
  std::size_t points = obj.residual_count();
  os << "granflow calibrate: job '" << job.name << "' (" << job.file << ")\n";
  os << "starting set: " << job.start.name << " (" << job.start.file << ")\n";
  os << "experiments: " << job.experiments.size() << ", curves: " << obj.curves().size() << ", points: " << points
     << ", threads: " << r.threads << "\n";
  os << "misfit: " << (job.misfit.scale == MisfitScale::Log ? "log" : "linear") << " least squares, each curve "
     << (job.misfit.scale == MisfitScale::Log ? "averaged over its points"
                                              : job.misfit.normalise == Normalise::Rms     ? "divided by its RMS"
                                                : job.misfit.normalise == Normalise::Range ? "divided by its range"
                                                                                           : "unscaled")
     << ", weighted\n";
  if (r.ensemble)
    os << "algorithm: ensemble method (ES-MDA), " << job.ensemble.members << " members x "
       << r.ensemble->result.iterations.size() << " batches (" << r.global_evaluations << " evaluations), polish "
       << r.local_evaluations << " evaluations, seed " << job.ensemble.seed << "\n";
  else
    os << "algorithm: global " << job.algorithm.global << " (" << r.global_evaluations << " evaluations), local "
       << job.algorithm.local << " x" << job.algorithm.starts << " (" << r.local_evaluations << " evaluations), seed "
       << job.algorithm.seed << "\n";
  os << "stopped by: " << r.stop_reason << "\n";
  os << "misfit: start " << num(r.at_start.misfit, 8) << " -> final " << num(r.at_best.misfit, 8) << "   ("
     << r.evaluations << " evaluations + " << r.identifiability.evaluations << " for the Jacobian, " << num(r.seconds, 4)
     << " s)\n\n";

  os << std::left << std::setw(24) << "parameter" << std::right << std::setw(13) << "start" << std::setw(13) << "fitted"
     << std::setw(12) << "lower" << std::setw(12) << "upper" << std::setw(8) << "scale" << std::setw(10) << "rel.sd"
     << "  note\n";
  for (std::size_t j = 0; j < job.free.size(); ++j) {
    const FreeParameter& p = job.free[j];
    os << std::left << std::setw(24) << p.key << std::right << std::setw(13) << num(r.start[j]) << std::setw(13)
       << num(r.theta[j]) << std::setw(12) << num(p.lower) << std::setw(12) << num(p.upper) << std::setw(8)
       << (p.log ? "log" : "lin") << std::setw(10) << shown(r.identifiability.rel_sd[j], 3) << "  "
       << (r.on_bound[j] < 0 ? "ON LOWER BOUND" : r.on_bound[j] > 0 ? "ON UPPER BOUND" : "") << "\n";
  }
  os << "(" << (r.ensemble ? "fitted: the best final member of the ensemble, polished; " : "")
     << "rel.sd: approximate relative standard deviation from the Jacobian at the optimum and the final misfit)\n";
  for (std::size_t j = 0; j < job.free.size(); ++j)
    if (!r.identifiability.undefined[j].empty())
      os << "rel.sd of " << job.free[j].key << " undefined: " << r.identifiability.undefined[j] << "\n";
  os << "\n";

  os << std::left << std::setw(52) << "curve" << std::right << std::setw(6) << "n" << std::setw(13) << "RMSE start"
     << std::setw(13) << "RMSE" << std::setw(10) << "R2 start" << std::setw(10) << "R2" << "\n";
  for (std::size_t c = 0; c < obj.curves().size(); ++c) {
    const Curve& cv = obj.curve(c);
    const auto& a = r.at_start.curves[c];
    const auto& b = r.at_best.curves[c];
    os << std::left << std::setw(52) << (cv.label() + " ~ " + cv.model_output) << std::right << std::setw(6)
       << cv.x.size() << std::setw(13) << shown(a.rmse, 4) << std::setw(13) << shown(b.rmse, 4) << std::setw(10)
       << shown(a.r2, 4) << std::setw(10) << shown(b.r2, 4) << (b.failure.empty() ? "" : "  model failed: " + b.failure)
       << (std::isfinite(b.rmse) && !std::isfinite(b.r2) ? "  R2 undefined: the data of this curve are constant" : "")
       << "\n";
  }

  const Identifiability& id = r.identifiability;
  os << "\nlocal identifiability at the optimum (finite differences, step " << job.algorithm.fd_step
     << " of each range)\nsensitivity: RMS change of each normalised curve per unit change of ln(parameter)\n";
  os << std::left << std::setw(52) << "curve" << std::right;
  for (const auto& p : job.free) os << std::setw(14) << p.key.substr(p.key.find('.') + 1);
  os << "\n";
  for (std::size_t c = 0; c < obj.curves().size(); ++c) {
    os << std::left << std::setw(52) << obj.curve(c).label() << std::right;
    for (std::size_t j = 0; j < job.free.size(); ++j) os << std::setw(14) << shown(id.sensitivity(c, j), 3);
    os << "\n";
  }
  os << "correlation matrix:\n" << std::left << std::setw(24) << "" << std::right;
  for (const auto& p : job.free) os << std::setw(14) << p.key.substr(p.key.find('.') + 1);
  os << "\n";
  for (std::size_t j = 0; j < job.free.size(); ++j) {
    os << std::left << std::setw(24) << job.free[j].key << std::right;
    for (std::size_t k = 0; k < job.free.size(); ++k) os << std::setw(14) << shown(id.correlation(j, k), 3);
    os << "\n";
  }
  std::string undefined;
  for (std::size_t j = 0; j < job.free.size(); ++j)
    if (!std::isfinite(id.correlation(j, j))) undefined += (undefined.empty() ? "" : ", ") + job.free[j].key;
  if (!undefined.empty()) os << "correlations undefined (-) for " << undefined << ": see rel.sd above\n";
  if (id.singular) os << "WARNING: the Jacobian is rank-deficient: some combination of parameters does not change any curve\n";
  if (id.correlated.empty()) {
    os << "no parameter pair with |correlation| > 0.95" << (undefined.empty() ? "" : " among the defined ones") << "\n";
  } else {
    for (const auto& [j, k] : id.correlated)
      os << "WARNING: |correlation(" << job.free[j].key << ", " << job.free[k].key << ")| = "
         << num(std::fabs(id.correlation(j, k)), 4) << " > 0.95: these data do not separate them\n";
  }
  os << "\n" << format_identifiability(obj, r);
  if (r.ensemble) os << "\n" << format_ensemble_report(obj, r);
  return os.str();
}

namespace {

// The value at unit coordinate u of parameter p (u may lie outside [0, 1]).
double at_unit(const FreeParameter& p, double u) {
  return p.log ? p.lower * std::exp(u * std::log(p.upper / p.lower)) : p.lower + u * (p.upper - p.lower);
}
double unit_of(const FreeParameter& p, double v) {
  return p.log ? std::log(v / p.lower) / std::log(p.upper / p.lower) : (v - p.lower) / (p.upper - p.lower);
}

// The other parameter of j's strongest flagged pair, with the correlation; "" when none.
std::string partner(const CalibrationJob& job, const Identifiability& id, std::size_t j) {
  std::string out;
  double best = 0;
  for (const auto& [a, b] : id.correlated) {
    if (a != j && b != j) continue;
    const std::size_t k = a == j ? b : a;
    if (std::fabs(id.correlation(j, k)) <= best) continue;
    best = std::fabs(id.correlation(j, k));
    out = job.free[k].key + " " + num(id.correlation(j, k), 3);
  }
  return out;
}

}  // namespace

std::string format_identifiability(const Objective& obj, const FitResult& r) {
  const CalibrationJob& job = obj.job();
  const Identifiability& id = r.identifiability;
  std::ostringstream os;
  os << "identifiability at the optimum (Gauss-Newton J^T J in the search's unit cube): cond(J^T J) = "
     << shown(id.condition, 3) << "\n";
  os << std::left << std::setw(24) << "parameter" << std::right << std::setw(13) << "fitted" << std::setw(10)
     << "sd/range" << std::setw(10) << "rel.sd" << "  status\n";
  for (std::size_t j = 0; j < job.free.size(); ++j) {
    const std::string with = partner(job, id, j);
    os << std::left << std::setw(24) << job.free[j].key << std::right << std::setw(13) << num(r.theta[j])
       << std::setw(10) << shown(id.sd_range[j], 3) << std::setw(10) << shown(id.rel_sd[j], 3) << "  " << id.status[j]
       << (with.empty() ? "" : " (with " + with + ")") << "\n";
  }
  os << "(sd/range: standard error over the range searched, in log for log = true; poorly identified above "
     << kPoorlyIdentified << "; correlated: |correlation| > 0.95 with another; linearised, so a curved valley "
        "is wider than this says)\n";
  return os.str();
}

std::string format_ensemble_report(const Objective& obj, const FitResult& r) {
  const CalibrationJob& job = obj.job();
  const EnsembleReport& e = *r.ensemble;
  const EnsembleResult& er = e.result;
  const std::size_t m = e.data.size(), N = er.posterior.size();
  std::size_t given = 0;
  for (std::size_t c = 0; c < obj.curves().size(); ++c) given += std::isfinite(obj.curve(c).sd);
  std::ostringstream os;
  os << "ensemble method: ES-MDA (Emerick & Reynolds 2013), " << N << " members, " << job.ensemble.iterations
     << " iterations with inflation alpha = " << job.ensemble.iterations << ", seed " << job.ensemble.seed
     << "; prior uniform within the bounds (in log for log = true), Latin hypercube; update in z = "
     << job.ensemble.transform << "(u)\n";
  os << "likelihood: Gaussian in " << (job.misfit.scale == MisfitScale::Log ? "ln(data)" : "data units") << ", " << m
     << " data; sd " << (given ? std::to_string(given) + " curve(s) from target_sd, the others " : "")
     << "relative_sd = " << num(job.likelihood.relative_sd)
     << (job.misfit.scale == MisfitScale::Log ? " (of ln y)" : " x each curve's RMS") << "\n";
  os << "misfit: chi-square, sum ((model - data) / sd)^2 over the data (about " << m
     << " when the model fits within the sd)\n";
  os << std::setw(10) << "iteration" << std::setw(16) << "mean misfit" << std::setw(16) << "best misfit" << std::setw(8)
     << "failed" << std::setw(11) << "seconds" << "\n";
  for (std::size_t i = 0; i < er.iterations.size(); ++i) {
    const EnsembleIteration& it = er.iterations[i];
    os << std::setw(10) << i << std::setw(16) << shown(it.mean_misfit, 6) << std::setw(16) << shown(it.best_misfit, 6)
       << std::setw(8) << it.failed << std::setw(11) << num(it.seconds, 4)
       << (i == 0 ? "  prior" : i + 1 == er.iterations.size() ? "  posterior" : "") << "\n";
  }
  if (er.replaced > 0)
    os << er.replaced << " failed member(s) were replaced by copies of computed ones before the updates\n";
  for (std::size_t i = 0; i < N; ++i)
    if (!er.ok[i]) {
      os << "final member " << i << " failed: " << er.iterations.back().why[i] << "\n";
      break;
    }
  long ok = 0;
  for (char c : er.ok) ok += c != 0;
  os << "\nposterior over the " << ok << " computed final members (q05, q95: 5 % and 95 % quantiles)\n";
  os << std::left << std::setw(24) << "parameter" << std::right << std::setw(13) << "mean" << std::setw(13) << "median"
     << std::setw(13) << "q05" << std::setw(13) << "q95" << std::setw(12) << "sd" << std::setw(13) << "best" << std::setw(13)
     << "fitted" << "\n";
  for (std::size_t j = 0; j < job.free.size(); ++j) {
    const ParameterSummary& p = er.summary[j];
    os << std::left << std::setw(24) << job.free[j].key << std::right << std::setw(13) << shown(p.mean) << std::setw(13)
       << shown(p.median) << std::setw(13) << shown(p.q05) << std::setw(13) << shown(p.q95) << std::setw(12)
       << shown(p.sd, 4) << std::setw(13) << num(e.best[j]) << std::setw(13) << num(r.theta[j]) << "\n";
  }
  os << "posterior correlation:\n" << std::left << std::setw(24) << "" << std::right;
  for (const auto& p : job.free) os << std::setw(14) << p.key.substr(p.key.find('.') + 1);
  os << "\n";
  for (std::size_t j = 0; j < job.free.size(); ++j) {
    os << std::left << std::setw(24) << job.free[j].key << std::right;
    for (std::size_t k = 0; k < job.free.size(); ++k) os << std::setw(14) << shown(er.correlation[j][k], 3);
    os << "\n";
  }
  os << "best final member: " << er.best << ", misfit " << num(e.best_misfit, 8) << "; polish: " << e.polish
     << "; written set: misfit " << num(e.fitted_misfit, 8) << " (" << num(e.fitted_misfit / static_cast<double>(m), 4)
     << " per datum)\n";
  if (e.fitted_misfit > 4.0 * static_cast<double>(m))
    os << "WARNING: the best misfit is " << num(e.fitted_misfit / static_cast<double>(m), 3)
       << " per datum (about 1 expected): the model does not fit within the sd, so the intervals are too narrow; "
          "raise likelihood.relative_sd (or target_sd) to the model's error\n";
  for (std::size_t j = 0; j < job.free.size(); ++j) {
    const ParameterSummary& p = er.summary[j];
    const FreeParameter& f = job.free[j];
    const double w = f.upper - f.lower;
    if (p.q05 - f.lower < 0.01 * w || f.upper - p.q95 < 0.01 * w)
      os << "note: the 5-95 % interval of " << f.key << " reaches its " << (p.q05 - f.lower < 0.01 * w ? "lower" : "upper")
         << " bound: the data leave it to the prior there\n";
  }
  return os.str();
}

namespace {

// posterior.csv, posterior_summary.csv, posterior_correlation.csv, iterations.csv, ensemble_curves.csv
void write_ensemble_files(const Objective& obj, const FitResult& r, const fs::path& tmp) {
  const CalibrationJob& job = obj.job();
  const EnsembleReport& e = *r.ensemble;
  const EnsembleResult& er = e.result;
  const std::size_t n = job.free.size(), N = er.posterior.size();
  std::ostringstream pc, sc, cc, ic, ec;
  pc << std::setprecision(12) << "member";
  for (const auto& p : job.free) pc << "," << p.key;
  pc << ",misfit,ok\n";
  for (std::size_t i = 0; i < N; ++i) {
    pc << i;
    for (std::size_t j = 0; j < n; ++j) pc << "," << Cell{er.posterior[i][j]};
    pc << "," << Cell{er.iterations.back().misfit[i]} << "," << (er.ok[i] ? 1 : 0) << "\n";
  }
  write_file(tmp / "posterior.csv", pc.str());
  sc << std::setprecision(12) << "key,mean,median,q05,q95,sd,best,fitted\n";
  for (std::size_t j = 0; j < n; ++j) {
    const ParameterSummary& p = er.summary[j];
    sc << job.free[j].key << "," << Cell{p.mean} << "," << Cell{p.median} << "," << Cell{p.q05} << "," << Cell{p.q95}
       << "," << Cell{p.sd} << "," << Cell{e.best[j]} << "," << Cell{r.theta[j]} << "\n";
  }
  write_file(tmp / "posterior_summary.csv", sc.str());
  cc << std::setprecision(8) << "parameter";
  for (const auto& p : job.free) cc << "," << p.key;
  cc << "\n";
  for (std::size_t j = 0; j < n; ++j) {
    cc << job.free[j].key;
    for (std::size_t k = 0; k < n; ++k) cc << "," << Cell{er.correlation[j][k]};
    cc << "\n";
  }
  write_file(tmp / "posterior_correlation.csv", cc.str());
  ic << std::setprecision(10) << "iteration,mean_misfit,best_misfit,failed,seconds\n";
  for (std::size_t i = 0; i < er.iterations.size(); ++i) {
    const EnsembleIteration& it = er.iterations[i];
    ic << i << "," << Cell{it.mean_misfit} << "," << Cell{it.best_misfit} << "," << it.failed << "," << Cell{it.seconds}
       << "\n";
  }
  write_file(tmp / "iterations.csv", ic.str());
  // Each point: data, its sd in data units, the 5/50/95 % quantiles of the final members' model and the best member.
  ec << std::setprecision(10)
     << "experiment,data_column,model_output,abscissa,quantity,x,data,sd,q05,median,q95,best,fitted\n";
  const bool logm = job.misfit.scale == MisfitScale::Log;
  std::size_t k = 0;
  std::vector<double> v;
  for (std::size_t c = 0; c < obj.curves().size(); ++c) {
    const Curve& cv = obj.curve(c);
    const std::string& q = job.experiments[obj.curves()[c].experiment]->abscissa_quantity;
    for (std::size_t i = 0; i < cv.x.size(); ++i, ++k) {
      v.clear();
      for (std::size_t mbr = 0; mbr < N; ++mbr)
        if (er.ok[mbr] && std::isfinite(e.members[mbr].curves[c].model[i])) v.push_back(e.members[mbr].curves[c].model[i]);
      std::sort(v.begin(), v.end());
      const auto qt = [&](double p) {
        if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
        const double pos = p * static_cast<double>(v.size() - 1);
        const std::size_t lo = static_cast<std::size_t>(pos), hi = std::min(lo + 1, v.size() - 1);
        return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
      };
      const double sd = logm ? e.sd[k] * cv.y[i] : e.sd[k];
      ec << csv_quote(cv.experiment) << "," << cv.data_column << "," << cv.model_output << "," << cv.abscissa << "," << q
         << "," << Cell{cv.x[i]} << "," << Cell{cv.y[i]} << "," << Cell{sd} << "," << Cell{qt(0.05)} << ","
         << Cell{qt(0.5)} << "," << Cell{qt(0.95)} << ","
         << Cell{e.members[static_cast<std::size_t>(er.best)].curves[c].model[i]} << "," << Cell{r.at_best.curves[c].model[i]}
         << "\n";
    }
  }
  write_file(tmp / "ensemble_curves.csv", ec.str());
}

void write_staged(const Objective& obj, const FitResult& r, io::StagedFolder& folder, bool plot) {
  const CalibrationJob& job = obj.job();
  const fs::path tmp = folder.staging();

  write_file(tmp / (job.output_name + ".toml"), fitted_toml(job, r));
  write_file(tmp / "report.txt", format_report(obj, r));

  std::ostringstream pc;
  pc << std::setprecision(12) << "key,start,fitted,lower,upper,log,on_bound,rel_sd\n";
  for (std::size_t j = 0; j < job.free.size(); ++j) {
    const FreeParameter& p = job.free[j];
    pc << p.key << "," << Cell{r.start[j]} << "," << Cell{r.theta[j]} << "," << Cell{p.lower} << "," << Cell{p.upper}
       << "," << (p.log ? 1 : 0) << "," << (r.on_bound[j] < 0 ? "lower" : r.on_bound[j] > 0 ? "upper" : "") << ","
       << Cell{r.identifiability.rel_sd[j]} << "\n";
  }
  write_file(tmp / "report_parameters.csv", pc.str());

  std::ostringstream ic;  // identifiability.csv (docs/calibration.md)
  ic << std::setprecision(12)
     << "key,fitted,lower,upper,log,sd_range,rel_sd,lower_2sd,upper_2sd,correlated_with,condition,status\n";
  const Identifiability& id = r.identifiability;
  for (std::size_t j = 0; j < job.free.size(); ++j) {
    const FreeParameter& p = job.free[j];
    const double u = unit_of(p, r.theta[j]), sd = id.sd_range[j];
    ic << p.key << "," << Cell{r.theta[j]} << "," << Cell{p.lower} << "," << Cell{p.upper} << "," << (p.log ? 1 : 0)
       << "," << Cell{sd} << "," << Cell{id.rel_sd[j]} << "," << Cell{std::isfinite(sd) ? at_unit(p, u - 2 * sd) : sd}
       << "," << Cell{std::isfinite(sd) ? at_unit(p, u + 2 * sd) : sd} << "," << csv_quote(partner(job, id, j)) << ","
       << Cell{id.condition} << "," << id.status[j] << "\n";
  }
  write_file(tmp / "identifiability.csv", ic.str());

  std::ostringstream cc, sc, xc;
  cc << std::setprecision(10)
     << "experiment,data_column,model_output,points,weight,rmse_start,r2_start,rmse,r2,misfit_start,misfit\n";
  sc << std::setprecision(8) << "curve";
  for (const auto& p : job.free) sc << "," << p.key;
  sc << "\n";
  xc << std::setprecision(10) << "experiment,data_column,model_output,abscissa,quantity,x,data,model_start,model_fit\n";
  for (std::size_t c = 0; c < obj.curves().size(); ++c) {
    const Curve& cv = obj.curve(c);
    const auto& a = r.at_start.curves[c];
    const auto& b = r.at_best.curves[c];
    cc << csv_quote(cv.experiment) << "," << cv.data_column << "," << cv.model_output << "," << cv.x.size() << ","
       << Cell{cv.weight} << "," << Cell{a.rmse} << "," << Cell{a.r2} << "," << Cell{b.rmse} << "," << Cell{b.r2} << ","
       << Cell{a.misfit} << "," << Cell{b.misfit} << "\n";
    sc << csv_quote(cv.label());
    for (std::size_t j = 0; j < job.free.size(); ++j) sc << "," << Cell{r.identifiability.sensitivity(c, j)};
    sc << "\n";
    const std::string& q = job.experiments[obj.curves()[c].experiment]->abscissa_quantity;
    for (std::size_t i = 0; i < cv.x.size(); ++i)
      xc << csv_quote(cv.experiment) << "," << cv.data_column << "," << cv.model_output << "," << cv.abscissa << "," << q
         << "," << Cell{cv.x[i]} << "," << Cell{cv.y[i]} << "," << Cell{a.model[i]} << "," << Cell{b.model[i]} << "\n";
  }
  write_file(tmp / "report_curves.csv", cc.str());
  write_file(tmp / "sensitivity.csv", sc.str());
  write_file(tmp / "curves.csv", xc.str());

  std::ostringstream kc;
  kc << std::setprecision(8) << "parameter";
  for (const auto& p : job.free) kc << "," << p.key;
  kc << "\n";
  for (std::size_t j = 0; j < job.free.size(); ++j) {
    kc << job.free[j].key;
    for (std::size_t k = 0; k < job.free.size(); ++k) kc << "," << Cell{r.identifiability.correlation(j, k)};
    kc << "\n";
  }
  write_file(tmp / "correlation.csv", kc.str());
  if (r.ensemble) write_ensemble_files(obj, r, tmp);

  if (plot) {
    const std::string py = python_with_matplotlib();
    const std::string script = io::script_path("plot_calibration.py");
    if (py.empty() || script.empty()) {
      std::cerr << "calibrate: fit.png skipped ("
                << (py.empty() ? "no python3 with matplotlib" : "scripts/plot_calibration.py not found")
                << "); curves.csv holds the curves\n";
    } else {
      std::string title = job.name;
      for (char& ch : title)
        if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '_' && ch != '-' && ch != '.') ch = ' ';
      const std::string cmd = py + " '" + script + "' '" + (tmp / "curves.csv").string() + "' '" +
                              (tmp / "fit.png").string() + "' '" + title + "'";
      if (std::system(cmd.c_str()) != 0) {
        std::error_code ec;
        fs::remove(tmp / "fit.png", ec);  // whatever it left is not a finished plot
        std::cerr << "calibrate: the plot script failed; curves.csv holds the curves\n";
      }
      const std::string post = io::script_path("plot_posterior.py");
      if (r.ensemble && !post.empty() && std::system((py + " '" + post + "' '" + tmp.string() + "' '" + title + "'").c_str()) != 0) {
        std::error_code ec;
        fs::remove(tmp / "posterior.png", ec);
        fs::remove(tmp / "ensemble_fit.png", ec);
        std::cerr << "calibrate: the posterior plot script failed; posterior.csv and ensemble_curves.csv hold the data\n";
      }
    }
  }
  folder.commit(r.stop_reason.empty() ? "complete" : "complete (stopped by: " + r.stop_reason + ")");
}

}  // namespace

void write_outputs(const Objective& obj, const FitResult& r, io::StagedFolder& folder, bool plot) {
  try {
    write_staged(obj, r, folder, plot);
  } catch (const io::OutputError& e) {
    throw folder.explain(e);
  }
}

void write_outputs(const Objective& obj, const FitResult& r, const std::string& dir, bool force, bool plot) {
  io::StagedFolder folder(dir, force);
  write_outputs(obj, r, folder, plot);
}

}  // namespace granflow::calibration
