// The processes of one run: MPI ranks when granflow runs under mpirun/srun (cli/mpi_ranks.cpp
// installs them), otherwise one process. Ensembles and calibration batches split their members
// over the ranks (docs/mpm_ensembles.md, "Several processes (MPI)"); the libraries never call
// MPI themselves, so they build and behave as before without it.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "ensemble.hpp"

namespace granflow::mpm {

class Ranks {
 public:
  virtual ~Ranks() = default;
  virtual int rank() const { return 0; }
  virtual int size() const { return 1; }
  virtual int local_rank() const { return 0; }  // rank among the processes of this host
  virtual std::string host() const;
  // Collectives: every rank must call them in the same order.
  // Every rank's bytes, in rank order.
  virtual std::vector<std::string> allgather(const std::string& mine) const { return {mine}; }
  // Rank 0's `bytes` to every rank.
  virtual void broadcast(std::string& bytes) const { (void)bytes; }
  virtual void barrier() const {}
  // "rank R of N on host H"
  std::string where() const;
};

// The process's ranks (one process unless set_ranks installed others).
const Ranks& ranks();
void set_ranks(std::unique_ptr<Ranks> r);

// Members [first, last) of `members` that rank `rank` of `size` runs: contiguous, the sizes
// differing by at most one, the larger ones first.
std::pair<long, long> rank_members(long members, int rank, int size);

// Byte packing for the collectives (host byte order: the ranks of one run share a build).
class Packer {
 public:
  template <class T> void pod(const T& v) { bytes_.append(reinterpret_cast<const char*>(&v), sizeof v); }
  template <class T> void pods(const std::vector<T>& v) {
    pod<std::uint64_t>(v.size());
    bytes_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  void str(const std::string& s) {
    pod<std::uint64_t>(s.size());
    bytes_ += s;
  }
  const std::string& bytes() const { return bytes_; }

 private:
  std::string bytes_;
};

class Unpacker {
 public:
  explicit Unpacker(const std::string& b) : b_(b) {}
  template <class T> T pod() {
    T v;
    take(&v, sizeof v);
    return v;
  }
  template <class T> std::vector<T> pods() {
    std::vector<T> v(pod<std::uint64_t>());
    take(v.data(), v.size() * sizeof(T));
    return v;
  }
  std::string str() {
    const auto n = pod<std::uint64_t>();
    std::string s(n, '\0');
    take(s.data(), n);
    return s;
  }
  bool done() const { return at_ == b_.size(); }

 private:
  void take(void* p, std::size_t n);
  const std::string& b_;
  std::size_t at_ = 0;
};

// Members' summaries (everything but the device timings) through the collectives.
std::string pack_members(const std::vector<MemberSummary>& ms);
std::vector<MemberSummary> unpack_members(const std::string& bytes);

}  // namespace granflow::mpm
