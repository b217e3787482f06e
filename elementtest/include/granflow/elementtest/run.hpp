// Element-test driver: one material point driven through a laboratory loading path.
//
// The state (sigma_f, eps_pd, e, s = sqrt(T) and the strain measures) is integrated in time
// with SUNDIALS CVODE (BDF, dense direct solver, difference-quotient Jacobian) using the
// constitutive library's rate law unchanged, or advanced with the MPM's incremental update
// (Model::update) at a fixed step so that update can be measured against the CVODE solution.
//
// This header is the API the calibration toolkit codes against (issue 4): keep its names.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <granflow/io/input_error.hpp>    // granflow_io (io/)
#include <granflow/io/parameter_set.hpp>

namespace granflow::io {
class TomlTable;
}

namespace granflow::elementtest {

// Loading path. Axis 1 (y) is vertical / axial; stresses tension-positive inside, reported
// compression-positive (sigma_n = -sigma_yy).
enum class LoadingPath {
  UndrainedSimpleShear,  // v = (gammadot y, 0, 0): constant volume, the paper's test
  SimpleShearConstantNormal,  // v = (gammadot y, D_yy y, 0); D_yy solved so the normal stress stays constant
  DrainedTriaxial,    // axial compression at rate; lateral stress held constant (D_xx = D_zz solved)
  UndrainedTriaxial,  // axial compression at rate; D_xx = D_zz = rate/2 (isochoric)
  Oedometric,         // axial compression at rate; no lateral strain
  Isotropic           // D = -rate I
};

enum class ProgrammeKind {
  Constant,      // rate(t) = rate
  Acceleration,  // rate(t) = rate for t < hold, then rate + acceleration (t - hold)
  Table,         // piecewise-linear rate(t) from a CSV file (columns time, rate)
  Sweep,         // one constant-rate run per rate, each to sweep_strain; one output row per rate
  Data           // the control column of a data file, row by row (reversals allowed); one output row per data row
};

// What a Data programme's column prescribes: the axial strain (compression positive) or the axial
// stress [Pa] (compression positive; oedometric path only: stress-controlled oedometer).
enum class Control { Strain, Stress };

enum class SolverKind { Cvode, Incremental };

// Which model the test drives; Auto: both parts if the parameter set has both, else the one it has.
enum class ModelChoice { Auto, Frictional, Collisional, PhaseTransition };

struct RateProgramme {
  ProgrammeKind kind = ProgrammeKind::Constant;
  double rate = 10.0;          // [1/s] shear rate (shear paths) or axial compression rate (others)
  double acceleration = 0.0;   // [1/s^2] (Acceleration)
  double hold = 0.0;           // [s] initial constant-rate phase (Acceleration)
  double duration = 1.0;       // [s] end time (Constant, Acceleration; Table: last table time if 0)
  std::vector<double> table_time, table_rate;  // (Table) non-decreasing times; equal times = jump
  std::string table_file;                      // where the table came from (messages)
  std::vector<double> sweep_rates;             // (Sweep) [1/s], each > 0
  double sweep_strain = 5.0;  // (Sweep) strain (gamma or axial) each rate is run to
  double direction = 1.0;     // axial paths: +1 compression, -1 extension (not Data: its sign is the data's)
  // (Data) the control column, one value per data row; time advances by |change| / rate, so
  // `rate` is |d control / dt| [1/s or Pa/s] and the solvers restart only where it reverses.
  Control control = Control::Strain;
  std::vector<double> data_control;
  std::vector<long> data_lines;  // file line of each value (messages; may be empty)
  std::string data_file, control_column;
};

struct InitialState {
  double e0 = 0.99;
  double sigma_v0 = 500.0;   // [Pa] initial vertical stress, compression positive (frictional part)
  double k0 = 1.0;           // lateral / vertical stress ratio (1 = isotropic)
  double T0 = -1.0;          // [m^2/s^2]; < 0: the parameter set's T0, else 1e-15
};

// The point state a MaterialUpdate advances: frictional stress (tension +, row-major 3x3), eps_pd,
// void ratio, s = sqrt(T); it writes the total stress after the step into `stress`.
struct PointState {
  std::array<double, 9> sigma_f{};
  double eps_pd = 0, e = 0, s = 0;
  std::array<double, 9> stress{};
};
// A material update in place of the library's Model::update in the incremental solver: advances
// `state` over a step dt with the velocity gradient L (row-major 3x3) the solver chose and returns
// the update's flags (granflow::info; an error flag stops the run as the library's would). It
// drives another implementation of the law through the driver's loading paths (the UMAT's tests).
using MaterialUpdate = std::function<std::uint32_t(PointState& state, const std::array<double, 9>& L, double dt)>;

struct SolverSettings {
  SolverKind kind = SolverKind::Cvode;
  double rtol = 1e-6;
  double atol = 1e-9;    // on the scaled state (stresses / max(sigma_v0, 1 Pa), s / (d * 1 s^-1), strains)
  double dt = 1e-4;      // [s] step of the incremental update
  long max_steps = 5000000;  // CVODE steps or incremental steps per run
  MaterialUpdate material_update;  // incremental solver only; empty: the library's Model::update
};

struct OutputSettings {
  int points = 201;      // output rows (Constant/Acceleration/Table), at equally spaced times
  bool log_spacing = false;  // log-spaced output times (first at duration * 1e-4)
};

struct ElementTest {
  std::string name;      // for messages and progress
  std::string file;      // the test file (messages)
  LoadingPath path = LoadingPath::UndrainedSimpleShear;
  RateProgramme programme;
  InitialState initial;
  SolverSettings solver;
  OutputSettings output;
  ModelChoice model = ModelChoice::Auto;
};

// Reads the [test] table of a test file (strict: unknown keys are errors naming file/line/key).
// Keys (all optional except where stated):
//   path = "undrained_simple_shear" | "simple_shear_constant_normal" | "drained_triaxial" |
//          "undrained_triaxial" | "oedometric" | "isotropic"
//   model = "auto" | "frictional" | "collisional" | "phase_transition"
//   programme = "constant" | "acceleration" | "table" | "sweep" | "data"
//   rate, acceleration, hold, duration, rate_file (CSV with columns time,rate; relative paths
//   are taken from the test file's folder), rates (array) or rate_min/rate_max/rates_per_decade,
//   sweep_strain, direction = "compression" | "extension" (axial paths)
//   data: data_file (CSV; in a calibration job the experiment's data by default), control_column,
//   control = "strain" | "stress" (stress: oedometric path; the stress is held at sigma_v0 while
//   the column is below it)
//   e0, sigma_v0, k0 (number) or initial_stress = "isotropic" | "k0" (k0 = 1 - sin phi_c), T0
//   solver = "cvode" | "incremental", rtol, atol, dt, max_steps
//   outputs (rows), output_spacing = "linear" | "log"
ElementTest parse_element_test(io::TomlTable& test_table);

// Reads a Data programme's control column from `file` into test.programme (data_file, data_control).
void load_programme_data(ElementTest& test, const std::string& file);

// Column names (also the CSV header), in this order:
//   time, gamma, shear_rate, eps_v, eps_a, sigma_n_f, sigma_n_c, sigma_n, tau_f, tau_c, tau,
//   p_f, q_f, p_c, q_c, p, q, e, T, K_col, eta_c, eps_pd, sigma_xx, sigma_zz, eps_xx, eps_zz, q_axial
// See docs/elementtest.md for their meaning and units.
const std::vector<std::string>& result_column_names();

struct RunStats {
  long rhs_evals = 0;   // right-hand-side evaluations (CVODE, incl. Jacobian DQ) or update calls
  long steps = 0;       // CVODE steps or incremental steps
  long events = 0;      // elastic/plastic switches and tension cut-offs located
  long newton_fails = 0;
  double cpu_seconds = 0;
  bool tension_cutoff = false;  // p_f reached zero (static liquefaction)
  double cutoff_time = -1.0;
  long vs_clamped = 0;          // outputs where V_s was clamped below V_sd in the kinetic functions
};

struct ResultTable {
  std::vector<std::string> names;
  std::vector<std::vector<double>> columns;  // columns[i][row]
  RunStats stats;

  const std::vector<double>& column(const std::string& name) const;  // throws io::InputError if absent
  std::size_t rows() const { return columns.empty() ? 0 : columns.front().size(); }
  std::string to_csv() const;
};

// Called now and then with the fraction done (0..1) of the run.
using ProgressCallback = std::function<void(double fraction)>;

// Runs the test. Throws
//   io::InputError      for input that cannot run: a model part missing from the parameter set,
//                       e0 outside (0, 2.97) or V_s0 >= V_sd, an initial stress outside the yield
//                       surface (r0 >= g M_p), non-positive rates/durations/tolerances, an empty
//                       sweep or table;
//   std::runtime_error  when CVODE fails (message names the CVODE flag, the time and the state:
//                       p_f, q_f, e, T, eps_pd) or when the incremental update reports a
//                       non-finite or inadmissible state (time and state named), or when the
//                       step budget (max_steps) is exhausted.
ResultTable run_element_test(const ElementTest& test, const io::ParameterSet& params,
                             const ProgressCallback& progress = {});

// Reads a whole test file: params key (name or path) and optional overrides array, [test] table.
struct TestFile {
  ElementTest test;
  std::string params = "element_test";
  std::vector<std::string> overrides;  // "section.key=value"
};
TestFile load_test_file(const std::string& path);

}  // namespace granflow::elementtest
