#include "rvegen/pipeline/ranks.hpp"

// The C interface only (Open MPI and MPICH would otherwise pull in their C++ bindings).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>

#include <cstdlib>
#include <iostream>
#include <string>

namespace rvegen {
namespace {

// The number of processes a launcher started, from the variables it sets (Open MPI, then the
// PMI of MPICH's hydra and of Slurm), or 1 when none is set.
int launched_size() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"}) {
    if (const char* v = std::getenv(name)) {
      const int n = std::atoi(v);
      if (n > 0) return n;
    }
  }
  return 1;
}

}  // namespace

Ranks::Ranks() {
  if (launched_size() < 2) return;
  int ready = 0;
  MPI_Initialized(&ready);
  if (!ready) MPI_Init(nullptr, nullptr);
  mpi_ = true;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
  MPI_Comm local;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &local);
  MPI_Comm_size(local, &local_size_);
  MPI_Comm_free(&local);
}

Ranks::~Ranks() {
  if (mpi_) MPI_Finalize();
}

std::ostream& say_once(const Ranks& ranks) {
  static std::ostream nowhere(nullptr);
  return ranks.root() ? std::cerr : nowhere;
}

Communicator Ranks::communicator() const {
  return mpi_ ? Communicator::from_fortran(MPI_Comm_c2f(MPI_COMM_WORLD)) : Communicator();
}

int Ranks::broadcast(int value) const {
  if (mpi_) MPI_Bcast(&value, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return value;
}

std::vector<int> Ranks::broadcast(std::vector<int> values) const {
  if (!mpi_) return values;
  int n = static_cast<int>(values.size());
  MPI_Bcast(&n, 1, MPI_INT, 0, MPI_COMM_WORLD);
  values.resize(static_cast<size_t>(n));
  if (n > 0) MPI_Bcast(values.data(), n, MPI_INT, 0, MPI_COMM_WORLD);
  return values;
}

std::vector<std::string> Ranks::gather(const std::string& text) const {
  if (!mpi_) return {text};
  int n = static_cast<int>(text.size());
  std::vector<int> counts(root() ? size_ : 0), offsets(root() ? size_ : 0);
  MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::string all;
  if (root()) {
    long long total = 0;
    for (int r = 0; r < size_; ++r) {
      offsets[r] = static_cast<int>(total);
      total += counts[r];
    }
    all.resize(static_cast<size_t>(total));
  }
  MPI_Gatherv(text.data(), n, MPI_CHAR, all.data(), counts.data(), offsets.data(), MPI_CHAR, 0,
              MPI_COMM_WORLD);
  std::vector<std::string> out;
  if (root()) {
    for (int r = 0; r < size_; ++r) out.push_back(all.substr(offsets[r], counts[r]));
  }
  return out;
}

}  // namespace rvegen
