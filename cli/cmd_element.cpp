// granflow element: drive one material point through an element test (CVODE or the MPM's
// incremental update) and write the CSV time series. Also `granflow bench element`.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <granflow/elementtest/paper.hpp>
#include <granflow/elementtest/run.hpp>

#include "commands.hpp"
#include <granflow/io/input_error.hpp>
#include <granflow/io/output.hpp>
#include <granflow/io/parameter_set.hpp>

namespace granflow::cli {

namespace {

struct ElementOptions {
  std::string test_file;
  std::string params;
  std::vector<std::string> overrides;
  std::string out;
  bool force = false;
};

// Checked before a run, so that a bad --out fails at once and not after the run: the folder
// must exist, the path must not be a folder, and an existing file needs --force.
void check_output_path(const std::string& path, bool force) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty() && !fs::is_directory(parent, ec))
    throw io::InputError(io::where(path) + "output folder '" + parent.string() +
                         "' does not exist (create it first; --out takes a file name)");
  if (fs::is_directory(path, ec))
    throw io::InputError(io::where(path) + "is a directory; --out takes a file name, e.g. " +
                         (fs::path(path) / "result.csv").string());
  if (fs::exists(path, ec) && !force)
    throw io::InputError(io::where(path) + "file exists; use --force to overwrite it");
}

// Writes text to path through the output layer; refuses to overwrite unless force. On failure
// nothing is left under a temporary name and an existing file at path is left as it was.
void write_result(const std::string& path, const std::string& text, bool force) {
  check_output_path(path, force);
  io::write_file(path, text);
}

void print_table(const elementtest::ResultTable& r, int rows) {
  std::printf("%10s %10s %11s %12s %12s %12s %12s %12s %8s\n", "t[s]", "gamma", "rate[1/s]", "sigma_n[Pa]", "tau[Pa]",
              "tau_f[Pa]", "tau_c[Pa]", "T[m2/s2]", "K_col");
  const std::size_t n = r.rows();
  const std::size_t every = std::max<std::size_t>(1, (n - 1) / std::max(1, rows - 1));
  for (std::size_t i = 0; i < n; ++i) {
    if (i % every != 0 && i + 1 != n) continue;
    std::printf("%10.4g %10.4g %11.4g %12.5g %12.5g %12.5g %12.5g %12.5g %8.4f\n", r.column("time")[i],
                r.column("gamma")[i], r.column("shear_rate")[i], r.column("sigma_n")[i], r.column("tau")[i],
                r.column("tau_f")[i], r.column("tau_c")[i], r.column("T")[i], r.column("K_col")[i]);
  }
}

void run_element(const ElementOptions& o) {
  elementtest::ElementTest test;
  std::string params = "element_test";
  std::vector<std::string> overrides;
  if (o.test_file.empty()) {
    test = elementtest::paper::fig6_test(0.99);
    test.output.points = 41;
  } else {
    elementtest::TestFile tf = elementtest::load_test_file(o.test_file);
    test = tf.test;
    params = tf.params;
    overrides = tf.overrides;
  }
  if (!o.params.empty()) params = o.params;
  io::ParameterSet set = io::load_parameter_set(params);
  for (const auto& a : overrides) io::apply_override(set, a, o.test_file + ": overrides");
  for (const auto& a : o.overrides) io::apply_override(set, a);
  if (!o.out.empty()) check_output_path(o.out, o.force);

  const auto t0 = std::chrono::steady_clock::now();
  bool shown = false;
  auto progress = [&](double f) {
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (el > 1.0) {
      std::fprintf(stderr, "\r  %s: %5.1f %% (%.1f s)", test.name.c_str(), 100 * f, el);
      shown = true;
    }
  };
  const elementtest::ResultTable r = elementtest::run_element_test(test, set, progress);
  if (shown) std::fprintf(stderr, "\n");
  if (o.test_file.empty())
    std::printf("# default job: Fig. 6 undrained simple shear, %s, e0 = %.2f, sigma_v0 = %g Pa,\n"
                "# 10 1/s for 0.5 s then 50 1/s^2 to 20 s (CVODE rtol %g)\n",
                set.name.c_str(), test.initial.e0, test.initial.sigma_v0, test.solver.rtol);
  if (o.out.empty()) {
    print_table(r, 21);
  } else {
    write_result(o.out, r.to_csv(), o.force);
    std::printf("wrote %s (%zu rows)\n", o.out.c_str(), r.rows());
  }
  std::printf("# %ld steps, %ld right-hand-side evaluations, %ld events, %.3f ms CPU%s\n", r.stats.steps,
              r.stats.rhs_evals, r.stats.events, 1e3 * r.stats.cpu_seconds,
              r.stats.tension_cutoff ? ("; frictional stress vanished (p_f = 0) at t = " +
                                        std::to_string(r.stats.cutoff_time) + " s")
                                           .c_str()
                                     : "");
}

}  // namespace

void register_element(CLI::App& app) {
  auto opt = std::make_shared<ElementOptions>();
  auto* cmd = app.add_subcommand(
      "element",
      "Drive one material point through an element test (TOML test file; without one: the paper's Fig. 6 "
      "undrained simple shear, e0 = 0.99)");
  cmd->add_option("test", opt->test_file, "Test file (TOML with params = ... and a [test] table)");
  cmd->add_option("--params", opt->params, "Parameter set: name under data/params or a TOML path (overrides the file's)");
  cmd->add_option("--set", opt->overrides, "Override one parameter, e.g. --set frictional.phi_c_deg=25");
  cmd->add_option("--out", opt->out, "Write the CSV time series here (otherwise a short table is printed)");
  cmd->add_flag("--force", opt->force, "Overwrite an existing --out file");
  cmd->callback([opt] { run_element(*opt); });
}

void register_bench_element(CLI::App& bench) {
  auto out = std::make_shared<std::string>("docs/figures");
  auto quick = std::make_shared<bool>(false);
  auto* cmd = bench.add_subcommand(
      "element", "Error against run time: CVODE rtol 1e-2..1e-10 and incremental dt 1e-2..1e-7 s (Figs. 4 and 6)");
  cmd->add_option("--out", *out, "Folder for bench_element.csv and the work-precision PNG")->capture_default_str();
  cmd->add_flag("--quick", *quick, "Fewer tolerances and steps (for a smoke test)");
  cmd->callback([out, quick] { elementtest::paper::bench_element(*out, *quick, std::cout); });
}

}  // namespace granflow::cli
