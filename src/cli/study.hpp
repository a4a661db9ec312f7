// rvegen study: the representativity of an RVE size (model/representativity.hpp), realizations
// at several sizes, resumable, summarised in study.json and study.csv.
#pragma once

#include <string>
#include <vector>

namespace rvegen::cli {

/// Its usage text.
const char* study_usage();
/// The `rvegen study` command (arguments after "study"); returns the exit code.
int cmd_study(const std::vector<std::string>& args);

}  // namespace rvegen::cli
