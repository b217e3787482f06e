// granflow.calibrate: a calibration job run as `granflow calibrate JOB [--out DIR]` runs it
// (load_job, Objective, fit, and with `out` the same output folder); results as a dict.
#include <algorithm>

#include <granflow/calibration/fit.hpp>
#include <granflow/calibration/job.hpp>
#include <granflow/calibration/test_report.hpp>

#include "common.hpp"
#include <granflow/io/run_folder.hpp>

namespace granflow::python {

namespace {

using namespace calibration;

std::string label(const FreeParameter& p) { return p.experiment.empty() ? p.key : p.key + "@" + p.experiment; }

py::array_t<double> matrix(const Eigen::MatrixXd& m) {
  py::array_t<double> a({static_cast<py::ssize_t>(m.rows()), static_cast<py::ssize_t>(m.cols())});
  for (Eigen::Index i = 0; i < m.rows(); ++i)
    for (Eigen::Index j = 0; j < m.cols(); ++j) a.mutable_at(i, j) = m(i, j);
  return a;
}

py::dict by_free(const CalibrationJob& job, const std::vector<double>& v) {
  py::dict d;
  for (std::size_t i = 0; i < job.free.size() && i < v.size(); ++i) d[py::str(label(job.free[i]))] = v[i];
  return d;
}

py::list curves_list(const Objective& obj, const Evaluation& ev) {
  py::list l;
  for (std::size_t c = 0; c < obj.curves().size() && c < ev.curves.size(); ++c) {
    const Curve& cv = obj.curve(c);
    const CurveEvaluation& ce = ev.curves[c];
    py::dict d;
    d["label"] = cv.label();
    d["experiment"] = cv.experiment;
    d["data_column"] = cv.data_column;
    d["model_output"] = cv.model_output;
    d["abscissa"] = cv.abscissa;
    d["x"] = to_array(cv.x);
    d["y"] = to_array(cv.y);
    d["model"] = to_array(ce.model);
    d["rmse"] = ce.rmse;
    d["r2"] = ce.r2;
    d["misfit"] = ce.misfit;
    d["failure"] = ce.failure;
    l.append(d);
  }
  return l;
}

py::dict calibrate(py::handle job_path, py::handle out_dir, bool force, unsigned threads, bool evaluate, bool plot,
                   bool progress) {
  const std::string path = path_arg(job_path, "job");
  const CalibrationJob job = load_job(path);
  const std::string out = out_dir.is_none() ? "" : path_arg(out_dir, "out");
  std::unique_ptr<io::StagedFolder> folder;  // locked for the whole fit, as the CLI does
  if (!out.empty()) folder = std::make_unique<io::StagedFolder>(out, force);
  Objective obj(job, threads);
  FitOptions fo;
  fo.progress = progress;
  fo.evaluate_only = evaluate;
  FitResult r;
  std::string test_report;
  {
    py::gil_scoped_release nogil;
    r = fit(obj, fo);
    const bool per_test = !job.predictions.empty() || std::any_of(job.free.begin(), job.free.end(), [](const auto& p) {
                            return !p.experiment.empty();
                          });
    if (per_test) {  // held-out tests or per-test e0: the per-test report, as the CLI
      const TestReport tr = evaluate_tests(job, obj.parameters_at(r.theta));
      test_report = format_test_report(tr);
      if (folder) write_test_report(tr, obj.parameters_at(r.theta), folder->staging(), plot);
    }
    if (folder) write_outputs(obj, r, *folder, plot);
  }
  py::dict d;
  d["job"] = job.name;
  d["file"] = job.file;
  d["fitted"] = r.fitted;
  d["fitted_toml"] = io::format_parameter_set(r.fitted);
  d["parameters"] = by_free(job, r.theta);
  d["start"] = by_free(job, r.start);
  d["misfit_start"] = r.at_start.misfit;
  d["misfit"] = r.at_best.misfit;
  d["evaluations"] = r.evaluations;
  d["global_evaluations"] = r.global_evaluations;
  d["local_evaluations"] = r.local_evaluations;
  d["seconds"] = r.seconds;
  d["threads"] = r.threads;
  d["stop_reason"] = r.stop_reason;
  py::dict bound;
  for (std::size_t i = 0; i < job.free.size() && i < r.on_bound.size(); ++i) bound[py::str(label(job.free[i]))] = r.on_bound[i];
  d["on_bound"] = bound;
  d["rel_sd"] = by_free(job, r.identifiability.rel_sd);
  d["correlation"] = matrix(r.identifiability.correlation);
  d["sensitivity"] = matrix(r.identifiability.sensitivity);
  d["curves"] = curves_list(obj, r.at_best);
  d["report"] = format_report(obj, r);
  d["test_report"] = test_report.empty() ? py::object(py::none()) : py::object(py::str(test_report));
  if (r.ensemble) {
    const EnsembleReport& e = *r.ensemble;
    py::dict en;
    en["best"] = by_free(job, e.best);
    en["best_misfit"] = e.best_misfit;
    en["fitted_misfit"] = e.fitted_misfit;
    en["polish"] = e.polish;
    py::array_t<double> post({static_cast<py::ssize_t>(e.result.posterior.size()), static_cast<py::ssize_t>(job.free.size())});
    for (std::size_t i = 0; i < e.result.posterior.size(); ++i)
      for (std::size_t j = 0; j < job.free.size(); ++j) post.mutable_at(i, j) = e.result.posterior[i][j];
    en["posterior"] = post;
    py::dict summary;
    for (std::size_t j = 0; j < job.free.size() && j < e.result.summary.size(); ++j) {
      const ParameterSummary& s = e.result.summary[j];
      summary[py::str(label(job.free[j]))] =
          py::dict(py::arg("mean") = s.mean, py::arg("median") = s.median, py::arg("q05") = s.q05,
                   py::arg("q95") = s.q95, py::arg("sd") = s.sd);
    }
    en["summary"] = summary;
    d["ensemble"] = en;
  } else {
    d["ensemble"] = py::none();
  }
  d["out"] = out.empty() ? py::object(py::none()) : py::object(py::str(out));
  return d;
}

}  // namespace

void register_calibrate(py::module_& m) {
  m.def("calibrate", &calibrate, py::arg("job"), py::arg("out") = py::none(), py::arg("force") = false,
        py::arg("threads") = 0u, py::arg("evaluate") = false, py::arg("plot") = false, py::arg("progress") = false,
        R"(Runs a calibration job (data/calibration/*.toml) as `granflow calibrate JOB` does.

out       also write the CLI's output folder there (fitted TOML, reports, CSVs; fit.png with plot=True);
          an existing folder needs force=True and must be one granflow wrote
threads   threads of the objective (0: all cores)
evaluate  only evaluate the starting set (no fit), as --evaluate

Returns a dict: fitted (ParameterSet), fitted_toml, parameters and start (free key -> value),
misfit, misfit_start, evaluations, seconds, stop_reason, on_bound, rel_sd, correlation,
sensitivity, curves (per curve: label, x, y, model, rmse, r2, misfit, failure), report (the
text the CLI prints), test_report (held-out tests, or None), ensemble (ES-MDA jobs: best,
posterior (members x free), summary; else None) and out.)");
}

}  // namespace granflow::python
