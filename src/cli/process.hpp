// What the command line's subcommands share about the process: the size limit of a scene file
// and the peak memory the whole command used.
#pragma once

#include <sys/resource.h>

#include <cstddef>
#include <initializer_list>
#include <string>

#include "rvegen/io/json_util.hpp"

namespace rvegen::cli {

constexpr size_t kMaxSceneBytes = size_t(16) << 20;

/// Peak resident memory of this process so far, in MiB.
inline double peak_memory_mb() {
  struct rusage ru {};
  if (getrusage(RUSAGE_SELF, &ru) != 0) return 0.0;
  return ru.ru_maxrss / 1024.0;  // kilobytes on Linux
}

using json_util::did_you_mean;

}  // namespace rvegen::cli
