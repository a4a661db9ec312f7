// HDF5 output: voxel labels, partial volumes, the inclusion table and metadata in one file,
// plus an XDMF description so ParaView opens the image directly.
#pragma once

#include <string>
#include <vector>

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
///   /fields/<name> for each local field given (float32, [nz][ny][nx][components]);
///   root attributes format = "rvegen.h5/1", box_origin, box_size, periodic; the scene and
///   report JSON as string datasets /scene and /report, and also as root attributes scene and
///   report when shorter than 60,000 bytes (HDF5 limits attributes to 64 KB).
/// A local field for /fields/<name>: `components` blocks of one value per voxel (x fastest),
/// written as [nz][ny][nx][components], with the components' names as an attribute.
struct LocalField {
  std::string name;        // e.g. "elasticity/load_0/strain"
  std::string components;  // e.g. "11 22 33 23 13 12"
  int count = 1;           // number of components
  const std::vector<float>* values = nullptr;
};

void write_hdf5(const std::string& path, const VoxelImage& image, const InclusionSet& set,
                const std::string& scene_json, const std::string& report_json,
                const std::vector<LocalField>& fields = {});

/// XDMF 3 text describing the image arrays of `h5_name` (a path relative to the .xdmf file),
/// the local fields among them.
std::string xdmf_text(const VoxelImage& image, const std::string& h5_name,
                      const std::vector<LocalField>& fields = {});

}  // namespace rvegen
