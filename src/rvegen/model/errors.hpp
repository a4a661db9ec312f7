// Errors of the input (what the user gave cannot be used as it is), and the stop a caller asked
// for.
#pragma once

#include <stdexcept>

namespace rvegen {

/// Invalid user input (scene or inclusion file). The message names the offending key.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Thrown by a long computation (the packers and generate(), the tetrahedral mesher) when its
/// caller asked it to stop: the run left nothing behind, and the same call may be made again.
class Cancelled : public std::runtime_error {
 public:
  Cancelled() : std::runtime_error("cancelled") {}
};

}  // namespace rvegen
