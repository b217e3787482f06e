// Bad input to granflow calibrate: malformed data CSVs and job files get one clear error that
// names the file and the line (CSV) or the file, line and key (job).
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <sstream>

#include <granflow/calibration/fit.hpp>
#include <granflow/calibration/job.hpp>

#include "helpers.hpp"

namespace granflow::calibration::test {

namespace {

const char* kGoodCsv =
    "# steady shear, d = rho_p = gammadot = 1\n"
    "nu,p,s,T,e_r\n"
    "0.30,0.38,0.16,0.43,0.7\n"
    "0.40,0.70,0.31,0.33,0.7\n"
    "0.50,1.84,0.81,0.25,0.7\n";

std::string job_text(const std::string& extra_top = "", const std::string& free = "", const std::string& experiment = "",
                     const std::string& targets = "{ p = \"p\", s = \"tau\" }") {
  return "params = \"collisional_element\"\n" + extra_top +
         "\n[[free]]\nkey = \"collisional.V_m\"\nlower = 0.2\nupper = 0.5\n" + free +
         "\n[algorithm]\nglobal = \"none\"\nlocal_evaluations = 20\n"
         "\n[[experiments]]\nname = \"dem\"\nkind = \"steady_shear\"\ndata = \"data.csv\"\nabscissa = \"nu\"\n"
         "quantity = \"solid_fraction\"\ntargets = " +
         targets + "\n" + experiment +
         "\n[experiments.steady_shear]\nrestitution_column = \"e_r\"\n";
}

struct BadInput : ::testing::Test {
  Scratch dir;
  std::string job(const std::string& csv, const std::string& text) {
    dir.write("data.csv", csv);
    return dir.write("job.toml", text);
  }
};

}  // namespace

TEST_F(BadInput, GoodJobLoads) {
  const CalibrationJob j = load_job(job(kGoodCsv, job_text()));
  ASSERT_EQ(j.experiments.size(), 1u);
  EXPECT_EQ(j.experiments[0]->curves.size(), 2u);
  EXPECT_EQ(j.experiments[0]->curves[0].x.size(), 3u);
}

// ---- data CSV ------------------------------------------------------------------------

// The abscissa window [lo, hi] keeps the rows at both bounds, the one at lo included.
TEST_F(BadInput, DataWindowKeepsTheRowsAtItsBounds) {
  DataSelection sel;
  sel.file = dir.write("w.csv", "strain,q\n0.01,1\n0.02,2\n0.03,3\n0.04,4\n");
  sel.abscissa = "strain";
  sel.quantity = "strain";
  sel.targets = {{"q", "q"}};
  sel.target_weights = {1.0};
  sel.x_lo = 0.02;
  sel.x_hi = 0.03;
  const std::vector<DataGroup> g = select_data(sel, "w");
  ASSERT_EQ(g.size(), 1u);
  ASSERT_EQ(g[0].curves.size(), 1u);
  EXPECT_EQ(g[0].curves[0].x, (std::vector<double>{0.02, 0.03}));
  EXPECT_EQ(g[0].curves[0].y, (std::vector<double>{2, 3}));
  EXPECT_EQ(g[0].curves[0].lines, (std::vector<long>{3, 4}));
}

// Strains are fractions: a strain column (the abscissa compared with a strain output, or a target
// mapped to one) above 1 in magnitude gets a warning naming the file, line and column
// (per cent?); one absurd value (1e300) is an error naming its line, not a strain in per cent.
TEST_F(BadInput, StrainColumnsOutsideAPlausibleRangeAreNamed) {
  static std::vector<std::string> warnings;
  warnings.clear();
  io::set_warning_sink([](const std::string& l) { warnings.push_back(l); });
  DataSelection sel;
  sel.abscissa = "eps_a";
  sel.quantity = "strain";
  sel.model_abscissa = "eps_a";
  sel.targets = {{"q", "q"}, {"ev", "eps_v"}};
  sel.target_weights = {1.0, 1.0};
  sel.file = dir.write("fraction.csv", "eps_a,q,ev\n0,0,0\n0.1,100,0.01\n0.26,150,0.02\n");
  select_data(sel, "t");
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  sel.file = dir.write("percent.csv", "eps_a,q,ev\n0,0,0\n10,100,1\n26,150,2\n");
  select_data(sel, "t");
  ASSERT_EQ(warnings.size(), 2u);
  for (const char* part : {"percent.csv:4", "column 'eps_a'", "26", "per cent"})
    EXPECT_NE(warnings[0].find(part), std::string::npos) << warnings[0];
  for (const char* part : {"percent.csv:4", "column 'ev'", "strain"})
    EXPECT_NE(warnings[1].find(part), std::string::npos) << warnings[1];
  warnings.clear();
  sel.file = dir.write("stray.csv", "eps_a,q,ev\n0,0,0\n0.1,100,1e300\n0.26,150,0.02\n");
  expect_input_error([&] { select_data(sel, "t"); }, {"stray.csv:3", "column 'ev'", "1e+300", "not a strain"});
  // not a strain: q may be anything, and so may an abscissa compared with a stress
  sel.file = dir.write("stress.csv", "eps_a,q,ev\n0,0,0\n0.1,1e5,0.01\n");
  select_data(sel, "t");
  sel.file = dir.write("oedometer.csv", "sigma_a,q,ev\n1e4,0,0\n2e5,1e5,0.01\n");
  sel.abscissa = "sigma_a";
  sel.model_abscissa = "sigma_n";
  select_data(sel, "t");
  EXPECT_TRUE(warnings.empty());
  io::set_warning_sink(nullptr);
}

// Spreadsheet programs write a UTF-8 byte-order mark before the header.
TEST_F(BadInput, CsvByteOrderMarkBeforeTheHeaderIsSkipped) {
  const CalibrationJob j = load_job(job(std::string("\xEF\xBB\xBF") + kGoodCsv, job_text()));
  ASSERT_EQ(j.experiments.size(), 1u);
  EXPECT_EQ(j.experiments[0]->curves[0].x.size(), 3u);
  const std::string p = job(std::string("\xEF\xBB\xBF") + "nu,p,T,e_r\n0.3,0.38,0.43,0.7\n", job_text());
  expect_input_error([&] { load_job(p); }, {"data.csv:1:", "needs column 's'", "header 'nu,p,T,e_r'"});
}

TEST_F(BadInput, CsvMissingColumnNamesFileLineAndColumn) {
  const std::string p = job("nu,p,T,e_r\n0.3,0.38,0.43,0.7\n", job_text());
  expect_input_error([&] { load_job(p); }, {"data.csv:1:", "needs column 's'", "header 'nu,p,T,e_r'"});
}

TEST_F(BadInput, CsvNonNumericCellNamesFileAndLine) {
  std::string csv = kGoodCsv;
  csv.replace(csv.find("0.31"), 4, "abc");
  const std::string p = job(csv, job_text());
  expect_input_error([&] { load_job(p); }, {"data.csv:4", "'abc' is not a number"});
}

TEST_F(BadInput, CsvUnsortedAbscissaNamesFileAndLine) {
  std::string csv = kGoodCsv;
  csv.replace(csv.find("0.50,"), 5, "0.35,");
  const std::string p = job(csv, job_text());
  expect_input_error([&] { load_job(p); }, {"data.csv:5:", "must increase strictly", "0.35 follows 0.4"});
}

TEST_F(BadInput, CsvNaNNamesFileAndLine) {
  std::string csv = kGoodCsv;
  csv.replace(csv.find("0.38"), 4, "nan");
  const std::string p = job(csv, job_text());
  expect_input_error([&] { load_job(p); }, {"data.csv:3", "'nan' is not a finite number"});
}

TEST_F(BadInput, CsvRepeatedAbscissaNeedsAverage) {
  std::string csv = std::string(kGoodCsv) + "0.50,1.86,0.83,0.26,0.7\n";
  const std::string p = job(csv, job_text());
  expect_input_error([&] { load_job(p); }, {"data.csv:6:", "duplicates = \"average\""});
  const CalibrationJob j = load_job(job(csv, job_text("", "", "duplicates = \"average\"\n")));
  EXPECT_EQ(j.experiments[0]->curves[0].x.size(), 3u);
  EXPECT_NEAR(j.experiments[0]->curves[0].y.back(), 1.85, 1e-12);
}

TEST_F(BadInput, CsvEmptyAndWrongDelimiter) {
  expect_input_error([&] { load_job(job("", job_text())); }, {"data.csv", "empty file"});
  expect_input_error([&] { load_job(job("nu;p;s;T;e_r\n0.3;0.38;0.16;0.43;0.7\n", job_text())); },
                     {"data.csv:1:", "delimiter must be a comma"});
}

TEST_F(BadInput, CsvParameterColumnMustBeConstantPerCurve) {
  std::string csv = kGoodCsv;
  csv.replace(csv.rfind("0.7"), 3, "0.8");
  expect_input_error([&] { load_job(job(csv, job_text())); }, {"data.csv:5:", "column 'e_r' must be constant"});
  // splitting by that column makes two curve groups instead
  const CalibrationJob j = load_job(job(csv, job_text("", "", "split_by = [\"e_r\"]\n")));
  EXPECT_EQ(j.experiments.size(), 2u);
}

TEST_F(BadInput, LogMisfitNeedsPositiveData) {
  std::string csv = kGoodCsv;
  csv.replace(csv.find("0.38"), 4, "-0.1");
  const std::string p = job(csv, job_text("\n[misfit]\nscale = \"log\"\n"));
  const CalibrationJob j = load_job(p);
  expect_input_error([&] { Objective o(j, 1); }, {"data.csv:3:", "not positive"});
}

// ---- job file ------------------------------------------------------------------------

TEST_F(BadInput, JobUnknownKeyNamesFileLineAndKey) {
  const std::string p = job(kGoodCsv, job_text("", "uper = 3\n"));
  expect_input_error([&] { load_job(p); }, {"job.toml:", "unknown key 'free[0].uper'"});
  expect_input_error([&] { load_job(job(kGoodCsv, job_text("", "", "wieght = 2\n"))); },
                     {"job.toml:", "unknown key 'experiments[0].wieght'"});
}

TEST_F(BadInput, JobBadFreeParameters) {
  auto with_free = [&](const std::string& f) {
    std::string t = job_text();
    t.replace(t.find("key = \"collisional.V_m\"\nlower = 0.2\nupper = 0.5\n"), 47, f);
    return job(kGoodCsv, t);
  };
  expect_input_error([&] { load_job(with_free("key = \"collisional.Vm\"\nlower = 0.2\nupper = 0.5\n")); },
                     {"job.toml:", "'free[0].key'", "not a parameter", "collisional.V_m"});
  expect_input_error([&] { load_job(with_free("key = \"collisional.V_m\"\nlower = 0.5\nupper = 0.2\n")); },
                     {"job.toml:", "'free[0].upper'", "must exceed lower"});
  expect_input_error([&] { load_job(with_free("key = \"collisional.V_m\"\nlower = 0.1\nupper = 0.3\n")); },
                     {"'free[0].lower'", "start value 0.4", "outside"});
  expect_input_error([&] { load_job(with_free("key = \"frictional.phi_c_deg\"\nlower = 10\nupper = 40\n")); },
                     {"has no [frictional] table"});
  expect_input_error([&] { load_job(with_free("key = \"collisional.V_m\"\nlower = 0\nupper = 0.5\nlog = true\n")); },
                     {"'free[0].lower'", "must be > 0 with log = true"});
  expect_input_error(
      [&] { load_job(job(kGoodCsv, job_text("", "\n[[free]]\nkey = \"collisional.V_m\"\nlower = 0.2\nupper = 0.5\n"))); },
      {"'free[1].key'", "freed twice"});
}

TEST_F(BadInput, JobBadExperiment) {
  expect_input_error([&] { load_job(job(kGoodCsv, job_text("", "", "", "{ p = \"pressure\" }"))); },
                     {"job.toml:", "'experiments[0].targets.p'", "must be one of 'p', 'tau', 'T', 'mu'"});
  std::string t = job_text();
  t.replace(t.find("data.csv"), 8, "nothere.csv");
  expect_input_error([&] { load_job(job(kGoodCsv, t)); }, {"job.toml:", "'experiments[0].data'", "no such file"});
  expect_input_error([&] { load_job(job(kGoodCsv, job_text("", "", "filter = { e_r = 0.9 }\n"))); },
                     {"data.csv", "no data row passes the filter e_r = 0.9"});
  t = job_text();
  const std::string q = "quantity = \"solid_fraction\"";
  t.replace(t.find(q), q.size(), "quantity = \"void_ratio\"");
  expect_input_error([&] { load_job(job(kGoodCsv, t)); }, {"'experiments[0].quantity'", "must be one of"});
}

TEST_F(BadInput, JobDataAboveTheLowestVsdIsRejected) {
  // V_sd free down to 0.45 while the data reach 0.5: the closed forms would not exist there.
  const std::string p =
      job(kGoodCsv, job_text("", "\n[[free]]\nkey = \"collisional.V_sd\"\nlower = 0.45\nupper = 0.7\nstart = 0.6\n"));
  expect_input_error([&] { load_job(p); }, {"job.toml", "solid fraction 0.5", "restrict its 'range'"});
  EXPECT_NO_THROW(load_job(job(kGoodCsv, job_text("", "\n[[free]]\nkey = \"collisional.V_sd\"\nlower = 0.55\nupper = 0.7\n"))));
}

TEST_F(BadInput, JobBadAlgorithm) {
  std::string t = job_text();
  t.replace(t.find("global = \"none\""), 15, "global = \"GN_CRS3\"");
  expect_input_error([&] { load_job(job(kGoodCsv, t)); }, {"job.toml:", "'algorithm.global'", "GN_CRS2_LM"});
  t = job_text();
  t.replace(t.find("local_evaluations = 20"), 22, "local_evaluations = 0");
  expect_input_error([&] { load_job(job(kGoodCsv, t)); }, {"'algorithm.local_evaluations'", "must be in [1,"});
  expect_input_error([&] { load_job(job(kGoodCsv, "params = \"collisional_element\"\n[algorithm\n")); },
                     {"job.toml:2", "TOML syntax error"});
  expect_input_error([&] { load_job(job(kGoodCsv, "params = \"no_such_set\"\n")); }, {"'params'", "no such file"});
}

// The ensemble method's keys: every error names the file, the line of the key and the key.
TEST_F(BadInput, JobBadEnsembleKeys) {
  auto ens = [&](const std::string& tables) {
    std::string t = job_text(tables);
    t.replace(t.find("[algorithm]\n"), 12, "[algorithm]\nmethod = \"ensemble\"\n");
    return job(kGoodCsv, t);
  };
  // "job.toml:<line of the key>:"
  auto at = [&](const std::string& key_text) {
    const std::string t = [&] {
      std::ifstream in(dir.path("job.toml"));
      std::stringstream ss;
      ss << in.rdbuf();
      return ss.str();
    }();
    const std::size_t pos = t.find(key_text);
    return "job.toml:" + std::to_string(1 + std::count(t.begin(), t.begin() + static_cast<long>(pos), '\n')) + ":";
  };
  const CalibrationJob good = load_job(ens("[ensemble]\nmembers = 16\niterations = 2\nseed = 4\npolish = false\n"
                                           "transform = \"logit\"\n[likelihood]\nrelative_sd = 0.1\n"));
  EXPECT_EQ(good.algorithm.method, "ensemble");
  EXPECT_EQ(good.ensemble.members, 16);
  EXPECT_EQ(good.ensemble.iterations, 2);
  EXPECT_FALSE(good.ensemble.polish);
  EXPECT_EQ(good.ensemble.transform, "logit");
  EXPECT_DOUBLE_EQ(good.likelihood.relative_sd, 0.1);

  std::string p = ens("[ensemble]\nmember = 16\n");
  expect_input_error([&] { load_job(p); }, {at("member = 16"), "unknown key 'ensemble.member'"});
  p = ens("[ensemble]\nmembers = 1\n");
  expect_input_error([&] { load_job(p); }, {at("members = 1"), "'ensemble.members'", "must be in [2,"});
  p = ens("[ensemble]\niterations = 0\n");
  expect_input_error([&] { load_job(p); }, {at("iterations = 0"), "'ensemble.iterations'", "must be in [1,"});
  p = ens("[ensemble]\ntransform = \"tanh\"\n");
  expect_input_error([&] { load_job(p); }, {at("transform ="), "'ensemble.transform'", "'probit'"});
  p = ens("[likelihood]\nrelative_sd = 0\n");
  expect_input_error([&] { load_job(p); }, {at("relative_sd = 0"), "'likelihood.relative_sd'", "must be > 0"});
  p = ens("[likelihood]\nrelative_sd = -0.1\n");
  expect_input_error([&] { load_job(p); }, {at("relative_sd = -0.1"), "'likelihood.relative_sd'", "must be > 0"});
  p = ens("[likelihood]\nrel_sd = 0.1\n");
  expect_input_error([&] { load_job(p); }, {at("rel_sd"), "unknown key 'likelihood.rel_sd'"});
  p = job(kGoodCsv, job_text("", "", "target_sd = { p = 0.0 }\n"));
  expect_input_error([&] { load_job(p); }, {at("target_sd"), "'experiments[0].target_sd.p'", "must be > 0"});
  p = job(kGoodCsv, job_text("", "", "target_sd = { T = 0.1 }\n"));
  expect_input_error([&] { load_job(p); }, {at("target_sd"), "'experiments[0].target_sd.T'", "not a target column"});
  std::string t = job_text();
  t.replace(t.find("[algorithm]\n"), 12, "[algorithm]\nmethod = \"mcmc\"\n");
  p = job(kGoodCsv, t);
  expect_input_error([&] { load_job(p); }, {at("method ="), "'algorithm.method'", "'nlopt', 'ensemble'"});
}

TEST_F(BadInput, OutputsAreNotOverwrittenWithoutForce) {
  const CalibrationJob j = load_job(job(kGoodCsv, job_text()));
  Objective obj(j, 1);
  FitOptions fo;
  fo.progress = false;
  const FitResult r = fit(obj, fo);
  const std::string out = dir.path("out");
  write_outputs(obj, r, out, false, false);
  EXPECT_TRUE(fs::exists(out + "/fitted.toml"));
  expect_input_error([&] { write_outputs(obj, r, out, false, false); }, {"out", "pass --force"});
  EXPECT_NO_THROW(write_outputs(obj, r, out, true, false));
  // no temporary folder is left behind
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir.path(""))) entries += e.path().filename().string().find(".tmp-") != std::string::npos;
  EXPECT_EQ(entries, 0);
}

}  // namespace granflow::calibration::test
