// mpm::Ranks over MPI_COMM_WORLD. The collectives are non-blocking ones polled with short
// sleeps: a rank waiting for the others (rank 0 of a calibration between batches, a rank whose
// members are done) leaves its core to the ranks still computing, where blocking calls of
// Open MPI would spin on it.
#include "mpi_ranks.hpp"

#include <cstdio>
#include <cstdlib>
#include <chrono>
#include <stdexcept>
#include <thread>

#include <granflow/mpm/ranks.hpp>

#ifdef GRANFLOW_WITH_MPI
#include <mpi.h>
#endif

namespace granflow::cli {

#ifdef GRANFLOW_WITH_MPI
namespace {

bool g_mpi = false;

// Launched by mpirun (Open MPI), a PMIx or PMI launcher (srun --mpi=pmix|pmi2)?
bool launched_by_mpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
    if (std::getenv(v)) return true;
  return false;
}

void check(int rc, const char* what) {
  if (rc != MPI_SUCCESS) {
    char msg[MPI_MAX_ERROR_STRING];
    int len = 0;
    MPI_Error_string(rc, msg, &len);
    throw std::runtime_error(std::string("MPI: ") + what + ": " + std::string(msg, len));
  }
}

void wait(MPI_Request& r, const char* what) {
  for (;;) {
    int done = 0;
    check(MPI_Test(&r, &done, MPI_STATUS_IGNORE), what);
    if (done) return;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
}

class MpiRanks final : public mpm::Ranks {
 public:
  MpiRanks() {
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
    MPI_Comm node;  // the ranks sharing this host: a rank's GPU is its rank among them
    MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &node);
    MPI_Comm_rank(node, &local_);
    MPI_Comm_free(&node);
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }
  int local_rank() const override { return local_; }

  std::vector<std::string> allgather(const std::string& mine) const override {
    const unsigned long long n = mine.size();
    if (n > 0x7fffffffull) throw std::runtime_error("MPI: a message of " + std::to_string(n) + " bytes exceeds 2 GiB");
    std::vector<unsigned long long> sizes(size_);
    MPI_Request r;
    check(MPI_Iallgather(&n, 1, MPI_UNSIGNED_LONG_LONG, sizes.data(), 1, MPI_UNSIGNED_LONG_LONG, MPI_COMM_WORLD, &r),
          "allgather");
    wait(r, "allgather");
    std::vector<int> counts(size_), displs(size_);
    unsigned long long total = 0;
    for (int i = 0; i < size_; ++i) {
      counts[i] = static_cast<int>(sizes[i]);
      displs[i] = static_cast<int>(total);
      total += sizes[i];
    }
    if (total > 0x7fffffffull) throw std::runtime_error("MPI: the gathered messages exceed 2 GiB");
    std::string all(total, '\0');
    check(MPI_Iallgatherv(mine.data(), counts[rank_], MPI_CHAR, all.data(), counts.data(), displs.data(), MPI_CHAR,
                          MPI_COMM_WORLD, &r),
          "allgatherv");
    wait(r, "allgatherv");
    std::vector<std::string> out(size_);
    for (int i = 0; i < size_; ++i) out[i] = all.substr(displs[i], counts[i]);
    return out;
  }

  void broadcast(std::string& bytes) const override {
    unsigned long long n = bytes.size();
    MPI_Request r;
    check(MPI_Ibcast(&n, 1, MPI_UNSIGNED_LONG_LONG, 0, MPI_COMM_WORLD, &r), "broadcast");
    wait(r, "broadcast");
    if (n > 0x7fffffffull) throw std::runtime_error("MPI: a broadcast of " + std::to_string(n) + " bytes exceeds 2 GiB");
    bytes.resize(n);
    check(MPI_Ibcast(bytes.data(), static_cast<int>(n), MPI_CHAR, 0, MPI_COMM_WORLD, &r), "broadcast");
    wait(r, "broadcast");
  }

  void barrier() const override {
    MPI_Request r;
    check(MPI_Ibarrier(MPI_COMM_WORLD, &r), "barrier");
    wait(r, "barrier");
  }

 private:
  int rank_ = 0, size_ = 1, local_ = 0;
};

}  // namespace

MpiSession::MpiSession(int& argc, char**& argv) {
  if (!launched_by_mpi()) return;
  int provided = 0;
  // SERIALIZED: rank 0 of a calibration may call from a pool thread, one call at a time.
  if (MPI_Init_thread(&argc, &argv, MPI_THREAD_SERIALIZED, &provided) != MPI_SUCCESS) {
    std::fprintf(stderr, "granflow: error: MPI_Init failed (started by mpirun/srun)\n");
    std::exit(1);
  }
  g_mpi = true;
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  mpm::set_ranks(std::make_unique<MpiRanks>());
}

MpiSession::~MpiSession() {
  if (!g_mpi) return;
  mpm::set_ranks(nullptr);
  MPI_Finalize();
}

void MpiSession::end_on_failure(int code) {
  if (!g_mpi || code == 0 || mpm::ranks().size() < 2) return;
  std::fflush(stdout);
  std::fflush(stderr);
  MPI_Abort(MPI_COMM_WORLD, code);
}

#else  // built without MPI: always one process

MpiSession::MpiSession(int&, char**&) {
  if (std::getenv("OMPI_COMM_WORLD_SIZE") && std::atoi(std::getenv("OMPI_COMM_WORLD_SIZE")) > 1)
    std::fprintf(stderr,
                 "granflow: note: started by mpirun with %s processes, but this granflow was built without MPI: "
                 "each process runs the whole job alone (rebuild with libopenmpi-dev; docs/mpm_ensembles.md)\n",
                 std::getenv("OMPI_COMM_WORLD_SIZE"));
}
MpiSession::~MpiSession() = default;
void MpiSession::end_on_failure(int) {}

#endif

std::string MpiSession::where() {
  return mpm::ranks().size() > 1 ? " (" + mpm::ranks().where() + ")" : "";
}

}  // namespace granflow::cli
