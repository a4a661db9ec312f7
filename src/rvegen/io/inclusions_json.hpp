// inclusions.json: the inclusion list, read strictly and written with round-trip precision.
#pragma once

#include <string>

#include "rvegen/model/inclusion_set.hpp"

namespace rvegen {

/// Reads and validates an inclusion list (format "rvegen.inclusions/1"). Throws InputError.
InclusionSet read_inclusions_json(const std::string& text);
/// Serialises an inclusion list; doubles are written with round-trip precision.
std::string write_inclusions_json(const InclusionSet& set);

}  // namespace rvegen
