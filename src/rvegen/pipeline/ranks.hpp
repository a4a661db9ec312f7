// The processes of one command started by an MPI launcher (mpirun, mpiexec, srun with PMI):
// their number, this one's rank, and the few collective steps `rvegen study` and `rvegen homogenize` need. Started
// without a launcher, the command is one process and MPI is never initialised.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "rvegen/homogenize/spectral.hpp"

namespace rvegen {

class Ranks {
 public:
  /// Initialises MPI when the environment shows an MPI launcher with more than one process.
  Ranks();
  ~Ranks();
  Ranks(const Ranks&) = delete;
  Ranks& operator=(const Ranks&) = delete;

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool root() const { return rank_ == 0; }
  /// Processes of this command on this machine (for sharing its cores).
  int local_size() const { return local_size_; }

  /// The ranks' communicator for the core's distributed solvers (unset in one process).
  Communicator communicator() const;

  /// Rank 0's value, on every rank.
  int broadcast(int value) const;
  std::vector<int> broadcast(std::vector<int> values) const;
  /// Every rank's text, on rank 0, in rank order (empty elsewhere).
  std::vector<std::string> gather(const std::string& text) const;

 private:
  int rank_ = 0;
  int size_ = 1;
  int local_size_ = 1;
  bool mpi_ = false;
};

/// Where messages go: standard error on rank 0 (or the only process); nowhere on the other
/// ranks, which meet the same input and would repeat them.
std::ostream& say_once(const Ranks& ranks);

}  // namespace rvegen
