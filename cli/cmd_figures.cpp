// Placeholder until the figures job exists; registered so --help lists it.
#include <iostream>

#include "commands.hpp"

namespace granflow::cli {

void register_figures(CLI::App& app) {
  auto* cmd = app.add_subcommand("figures", "(figures: not yet implemented in this version)");
  cmd->allow_extras();
  cmd->callback([] {
    std::cerr << "granflow figures: not implemented yet\n";
    std::exit(3);
  });
}

}  // namespace granflow::cli
