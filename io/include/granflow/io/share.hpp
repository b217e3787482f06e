// Where the shipped files are found at run time: data/ (parameter sets, test files, calibration
// jobs, lab data), mpm/scenes/ and scripts/ (plot scripts), in one folder laid out as the source
// tree. No path is compiled in (docs/install.md); the folder is, in this order:
//   1. $GRANFLOW_DATA_DIR/.. (GRANFLOW_DATA_DIR names the data folder itself);
//   2. <folder of the running program>/../share/granflow (an installed program; the relative
//      path follows CMAKE_INSTALL_BINDIR and CMAKE_INSTALL_DATADIR);
//   3. the source tree named in granflow_source_dir.txt, a file CMake writes into the build folder,
//      looked for from the program's folder upward (the program and the tests in a build tree);
//   4. the current folder.
#pragma once

#include <string>

namespace granflow::io {

// The folder holding data/, mpm/scenes/ and scripts/ (1-4 above).
std::string share_directory();

// Path of a script of scripts/ (e.g. "plot_figures.py"); "" when it is in none of the folders
// 1-4 (a GRANFLOW_DATA_DIR without scripts beside it falls back to 2-4).
std::string script_path(const std::string& name);

// The folder of the running program (from /proc/self/exe); "" when it cannot be read.
std::string program_directory();

// Where data_directory() came from and what was searched, for messages about a missing shipped
// file: "GRANFLOW_DATA_DIR = 'D'[, a relative path: from the folder C]" or "GRANFLOW_DATA_DIR is
// not set; searched: ...".
std::string data_directory_origin();

}  // namespace granflow::io
