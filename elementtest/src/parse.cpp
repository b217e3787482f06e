// Reading element-test files: strict validation with io::TomlTable (unknown keys are errors
// naming file, line and key).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "granflow/elementtest/run.hpp"
#include "test_file_text.hpp"
#include <granflow/io/csv_table.hpp>
#include <granflow/io/toml_reader.hpp>

namespace granflow::elementtest {

namespace {

LoadingPath path_of(const std::string& s) {
  if (s == "simple_shear_constant_normal") return LoadingPath::SimpleShearConstantNormal;
  if (s == "drained_triaxial") return LoadingPath::DrainedTriaxial;
  if (s == "undrained_triaxial") return LoadingPath::UndrainedTriaxial;
  if (s == "oedometric") return LoadingPath::Oedometric;
  if (s == "isotropic") return LoadingPath::Isotropic;
  return LoadingPath::UndrainedSimpleShear;
}

}  // namespace

ElementTest parse_element_test(io::TomlTable& t) {
  using io::Bounds;
  ElementTest et;
  et.file = t.file();
  et.name = t.string_or("name", "");
  et.path = path_of(t.choice("path",
                             {"undrained_simple_shear", "simple_shear_constant_normal", "drained_triaxial",
                              "undrained_triaxial", "oedometric", "isotropic"},
                             "undrained_simple_shear"));
  const std::string model = t.choice("model", {"auto", "frictional", "collisional", "phase_transition"}, "auto");
  et.model = model == "frictional"    ? ModelChoice::Frictional
             : model == "collisional" ? ModelChoice::Collisional
             : model == "phase_transition" ? ModelChoice::PhaseTransition
                                           : ModelChoice::Auto;

  // Rate programme.
  RateProgramme& g = et.programme;
  const std::string prog = t.choice("programme", {"constant", "acceleration", "table", "sweep", "data"}, "constant");
  g.rate = t.number_or("rate", g.rate, Bounds::non_negative());
  const auto acc = t.optional_number("acceleration", Bounds::any());
  const auto hold = t.optional_number("hold", Bounds::non_negative());
  const auto duration = t.optional_number("duration", Bounds::positive());
  const bool has_file = t.has("rate_file");
  const std::string rate_file = t.string_or("rate_file", "");
  const bool has_rates = t.has("rates");
  std::vector<double> rates;
  if (has_rates)
    rates = t.numbers("rates", Bounds::positive());
  else
    (void)t.optional_number("rates");  // absent: only lists it among the allowed keys
  const auto rmin = t.optional_number("rate_min", Bounds::positive());
  const auto rmax = t.optional_number("rate_max", Bounds::positive());
  const long per_decade = t.integer_or("rates_per_decade", 4, 1, 1000);
  const auto sweep_strain = t.optional_number("sweep_strain", Bounds::positive());
  const bool has_direction = t.has("direction");
  g.direction = t.choice("direction", {"compression", "extension"}, "compression") == "extension" ? -1.0 : 1.0;
  const bool has_data_file = t.has("data_file");
  const std::string data_file = t.string_or("data_file", "");
  const bool has_control_column = t.has("control_column");
  g.control_column = t.string_or("control_column", "");
  const bool has_control = t.has("control");
  g.control = t.choice("control", {"strain", "stress"}, "strain") == "stress" ? Control::Stress : Control::Strain;

  auto forbid = [&](bool present, const std::string& key, const std::string& why) {
    if (present) t.fail(key, "not used by programme '" + prog + "'" + why);
  };
  if (prog == "constant") {
    g.kind = ProgrammeKind::Constant;
    if (!(g.rate > 0)) t.fail("rate", "must be > 0 for programme 'constant'");
    g.duration = duration.value_or(1.0);
  } else if (prog == "acceleration") {
    g.kind = ProgrammeKind::Acceleration;
    if (!acc) t.fail("acceleration", "required key is missing for programme 'acceleration' [1/s^2]");
    g.acceleration = *acc;
    g.hold = hold.value_or(0.0);
    if (!duration) t.fail("duration", "required key is missing for programme 'acceleration' [s]");
    g.duration = *duration;
    if (!(g.hold < g.duration)) t.fail("hold", "must be shorter than duration");
    if (g.rate + g.acceleration * (g.duration - g.hold) < 0)
      t.fail("acceleration", "the rate would become negative before 'duration'");
  } else if (prog == "table") {
    g.kind = ProgrammeKind::Table;
    if (!has_file) t.fail("rate_file", "required key is missing for programme 'table' (CSV with columns time,rate)");
    std::filesystem::path p(rate_file);
    std::error_code ec;  // a name the OS refuses (too long, ...) is an input error further on, not a throw here
    if (p.is_relative() && !std::filesystem::exists(p, ec))
      p = std::filesystem::path(t.file()).parent_path() / p;
    g.table_file = p.string();
    const io::CsvColumns c = io::read_csv_columns(g.table_file, {"time", "rate"});
    g.table_time = c.column("time");
    g.table_rate = c.column("rate");
    if (g.table_time.size() < 2) throw io::InputError(io::where(g.table_file) + "a rate table needs at least 2 rows");
    for (std::size_t i = 0; i < g.table_time.size(); ++i) {
      if (i > 0 && g.table_time[i] < g.table_time[i - 1])
        throw io::InputError(io::where(g.table_file, c.lines[i]) + "'time' must not decrease (equal times = a jump)");
      if (g.table_rate[i] < 0) throw io::InputError(io::where(g.table_file, c.lines[i]) + "'rate' must be >= 0");
    }
    if (std::fabs(g.table_time.front()) > 0)
      throw io::InputError(io::where(g.table_file, c.lines[0]) + "the rate table must start at time 0");
    g.duration = duration.value_or(g.table_time.back());
    if (g.duration > g.table_time.back())
      t.fail("duration", "extends past the last time of the rate table");
  } else if (prog == "data") {
    g.kind = ProgrammeKind::Data;
    if (!(g.rate > 0)) t.fail("rate", "must be > 0 for programme 'data' (|d control/dt|)");
    if (!has_control_column) t.fail("control_column", "required key is missing for programme 'data' (the column the test follows)");
    forbid(duration.has_value(), "duration", " (the data rows set the end)");
    forbid(has_direction, "direction", " (the sign of the data's changes sets it)");
    if (has_data_file) {
      std::filesystem::path p(data_file);
      std::error_code ec;
      if (p.is_relative() && !std::filesystem::exists(p, ec)) p = std::filesystem::path(t.file()).parent_path() / p;
      load_programme_data(et, p.string());
    }
  } else {
    g.kind = ProgrammeKind::Sweep;
    if (has_rates) {
      g.sweep_rates = rates;
      if (rmin || rmax) t.fail("rate_min", "give either 'rates' or 'rate_min'/'rate_max', not both");
    } else {
      if (!rmin || !rmax) t.fail("rates", "programme 'sweep' needs 'rates' or 'rate_min' and 'rate_max'");
      if (!(*rmax > *rmin)) t.fail("rate_max", "must exceed rate_min");
      // In logarithms: rate_max / rate_min can overflow (rate_min = 5e-324 gave inf and an
      // inf -> int conversion, undefined behaviour; found by fuzzing), and at least one step.
      const double lo = std::log10(*rmin), decades = std::log10(*rmax) - lo;
      const double steps = std::ceil(decades * per_decade - 1e-9);
      constexpr double kMaxSweepRates = 100000;
      if (!(steps <= kMaxSweepRates)) {
        std::ostringstream os;
        os << "the sweep from rate_min to rate_max (" << decades << " decades at " << per_decade
           << " per decade) would need more than " << kMaxSweepRates << " rates";
        t.fail("rate_max", os.str());
      }
      const int n = std::max(1, static_cast<int>(steps));
      for (int i = 0; i <= n; ++i) g.sweep_rates.push_back(std::pow(10.0, lo + decades * double(i) / n));
      g.sweep_rates.front() = *rmin;
      g.sweep_rates.back() = *rmax;
    }
    g.sweep_strain = sweep_strain.value_or(g.sweep_strain);
  }
  if (prog != "acceleration") {
    forbid(acc.has_value(), "acceleration", "");
    forbid(hold.has_value(), "hold", "");
  }
  if (prog != "table") forbid(has_file, "rate_file", "");
  if (prog != "data") {
    forbid(has_data_file, "data_file", "");
    forbid(has_control_column, "control_column", "");
    forbid(has_control, "control", "");
  }
  if (prog != "sweep") {
    forbid(has_rates, "rates", "");
    forbid(rmin.has_value(), "rate_min", "");
    forbid(rmax.has_value(), "rate_max", "");
    forbid(sweep_strain.has_value(), "sweep_strain", "");
  } else {
    forbid(duration.has_value(), "duration", " (each rate runs to sweep_strain)");
  }

  const bool shear = et.path == LoadingPath::UndrainedSimpleShear || et.path == LoadingPath::SimpleShearConstantNormal;
  if (has_direction && shear) t.fail("direction", "only for axial paths (triaxial, oedometric, isotropic)");
  if (g.control == Control::Stress && et.path != LoadingPath::Oedometric)
    t.fail("control", "\"stress\" (stress-controlled loading) needs path = \"oedometric\"");
  if (prog == "data" && shear) t.fail("programme", "'data' drives the axial strain or stress: use an axial path");

  // Initial state.
  InitialState& in = et.initial;
  in.e0 = t.number_or("e0", in.e0, Bounds::open(0.0, 2.97));
  in.sigma_v0 = t.number_or("sigma_v0", in.sigma_v0, Bounds::positive());
  const bool has_k0 = t.has("k0");
  const auto k0 = t.optional_number("k0", Bounds::open(0.0, 10.0));
  const std::string init = t.choice("initial_stress", {"isotropic", "k0"}, has_k0 ? "k0" : "isotropic");
  if (k0) {
    if (init != "k0") t.fail("k0", "only with initial_stress = \"k0\"");
    in.k0 = *k0;
  } else {
    in.k0 = init == "k0" ? -1.0 : 1.0;  // -1: Jaky's 1 - sin(phi_c), resolved when run
  }
  in.T0 = t.number_or("T0", -1.0, Bounds::non_negative());

  // Solver.
  SolverSettings& s = et.solver;
  const std::string solver = t.choice("solver", {"cvode", "incremental"}, "cvode");
  s.kind = solver == "cvode" ? SolverKind::Cvode : SolverKind::Incremental;
  const auto rtol = t.optional_number("rtol", Bounds::open(0.0, 1.0));
  const auto atol = t.optional_number("atol", Bounds::positive());
  const auto dt = t.optional_number("dt", Bounds::positive());
  s.max_steps = t.integer_or("max_steps", s.max_steps, 1, 2000000000L);
  if (s.kind == SolverKind::Cvode) {
    if (dt) t.fail("dt", "only with solver = \"incremental\"");
    s.rtol = rtol.value_or(s.rtol);
    s.atol = atol.value_or(s.atol);
  } else {
    if (rtol) t.fail("rtol", "only with solver = \"cvode\"");
    if (atol) t.fail("atol", "only with solver = \"cvode\"");
    s.dt = dt.value_or(s.dt);
  }

  // Output.
  if (prog == "data" && t.has("outputs")) t.fail("outputs", "programme 'data' writes one row per data row");
  if (prog == "data" && t.has("output_spacing")) t.fail("output_spacing", "programme 'data' writes one row per data row");
  et.output.points = static_cast<int>(t.integer_or("outputs", et.output.points, 2, 10000000));
  et.output.log_spacing = t.choice("output_spacing", {"linear", "log"}, "linear") == "log";
  t.finish();
  return et;
}

void load_programme_data(ElementTest& test, const std::string& file) {
  RateProgramme& g = test.programme;
  const io::CsvColumns c = io::read_csv_columns(file, {g.control_column});
  g.data_file = file;
  g.data_control = c.column(g.control_column);
  g.data_lines = c.lines;
  if (g.data_control.size() < 2) throw io::InputError(io::where(file) + "programme 'data' needs at least 2 rows");
  if (g.control == Control::Strain) io::check_strain_column(c, g.control_column);
}

TestFile load_test_file(const std::string& path) {
  return read_test_file(io::TomlTable::parse_file(path), path);
}

TestFile parse_test_file_text(const std::string& text, const std::string& path) {
  return read_test_file(io::TomlTable::parse_text(text, path), path);
}

TestFile read_test_file(const toml::table& doc, const std::string& path) {
  io::TomlTable root(doc, path);
  TestFile f;
  f.params = root.string_or("params", f.params);
  if (root.has("overrides")) {
    const toml::node* n = root.raw().get("overrides");
    if (!n->is_array()) root.fail("overrides", "expected an array of strings \"section.key=value\"");
    for (const auto& v : *n->as_array()) {
      if (!v.is_string()) root.fail("overrides", "expected an array of strings \"section.key=value\"");
      f.overrides.push_back(v.as_string()->get());
    }
  }
  (void)root.string_or("description", "");
  auto t = root.table("test");
  f.test = parse_element_test(t);
  if (f.test.name.empty()) f.test.name = std::filesystem::path(path).stem().string();
  // The root is checked by hand: 'overrides' is an array of strings, which TomlTable has no reader for.
  for (const auto& [k, v] : root.raw()) {
    const std::string key(k.str());
    if (key != "params" && key != "overrides" && key != "test" && key != "description") {
      std::ostringstream os;
      os << "unknown key '" << key << "' (allowed at top level: params, overrides, description, [test])";
      long line = v.source().begin ? static_cast<long>(v.source().begin.line) : 0;
      throw io::InputError(io::where(path, line) + os.str());
    }
  }
  return f;
}

}  // namespace granflow::elementtest
