// granflow element: constant-volume simple shear of one material point with the MPM's
// incremental update (the CVODE driver and other loading paths come with the element-test job).
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include <granflow/constitutive.hpp>

#include "commands.hpp"
#include "io/input_error.hpp"
#include "io/parameter_set.hpp"

namespace granflow::cli {

namespace {

struct ElementOptions {
  std::string params = "element_test";
  std::vector<std::string> overrides;
  double e0 = 0;  // 0: first e0 of the set
  double sigma_v0 = 500.0;
  double rate = 10.0;
  double duration = 0.5;
  double dt = 1e-5;
  int prints = 20;
};

void run_element(const ElementOptions& o) {
  io::ParameterSet set = io::load_parameter_set(o.params);
  for (const auto& a : o.overrides) io::apply_override(set, a);
  const double e0 = o.e0 > 0 ? o.e0 : (set.e0.empty() ? 0.0 : set.e0.front());
  if (!(e0 > 0)) throw io::InputError(io::where(set.file) + "no initial void ratio: give --e0 or initial.e0");
  io::check_initial_void_ratio(set, e0, "--e0");
  using Model = PhaseTransitionModel<double>;
  const auto p = set.phase_transition();
  Model::State st;
  st.sigma_f = -o.sigma_v0 * Mat3<double>::Identity();
  st.e = e0;
  st.s = std::sqrt(set.T0.value_or(1e-15));
  Mat3<double> L = Mat3<double>::Zero();
  L(0, 1) = o.rate;
  const long steps = static_cast<long>(o.duration / o.dt + 0.5);
  const long every = std::max(1L, steps / std::max(1, o.prints));
  std::printf("# undrained simple shear, %s, e0 = %.3f, sigma_v0 = %.1f Pa, gammadot = %g 1/s, dt = %g s\n",
              set.name.c_str(), e0, o.sigma_v0, o.rate, o.dt);
  std::printf("%10s %10s %12s %12s %12s %12s %12s %8s\n", "t[s]", "gamma", "sigma_v[Pa]", "tau[Pa]", "tau_f[Pa]",
              "tau_c[Pa]", "T[m2/s2]", "K_col");
  Mat3<double> stress = st.sigma_f;
  for (long i = 1; i <= steps; ++i) {
    const UpdateInfo inf = Model::update(p, st, L, o.dt, stress);
    if (!inf.ok()) throw std::runtime_error("constitutive update failed at step " + std::to_string(i));
    if (i % every == 0 || i == steps) {
      const Diagnostics<double> d = Model::diagnostics(p, st, sym(L));
      std::printf("%10.4f %10.4f %12.5g %12.5g %12.5g %12.5g %12.5g %8.4f\n", i * o.dt, i * o.dt * o.rate,
                  -stress(1, 1), stress(0, 1), st.sigma_f(0, 1), stress(0, 1) - st.sigma_f(0, 1), d.T, d.K_col);
    }
  }
}

}  // namespace

void register_element(CLI::App& app) {
  auto opt = std::make_shared<ElementOptions>();
  auto* cmd = app.add_subcommand("element", "Drive one material point through an element test");
  cmd->add_option("--params", opt->params, "Parameter set: name under data/params or a TOML path")
      ->capture_default_str();
  cmd->add_option("--set", opt->overrides, "Override one parameter, e.g. --set frictional.phi_c_deg=25");
  cmd->add_option("--e0", opt->e0, "Initial void ratio (default: first initial.e0 of the set)");
  cmd->add_option("--sigma-v0", opt->sigma_v0, "Initial isotropic stress [Pa]")->capture_default_str();
  cmd->add_option("--rate", opt->rate, "Shear rate [1/s]")->capture_default_str();
  cmd->add_option("--duration", opt->duration, "Duration [s]")->capture_default_str();
  cmd->add_option("--prints", opt->prints, "Rows printed")->capture_default_str();
  cmd->add_option("--dt", opt->dt, "Time step of the incremental update [s]")->capture_default_str();
  cmd->callback([opt] { run_element(*opt); });
}

}  // namespace granflow::cli

namespace granflow::cli {
void register_bench_element(CLI::App& bench) {
  auto* cmd = bench.add_subcommand("element", "(element-test benchmark: not yet implemented)");
  cmd->allow_extras();
  cmd->callback([] { throw std::runtime_error("granflow bench element: not implemented yet"); });
}
}  // namespace granflow::cli
