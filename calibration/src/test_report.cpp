// Per-test report (test_report.hpp): each fitted and held-out experiment with the fitted set.
#include "granflow/calibration/test_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "granflow/calibration/experiment.hpp"
#include "granflow/calibration/fit.hpp"
#include <granflow/io/output.hpp>
#include <granflow/io/share.hpp>
#include "common.hpp"

namespace granflow::calibration {

namespace fs = std::filesystem;

namespace {

bool is_q(const Curve& c) { return c.model_output == "q" || c.model_output == "q_axial"; }
bool is_p(const Curve& c) { return c.model_output == "p" || c.model_output == "p_f"; }

// RMS and max of |model - data| over the points where the model exists; NaN if none.
std::pair<double, double> errors(const std::vector<double>& data, const std::vector<double>& model) {
  double ss = 0, mx = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < data.size(); ++i)
    if (std::isfinite(model[i])) {
      const double d = model[i] - data[i];
      ss += d * d;
      mx = std::max(mx, std::fabs(d));
      ++n;
    }
  return n ? std::make_pair(std::sqrt(ss / n), mx) : std::make_pair(kNaN, kNaN);
}

double min_ratio(const std::vector<double>& p) {
  double mn = kNaN, first = kNaN;
  for (double v : p)
    if (std::isfinite(v)) {
      if (!std::isfinite(first)) first = v;
      mn = std::isfinite(mn) ? std::min(mn, v) : v;
    }
  return mn / first;
}

TestMetrics metrics(const Experiment& e, const std::string& role, const io::ParameterSet& set, TestReport& out) {
  TestMetrics m;
  m.test = e.base_name.empty() ? e.name : e.base_name;
  m.role = role;
  m.path = e.loading_path();
  const auto fitted_e0 = set.test_e0.find(e.base_name);
  m.e0_fitted = fitted_e0 != set.test_e0.end();
  m.e0 = m.e0_fitted ? fitted_e0->second : e.initial_void_ratio();
  const Prediction pr = e.predict(set);
  if (!pr.ok) {
    m.failure = pr.error;
    return m;
  }
  const Curve *q = nullptr, *p = nullptr, *ec = nullptr, *ev = nullptr;
  const std::vector<double> *mq = nullptr, *mp = nullptr, *me = nullptr, *mv = nullptr;
  for (std::size_t c = 0; c < e.curves.size(); ++c) {
    const Curve& cv = e.curves[c];
    const std::vector<double>& mod = pr.values[c];
    if (std::any_of(mod.begin(), mod.end(), [](double v) { return !std::isfinite(v); }) && m.failure.empty())
      m.failure = "model undefined at some points of " + cv.data_column;
    if (is_q(cv)) q = &cv, mq = &mod;
    if (is_p(cv)) p = &cv, mp = &mod;
    if (cv.model_output == "e") ec = &cv, me = &mod;
    if (cv.model_output == "eps_v") ev = &cv, mv = &mod;
    out.curves.push_back({m.test, role, cv.data_column, cv.model_output, cv.abscissa, cv.x, cv.y, mod});
  }
  if (q) {
    m.peak_q = 0;
    for (double v : q->y) m.peak_q = std::max(m.peak_q, std::fabs(v));
    m.rms_q = errors(q->y, *mq).first / m.peak_q;
    if (p) m.rms_p = errors(p->y, *mp).first / m.peak_q;
  }
  // void ratio and volumetric strain determine each other: e = (1 + e0) exp(-eps_v) - 1
  auto to_e = [&](const std::vector<double>& v) {
    std::vector<double> r(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) r[i] = (1 + m.e0) * std::exp(-v[i]) - 1;
    return r;
  };
  auto to_eps_v = [&](const std::vector<double>& v) {
    std::vector<double> r(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) r[i] = -std::log((1 + v[i]) / (1 + m.e0));
    return r;
  };
  if (ec) std::tie(m.e_rms, m.e_max) = errors(ec->y, *me);
  if (ev) std::tie(m.eps_v_rms, m.eps_v_max) = errors(ev->y, *mv);
  if (ev && !ec) std::tie(m.e_rms, m.e_max) = errors(to_e(ev->y), to_e(*mv));
  if (ec && !ev) std::tie(m.eps_v_rms, m.eps_v_max) = errors(to_eps_v(ec->y), to_eps_v(*me));
  if (p && m.path.rfind("undrained", 0) == 0) {
    m.min_p_data = min_ratio(p->y);
    m.min_p_model = min_ratio(*mp);
  }
  return m;
}

std::string report_num(double v, int prec = 3) {
  if (!std::isfinite(v)) return "-";
  std::ostringstream os;
  os << std::setprecision(prec) << v;
  return os.str();
}

std::string cell(double v) {
  if (!std::isfinite(v)) return "";
  std::ostringstream os;
  os << std::setprecision(10) << v;
  return os.str();
}

std::string quote(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : c == '\n' ? std::string(" ") : std::string(1, c);
  return q + "\"";
}

}  // namespace

TestReport evaluate_tests(const CalibrationJob& job, const io::ParameterSet& fitted) {
  TestReport r;
  for (const auto& e : job.experiments)
    if (e->kind == "element") r.tests.push_back(metrics(*e, "fit", fitted, r));
  for (const auto& e : job.predictions)
    if (e->kind == "element") r.tests.push_back(metrics(*e, "predict", fitted, r));
  return r;
}

std::string format_test_report(const TestReport& report) {
  std::ostringstream os;
  os << "\nper test (q, p' RMS relative to the test's peak q; e, eps_v: RMS / max |model - data|; "
        "undrained: min p'/p'0 data / model)\n";
  os << std::left << std::setw(10) << "test" << std::setw(8) << "role" << std::setw(20) << "path" << std::right
     << std::setw(9) << "e0" << std::setw(9) << "peak q" << std::setw(8) << "q" << std::setw(8) << "p'"
     << std::setw(16) << "e" << std::setw(18) << "eps_v" << std::setw(15) << "min p'/p'0" << "  goals\n";
  int held = 0, met = 0;
  for (const TestMetrics& t : report.tests) {
    // The goals: held out: q and p' RMS <= 10 % of peak q; oedometer e within 0.005;
    // every undrained test: min p'/p'0 within 0.05.
    std::string goals;
    bool ok = true;
    if (t.role == "predict" && std::isfinite(t.rms_q)) ok = ok && t.rms_q <= 0.10 && !(t.rms_p > 0.10);
    if (t.role == "predict" && t.path == "oedometric") ok = ok && t.e_max <= 0.005;
    if (std::isfinite(t.min_p_data)) ok = ok && std::fabs(t.min_p_model - t.min_p_data) <= 0.05;
    if (!t.failure.empty()) ok = false;
    if (t.role == "predict") {
      ++held;
      met += ok;
    }
    goals = ok ? "met" : "MISSED";
    if (t.role == "fit" && !std::isfinite(t.min_p_data)) goals = "(fitted)";
    os << std::left << std::setw(10) << t.test << std::setw(8) << t.role << std::setw(20) << t.path << std::right
       << std::setw(9) << (report_num(t.e0, 4) + (t.e0_fitted ? "*" : "")) << std::setw(9)
       << (std::isfinite(t.peak_q) ? report_num(t.peak_q / 1e3, 4) + "k" : "-") << std::setw(8) << report_num(t.rms_q, 2)
       << std::setw(8) << report_num(t.rms_p, 2) << std::setw(16) << (report_num(t.e_rms, 2) + " / " + report_num(t.e_max, 2))
       << std::setw(18) << (report_num(t.eps_v_rms, 2) + " / " + report_num(t.eps_v_max, 2)) << std::setw(15)
       << (std::isfinite(t.min_p_data) ? report_num(t.min_p_data, 2) + " / " + report_num(t.min_p_model, 2) : "-") << "  "
       << goals << (t.failure.empty() ? "" : " (" + t.failure.substr(0, 100) + ")") << "\n";
  }
  os << "(* e0 fitted per test.) held-out tests meeting every goal: " << met << " of " << held << "\n";
  return os.str();
}

void write_test_report(const TestReport& report, const io::ParameterSet& fitted, const std::string& dir, bool plot) {
  std::ostringstream tc;
  tc << "test,role,path,e0,e0_fitted,peak_q,rms_q_rel,rms_p_rel,e_rms,e_max,eps_v_rms,eps_v_max,min_p_ratio_data,"
        "min_p_ratio_model,failure\n";
  for (const TestMetrics& t : report.tests)
    tc << io::csv_field(t.test) << "," << t.role << "," << t.path << "," << cell(t.e0) << "," << (t.e0_fitted ? 1 : 0) << ","
       << cell(t.peak_q) << "," << cell(t.rms_q) << "," << cell(t.rms_p) << "," << cell(t.e_rms) << ","
       << cell(t.e_max) << "," << cell(t.eps_v_rms) << "," << cell(t.eps_v_max) << "," << cell(t.min_p_data) << ","
       << cell(t.min_p_model) << "," << quote(t.failure) << "\n";
  std::ostringstream cc;
  cc << "test,role,data_column,model_output,abscissa,x,data,model\n";
  for (const TestCurve& c : report.curves)
    for (std::size_t i = 0; i < c.x.size(); ++i)
      cc << io::csv_field(c.test) << "," << c.role << "," << io::csv_field(c.data_column) << "," << c.model_output << "," << c.abscissa << ","
         << cell(c.x[i]) << "," << cell(c.data[i]) << "," << cell(c.model[i]) << "\n";
  const fs::path d(dir);
  io::write_file((d / "tests.csv").string(), tc.str(), io::Durability::Buffered);
  io::write_file((d / "test_curves.csv").string(), cc.str(), io::Durability::Buffered);
  io::write_file((d / "tests.txt").string(), format_test_report(report), io::Durability::Buffered);
  if (!plot || !fitted.frictional) return;
  const std::string script = io::script_path("plot_sand_tests.py");
  const std::string py = python_with_matplotlib();
  if (py.empty() || script.empty()) {
    std::cerr << "calibrate: the per-test PNGs skipped ("
              << (py.empty() ? "no python3 with matplotlib" : "scripts/plot_sand_tests.py not found") << ")\n";
    return;
  }
  const auto& f = *fitted.frictional;
  std::ostringstream cmd;
  cmd << std::setprecision(12) << py << " '" << script << "' '" << dir << "' --phi-c " << f.phi_c * 180.0 / M_PI
      << " --csl " << f.e_ref << "," << f.lambda_c << "," << f.xi << "," << f.p_at;
  if (std::system(cmd.str().c_str()) != 0) std::cerr << "calibrate: the per-test plot script failed; test_curves.csv holds the curves\n";
}

}  // namespace granflow::calibration
