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
  uint8_t outside = 0;  // the label beyond the surfaces near the voxel: matrix or void
  /// For a coated inclusion, the shell's label and its share of the voxel (0 otherwise): the
  /// voxel then holds up to three layers along the normal, core, shell and the outside (the
  /// shell's two surfaces are parallel, a distance t apart).
  uint8_t middle = 0;
  double middle_fraction = 0.0;
  /// Share of the voxel inside the core, in [0, 1): exact along x on subsamples^2 lines for
  /// straight cores, on subsamples^3 points otherwise (the shell's share on subsamples^3
  /// points). The voxel holds two of the layers at least.
  double fraction = 0.0;
  /// Outward unit normal of the core: the gradient of its distance at the voxel centre (for
  /// spheres and straight cylinders the normal at the surface point nearest the centre).
  Vec3 normal = Vec3::UnitX();
};

struct CutVoxels {
  std::vector<CutVoxel> voxels;  // sorted by voxel
  /// Voxels cut by the surfaces of two or more inclusions (touching inclusions): left out (a
  /// rule for parallel interfaces does not apply to them).
  size_t shared = 0;
};

/// Every voxel of the layout (voxel_layout) that the surfaces of exactly one inclusion cut (its
/// core's, and a coated one's shell's). Parallel over inclusions (TBB); the result does not
/// depend on the number of threads.
CutVoxels cut_voxels(const InclusionSet& set, const VoxelImage& layout, int subsamples = 8);

}  // namespace rvegen
