// report.json's sections of the later stages: the tetrahedral mesh ("mesh_tet") and the
// effective properties ("effective"), as JSON object text for report_json's `sections`, so
// that every front end reports them alike.
#pragma once

#include <string>
#include <vector>

#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/homogenize/effective.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/packing/audit.hpp"

namespace rvegen {

/// What the run did around the tetrahedral mesh, beside the mesh itself.
struct TetMeshRun {
  int nudged = 0;                   // inclusions moved off the cell's faces (mesh_tet.nudge)
  int nudge_stuck = 0;              // those that graze it with no room to move
  double estimated_elements = 0.0;  // the estimate the memory check used
  double face_clearance = 0.0;      // of the cell meshed (tet_mesh.hpp: face_clearance)
  double edge_clearance = 0.0;      // (tet_mesh.hpp: edge_clearance)
  std::vector<std::string> decks;   // the CalculiX decks written beside the mesh
};

/// "mesh_tet": counts, the volume of each phase against the exact one, the least element
/// volume and the distribution of the elements' least dihedral angles (`quality`, of tet_quality).
std::string tet_mesh_section(const InclusionSet& set, const TetMesh& mesh,
                             const TetQuality& quality, const TetMeshRun& run);

/// "effective": the voxel rule, the resolution, the phase shares and each tensor solved with
/// its iterations, residual and the bounds beside it. `ranks`: the processes that solved it
/// (named when more than one).
std::string effective_section(const HomogenizationSpec& h, const EffectiveProperties& e,
                              int ranks = 1);

/// `rvegen check --json`: the count of inclusions, of overlapping pairs (each with the ids, the
/// pair test, the depth and the periodic shift) and the inclusions outside a closed box.
std::string audit_json(const InclusionSet& set, const AuditReport& report);
/// `rvegen check`: a line per overlap and per inclusion outside the box, then the counts.
std::string audit_text(const InclusionSet& set, const AuditReport& report);

}  // namespace rvegen
