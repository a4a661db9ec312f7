// Helpers shared by the test suites.
#pragma once

#include <string>

#include "rvegen/io/scene_json.hpp"
#include "rvegen/model/scene.hpp"

namespace rvegen {

/// The InputError message parse_scene gives for `text`, or "no error".
inline std::string scene_error(const std::string& text) {
  try {
    parse_scene(text);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace rvegen
