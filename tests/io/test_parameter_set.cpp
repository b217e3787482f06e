// Parameter-set files: shipped sets load; every bad value is an error naming file, line and key.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <granflow/io/input_error.hpp>
#include <granflow/io/parameter_set.hpp>

using namespace granflow;
using granflow::io::InputError;

namespace {

std::string data_dir() { return std::string(GRANFLOW_SOURCE_DIR) + "/data"; }

std::string write_temp(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / ("granflow_test_" + name + ".toml");
  std::ofstream(path) << text;
  return path.string();
}

const char* kGood = R"(name = "ok"
[frictional]
K0 = 120
nu = 0.2
n = 0.5
phi_c_deg = 19.8
e_ref = 0.977
lambda_c = 0.0596
xi = 0.365
A_d = 0.7
k_p = 0.0044
n_p = 2.4
n_d = 2.9

[collisional]
rho_p = 2650
d = 1.25e-3
e_sd = 0.62
V_m = 0.4
eps_n = 0.6
mu_p = 0.2

[initial]
e0 = 0.95
)";

// Replaces the first occurrence of `from` in the good file and expects an error mentioning all `needles`.
void expect_error(const std::string& from, const std::string& to, std::initializer_list<std::string> needles) {
  std::string text = kGood;
  const auto pos = text.find(from);
  ASSERT_NE(pos, std::string::npos) << from;
  text.replace(pos, from.size(), to);
  const std::string path = write_temp("bad", text);
  try {
    io::load_parameter_set(path);
    FAIL() << "no error for " << to;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    for (const auto& n : needles) EXPECT_NE(msg.find(n), std::string::npos) << "'" << n << "' not in: " << msg;
  }
}

}  // namespace

TEST(ParameterSet, ShippedSetsLoadAndMatchTheSourceTables) {
  setenv("GRANFLOW_DATA_DIR", data_dir().c_str(), 1);
  const auto el = io::load_parameter_set("element_test");
  ASSERT_TRUE(el.has_frictional() && el.has_collisional());
  EXPECT_NEAR(el.collisional->V_sd, 0.520833, 1e-6);
  EXPECT_NEAR(el.frictional->phi_c * 180 / M_PI, 23.0, 1e-12);
  EXPECT_EQ(el.e0.size(), 3u);
  const auto t1 = io::load_parameter_set("frictional_element");
  EXPECT_FALSE(t1.has_collisional());
  EXPECT_THROW(t1.phase_transition(), InputError);
  const auto t2 = io::load_parameter_set(data_dir() + "/params/collisional_element.toml");
  EXPECT_FALSE(t2.has_frictional());
  EXPECT_DOUBLE_EQ(t2.collisional->V_sd, 0.6);
  for (const char* name : {"column_collapse", "flume"}) EXPECT_NO_THROW(io::load_parameter_set(name));
}

TEST(ParameterSet, RoundTripThroughTheWriter) {
  const auto a = io::load_parameter_set(data_dir() + "/params/flume.toml");
  const auto path = write_temp("roundtrip", io::format_parameter_set(a));
  const auto b = io::load_parameter_set(path);
  EXPECT_EQ(a.frictional->phi_c, b.frictional->phi_c);
  EXPECT_EQ(a.collisional->V_sd, b.collisional->V_sd);
  EXPECT_EQ(a.e0, b.e0);
}

// phi_c_deg is written as the value it was read from (30, not 29.999999999999996), for every
// angle with two decimals; the written text still reads back to the same radians.
TEST(ParameterSet, DegreesAreWrittenAsRead) {
  const std::string good = kGood;
  const std::string key = "phi_c_deg = 19.8";
  ASSERT_NE(good.find(key), std::string::npos);
  int naive_differs = 0;  // angles whose radians / (pi / 180) is not the value read
  for (int k = 1; k < 9000; ++k) {
    char deg[16];
    std::snprintf(deg, sizeof deg, "%.2f", k / 100.0);
    std::string text = good;
    text.replace(text.find(key), key.size(), std::string("phi_c_deg = ") + deg);
    const auto a = io::parse_parameter_set_text(text, "p.toml");
    const std::string out = io::format_parameter_set(a);
    const std::size_t at = out.find("phi_c_deg = ");
    ASSERT_NE(at, std::string::npos);
    const double written = std::strtod(out.c_str() + at + 12, nullptr);
    ASSERT_EQ(written, std::strtod(deg, nullptr)) << deg << " written as " << out.substr(at, 40);
    ASSERT_EQ(io::parse_parameter_set_text(out, "out.toml").frictional->phi_c, a.frictional->phi_c) << deg;
    naive_differs += a.frictional->phi_c / (M_PI / 180.0) != written;
  }
  EXPECT_GT(naive_differs, 100);  // the case the writer has to handle occurs
}

TEST(ParameterSet, OverridesAreValidated) {
  auto s = io::load_parameter_set(data_dir() + "/params/element_test.toml");
  io::apply_override(s, "frictional.phi_c_deg=31");
  EXPECT_NEAR(s.frictional->phi_c * 180 / M_PI, 31.0, 1e-12);
  io::apply_override(s, "collisional.e_sd=0.8");
  EXPECT_NEAR(s.collisional->V_sd, 1 / 1.8, 1e-14);
  EXPECT_THROW(io::apply_override(s, "frictional.nu=0.7"), InputError);
  EXPECT_THROW(io::apply_override(s, "frictional.nuu=0.2"), InputError);
  EXPECT_THROW(io::apply_override(s, "phi=3"), InputError);
}

TEST(ParameterSet, BadValuesNameTheKey) {
  expect_error("nu = 0.2", "nu = 0.7", {"frictional.nu", "(-1, 0.5)", ":4:"});
  expect_error("nu = 0.2", "nu = \"x\"", {"frictional.nu", "expected a number"});
  expect_error("nu = 0.2", "nuu = 0.2", {"'frictional.nu'", "'frictional.nuu'", "a typo?"});
  expect_error("xi = 0.365", "xi = 0.365\nxj = 1", {"unknown key 'frictional.xj'"});
  expect_error("nu = 0.2\n", "", {"frictional.nu", "missing"});
  expect_error("d = 1.25e-3", "d = -1e-3", {"collisional.d", "> 0"});
  expect_error("eps_n = 0.6", "eps_n = 1.2", {"collisional.eps_n", "[0, 1]"});
  expect_error("phi_c_deg = 19.8", "phi_c_deg = 90", {"frictional.phi_c_deg", "(0, 90)"});
  expect_error("e0 = 0.95", "e0 = 3.5", {"initial.e0"});
  expect_error("e0 = 0.95", "e0 = 0.55", {"V_sd", "e0 = 0.55"});  // V_s0 = 0.645 above V_sd = 0.617
  expect_error("e_sd = 0.62", "e_sd = 0.62\nV_sd = 0.6", {"exactly one of e_sd or V_sd"});
  expect_error("V_m = 0.4", "V_m = 0.7", {"collisional.V_m", "below V_sd"});
  expect_error("K0 = 120", "K0 = nan", {"frictional.K0"});
  expect_error("[initial]", "[initial", {"TOML syntax error"});
  expect_error("name = \"ok\"", "name = \"ok\"\nsurprise = 1", {"unknown key 'surprise'"});
}

TEST(ParameterSet, UnknownNameListsTheShippedSets) {
  setenv("GRANFLOW_DATA_DIR", data_dir().c_str(), 1);
  try {
    io::load_parameter_set("colum_collapse");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("column_collapse"), std::string::npos) << e.what();
  }
}

// Options of the collisional part (issue 25): optional sections of [collisional]; absent, the set
// is MODEL.md's model; each written back only where set, and every bad value names its key.
TEST(ParameterSet, CollisionalOptionsReadWriteAndOverride) {
  std::string text = kGood;
  const std::string opts = "mu_p = 0.2\n\n[collisional.jamming]\nmodel = \"friction\"\nV_sd_inf = 0.58\nmu_star = 0.1\n"
                           "\n[collisional.correlation_length]\nc = 0.5\n\n[collisional.dilute]\nmodel = \"uniform_shear\"\n"
                           "\n[collisional.restitution]\nuse = \"dissipation_only\"\n";
  text.replace(text.find("mu_p = 0.2\n"), 11, opts);
  const auto a = io::load_parameter_set(write_temp("options", text));
  const auto& c = *a.collisional;
  EXPECT_TRUE(c.jamming_friction);
  EXPECT_EQ(c.V_sd_inf, 0.58);
  EXPECT_EQ(c.mu_star, 0.1);
  EXPECT_EQ(c.corr_c, 0.5);
  EXPECT_TRUE(c.dilute_usf);
  EXPECT_EQ(c.restitution, RestitutionUse::DissipationOnly);
  const auto b = io::load_parameter_set(write_temp("options_rt", io::format_parameter_set(a)));
  EXPECT_EQ(io::format_parameter_set(a), io::format_parameter_set(b));
  // without options nothing of them is written (shipped sets keep their text)
  const auto plain = io::load_parameter_set(data_dir() + "/params/flume.toml");
  EXPECT_EQ(io::format_parameter_set(plain).find("[collisional."), std::string::npos);
  EXPECT_FALSE(plain.collisional->jamming_friction || plain.collisional->dilute_usf || plain.collisional->corr_c > 0);
  // nested keys through --set
  auto s = a;
  io::apply_override(s, "collisional.jamming.mu_star=0.3");
  EXPECT_EQ(s.collisional->mu_star, 0.3);
  EXPECT_THROW(io::apply_override(s, "collisional.jamming.V_sd_inf=0.7"), InputError);  // above V_sd = 0.617
  EXPECT_THROW(io::apply_override(s, "collisional.nothing.c=1"), InputError);
}

// A bare word after '=' is a string, as for scene keys (granflow mpm --help): a choice can be
// set without TOML quotes, and a bare word where a number belongs names the key and the type.
TEST(ParameterSet, OverrideTakesABareWordAsAString) {
  std::string text = kGood;
  text.replace(text.find("mu_p = 0.2\n"), 11,
               "mu_p = 0.2\n\n[collisional.jamming]\nmodel = \"friction\"\nV_sd_inf = 0.58\nmu_star = 0.1\n"
               "\n[collisional.restitution]\nuse = \"dissipation_only\"\n");
  auto s = io::load_parameter_set(write_temp("bare_word", text));
  io::apply_override(s, "collisional.jamming.model=friction");
  EXPECT_TRUE(s.collisional->jamming_friction);
  io::apply_override(s, "collisional.restitution.use=\"dissipation_only\"");  // quoted, as before
  EXPECT_EQ(s.collisional->restitution, RestitutionUse::DissipationOnly);
  io::apply_override(s, "collisional.restitution.use=everywhere");
  EXPECT_EQ(s.collisional->restitution, RestitutionUse::Everywhere);
  try {
    io::apply_override(s, "frictional.K0=high");
    ADD_FAILURE() << "accepted a word for a number";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'frictional.K0': expected a number, got a string"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(io::apply_override(s, "frictional.K0=1 2"), InputError);  // not one value, not a bare word
}

TEST(ParameterSet, CollisionalOptionErrorsNameTheKey) {
  auto with = [](const std::string& section) { return "mu_p = 0.2\n\n" + section; };
  expect_error("mu_p = 0.2", with("[collisional.jamming]\nmodel = \"friction\"\nV_sd_inf = 0.7\nmu_star = 0.1\n"),
               {"collisional.jamming.V_sd_inf", "frictionless V_sd"});
  expect_error("mu_p = 0.2", with("[collisional.jamming]\nmodel = \"friction\"\nV_sd_inf = 0.35\nmu_star = 0.1\n"),
               {"collisional.jamming.V_sd_inf", "V_m"});
  expect_error("mu_p = 0.2", with("[collisional.jamming]\nmodel = \"friction\"\nV_sd_inf = 0.58\n"),
               {"collisional.jamming.mu_star", "missing"});
  expect_error("mu_p = 0.2", with("[collisional.jamming]\nmodel = \"linear\"\n"), {"collisional.jamming.model", "'friction'"});
  expect_error("mu_p = 0.2", with("[collisional.correlation_length]\nc = -1\n"), {"collisional.correlation_length.c", "> 0"});
  expect_error("mu_p = 0.2", with("[collisional.dilute]\nmodel = \"burnett\"\n"), {"collisional.dilute.model"});
  expect_error("mu_p = 0.2", with("[collisional.restitution]\nuse = \"both\"\n"), {"collisional.restitution.use"});
  expect_error("mu_p = 0.2", with("[collisional.dilute]\nmodel = \"uniform_shear\"\nc = 1\n"),
               {"unknown key 'collisional.dilute.c'"});
  expect_error("mu_p = 0.2", with("[collisional.jaming]\nmodel = \"friction\"\n"), {"collisional.jaming"});
  // e0 against the jamming fraction at the set's mu_p: V_sd(0.2) = 0.58 + 0.037 e^-2 = 0.585 < V_s0 = 0.606
  expect_error("mu_p = 0.2\n\n[initial]\ne0 = 0.95",
               with("[collisional.jamming]\nmodel = \"friction\"\nV_sd_inf = 0.58\nmu_star = 0.1\n\n[initial]\ne0 = 0.65"),
               {"V_sd = 0.585", "e0 = 0.65"});
}
