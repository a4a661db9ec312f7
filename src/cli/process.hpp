// What the command line's subcommands share about the process: the size limit of a scene file,
// the peak memory the whole command used and the memory sizes given to it.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <initializer_list>
#include <string>

#include "rvegen/io/json_util.hpp"
#include "rvegen/model/resources.hpp"

namespace rvegen::cli {

constexpr size_t kMaxSceneBytes = size_t(16) << 20;

using rvegen::peak_memory_mb;

/// "2G", "512M", "1000000": bytes; negative when malformed (--max-memory).
inline double parse_size(const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || !std::isfinite(v) || v <= 0.0) return -1.0;
  const std::string unit = end;
  if (unit.empty()) return v;
  if (unit == "K" || unit == "k") return v * 1024.0;
  if (unit == "M") return v * 1024.0 * 1024.0;
  if (unit == "G") return v * 1024.0 * 1024.0 * 1024.0;
  return -1.0;
}

using json_util::did_you_mean;

}  // namespace rvegen::cli
