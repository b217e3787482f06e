// MPI for granflow ensemble and granflow calibrate (docs/mpm_ensembles.md, "Several processes").
// Started only when a launcher (mpirun, srun) started this process; otherwise, and in builds
// without MPI, granflow is one process as before.
#pragma once

#include <string>

namespace granflow::cli {

class MpiSession {
 public:
  MpiSession(int& argc, char**& argv);  // MPI_Init where launched by mpirun/srun; installs mpm::ranks()
  ~MpiSession();                        // MPI_Finalize
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  // "" in one process; else " (rank R of N on host H)" for error messages.
  static std::string where();
  // Several ranks and exit status `code` != 0: ends every rank (MPI_Abort), so none waits in a
  // collective for a rank that gave up. Returns otherwise.
  static void end_on_failure(int code);
};

}  // namespace granflow::cli
