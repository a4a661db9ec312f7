// HDF5 output: voxel labels, partial volumes, the inclusion table and metadata in one file,
// plus an XDMF description so ParaView opens the image directly.
#pragma once

#include <string>

#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen {

/// Writes an HDF5 file at `path` (which must not exist; OutputSet::staged_path):
///   /voxels/phase (uint8), /voxels/inclusion_id (int32), /voxels/fraction (float32, when
///   computed), each [nz][ny][nx] with attributes origin, spacing (x, y, z order);
///   /phases/{label,name,kind,family}; /inclusions/{id,family,shape,center,radius,half_axis,
///   semi_axes,rotation} (one row per inclusion; unused fields 0);
///   /composite_voxels/{voxel,inclusion_id,inside_phase,outside_phase,fraction,normal}: the
///   voxels one core surface cuts (cut_voxels), for solvers that take laminate voxels;
///   root attributes format = "rvegen.h5/1", box_origin, box_size, periodic; the scene and
///   report JSON as string datasets /scene and /report, and also as root attributes scene and
///   report when shorter than 60,000 bytes (HDF5 limits attributes to 64 KB).
void write_hdf5(const std::string& path, const VoxelImage& image, const InclusionSet& set,
                const std::string& scene_json, const std::string& report_json);

/// XDMF 3 text describing the image arrays of `h5_name` (a path relative to the .xdmf file).
std::string xdmf_text(const VoxelImage& image, const std::string& h5_name);

}  // namespace rvegen
