// Voxels cut by an inclusion's core surface, with what composite-voxel rules need (Kabel,
// Merkert, Schneider 2015): the share of the voxel inside the core, the surface's normal and the
// phase on the other side. rvegen knows the exact geometry, so none of these is guessed from the
// label image.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "rvegen/raster/voxelize.hpp"

namespace rvegen {

struct CutVoxel {
  size_t voxel = 0;     // index over the layout's extent, x fastest
  int inclusion = 0;    // index in InclusionSet::inclusions
  uint8_t inside = 0;   // the core's phase label
  uint8_t outside = 0;  // the label just outside the core near the voxel: matrix, shell or void
  /// Share of the voxel inside the core, in (0, 1): exact along x on subsamples^2 lines for
  /// straight cores, on subsamples^3 points otherwise.
  double fraction = 0.0;
  /// Outward unit normal of the core: the gradient of its distance at the voxel centre (for
  /// spheres and straight cylinders the normal at the surface point nearest the centre).
  Vec3 normal = Vec3::UnitX();
};

struct CutVoxels {
  std::vector<CutVoxel> voxels;  // sorted by voxel
  /// Voxels cut by two or more cores (touching inclusions): left out (a rule for one interface
  /// does not apply to them).
  size_t shared = 0;
};

/// Every voxel of the layout (voxel_layout) that exactly one core surface cuts. Parallel over
/// inclusions (TBB); the result does not depend on the number of threads.
CutVoxels cut_voxels(const InclusionSet& set, const VoxelImage& layout, int subsamples = 8);

}  // namespace rvegen
