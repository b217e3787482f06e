// Placeholder until the mpm job exists; registered so --help lists it.
#include <iostream>

#include "commands.hpp"

namespace granflow::cli {

void register_mpm(CLI::App& app) {
  auto* cmd = app.add_subcommand("mpm", "(mpm: not yet implemented in this version)");
  cmd->allow_extras();
  cmd->callback([] {
    std::cerr << "granflow mpm: not implemented yet\n";
    std::exit(3);
  });
}

void register_bench_mpm(CLI::App& bench) {
  auto* cmd = bench.add_subcommand("mpm", "(MPM benchmark: not yet implemented)");
  cmd->allow_extras();
  cmd->callback([] {
    std::cerr << "granflow bench mpm: not implemented yet\n";
    std::exit(3);
  });
}

}  // namespace granflow::cli
