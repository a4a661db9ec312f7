// Each phase's volume in a mesh of the Gmsh tests, beside the exact one (io/report's).
#pragma once

#include <utility>
#include <vector>

#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/io/report.hpp"

namespace rvegen::femesh_test {

// Every phase's volume in the mesh and the exact one, by label.
inline std::pair<std::vector<double>, std::vector<double>> volumes(const InclusionSet& set,
                                                                   const TetMesh& mesh) {
  std::vector<double> exact = phase_volume_fractions(set, mesh.phases);
  for (double& v : exact) v *= set.box.volume();
  return {tet_quality(mesh).phase_volume, exact};
}

}  // namespace rvegen::femesh_test
