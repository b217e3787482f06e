// What granflow mpm, granflow bench mpm and granflow ensemble share: scene set-up with
// overrides, the --params/--set and CUDA options, the runner, signal handling, helper scripts.
#pragma once

#include <signal.h>

#include <csignal>
#include <memory>
#include <string>
#include <utility>

#include <CLI/CLI.hpp>

#include <granflow/io/input_error.hpp>
#include <granflow/mpm/runner.hpp>
#include <granflow/mpm/scene_file.hpp>

namespace granflow::cli {

// precision: "" keeps the scene's solver.precision; fp64 | mixed | fp32 overrides it.
mpm::SceneSetup setup_from_file(const std::string& file, const mpm::SceneOverrides& overrides,
                                const std::string& precision);
// A word as the shell reads it back: quoted unless it is plain.
std::string shell_word(const std::string& w);
// --params and --set as given, for a command line to print.
std::string override_args(const mpm::SceneOverrides& ov);
// --params and --set: the same options for every MPM command.
void add_override_options(CLI::App* cmd, mpm::SceneOverrides& ov);

// The CUDA backend's options as given on the command line (name -> value, unset ones empty).
struct CudaFlags {
  std::string graphs, graph_steps, sort, p2g, g2p_block, g2p_regcap, g2p_split, update_stats;
  mpm::CudaOptions options() const {
    mpm::CudaOptions o;
    const std::pair<const char*, const std::string*> all[] = {{"graphs", &graphs}, {"graph-steps", &graph_steps},
                                                              {"sort", &sort},     {"p2g", &p2g},
                                                              {"g2p-block", &g2p_block}, {"g2p-regcap", &g2p_regcap},
                                                              {"g2p-split", &g2p_split}, {"update-stats", &update_stats}};
    for (const auto& [name, value] : all)
      if (!value->empty() && !mpm::set_cuda_option(o, name, *value))
        throw io::InputError(std::string("--") + name + ": invalid value '" + *value + "'");
    return o;
  }
  void add(CLI::App* cmd) {
    cmd->add_option("--graphs", graphs, "CUDA: replay captured chunks of steps as graphs (on|off; default on)");
    cmd->add_option("--graph-steps", graph_steps, "CUDA: longest captured chunk in steps (default 32)");
    cmd->add_option("--sort", sort, "CUDA: reorder particles by cell every N steps (0: never; default 32)");
    cmd->add_option("--p2g", p2g, "CUDA: P2G scatter atomic|warp|tile (default warp)");
    cmd->add_option("--g2p-block", g2p_block, "CUDA: threads per block of G2P + constitutive (default 128)");
    cmd->add_option("--g2p-regcap", g2p_regcap, "CUDA: G2P + constitutive with at most 168 registers (on|off)");
    cmd->add_option("--update-stats", update_stats,
                    "CUDA: reduce the per-point update records after every step: the plastic returns' cost in the "
                    "report (on|off; default off; the CPU twin always does)");
    cmd->add_option("--g2p-split", g2p_split,
                    "CUDA: G2P in two passes, elastic updates then the deferred plastic returns (auto|on|off; default auto: from 2 waves of the fused kernel)");
  }
};

std::unique_ptr<mpm::Runner> make_runner(const mpm::SceneSetup& su, const std::string& backend,
                                         const CudaFlags& flags, int devices = 1);
// --backend cuda where it cannot run: an InputError, the same for every MPM command, before
// anything is set up or written.
void require_backend(const std::string& backend);

// The "plastic returns" line of an UpdateStats (nothing when no update was plastic): share,
// residual evaluations, halvings, hand-overs and how the slow points sit in 32-point groups.
void print_plastic_returns(const mpm::UpdateStats& u);

// scripts/NAME from the working directory or beside the installed data; "" when not found.
std::string locate_script(const std::string& name);

// Set by SIGINT/SIGTERM while a SignalGuard lives; the time loops poll it after every step.
extern volatile std::sig_atomic_t g_signal;
// Installs the handlers for its lifetime. A second Ctrl-C stops at once, except during a
// checkpoint write (io::CriticalWrite): that one finishes first, so a --restart finds it.
class SignalGuard {
 public:
  SignalGuard();
  ~SignalGuard();
  SignalGuard(const SignalGuard&) = delete;
  SignalGuard& operator=(const SignalGuard&) = delete;

 private:
  struct sigaction old_int_ {}, old_term_ {};
};

}  // namespace granflow::cli
