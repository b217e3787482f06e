// Subcommands of the granflow program; each lives in cmd_<name>.cpp.
#pragma once

#include <CLI/CLI.hpp>

namespace granflow::cli {

void register_element(CLI::App& app);
void register_figures(CLI::App& app);
void register_calibrate(CLI::App& app);
void register_mpm(CLI::App& app);
void register_bench(CLI::App& app);

}  // namespace granflow::cli
