// What the subcommands share: one reader of their arguments (options from a table, "did you
// mean" for an unknown one, errors in one line) and the size limit of a scene file.
#pragma once

#include <cmath>
#include <cstdlib>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

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

class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Option {
  std::vector<std::string> names;  // "-o", "--output"
  std::string value;               // what follows it, for "-o needs a directory"; empty: a flag
  std::function<void(const std::string& value)> take;  // throws UsageError on a bad value
};

/// A number of `text` in [lo, hi] (whole when `whole`), or UsageError("NAME needs WHAT").
inline double number_in(const std::string& text, double lo, double hi, bool whole,
                        const std::string& name, const std::string& what) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  // A whole number is digits only (no "2.0", "0x10", "1e1" or "+2").
  const bool digits = text.find_first_not_of("0123456789") == std::string::npos;
  if (text.empty() || *end != '\0' || !(v >= lo && v <= hi) || (whole && !digits))
    throw UsageError(name + " needs " + what + " (got \"" + text + "\")");
  return v;
}

/// A size in bytes ("8G", "512M", "1000000"), or UsageError.
inline double size_in_bytes(const std::string& text, const std::string& name) {
  const double v = parse_size(text);
  if (v <= 0.0)
    throw UsageError(name + " needs a size such as 8G, 512M or 1000000 (got \"" + text + "\")");
  return v;
}

/// "a,b,c" as its items (empty items kept, for the reader to name).
inline std::vector<std::string> split_commas(const std::string& text) {
  std::vector<std::string> items;
  size_t at = 0;
  while (at <= text.size()) {
    const size_t comma = std::min(text.find(',', at), text.size());
    items.push_back(text.substr(at, comma - at));
    at = comma + 1;
  }
  return items;
}

/// Reads `args` of `command` by `options`; returns the positional arguments.
inline std::vector<std::string> read_args(const std::vector<std::string>& args,
                                          const std::string& command,
                                          const std::vector<Option>& options) {
  std::vector<std::string> positional;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    const Option* found = nullptr;
    std::vector<std::string> known = {"--help"};
    for (const Option& o : options) {
      for (const std::string& n : o.names) {
        known.push_back(n);
        if (n == a) found = &o;
      }
    }
    if (!found && !a.empty() && a[0] == '-' && a != "-") {
      throw UsageError("unknown option " + a + " of " + command +
                       json_util::did_you_mean(a, known));
    }
    if (!found) {
      positional.push_back(a);
    } else if (found->value.empty()) {
      found->take("");
    } else if (i + 1 >= args.size()) {
      throw UsageError(a + " needs " + found->value);
    } else {
      found->take(args[++i]);
    }
  }
  return positional;
}

}  // namespace rvegen::cli
