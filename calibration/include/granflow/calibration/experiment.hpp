// Experiments of a calibration: a model computation paired with measured curves.
// Each curve is one data column against one abscissa column, mapped to one model output.
// Two kinds: steady simple-shear flow curves from the closed forms of MODEL.md 5.3
// (the DEM / shear-cell case) and element tests run by the element-test driver.
#pragma once

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <granflow/io/parameter_set.hpp>

namespace granflow::io {
class TomlTable;
}

namespace granflow::calibration {

struct Curve {
  std::string experiment;    // name of the experiment (with its split values)
  std::string data_column;   // measured column
  std::string model_output;  // model quantity it is compared with
  std::string abscissa;      // abscissa column (for labels)
  std::vector<double> x, y;  // data, x strictly increasing (unless branch is set)
  // Abscissa that reverses (abscissa_reverses): the monotonic run each point lies on, counted
  // from 0; the model's runs are found with the same tolerance and matched in order. Empty: x increases.
  std::vector<int> branch;
  double reversal_tolerance = 0;
  std::vector<long> lines;   // file line of each point (first of averaged duplicates)
  std::string file;          // the data file the points come from
  double weight = 1.0;
  // Standard deviation of the data in data units for the Gaussian likelihood of the ensemble
  // method (NaN: the job's default for its kind; docs/calibration.md, "Uncertainty").
  double sd = std::numeric_limits<double>::quiet_NaN();
  std::string label() const { return experiment + ":" + data_column; }
};

// Model values at each curve's abscissae (values[c][i]). A value the model cannot produce is
// NaN; a whole failed computation sets ok = false with a message.
struct Prediction {
  std::vector<std::vector<double>> values;
  bool ok = true;
  std::string error;
};

class Experiment {
 public:
  virtual ~Experiment() = default;
  std::string name;
  std::string kind;               // "steady_shear" or "element"
  std::string abscissa_quantity;  // time, strain, shear_rate, solid_fraction
  std::string data_file;
  std::vector<Curve> curves;
  virtual Prediction predict(const io::ParameterSet& params) const = 0;
  // Predictions for many sets at once. Batched experiments (MPM scenes: one ensemble run for all
  // sets) override it; the others are evaluated set by set on the caller's threads.
  virtual bool batched() const { return false; }
  virtual std::vector<Prediction> predict_batch(const std::vector<io::ParameterSet>& sets) const {
    std::vector<Prediction> out;
    for (const auto& s : sets) out.push_back(predict(s));
    return out;
  }
  // Parameters the experiment takes from its data instead of the set (written into the fitted file).
  virtual std::string data_parameters() const { return ""; }
  // The [[experiments]] name before any split suffix (per-test free parameters address it).
  std::string base_name;
  // Initial void ratio of an element test (the start of a per-test free e0); NaN for other kinds.
  virtual double initial_void_ratio() const { return std::numeric_limits<double>::quiet_NaN(); }
  // The element test's loading path as in a test file ("drained_triaxial", ...); "" for other kinds.
  virtual std::string loading_path() const { return ""; }
  // Particle friction and restitution a steady-shear group takes from its data columns (NaN: none).
  virtual double data_friction() const { return std::numeric_limits<double>::quiet_NaN(); }
  virtual double data_restitution() const { return std::numeric_limits<double>::quiet_NaN(); }
  // Highest abscissa value (for the steady-shear V_sd check).
  double x_max() const;
};

// Selection of rows of a data file: the part of an [[experiments]] table shared by all kinds.
struct DataSelection {
  std::string file;                      // resolved path
  std::string abscissa;                  // column
  std::string quantity;                  // time | strain | shear_rate | solid_fraction
  std::string model_abscissa;            // the model output the abscissa is (element tests; may be empty)
  std::vector<std::pair<std::string, double>> filter;
  std::vector<std::string> split_by;
  std::vector<std::string> extra_columns;  // columns the experiment reads per group (constant within it)
  double x_lo = -1e300, x_hi = 1e300;
  bool average_duplicates = false;
  bool reverses = false;            // abscissa_reverses: monotonic runs (Curve::branch) instead of increasing
  double reversal_tolerance = 0;    // a move back by more than this starts a new run
  std::vector<std::pair<std::string, std::string>> targets;  // data column -> model output
  std::vector<double> target_weights;
  std::vector<double> target_sd;  // per target: Curve::sd (NaN: the job's default)
  double weight = 1.0;
};

// One group of rows after filtering and splitting: its curves and the values of the extra columns.
struct DataGroup {
  std::string suffix;  // "[restitution_e=0.7]" for split groups, else ""
  std::vector<Curve> curves;
  std::vector<double> extra;  // value of each extra column (checked constant in the group)
};

std::vector<DataGroup> select_data(const DataSelection& sel, const std::string& experiment_name);

// Monotonic runs of x: the run index of each point. A run ends at its extreme once x has moved
// back from it by more than `tolerance`; smaller moves back stay in the run.
std::vector<int> abscissa_branches(const std::vector<double>& x, double tolerance);

// Steady simple shear (closed forms of MODEL.md 5.3): outputs p, tau, T, mu.
struct SteadyShearSpec {
  bool dimensionless = true;      // p, tau in rho_p d^2 gammadot^2; T in d^2 gammadot^2
  double shear_rate = 1.0;        // when the abscissa is the solid fraction
  double solid_fraction = 0.0;    // when the abscissa is the shear rate
  std::string restitution_column; // take eps_n from this column (constant per curve group)
  std::string friction_column;    // take mu_p from this column
};
std::vector<std::shared_ptr<const Experiment>> make_steady_shear_experiments(const std::string& name,
                                                                               const DataSelection& sel,
                                                                               const SteadyShearSpec& spec);
const std::vector<std::string>& steady_shear_outputs();

// Element tests through granflow_elementtest (when the library is built).
bool element_tests_available();
const std::vector<std::string>& element_test_outputs();
std::vector<std::shared_ptr<const Experiment>> make_element_experiments(const std::string& name,
                                                                        const DataSelection& sel,
                                                                        io::TomlTable& test_table,
                                                                        const std::string& model_abscissa);

// MPM scenes (kind = "mpm_scene", scene_experiment.cpp): the [[experiments]] table names a scene
// file, fixed --set overrides, and measured data (final free surface, front against time, a
// tracked point's path), each with its standard deviation. `job_file` resolves relative paths.
std::shared_ptr<const Experiment> make_scene_experiment(io::TomlTable& table, const std::string& job_file,
                                                        std::size_t index);

// Several MPI ranks (mpm/ranks.hpp; docs/calibration.md, "Several processes"): rank 0 runs the
// calibration and splits each batch of more than one set of an mpm_scene experiment over the
// ranks. The other ranks call serve_scene_batches with the job's experiments; it returns when
// rank 0 calls end_scene_batches. Both do nothing in one process.
void serve_scene_batches(const std::vector<std::shared_ptr<const Experiment>>& experiments);
void end_scene_batches();

// Synthetic data for an element experiment: runs the test with `truth`, keeps every `stride`-th
// output row after the first, multiplies every target by (1 + noise * N(0,1)) from a generator
// seeded with `seed` and returns the text of sel.file (the abscissa and target columns). Used by
// the round-trip tests and the benchmark's synthetic curves.
std::string synthesize_element_data(const DataSelection& sel, io::TomlTable& test_table,
                                    const std::string& model_abscissa, const io::ParameterSet& truth, double noise,
                                    unsigned long seed, long stride);

}  // namespace granflow::calibration
