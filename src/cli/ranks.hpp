// The processes of one command started by an MPI launcher (mpirun, mpiexec, srun with PMI):
// their number, this one's rank, and the few collective steps `rvegen study` needs. Started
// without a launcher, the command is one process and MPI is never initialised.
#pragma once

#include <string>
#include <vector>

namespace rvegen::cli {

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

}  // namespace rvegen::cli
