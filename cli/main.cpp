// granflow: one program for element tests, calibration, MPM runs, benchmarks and figures.
#include <cstdio>
#include <exception>
#include <iostream>
#include <new>
#include <string>

#include "commands.hpp"
#include "mpi_ranks.hpp"
#include <granflow/mpm/ranks.hpp>
#include <granflow/io/input_error.hpp>
#include <granflow/io/output.hpp>

namespace {

int run(int argc, char** argv) {
  CLI::App app{
      "granflow: granular flow through the solid-like to fluid-like transition\n"
      "(SIMSAND-type frictional stress + kinetic-theory collisional stress)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "granflow 0.1.0");
#ifdef GRANFLOW_WITH_SOLVERS
  granflow::cli::register_element(app);
  granflow::cli::register_figures(app);
#endif
#ifdef GRANFLOW_WITH_CALIBRATION
  granflow::cli::register_calibrate(app);
#endif
  granflow::cli::register_mpm(app);
  granflow::cli::register_ensemble(app);
  granflow::cli::register_bench(app);
  const std::string at = granflow::cli::MpiSession::where();  // "" in one process
  try {
    if (granflow::mpm::ranks().size() > 1 && argc > 1 && std::string(argv[1]) != "ensemble" &&
        std::string(argv[1]) != "calibrate" && std::string(argv[1]).rfind("-", 0) != 0)
      throw granflow::io::InputError(std::string("granflow ") + argv[1] +
                                     " runs in one process: under mpirun or srun start ensemble or calibrate, or "
                                     "give -np 1");
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // Command-line mistakes: one line naming what was given, then where to look.
    std::cerr << "granflow: error" << at << ": " << e.what();
    if (argc > 1) {
      std::cerr << " (command line:";
      for (int i = 1; i < argc; ++i) std::cerr << ' ' << argv[i];
      std::cerr << ")";
    }
    std::cerr << "; options: granflow [<command>] --help\n";
    return e.get_exit_code() == 0 ? 2 : e.get_exit_code();
  } catch (const granflow::cli::ExitStatus& e) {
    return e.code;
  } catch (const granflow::io::OutputError& e) {
    // a full disk, a read-only or forbidden folder: the user can fix it (2); EIO and the like: 1
    std::cerr << "granflow: error" << at << ": " << e.what() << "\n";
    return e.user_fixable() ? 2 : 1;
  } catch (const granflow::io::InputError& e) {
    std::cerr << "granflow: error" << at << ": " << e.what() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {  // where no caller said what the memory was for
    std::cerr << "granflow: error" << at << ": out of memory (an allocation failed): use a coarser grid or fewer "
                                              "members, or free memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "granflow: error" << at << ": " << e.what() << "\n";
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  granflow::cli::MpiSession mpi(argc, argv);
  const int rc = run(argc, argv);
  granflow::cli::MpiSession::end_on_failure(rc);  // several ranks: a failed one ends them all
  return rc;
}
