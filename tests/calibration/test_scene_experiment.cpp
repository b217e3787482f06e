// MPM scenes as calibration experiments: the job format, and predictions of a batch (one
// ensemble run) equal to single runs of the same sets.
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

#include <granflow/calibration/fit.hpp>
#include <granflow/calibration/job.hpp>
#include <granflow/calibration/experiment.hpp>
#include <granflow/io/parameter_set.hpp>
#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/scene_file.hpp>

#include "helpers.hpp"
#include "scene_column.hpp"

namespace granflow::calibration {
namespace {

using test::Scratch;
using test::column_sets;
using test::set_array;

std::string job_text(const std::string& scene_dir, double collapse = 0.3) {
  return "params = \"column_collapse\"\n"
         "[[free]]\nkey = \"frictional.phi_c_deg\"\nlower = 15.0\nupper = 25.0\n"
         "[[experiments]]\nkind = \"mpm_scene\"\nname = \"column\"\n"
         "scene = \"" + scene_dir + "/mpm/scenes/column_collapse_ci.toml\"\n"
         "set = " + set_array(column_sets(collapse)) + "\nbackend = \"cpu\"\nprogress = false\n"
         "[experiments.surface]\ndata = \"surface.csv\"\nsd = 0.004\n"
         "[experiments.front]\ndata = \"front.csv\"\n";
}

// A batch (one ensemble run of both sets) against a single run of the first, after `collapse` s.
void expect_batch_equals_single_runs(double collapse) {
  Scratch s;
  std::string surface = "x,y\n0.001,0.1\n", front = "t,x\n";  // 0.001: before the first bin's centre
  for (int i = 0; i < 25; ++i) surface += std::to_string(0.01 + 0.02 * i) + ",0.05\n";  // beyond the deposit too
  for (double f : {1.0 / 6, 1.0 / 3, 2.0 / 3, 1.0}) front += std::to_string(f * collapse) + ",0.3\n";
  s.write("surface.csv", surface);
  s.write("front.csv", front);
  const CalibrationJob job = load_job(s.write("job.toml", job_text(test::source_dir(), collapse)));
  ASSERT_EQ(job.experiments.size(), 1u);
  const Experiment& e = *job.experiments[0];
  ASSERT_TRUE(e.batched());
  ASSERT_EQ(e.curves.size(), 2u);
  EXPECT_DOUBLE_EQ(e.curves[0].sd, 0.004);
  EXPECT_DOUBLE_EQ(e.curves[1].sd, 0.01);  // the documented default of a front

  io::ParameterSet a = job.start, b = job.start;
  b.frictional->phi_c = 24.0 * M_PI / 180;
  const std::vector<Prediction> batch = e.predict_batch({a, b});
  ASSERT_EQ(batch.size(), 2u);
  for (const Prediction& p : batch) ASSERT_TRUE(p.ok) << p.error;

  // set a alone, as granflow mpm runs it
  mpm::SceneOverrides ov;
  ov.sets = column_sets(collapse);
  ov.sets.push_back("time.cap_to_stable=false");  // a batch is an ensemble: it runs time.dt as given
  const mpm::Scene sc = mpm::load_scene(test::source_dir() + "/mpm/scenes/column_collapse_ci.toml", ov);
  const mpm::SceneSetup su = mpm::make_setup(sc);
  auto r = mpm::make_cpu_runner(su);
  mpm::RunOptions ro;
  ro.progress = false;
  const mpm::RunSummary rs = mpm::run(su, *r, ro);
  ASSERT_TRUE(rs.ok) << rs.message;
  mpm::Frame fr;
  r->frame(fr, false);
  const auto prof = mpm::free_surface(fr, su);
  const std::vector<double>& x = e.curves[0].x;
  for (size_t i = 0; i < x.size(); ++i) {
    double expect = 0;  // beyond the deposit: the floor
    for (size_t j = 1; j < prof.size(); ++j)
      if (x[i] >= prof[j - 1].first && x[i] <= prof[j].first) {
        const double w = (x[i] - prof[j - 1].first) / (prof[j].first - prof[j - 1].first);
        expect = prof[j - 1].second + w * (prof[j].second - prof[j - 1].second);
      }
    if (x[i] < prof.front().first) expect = prof.front().second;
    EXPECT_NEAR(batch[0].values[0][i], expect, 1e-12) << "x = " << x[i];
  }
  EXPECT_EQ(batch[0].values[0].back(), 0.0);  // 0.49 m lies beyond the 20 mm column's deposit
  // the front at the end of the collapse is the run's final run-out
  EXPECT_NEAR(batch[0].values[1].back(), rs.final.runout, 1e-12);
  // a higher friction angle: a shorter run-out
  EXPECT_LT(batch[1].values[1].back(), batch[0].values[1].back());
}

TEST(SceneExperiment, BatchPredictionsAreTheSingleRunsOfEachSet) { expect_batch_equals_single_runs(0.3); }

// The same after 0.12 s of collapse (900 steps against 1800): the sanitizer stage's case.
TEST(SceneExperiment, BatchPredictionsCiSizedAreTheSingleRunsOfEachSet) { expect_batch_equals_single_runs(0.12); }

// A front is the run-out against the time since the release (the last stage's start, here
// 0.06 s): its model values at t are the single run's run-out at 0.06 s + t, not at t.
TEST(SceneExperiment, FrontIsMeasuredAgainstTheTimeSinceTheRelease) {
  Scratch s;
  s.write("surface.csv", "x,y\n0.1,0.05\n");
  s.write("front.csv", "t,x\n0.02,0.3\n0.05,0.3\n0.1,0.3\n");
  const CalibrationJob job = load_job(s.write("job.toml", job_text(test::source_dir(), 0.1)));
  const std::vector<Prediction> p = job.experiments[0]->predict_batch({job.start});
  ASSERT_TRUE(p[0].ok) << p[0].error;
  mpm::SceneOverrides ov;
  ov.sets = column_sets(0.1);
  ov.sets.push_back("time.cap_to_stable=false");  // as the batch (an ensemble) runs it
  const mpm::SceneSetup su = mpm::make_setup(mpm::load_scene(test::source_dir() + "/mpm/scenes/column_collapse_ci.toml", ov));
  auto r = mpm::make_cpu_runner(su);
  mpm::RunOptions ro;
  ro.progress = false;
  const mpm::RunSummary rs = mpm::run(su, *r, ro);
  ASSERT_TRUE(rs.ok) << rs.message;
  auto runout_at = [&](double t) {  // the sample at time t of the run
    for (const auto& row : rs.series)
      if (std::fabs(row.t - t) < 1e-9) return row.m.runout;
    ADD_FAILURE() << "no sample at t = " << t;
    return std::nan("");
  };
  const std::vector<double> t_data = {0.02, 0.05, 0.1};
  ASSERT_EQ(p[0].values[1].size(), t_data.size());
  for (size_t i = 0; i < t_data.size(); ++i)
    EXPECT_NEAR(p[0].values[1][i], runout_at(0.06 + t_data[i]), 1e-12) << "t = " << t_data[i];
  // the column moves after the release: against the run's own time the values would differ
  EXPECT_GT(runout_at(0.16), runout_at(0.1) + 0.01);
}

TEST(SceneExperiment, JobErrorsNameTheFileAndKey) {
  Scratch s;
  s.write("surface.csv", "x,y\n0.1,0.05\n0.05,0.04\n");
  s.write("front.csv", "t,x\n0.1,0.2\n");
  try {
    load_job(s.write("job.toml", job_text(test::source_dir())));
    ADD_FAILURE() << "accepted a surface whose x decreases";
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("surface.csv:3"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("increase strictly"), std::string::npos) << e.what();
  }
  s.write("surface.csv", "x,y\n0.1,0.05\n");
  std::string bad = job_text(test::source_dir());
  bad += "[[experiments.track]]\nname = \"Z\"\ndata = \"front.csv\"\n";
  try {
    load_job(s.write("job2.toml", bad));
    ADD_FAILURE() << "accepted a track the scene does not have";
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("the scene tracks no point 'Z'"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace granflow::calibration
