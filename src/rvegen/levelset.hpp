// Sparse narrow-band level sets (OpenVDB FloatGrid, class level set) for what the analytic
// shapes cannot say: wavy and deformed inclusions and interphase shells. Straight inclusions
// stay analytic and get no grid. The OpenVDB types stay behind this header.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "rvegen/inclusion_set.hpp"
#include "rvegen/mesh.hpp"

namespace rvegen {

struct LevelSetOptions {
  /// Voxel size of the grids; 0 picks the smallest box size / 256.
  double voxel_size = 0.0;
  /// Half width of the narrow band, in voxels.
  double half_width = 3.0;
};

/// One grid: the union of one family's wavy or deformed cores ("<family>_core") or of its
/// interphase shells ("<family>_interphase"), periodic images that reach into the box included.
struct LevelSetInfo {
  std::string name;
  std::string kind;  // "core" or "interphase"
  int family = 0;
  int phase = 0;  // label in phase_table(set)
  int inclusions = 0;
  long long active_voxels = 0;
  long long memory_bytes = 0;  // of the sparse tree
};

struct LevelSets {
  std::vector<LevelSetInfo> grids;
  double voxel_size = 0.0;
  double half_width = 0.0;
  /// Bytes of dense float grids of the same voxel size over the box (one per named grid), for
  /// comparison.
  long long dense_bytes = 0;
  long long memory_bytes = 0;  // all sparse grids
  std::shared_ptr<void> data;  // the OpenVDB grids
  bool empty() const { return grids.empty(); }
};

/// Builds the grids the set needs (none when no inclusion is wavy, deformed or coated).
/// Values are the signed distances of BodyQuery::core_distance / shell_distance in the narrow
/// band (exact signs; exact distances for spheres and straight cylinders), the inside filled
/// by OpenVDB's signed flood fill.
LevelSets build_level_sets(const InclusionSet& set, const LevelSetOptions& options = {});

/// Signed value of grid `g` at x (trilinear), the background sign outside the band.
double level_set_value(const LevelSets& ls, size_t g, const Vec3& x);

/// The grids in OpenVDB's file format (levelsets.vdb), with grid and file metadata.
std::string vdb_bytes(const LevelSets& ls, const InclusionSet& set);

/// Reads back a .vdb written by vdb_bytes: grid names with their active voxel counts.
std::vector<std::pair<std::string, long long>> read_vdb_summary(const std::string& path);

/// Zero iso-surfaces of the grids (OpenVDB volumeToMesh), triangles wound outward; cell data
/// family from the grid and phase/shape set for cores (shape of the family) and interphases.
SurfaceMesh level_set_surfaces(const LevelSets& ls);

}  // namespace rvegen
