// granflow calibrate: fit a parameter set to measured curves (issue 4; docs/calibration.md), by
// NLopt or by the ensemble method (docs/calibration_ensemble.md; the only one without NLopt).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

#include <granflow/calibration/experiment.hpp>
#include <granflow/calibration/fit.hpp>
#include <granflow/calibration/flow_curves.hpp>
#include <granflow/calibration/job.hpp>
#include <granflow/calibration/synthesize.hpp>
#include <granflow/calibration/test_report.hpp>

#include "commands.hpp"
#include <granflow/io/input_error.hpp>
#include <granflow/io/parameter_set.hpp>
#include <granflow/io/run_folder.hpp>
#include <granflow/mpm/ranks.hpp>

namespace granflow::cli {

namespace {

namespace fs = std::filesystem;

struct CalibrateOptions {
  std::string job;
  std::string out;
  bool force = false;
  unsigned threads = 0;
  bool no_plot = false;
  bool quiet = false;
  bool bench = false;
  bool evaluate = false;
  bool no_cv = false;
  std::string synthesize;  // truth parameter set
  double noise = 0.02;
  unsigned long seed = 1;
  long stride = 1;
};

void run_calibrate(const CalibrateOptions& o) {
  using namespace calibration;
  if (!o.synthesize.empty()) {
    SynthesisOptions s;
    s.truth = io::load_parameter_set(o.synthesize);
    s.noise = o.noise;
    s.seed = o.seed;
    s.stride = o.stride;
    s.force = o.force;
    synthesize_job_data(o.job, s);
    end_scene_batches();
    std::cerr << "calibrate: wrote the data files of the element experiments of " << o.job << " from "
              << s.truth.file << " (noise " << o.noise << ", seed " << o.seed << ")\n";
    return;
  }
  const CalibrationJob job = load_job(o.job);
  const std::string out = o.out.empty() ? fs::path(o.job).stem().string() + "_fit" : o.out;
  // locked for the whole fit; an existing folder is refused unless --force and granflow's
  io::StagedFolder folder(out, o.force);
  Objective obj(job, o.threads);
  FitOptions fo;
  fo.progress = !o.quiet;
  fo.evaluate_only = o.evaluate;
  // the ES-MDA state beside the folder, as its lock: a run stopped part way continues from it
  const std::string state = out + ".esmda-state";
  if (job.algorithm.method == "ensemble" && !o.evaluate) fo.state_file = state;
  if (mpm::ranks().size() > 1)
    std::fprintf(stderr, "calibrate: %d MPI ranks: the members of each mpm_scene batch are split over them\n",
                 mpm::ranks().size());
  const FitResult r = fit(obj, fo);
  end_scene_batches();  // the other ranks are done
  if (!o.quiet) std::cout << format_report(obj, r);
  const bool per_test = !job.predictions.empty() ||
                        std::any_of(job.free.begin(), job.free.end(), [](const auto& p) { return !p.experiment.empty(); });
  if (per_test) {  // held-out tests or per-test e0: the per-test report (tests.csv, PNGs) beside the fit's
    const TestReport tr = evaluate_tests(job, obj.parameters_at(r.theta));
    if (!o.quiet) std::cout << format_test_report(tr);
    write_test_report(tr, obj.parameters_at(r.theta), folder.staging(), !o.no_plot);
  }
  if (job.cross_validation.present) {  // flow curves across groups: scores, LOGO / LOFO tables, PNGs
    CalibrationJob cvjob = job;
    if (o.no_cv || o.evaluate) cvjob.cross_validation.leave_one_group = cvjob.cross_validation.leave_one_friction = false;
    const FlowCurveReport fr = flow_curve_report(cvjob, obj.parameters_at(r.theta), o.threads, !o.quiet);
    if (!o.quiet) std::cout << "\n" << format_flow_curve_report(fr);
    write_flow_curve_report(fr, folder.staging(), !o.no_plot);
  }
  // the per-parameter verdict last, where the reader looks (also at the end of report.txt's fit part)
  if (!o.quiet && (per_test || job.cross_validation.present)) std::cout << "\n" << format_identifiability(obj, r);
  write_outputs(obj, r, folder, !o.no_plot);
  if (!fo.state_file.empty()) {  // the results are in place: nothing to resume
    std::error_code ec;
    fs::remove(fo.state_file, ec);
  }
  std::cerr << "calibrate: wrote " << out << "/" << job.output_name << ".toml and the reports in " << out << "/\n";
}

void run_bench(const CalibrateOptions& o) {
  using namespace calibration;
  const std::string dir = io::data_directory() + "/calibration/";
  const char* jobs[] = {"dem_collisional_mu0.toml", "dem_collisional_mu05.toml", "dem_collisional_joint.toml", "frictional_synthetic.toml",
                        "frictional_synthetic_ensemble.toml", "kfs_fit.toml"};
  std::printf("%-36s %8s %8s %10s %12s %12s %9s\n", "job", "threads", "params", "evals", "misfit0", "misfit", "time[s]");
  for (const char* name : jobs) {
    try {
      const CalibrationJob job = load_job(dir + name);
      Objective obj(job, o.threads);
      FitOptions fo;
      fo.progress = false;
      const FitResult r = fit(obj, fo);
      std::printf("%-36s %8u %8zu %10ld %12.5g %12.5g %9.3f\n", name, obj.threads(), job.free.size(), r.evaluations,
                  r.at_start.misfit, r.at_best.misfit, r.seconds);
    } catch (const std::exception& e) {  // e.g. an NLopt job in a build without NLopt
      std::printf("%-36s skipped: %s\n", name, e.what());
    }
    std::fflush(stdout);
  }
}

}  // namespace

void register_calibrate(CLI::App& app) {
  auto o = std::make_shared<CalibrateOptions>();
  auto* cmd = app.add_subcommand("calibrate", "Fit a parameter set to measured curves (docs/calibration.md)");
  cmd->add_option("job", o->job, "Calibration job (TOML)");
  cmd->add_option("--out", o->out, "Output directory (default: <job>_fit)");
  cmd->add_flag("--force", o->force, "Replace an existing output directory (one granflow wrote), or with --synthesize the data files");
  cmd->add_option("--threads", o->threads, "Threads for the objective (0: all cores)")->capture_default_str();
  cmd->add_flag("--no-plot", o->no_plot, "Do not draw fit.png");
  cmd->add_flag("--quiet", o->quiet, "No progress line, no report on stdout");
  cmd->add_flag("--evaluate", o->evaluate, "Only evaluate the starting set (misfit, RMSE, R2, identifiability); no fit");
  cmd->add_flag("--no-cross-validation", o->no_cv,
                "With a [cross_validation] table: scores of the fitted set only, no leave-one-out fits");
  cmd->add_flag("--bench", o->bench,
                "Time the shipped DEM, synthetic-frictional and measured-sand fits (and the ensemble job) and print the figures");
  cmd->add_option("--synthesize", o->synthesize,
                  "Write the job's element-test data files from this parameter set instead of fitting");
  cmd->add_option("--noise", o->noise, "Relative noise of --synthesize")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Seed of --synthesize")->capture_default_str();
  cmd->add_option("--stride", o->stride, "Keep every n-th output row in --synthesize")->capture_default_str();
  cmd->callback([o] {
    if (o->bench && mpm::ranks().size() > 1) throw io::InputError("calibrate --bench runs in one process");
    if (o->bench) return run_bench(*o);
    if (o->job.empty()) throw io::InputError("granflow calibrate: give a job file (or --bench)");
    if (mpm::ranks().rank() != 0) {  // MPI: rank 0 calibrates, the others run their share of its batches
      if (!o->synthesize.empty()) return calibration::serve_scene_batches({});
      return calibration::serve_scene_batches(calibration::load_job(o->job).experiments);
    }
    run_calibrate(*o);
  });
}

}  // namespace granflow::cli
