// granflow figures: regenerates the source's element-test figures (Figs. 4-7) and the DEM
// steady-shear comparison as CSV, then plots them with scripts/plot_figures.py (matplotlib).
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>

#include <granflow/elementtest/paper.hpp>
#include <granflow/io/share.hpp>

#include "commands.hpp"

namespace granflow::cli {

namespace {

std::string plot_script() { return io::script_path("plot_figures.py"); }

// The first python3 that has matplotlib (a pyenv shim may shadow the system one).
std::string python_with_matplotlib() {
  for (const char* py : {"python3", "/usr/bin/python3"}) {
    const std::string probe = std::string(py) + " -c 'import matplotlib' >/dev/null 2>&1";
    if (std::system(probe.c_str()) == 0) return py;
  }
  return "";
}

void plot(const std::string& script, const std::string& dir) {
  if (script.empty()) {
    std::cerr << "granflow figures: scripts/plot_figures.py not found beside the data ("
              << io::share_directory() << "): CSVs written, PNGs not made (docs/install.md)\n";
    return;
  }
  const std::string py = python_with_matplotlib();
  if (py.empty()) {
    std::cerr << "granflow figures: no python3 with matplotlib found: CSVs written, PNGs not made.\n"
                 "  Install python3-matplotlib and run: python3 "
              << script << " " << dir << "\n";
    return;
  }
  const std::string cmd = py + " '" + script + "' '" + dir + "'";
  if (std::system(cmd.c_str()) != 0) std::cerr << "granflow figures: plotting failed: " << cmd << "\n";
}

}  // namespace

void register_figures(CLI::App& app) {
  auto out = std::make_shared<std::string>("docs/figures");
  auto* cmd = app.add_subcommand("figures", "Regenerate Figs. 4-7 and the DEM comparison (CSV + PNG)");
  auto no_png = std::make_shared<bool>(false);
  cmd->add_option("--out", *out, "Output folder")->capture_default_str();
  cmd->add_flag("--no-png", *no_png, "CSVs only, no plots");
  cmd->callback([out, no_png] {
    std::cout << "granflow figures -> " << *out << "\n";
    const auto files = elementtest::paper::write_figures(*out, std::cout);
    for (const auto& f : files) std::cout << "  wrote " << f << "\n";
    if (!*no_png) plot(plot_script(), *out);
  });
}

}  // namespace granflow::cli
