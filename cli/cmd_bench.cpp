// granflow bench: benchmarks that print figures (element-test and MPM timings).
#include "commands.hpp"

namespace granflow::cli {

void register_bench_element(CLI::App& bench);  // cmd_element.cpp
void register_bench_mpm(CLI::App& bench);      // cmd_mpm.cpp

void register_bench(CLI::App& app) {
  auto* cmd = app.add_subcommand("bench", "Benchmarks: print timings and accuracy figures");
  cmd->require_subcommand(1);
#ifdef GRANFLOW_WITH_SOLVERS
  register_bench_element(*cmd);
#endif
  register_bench_mpm(*cmd);
}

}  // namespace granflow::cli
