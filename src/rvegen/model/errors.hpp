// Errors of the input: what the user gave cannot be used as it is.
#pragma once

#include <stdexcept>

namespace rvegen {

/// Invalid user input (scene or inclusion file). The message names the offending key.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace rvegen
