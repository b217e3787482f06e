// The source's element tests as definitions, the DEM comparison, figures and the benchmark.
#include "granflow/elementtest/paper.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include <granflow/constitutive.hpp>

#include <granflow/io/csv_table.hpp>
#include <granflow/io/output.hpp>

namespace granflow::elementtest::paper {

ElementTest fig4_test(double e0, double gamma_end) {
  ElementTest t;
  t.name = "fig4_e" + std::to_string(e0).substr(0, 4);
  t.model = ModelChoice::Frictional;
  t.programme.kind = ProgrammeKind::Constant;
  t.programme.rate = 1.0;
  t.programme.duration = gamma_end;
  t.initial.e0 = e0;
  t.initial.sigma_v0 = 100e3;
  t.initial.k0 = -1.0;  // Jaky: 1 - sin(phi_c) = 0.5 (from 100 kPa isotropic e0 = 0.90 liquefies, MODEL 6.4)
  t.output.points = 301;
  return t;
}

ElementTest fig5_test(double e0) {
  ElementTest t;
  t.name = "fig5_e" + std::to_string(e0).substr(0, 4);
  t.model = ModelChoice::Collisional;
  t.programme.kind = ProgrammeKind::Acceleration;
  t.programme.rate = 0.0;
  t.programme.acceleration = 50.0;
  t.programme.duration = 3.0;
  t.initial.e0 = e0;
  t.initial.T0 = 1e-15;
  t.output.points = 301;
  return t;
}

ElementTest fig6_test(double e0) {
  ElementTest t;
  t.name = "fig6_e" + std::to_string(e0).substr(0, 4);
  t.model = ModelChoice::PhaseTransition;
  t.programme.kind = ProgrammeKind::Acceleration;
  t.programme.rate = 10.0;
  t.programme.hold = 0.5;
  t.programme.acceleration = 50.0;
  t.programme.duration = 20.0;
  t.initial.e0 = e0;
  t.initial.sigma_v0 = 500.0;
  t.output.points = 391;
  return t;
}

ElementTest fig6_sweep(double e0) {
  ElementTest t = fig6_test(e0);
  t.name = "fig6_sweep_e" + std::to_string(e0).substr(0, 4);
  t.programme = RateProgramme{};
  t.programme.kind = ProgrammeKind::Sweep;
  for (int i = 0; i <= 24; ++i) t.programme.sweep_rates.push_back(1e-4 * std::pow(10.0, i / 4.0));
  t.programme.sweep_strain = 5.0;
  return t;
}

ElementTest fig7_fixed_strain_sweep(double e0, double gamma_end) {
  ElementTest t = fig6_sweep(e0);
  t.name = "fig7_fixed_strain";
  t.programme.sweep_strain = gamma_end;
  t.programme.sweep_rates.clear();  // 1e-4 .. 1e4 1/s: the collisional part needs > 100 1/s here
  for (int i = 0; i <= 32; ++i) t.programme.sweep_rates.push_back(1e-4 * std::pow(10.0, i / 4.0));
  return t;
}

}  // namespace granflow::elementtest::paper

namespace granflow::elementtest::paper {

namespace {

double wall_now() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

std::string fmt(double v) {
  std::ostringstream os;
  os << std::setprecision(4) << std::fixed << v;
  return os.str();
}

// Long-format CSV: a leading label column, then the result columns.
void write_long(const std::string& path, const std::string& label,
                const std::vector<std::pair<double, ResultTable>>& runs) {
  io::AtomicFile file(path);
  std::ostream& os = file.stream();
  os << std::setprecision(9);
  os << label;
  for (const auto& n : result_column_names()) os << "," << n;
  os << "\n";
  for (const auto& [v, r] : runs)
    for (std::size_t i = 0; i < r.rows(); ++i) {
      os << v;
      for (const auto& c : r.columns) os << "," << c[i] + 0.0;
      os << "\n";
    }
  file.commit();
}

}  // namespace

std::vector<DemComparison> dem_comparison(const std::string& csv_path, const io::ParameterSet& base) {
  if (!base.has_collisional()) throw io::InputError(io::where(base.file) + "the DEM comparison needs [collisional]");
  const io::CsvColumns t = io::read_csv_columns(
      csv_path, {"contact_friction_mu", "restitution_e", "solid_fraction_nu", "p_dimless", "s_dimless", "T_dimless"});
  std::vector<DemComparison> out;
  for (std::size_t i = 0; i < t.rows(); ++i) {
    const double mu = t.column("contact_friction_mu")[i], en = t.column("restitution_e")[i];
    if (out.empty() || out.back().mu_p != mu || out.back().eps_n != en) {
      out.push_back({});
      out.back().mu_p = mu;
      out.back().eps_n = en;
    }
    DemComparison& c = out.back();
    CollisionalParams<double> cp = *base.collisional;
    cp.rho_p = 1;
    cp.d = 1;
    cp.eps_n = en;
    cp.mu_p = mu;
    const double nu = t.column("solid_fraction_nu")[i];
    c.nu.push_back(nu);
    c.p_dem.push_back(t.column("p_dimless")[i]);
    c.s_dem.push_back(t.column("s_dimless")[i]);
    c.T_dem.push_back(t.column("T_dimless")[i]);
    const bool valid = nu < cp.V_sd - cp.vs_gap && effective_restitution(cp) > -1;
    if (valid) {
      const KineticCoefficients<double> kc = kinetic_coefficients(cp, nu);
      const SteadyShear<double> ss = steady_simple_shear(cp, kc, 1.0);
      c.p_model.push_back(ss.p);
      c.s_model.push_back(ss.tau);
      c.T_model.push_back(ss.T);
    } else {
      c.p_model.push_back(std::nan(""));
      c.s_model.push_back(std::nan(""));
      c.T_model.push_back(std::nan(""));
    }
  }
  for (DemComparison& c : out) {
    double sp = 0, ss = 0, sT = 0;
    int n = 0;
    for (std::size_t i = 0; i < c.nu.size(); ++i) {
      if (!std::isfinite(c.p_model[i]) || !(c.p_model[i] > 0) || !(c.p_dem[i] > 0)) continue;
      sp += std::pow(std::log(c.p_model[i] / c.p_dem[i]), 2);
      ss += std::pow(std::log(c.s_model[i] / c.s_dem[i]), 2);
      sT += std::pow(std::log(c.T_model[i] / c.T_dem[i]), 2);
      ++n;
    }
    c.points_used = n;
    if (n > 0) {
      c.rms_log_p = std::sqrt(sp / n);
      c.rms_log_s = std::sqrt(ss / n);
      c.rms_log_T = std::sqrt(sT / n);
    }
  }
  return out;
}

std::vector<std::string> write_figures(const std::string& dir, std::ostream& log) {
  namespace fs = std::filesystem;
  std::vector<std::string> files;
  const io::ParameterSet fric = io::load_parameter_set("frictional_element");
  const io::ParameterSet coll = io::load_parameter_set("collisional_element");
  const io::ParameterSet full = io::load_parameter_set("element_test");
  io::make_folder(dir);  // once the sets are found: a refused run leaves no empty folder
  const double w0 = wall_now();
  auto run_all = [&](const std::string& name, const std::string& label, const io::ParameterSet& set,
                     const std::vector<double>& values, auto make) {
    std::vector<std::pair<double, ResultTable>> runs;
    for (double v : values) {
      const double w = wall_now();
      ResultTable r = run_element_test(make(v), set);
      log << "  " << name << " " << label << " = " << v << ": " << std::fixed << std::setprecision(2)
          << 1e3 * (wall_now() - w) << " ms wall, " << r.stats.rhs_evals << " RHS evaluations, " << r.stats.steps
          << " steps" << (r.stats.tension_cutoff ? (r.stats.cutoff_time >= 0 ? ", p_f -> 0 at t = " + std::to_string(r.stats.cutoff_time) + " s" : std::string(", p_f -> 0")) : std::string())
          << "\n";
      log.unsetf(std::ios::floatfield);
      log << std::setprecision(6);
      runs.emplace_back(v, std::move(r));
    }
    const std::string path = (fs::path(dir) / (name + ".csv")).string();
    write_long(path, label, runs);
    files.push_back(path);
  };
  run_all("fig4", "e0", fric, {0.80, 0.85, 0.90, 0.95}, [](double e) { return fig4_test(e); });
  run_all("fig5", "e0", coll, {0.80, 0.85, 0.90, 0.95}, [](double e) { return fig5_test(e); });
  run_all("fig6", "e0", full, {0.99, 1.02, 1.05}, [](double e) { return fig6_test(e); });
  run_all("fig6_sweep", "e0", full, {0.99, 1.02, 1.05}, [](double e) { return fig6_sweep(e); });
  run_all("fig7", "e0", full, {1.10}, [](double e) { return fig6_test(e); });
  run_all("fig7_fixed_strain", "gamma_end", full, {0.001, 0.002, 0.003},
          [](double g) { return fig7_fixed_strain_sweep(1.10, g); });
  log << "  all element-test figures: " << std::fixed << std::setprecision(1) << 1e3 * (wall_now() - w0)
      << " ms wall\n";
  log.unsetf(std::ios::floatfield);
  log << std::setprecision(6);

  // DEM comparison (collisional part, Table 2 set for V_sd = 0.6, V_m = 0.4).
  const std::string dem = io::data_directory() + "/dem_steady_shear/steady_simple_shear_mu0_mu05.csv";
  const std::vector<DemComparison> cmp = dem_comparison(dem, coll);
  {
    const std::string path = (fs::path(dir) / "dem_comparison.csv").string();
    io::AtomicFile file(path);
    std::ostream& os = file.stream();
    os << std::setprecision(8) << "mu_p,eps_n,nu,p_dem,p_model,s_dem,s_model,T_dem,T_model\n";
    for (const auto& c : cmp)
      for (std::size_t i = 0; i < c.nu.size(); ++i)
        os << c.mu_p << "," << c.eps_n << "," << c.nu[i] << "," << c.p_dem[i] << "," << c.p_model[i] << ","
           << c.s_dem[i] << "," << c.s_model[i] << "," << c.T_dem[i] << "," << c.T_model[i] << "\n";
    file.commit();
    files.push_back(path);
    const std::string epath = (fs::path(dir) / "dem_errors.csv").string();
    io::AtomicFile efile(epath);
    std::ostream& es = efile.stream();
    es << "mu_p,eps_n,alpha_effective,points,rms_log_p,rms_log_s,rms_log_T\n";
    log << "  DEM comparison (RMS of ln(model/DEM) over solid fractions below V_sd - vs_gap = "
        << coll.collisional->V_sd - coll.collisional->vs_gap << "):\n";
    for (const auto& c : cmp) {
      CollisionalParams<double> cp = *coll.collisional;
      cp.eps_n = c.eps_n;
      cp.mu_p = c.mu_p;
      es << c.mu_p << "," << c.eps_n << "," << effective_restitution(cp) << "," << c.points_used << ","
         << c.rms_log_p << "," << c.rms_log_s << "," << c.rms_log_T << "\n";
      log << "    mu_p = " << c.mu_p << ", e_n = " << c.eps_n << ": p " << fmt(c.rms_log_p) << ", s "
          << fmt(c.rms_log_s) << ", T " << fmt(c.rms_log_T) << " (" << c.points_used << " points)\n";
    }
    efile.commit();
    files.push_back(epath);
  }
  return files;
}

namespace {

// Max relative error of sigma_n and tau against a reference (same output times).
double curve_error(const ResultTable& r, const ResultTable& ref) {
  double err = 0;
  for (const char* name : {"sigma_n", "tau"}) {
    const auto& a = r.column(name);
    const auto& b = ref.column(name);
    double scale = 0;
    for (double v : b) scale = std::max(scale, std::fabs(v));
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i)
      err = std::max(err, std::fabs(a[i] - b[i]) / scale);
  }
  return err;
}

}  // namespace

void bench_element(const std::string& dir, bool quick, std::ostream& log) {
  namespace fs = std::filesystem;
  io::make_folder(dir);
  struct Case {
    std::string name;
    ElementTest test;
    io::ParameterSet set;
  };
  std::vector<Case> cases = {{"fig4_e0.80", fig4_test(0.80), io::load_parameter_set("frictional_element")},
                             {"fig6_e0.99", fig6_test(0.99), io::load_parameter_set("element_test")}};
  const std::string path = (fs::path(dir) / "bench_element.csv").string();
  io::AtomicFile file(path);
  std::ostream& os = file.stream();
  os << std::setprecision(6) << "case,solver,setting,error,cpu_s,rhs_evals,steps\n";
  const long max_steps = quick ? 200000 : 4000000;
  for (Case& c : cases) {
    c.test.output.points = 101;
    ElementTest ref = c.test;
    ref.solver.rtol = 1e-12;
    ref.solver.atol = 1e-15;
    const ResultTable R = run_element_test(ref, c.set);
    log << c.name << ": reference CVODE rtol 1e-12: " << R.stats.steps << " steps, " << 1e3 * R.stats.cpu_seconds
        << " ms\n";
    log << "  solver        setting    error       CPU [ms]   RHS/updates\n";
    std::vector<double> rtols = quick ? std::vector<double>{1e-2, 1e-4, 1e-6}
                                      : std::vector<double>{1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10};
    for (double rt : rtols) {
      ElementTest t = c.test;
      t.solver.rtol = rt;
      t.solver.atol = rt * 1e-3;
      // best of 3 for a stable timing
      ResultTable r;
      try {
        r = run_element_test(t, c.set);
      } catch (const std::runtime_error& e) {
        log << "  cvode      rtol " << std::setw(7) << rt << "  FAILED: " << e.what() << "\n";
        os << c.name << ",cvode," << rt << ",nan,nan,nan,nan\n";
        continue;
      }
      double cpu = r.stats.cpu_seconds;
      for (int k = 0; k < 2; ++k) cpu = std::min(cpu, run_element_test(t, c.set).stats.cpu_seconds);
      const double e = curve_error(r, R);
      os << c.name << ",cvode," << rt << "," << e << "," << cpu << "," << r.stats.rhs_evals << "," << r.stats.steps << "\n";
      log << "  cvode      rtol " << std::setw(7) << rt << "  " << std::setw(10) << e << "  " << std::setw(10)
          << 1e3 * cpu << "  " << r.stats.rhs_evals << "\n";
    }
    std::vector<double> dts = quick ? std::vector<double>{1e-2, 1e-3} : std::vector<double>{1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7};
    for (double dt : dts) {
      ElementTest t = c.test;
      t.solver.kind = SolverKind::Incremental;
      t.solver.dt = dt;
      const double steps = t.programme.duration / dt;
      if (steps > max_steps) {
        log << "  incremental dt " << std::setw(7) << dt << "  skipped: " << steps << " steps > cap " << max_steps << "\n";
        os << c.name << ",incremental," << dt << ",nan,nan,nan," << steps << "\n";
        continue;
      }
      const ResultTable r = run_element_test(t, c.set);
      const double e = curve_error(r, R);
      os << c.name << ",incremental," << dt << "," << e << "," << r.stats.cpu_seconds << "," << r.stats.rhs_evals << ","
         << r.stats.steps << "\n";
      log << "  incremental dt " << std::setw(7) << dt << "  " << std::setw(10) << e << "  " << std::setw(10)
          << 1e3 * r.stats.cpu_seconds << "  " << r.stats.rhs_evals << "\n";
    }
  }
  file.commit();
  log << "wrote " << path << "\n";
}

}  // namespace granflow::elementtest::paper
