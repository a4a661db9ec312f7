// Sparse narrow-band level sets (OpenVDB FloatGrid, class level set) for what the analytic
// shapes cannot say: wavy and deformed inclusions and interphase shells. Straight inclusions
// stay analytic and get no grid. The OpenVDB types stay behind this header.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/raster/levelset_info.hpp"
#include "rvegen/raster/mesh.hpp"

namespace rvegen {

/// Builds the grids the set needs (none when no inclusion is wavy, bent or deformed; the shells
/// of straight coated inclusions only with options.exact_shapes).
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
