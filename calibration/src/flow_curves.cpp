#include "granflow/calibration/flow_curves.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "granflow/calibration/experiment.hpp"
#include "granflow/calibration/fit.hpp"
#include "granflow/calibration/parameters.hpp"
#include <granflow/io/input_error.hpp>
#include <granflow/io/output.hpp>
#include <granflow/io/share.hpp>
#include "common.hpp"

namespace granflow::calibration {

namespace {

struct Sums {
  double ss = 0;
  int n = 0;
  void add(double r) {
    ss += r * r;
    ++n;
  }
  double rms() const { return n ? std::sqrt(ss / n) : kNaN; }
};

int curve_of(const Experiment& e, const std::string& output) {
  for (std::size_t c = 0; c < e.curves.size(); ++c)
    if (e.curves[c].model_output == output) return static_cast<int>(c);
  return -1;
}

std::string fmt(double v, int prec = 3) {
  if (!std::isfinite(v)) return "-";
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", prec, v);
  return b;
}

}  // namespace

int worst_group(const std::vector<GroupScore>& scores, std::size_t w) {
  int k = -1;
  for (std::size_t i = 0; i < scores.size(); ++i)
    if (w < scores[i].rmse.size() && std::isfinite(scores[i].rmse[w]) && (k < 0 || scores[i].rmse[w] > scores[k].rmse[w]))
      k = static_cast<int>(i);
  return k;
}

std::vector<GroupScore> score_groups(const CalibrationJob& job, const io::ParameterSet& set,
                                     std::vector<FlowPoint>* points) {
  const auto& cv = job.cross_validation;
  const auto windows = cv.windows.empty() ? std::vector<std::pair<double, double>>{{0.0, 0.57}} : cv.windows;
  std::vector<GroupScore> out;
  for (const auto& src : job.steady_shear_sources) {
    DataSelection sel = *std::static_pointer_cast<const DataSelection>(src.selection);
    if (sel.quantity != "solid_fraction") continue;  // flow curves against the solid fraction only
    sel.x_lo = -1e300;
    sel.x_hi = 1e300;
    const auto& spec = *std::static_pointer_cast<const SteadyShearSpec>(src.spec);
    for (const auto& e : make_steady_shear_experiments(src.name, sel, spec)) {
      const Prediction pr = e->predict(set);
      const int ip = curve_of(*e, "p"), is = curve_of(*e, "tau"), iT = curve_of(*e, "T");
      GroupScore g;
      g.name = e->name;
      g.mu_p = std::isfinite(e->data_friction()) ? e->data_friction() : set.collisional->mu_p;
      g.eps_n = std::isfinite(e->data_restitution()) ? e->data_restitution() : set.collisional->eps_n;
      std::vector<Sums> win(windows.size()), band(cv.bands.size() > 1 ? cv.bands.size() - 1 : 0);
      Sums fr;
      // the abscissae of one group's curves agree (same rows); index the points by the p curve
      const Curve& ref = e->curves[ip >= 0 ? ip : 0];
      for (std::size_t i = 0; i < ref.x.size(); ++i) {
        const double nu = ref.x[i];
        auto val = [&](int c, bool model) {
          if (c < 0 || i >= e->curves[c].x.size() || e->curves[c].x[i] != nu) return kNaN;
          return model ? (pr.ok ? pr.values[c][i] : kNaN) : e->curves[c].y[i];
        };
        FlowPoint fp{e->name, nu, val(ip, false), val(is, false), val(iT, false), val(ip, true), val(is, true), val(iT, true)};
        if (points) points->push_back(fp);
        for (std::size_t w = 0; w < windows.size(); ++w) {
          if (!(nu >= windows[w].first && nu < windows[w].second)) continue;
          for (auto [d, m] : {std::pair{fp.p, fp.p_m}, std::pair{fp.s, fp.s_m}, std::pair{fp.T, fp.T_m}}) {
            if (!std::isfinite(d)) continue;
            if (!(m > 0) || !std::isfinite(m)) {
              if (w == 0) ++g.undefined;
              continue;
            }
            win[w].add(std::log(m / d));
          }
          if (w == 0 && fp.p > 0 && fp.s > 0 && fp.p_m > 0 && fp.s_m > 0) fr.add(std::log((fp.s_m / fp.p_m) / (fp.s / fp.p)));
        }
        for (std::size_t b = 0; b < band.size(); ++b) {
          if (!(nu >= cv.bands[b] && nu < cv.bands[b + 1])) continue;
          for (auto [d, m] : {std::pair{fp.p, fp.p_m}, std::pair{fp.s, fp.s_m}, std::pair{fp.T, fp.T_m}})
            if (std::isfinite(d) && m > 0 && std::isfinite(m)) band[b].add(std::log(m / d));
        }
      }
      for (const auto& s : win) {
        g.rmse.push_back(s.rms());
        g.points.push_back(s.n);
      }
      for (const auto& s : band) g.band_rmse.push_back(s.rms());
      g.friction_rmse = fr.rms();
      out.push_back(std::move(g));
    }
  }
  return out;
}

namespace {

// Fits the job restricted to `keep` (experiments by index); free parameters none of them depends
// on (the misfit does not move between their bounds) stay at their start values.
CrossValidationRow fit_subset(const CalibrationJob& job, const std::vector<std::size_t>& keep, unsigned threads,
                              std::vector<std::string>& held, const std::vector<std::string>& hold = {}) {
  CalibrationJob sub = job;
  sub.experiments.clear();
  for (std::size_t i : keep) sub.experiments.push_back(job.experiments[i]);
  sub.predictions.clear();
  {
    Objective probe(sub, threads);
    const std::vector<double> s = probe.start_values();
    const double f0 = probe.misfit(s);
    std::vector<FreeParameter> free;
    for (std::size_t k = 0; k < sub.free.size(); ++k) {
      if (std::find(hold.begin(), hold.end(), sub.free[k].key) != hold.end()) {
        held.push_back(sub.free[k].key);
        continue;
      }
      bool moves = false;
      for (double v : {sub.free[k].lower, sub.free[k].upper}) {
        std::vector<double> t = s;
        t[k] = v;
        const double f = probe.misfit(t);
        moves = moves || !(std::fabs(f - f0) <= 1e-12 * std::max(1.0, std::fabs(f0)));
      }
      if (moves) free.push_back(sub.free[k]);
      else held.push_back(sub.free[k].key);
    }
    sub.free = free;
  }
  CrossValidationRow row;
  const auto t0 = std::chrono::steady_clock::now();
  io::ParameterSet set = sub.start;
  if (!sub.free.empty()) {
    Objective obj(sub, threads);
    FitOptions fo;
    fo.progress = false;
    const FitResult r = fit(obj, fo);
    set = obj.parameters_at(r.theta);
  }
  row.fit_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (const auto& p : job.free) row.theta.push_back(get_parameter(set, p.key));
  // the scores are filled by the caller from this set
  row.scores = score_groups(job, set);
  return row;
}

}  // namespace

FlowCurveReport flow_curve_report(const CalibrationJob& job, const io::ParameterSet& fitted, unsigned threads,
                                  bool progress) {
  FlowCurveReport r;
  const auto& cv = job.cross_validation;
  r.windows = cv.windows.empty() ? std::vector<std::pair<double, double>>{{0.0, 0.57}} : cv.windows;
  r.bands = cv.bands;
  for (const auto& p : job.free) r.free_keys.push_back(p.key);
  r.fitted = score_groups(job, fitted, &r.points);
  for (std::size_t w = 0; w < r.windows.size(); ++w) {
    double ss = 0;
    int n = 0;
    for (const auto& g : r.fitted)
      if (g.points[w] > 0) {
        ss += g.rmse[w] * g.rmse[w] * g.points[w];
        n += g.points[w];
      }
    r.overall.push_back(n ? std::sqrt(ss / n) : kNaN);
  }
  // s/p against I = gammadot d / sqrt(p / rho_p) = 1/sqrt(p) in the DEM's units, first window
  r.I_edges = {0.0, 0.1, 0.3, 1.0, 1e9};
  std::vector<Sums> Ib(r.I_edges.size() - 1);
  for (const auto& fp : r.points) {
    if (!(fp.nu >= r.windows[0].first && fp.nu < r.windows[0].second)) continue;
    if (!(fp.p > 0 && fp.s > 0 && fp.p_m > 0 && fp.s_m > 0)) continue;
    const double I = 1.0 / std::sqrt(fp.p);
    for (std::size_t b = 0; b < Ib.size(); ++b)
      if (I >= r.I_edges[b] && I < r.I_edges[b + 1]) Ib[b].add(std::log((fp.s_m / fp.p_m) / (fp.s / fp.p)));
  }
  for (const auto& s : Ib) {
    r.I_band_rmse.push_back(s.rms());
    r.I_band_points.push_back(s.n);
  }
  if (!cv.present) return r;

  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n = job.experiments.size();
  if (cv.leave_one_group && n > 1) {
    for (std::size_t g = 0; g < n; ++g) {
      std::vector<std::size_t> keep;
      for (std::size_t i = 0; i < n; ++i)
        if (i != g) keep.push_back(i);
      std::vector<std::string> held;
      CrossValidationRow row = fit_subset(job, keep, threads, held);
      row.left_out = job.experiments[g]->name;
      row.scores.erase(std::remove_if(row.scores.begin(), row.scores.end(),
                                      [&](const GroupScore& s) { return s.name != row.left_out; }),
                       row.scores.end());
      if (progress) std::cerr << "\rcross-validation: left out group " << g + 1 << "/" << n << std::flush;
      r.leave_one_group.push_back(std::move(row));
    }
  }
  if (cv.leave_one_friction) {
    std::vector<double> levels;
    for (const auto& e : job.experiments)
      if (std::isfinite(e->data_friction()) && std::find(levels.begin(), levels.end(), e->data_friction()) == levels.end())
        levels.push_back(e->data_friction());
    if (levels.size() > 1) {
      for (double f : levels) {
        std::vector<std::size_t> keep;
        for (std::size_t i = 0; i < n; ++i)
          if (job.experiments[i]->data_friction() == f) keep.push_back(i);
        std::vector<std::string> held;
        std::vector<std::string> hold;
        for (const auto& [mu, keys] : cv.friction_held)
          if (mu == f) hold = keys;
        CrossValidationRow row = fit_subset(job, keep, threads, held, hold);
        std::ostringstream os;
        os << "fit on mu_p = " << f;
        if (!held.empty()) {
          os << " (held at start:";
          for (const auto& h : held) os << " " << h;
          os << ")";
        }
        row.left_out = os.str();
        row.scores.erase(std::remove_if(row.scores.begin(), row.scores.end(),
                                        [&](const GroupScore& s) { return s.mu_p == f; }),
                         row.scores.end());
        if (progress) std::cerr << "\rcross-validation: fit on friction " << f << "              " << std::flush;
        r.leave_one_friction.push_back(std::move(row));
      }
    }
  }
  if (progress) std::cerr << "\n";
  r.cv_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

std::string format_flow_curve_report(const FlowCurveReport& r) {
  std::ostringstream os;
  auto wname = [&](std::size_t w) { return "[" + fmt(r.windows[w].first, 3) + "," + fmt(r.windows[w].second, 3) + ")"; };
  os << "Flow curves: log-RMSE of p, s, T (RMS of ln(model/data)) per group, fitted set\n";
  os << "  group                                              ";
  for (std::size_t w = 0; w < r.windows.size(); ++w) os << " nu in " << wname(w);
  for (std::size_t b = 0; b + 1 < r.bands.size(); ++b) os << "  band " << fmt(r.bands[b], 2) << "-" << fmt(r.bands[b + 1], 2);
  os << "  s/p\n";
  for (const auto& g : r.fitted) {
    char b[64];
    std::snprintf(b, sizeof b, "  %-50s", g.name.c_str());
    os << b;
    for (double v : g.rmse) os << "  " << fmt(v) << "          ";
    for (double v : g.band_rmse) os << "  " << fmt(v) << "          ";
    os << "  " << fmt(g.friction_rmse);
    if (g.undefined) os << "  (" << g.undefined << " values undefined: V_s >= V_sd)";
    os << "\n";
  }
  os << "  overall                                           ";
  for (double v : r.overall) os << "  " << fmt(v) << "          ";
  os << "\n";
  for (std::size_t w = 0; w < r.windows.size(); ++w) {
    const int k = worst_group(r.fitted, w);
    if (k >= 0) os << "  worst fitted group in " << wname(w) << ": " << r.fitted[k].name << " " << fmt(r.fitted[k].rmse[w]) << "\n";
  }
  os << "\nMacroscopic friction s/p against the inertial number I = 1/sqrt(p) (DEM units), window " << wname(0)
     << ": RMS of ln(mu_model/mu_data)\n";
  for (std::size_t b = 0; b < r.I_band_rmse.size(); ++b)
    os << "  I in [" << fmt(r.I_edges[b], 2) << ", " << (r.I_edges[b + 1] > 1e8 ? "inf" : fmt(r.I_edges[b + 1], 2)) << "): "
       << fmt(r.I_band_rmse[b]) << " (" << r.I_band_points[b] << " points)\n";
  auto table = [&](const char* title, const std::vector<CrossValidationRow>& rows) {
    if (rows.empty()) return;
    os << "\n" << title << "\n";
    for (const auto& row : rows) {
      os << "  " << row.left_out << "  [fit " << fmt(row.fit_seconds, 2) << " s; ";
      for (std::size_t k = 0; k < r.free_keys.size(); ++k) os << (k ? ", " : "") << r.free_keys[k] << " = " << fmt(row.theta[k], 4);
      os << "]\n";
      for (const auto& g : row.scores) {
        os << "      " << g.name;
        for (std::size_t w = 0; w < g.rmse.size(); ++w) os << "  " << wname(w) << " " << fmt(g.rmse[w]);
        for (std::size_t b = 0; b < g.band_rmse.size(); ++b)
          os << "  band " << fmt(r.bands[b], 2) << "-" << fmt(r.bands[b + 1], 2) << " " << fmt(g.band_rmse[b]);
        if (g.undefined) os << "  (" << g.undefined << " undefined)";
        os << "\n";
      }
    }
    for (std::size_t w = 0; w < r.windows.size(); ++w) {
      double worst = -1;
      std::string who;
      for (const auto& row : rows)
        for (const auto& g : row.scores)
          if (std::isfinite(g.rmse[w]) && g.rmse[w] > worst) {
            worst = g.rmse[w];
            who = g.name;
          }
      if (worst >= 0) os << "  worst left-out group in " << wname(w) << ": " << who << " " << fmt(worst) << "\n";
    }
  };
  table("Leave one group out (fit on the others, score the one left out):", r.leave_one_group);
  table("Leave one friction out (fit on one friction level, score the others):", r.leave_one_friction);
  if (!r.leave_one_group.empty() || !r.leave_one_friction.empty())
    os << "  cross-validation fits took " << fmt(r.cv_seconds, 2) << " s\n";
  return os.str();
}

void write_flow_curve_report(const FlowCurveReport& r, const std::string& dir, bool plot) {
  namespace fs = std::filesystem;
  // Each file through the checked write path (temporary name, checked, renamed).
  auto put = [&](const std::string& name, const std::function<void(std::ostream&)>& body) {
    std::ostringstream f;
    f.precision(10);
    body(f);
    io::write_file((fs::path(dir) / name).string(), f.str(), io::Durability::Buffered);
  };
  auto header = [&](std::ostream& f) {
    f << "group,mu_p,eps_n";
    for (const auto& w : r.windows) f << ",rmse_" << w.first << "_" << w.second;
    for (std::size_t b = 0; b + 1 < r.bands.size(); ++b) f << ",band_" << r.bands[b] << "_" << r.bands[b + 1];
    f << ",friction_rmse,undefined\n";
  };
  auto row = [&](std::ostream& f, const GroupScore& g, const std::string& prefix) {
    f << prefix << "\"" << g.name << "\"," << g.mu_p << "," << g.eps_n;
    for (double v : g.rmse) f << "," << (std::isfinite(v) ? std::to_string(v) : "");
    for (double v : g.band_rmse) f << "," << (std::isfinite(v) ? std::to_string(v) : "");
    f << "," << (std::isfinite(g.friction_rmse) ? std::to_string(g.friction_rmse) : "") << "," << g.undefined << "\n";
  };
  put("flow_scores.csv", [&](std::ostream& f) {
    header(f);
    for (const auto& g : r.fitted) row(f, g, "");
  });
  for (const auto& [name, rows] : {std::pair{"flow_cv_groups.csv", &r.leave_one_group},
                                   std::pair{"flow_cv_friction.csv", &r.leave_one_friction}}) {
    if (rows->empty()) continue;
    put(name, [&, rows = rows](std::ostream& f) {
      f << "fit,";
      header(f);
      for (const auto& rw : *rows)
        for (const auto& g : rw.scores) row(f, g, "\"" + rw.left_out + "\",");
    });
  }
  put("flow_points.csv", [&](std::ostream& f) {
    f << "group,nu,p,s,T,p_model,s_model,T_model\n";
    auto v = [](double x) { return std::isfinite(x) ? std::to_string(x) : std::string(); };
    for (const auto& p : r.points)
      f << "\"" << p.group << "\"," << p.nu << "," << v(p.p) << "," << v(p.s) << "," << v(p.T) << "," << v(p.p_m) << ","
        << v(p.s_m) << "," << v(p.T_m) << "\n";
  });
  put("flow_report.txt", [&](std::ostream& f) { f << format_flow_curve_report(r); });
  if (!plot) return;
  const std::string script = io::script_path("plot_flow_curves.py");
  const std::string py = python_with_matplotlib();
  if (py.empty() || script.empty()) {
    std::cerr << "calibrate: flow-curve PNGs skipped ("
              << (py.empty() ? "no python3 with matplotlib" : "scripts/plot_flow_curves.py not found") << ")\n";
    return;
  }
  const std::string cmd = py + " '" + script + "' '" + dir + "' > /dev/null 2>&1";
  if (std::system(cmd.c_str()) != 0) std::cerr << "calibrate: the flow-curve plot script failed; flow_points.csv holds the curves\n";
}

}  // namespace granflow::calibration
