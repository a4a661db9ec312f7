// Voxel image of an RVE: one label per voxel, sampled at voxel centres.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "rvegen/inclusion_set.hpp"

namespace rvegen {

struct VoxelImage {
  std::array<int, 3> dims = {0, 0, 0};  // voxels per axis
  Vec3 origin = Vec3::Zero();           // corner of voxel (0,0,0)
  Vec3 spacing = Vec3::Ones();
  /// 0 = matrix, family index + 1 otherwise. x varies fastest.
  std::vector<uint8_t> phase;
  /// Inclusion id, -1 in the matrix.
  std::vector<int32_t> inclusion_id;

  size_t index(int i, int j, int k) const {
    return (static_cast<size_t>(k) * dims[1] + j) * dims[0] + i;
  }
};

/// Labels every voxel whose centre lies inside an inclusion (periodic images wrap around).
VoxelImage voxelize(const InclusionSet& set, const std::array<int, 3>& dims);

}  // namespace rvegen
