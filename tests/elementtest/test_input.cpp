// Bad test files give errors naming file, line and key.
#include "common.hpp"

#include <fstream>
#include <string>
#include <vector>

namespace {

std::string error_of(const std::string& path) {
  try {
    gt::load_test_file(path);
  } catch (const granflow::io::InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(ElementInput, ShippedExamplesParseAndRun) {
  for (const char* f : {"data/tests/fig4_e080.toml", "data/tests/fig6_e099.toml"}) {
    const gt::TestFile tf = gt::load_test_file(std::string(GRANFLOW_SOURCE_DIR) + "/" + f);
    gt::ElementTest t = tf.test;
    t.programme.duration = std::min(t.programme.duration, 0.01);
    expect_admissible(gt::run_element_test(t, pset(tf.params)));
  }
}

TEST(ElementInput, UnknownKeyNamesFileLineAndKey) {
  const std::string p = write("bad1.toml", "params = \"element_test\"\n[test]\nrate = 1\nduration = 1\nsigma_v = 5\n");
  const std::string e = error_of(p);
  EXPECT_NE(e.find("bad1.toml:5"), std::string::npos) << e;
  EXPECT_NE(e.find("test.sigma_v"), std::string::npos) << e;
}

TEST(ElementInput, OutOfRangeValueNamesKey) {
  const std::string p = write("bad2.toml", "[test]\nrtol = 2\n");
  const std::string e = error_of(p);
  EXPECT_NE(e.find("bad2.toml:2"), std::string::npos) << e;
  EXPECT_NE(e.find("test.rtol"), std::string::npos) << e;
}

TEST(ElementInput, WrongProgrammeKeysAreErrors) {
  EXPECT_NE(error_of(write("bad3.toml", "[test]\nprogramme = \"constant\"\nacceleration = 5\n")).find("test.acceleration"),
            std::string::npos);
  EXPECT_NE(error_of(write("bad4.toml", "[test]\nprogramme = \"table\"\n")).find("rate_file"), std::string::npos);
  EXPECT_NE(error_of(write("bad5.toml", "[test]\nsolver = \"cvode\"\ndt = 1e-3\n")).find("test.dt"), std::string::npos);
  EXPECT_NE(error_of(write("bad6.toml", "[test]\npath = \"triaxial\"\n")).find("test.path"), std::string::npos);
  EXPECT_NE(error_of(write("bad7.toml", "parms = \"x\"\n[test]\n")).find("bad7.toml:1"), std::string::npos);
}

TEST(ElementInput, BadRateTableNamesFileAndLine) {
  write("rates.csv", "time,rate\n0,1\n0.5,2\n0.4,3\n");
  const std::string e = error_of(write("bad8.toml", "[test]\nprogramme = \"table\"\nrate_file = \"rates.csv\"\n"));
  EXPECT_NE(e.find("rates.csv:4"), std::string::npos) << e;
  write("rates2.csv", "time,rate\n0,1\n0.5,abc\n");
  const std::string e2 = error_of(write("bad9.toml", "[test]\nprogramme = \"table\"\nrate_file = \"rates2.csv\"\n"));
  EXPECT_NE(e2.find("rates2.csv:3"), std::string::npos) << e2;
}

TEST(ElementInput, RunErrorsAreInputErrors) {
  gt::ElementTest t;
  t.model = gt::ModelChoice::Frictional;
  EXPECT_THROW(gt::run_element_test(t, pset("collisional_element")), granflow::io::InputError);
  t.model = gt::ModelChoice::Auto;
  t.initial.e0 = 0.5;  // V_s above V_sd
  EXPECT_THROW(gt::run_element_test(t, pset("element_test")), granflow::io::InputError);
  gt::ResultTable r;
  EXPECT_THROW(r.column("nope"), granflow::io::InputError);
}

TEST(ElementInput, BadDataProgrammesAreErrors) {
  write("prog.csv", "sigma_a,eps_a\n0,0\n1000,0.001\n");
  write("flat.csv", "sigma_a\n5\n5\n");
  const std::string head = "[test]\nprogramme = \"data\"\n";
  EXPECT_NE(error_of(write("d1.toml", head + "path = \"oedometric\"\ndata_file = \"prog.csv\"\n")).find("test.control_column"),
            std::string::npos);
  EXPECT_NE(error_of(write("d2.toml", head + "path = \"drained_triaxial\"\ndata_file = \"prog.csv\"\ncontrol_column = "
                                              "\"sigma_a\"\ncontrol = \"stress\"\n"))
                .find("test.control"),
            std::string::npos);
  EXPECT_NE(error_of(write("d3.toml", "[test]\npath = \"undrained_simple_shear\"\ndirection = \"extension\"\n")).find("test.direction"),
            std::string::npos);
  EXPECT_NE(error_of(write("d4.toml", head + "path = \"oedometric\"\ndata_file = \"prog.csv\"\ncontrol_column = \"eps_a\"\n"
                                              "outputs = 10\n"))
                .find("test.outputs"),
            std::string::npos);
  const std::string e5 = error_of(write("d5.toml", head + "path = \"oedometric\"\ndata_file = \"prog.csv\"\ncontrol_column = \"eps_x\"\n"));
  EXPECT_NE(e5.find("prog.csv"), std::string::npos) << e5;
  EXPECT_NE(e5.find("eps_x"), std::string::npos) << e5;
  EXPECT_NE(error_of(write("d6.toml", head + "path = \"undrained_triaxial\"\ndata_file = \"prog.csv\"\ncontrol_column = "
                                              "\"eps_a\"\ndirection = \"extension\"\n"))
                .find("test.direction"),
            std::string::npos);
  // stress held at sigma_v0 = 1e4 while the column stays below it: nothing to run
  const gt::TestFile tf = gt::load_test_file(write(
      "d7.toml", head + "path = \"oedometric\"\ndata_file = \"flat.csv\"\ncontrol_column = \"sigma_a\"\ncontrol = \"stress\"\n"
                        "sigma_v0 = 1e4\n"));
  try {
    gt::run_element_test(tf.test, pset("frictional_element"));
    ADD_FAILURE() << "no error";
  } catch (const granflow::io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("never changes"), std::string::npos) << e.what();
  }
  gt::ElementTest t = tf.test;  // a data programme with no data (the API without a data file)
  t.programme.data_control.clear();
  EXPECT_THROW(gt::run_element_test(t, pset("frictional_element")), granflow::io::InputError);
}

// A strain the data programme follows is a fraction: a column in per cent (values up to 26) gets a
// warning naming the file, the line and the column; a stray 1e300 is an error naming its line,
// as is any value whose change takes the programme past a finite time (not "never changes").
TEST(ElementInput, ImplausibleDataProgrammeValuesAreNamed) {
  static std::vector<std::string> warnings;
  warnings.clear();
  granflow::io::set_warning_sink([](const std::string& l) { warnings.push_back(l); });
  const std::string head = "[test]\nprogramme = \"data\"\npath = \"drained_triaxial\"\ncontrol_column = \"eps_a\"\n";
  write("fraction.csv", "eps_a\n0\n0.1\n0.26\n");
  gt::load_test_file(write("p1.toml", head + "data_file = \"fraction.csv\"\n"));
  EXPECT_TRUE(warnings.empty());
  write("percent.csv", "eps_a\n0\n10\n26\n20\n");
  gt::load_test_file(write("p2.toml", head + "data_file = \"percent.csv\"\n"));
  ASSERT_EQ(warnings.size(), 1u);
  for (const char* part : {"percent.csv:4", "column 'eps_a'", "26", "per cent"})
    EXPECT_NE(warnings[0].find(part), std::string::npos) << warnings[0];
  write("stray.csv", "eps_a\n0\n0.01\n1e300\n0.03\n");
  const std::string e = error_of(write("p3.toml", head + "data_file = \"stray.csv\"\n"));
  for (const char* part : {"stray.csv:4", "column 'eps_a'", "1e+300", "not a strain"})
    EXPECT_NE(e.find(part), std::string::npos) << e;
  granflow::io::set_warning_sink(nullptr);
  // a stress the programme follows at 1e-9 Pa/s: 1e300 Pa takes longer than any finite time
  write("stress.csv", "sigma_a\n0\n1000\n1e300\n2000\n");
  const gt::TestFile tf = gt::load_test_file(write(
      "p4.toml", "[test]\nprogramme = \"data\"\npath = \"oedometric\"\ncontrol_column = \"sigma_a\"\n"
                 "control = \"stress\"\ndata_file = \"stress.csv\"\nrate = 1e-9\n"));
  try {
    gt::run_element_test(tf.test, pset("frictional_element"));
    ADD_FAILURE() << "no error";
  } catch (const granflow::io::InputError& x) {
    const std::string m = x.what();
    for (const char* part : {"stress.csv:4", "column 'sigma_a'", "1e+300", "not finite"})
      EXPECT_NE(m.find(part), std::string::npos) << m;
    EXPECT_EQ(m.find("never changes"), std::string::npos) << m;
  }
}
