// Placeholder until the calibrate job exists; registered so --help lists it.
#include <iostream>

#include "commands.hpp"

namespace granflow::cli {

void register_calibrate(CLI::App& app) {
  auto* cmd = app.add_subcommand("calibrate", "(calibrate: not yet implemented in this version)");
  cmd->allow_extras();
  cmd->callback([] {
    std::cerr << "granflow calibrate: not implemented yet\n";
    std::exit(3);
  });
}

}  // namespace granflow::cli
