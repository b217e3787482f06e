// Subcommands of the granflow program; each lives in cmd_<name>.cpp.
#pragma once

#include <CLI/CLI.hpp>

namespace granflow::cli {

// Thrown by a command that has printed its own message: granflow exits with this status.
struct ExitStatus {
  int code;
};

void register_element(CLI::App& app);
void register_figures(CLI::App& app);
void register_calibrate(CLI::App& app);
void register_mpm(CLI::App& app);
void register_ensemble(CLI::App& app);
void register_bench(CLI::App& app);

}  // namespace granflow::cli
