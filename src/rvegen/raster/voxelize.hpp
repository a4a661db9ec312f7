// Voxel image of an RVE: phase and inclusion labels sampled at voxel centres, plus the
// partial volume of the inclusions in every voxel (the share of the voxel inside cores).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/phases.hpp"

namespace rvegen {

struct VoxelOptions {
  /// Also compute `fraction` (partial volume of cores per voxel).
  bool partial_volume = true;
  /// Boundary voxels are sampled on a subsamples^3 grid for `fraction`.
  int subsamples = 4;
  /// Voxel index range [lo, hi) per axis to compute (a sub-extent of the whole image);
  /// empty: the whole image.
  std::array<int, 6> extent = {0, -1, 0, -1, 0, -1};
};

struct VoxelImage {
  std::array<int, 3> dims = {0, 0, 0};             // voxels per axis of the whole image
  std::array<int, 6> extent = {0, 0, 0, 0, 0, 0};  // computed range [lo, hi) per axis
  Vec3 origin = Vec3::Zero();                      // corner of voxel (0,0,0)
  Vec3 spacing = Vec3::Ones();
  std::vector<Phase> phases;
  /// Phase label of the voxel centre (see phase_table). x varies fastest, over `extent`.
  std::vector<uint8_t> phase;
  /// Inclusion id at the voxel centre (cores, shells and voids alike), -1 in the matrix.
  std::vector<int32_t> inclusion_id;
  /// Share of the voxel inside inclusion cores, in [0, 1] (empty unless partial_volume).
  std::vector<float> fraction;
  /// Voxel centres claimed by two cores (0 unless inclusions overlap).
  long long conflicts = 0;

  int size(int axis) const { return extent[2 * axis + 1] - extent[2 * axis]; }
  size_t count() const { return static_cast<size_t>(size(0)) * size(1) * size(2); }
  /// Index of voxel (i, j, k) in whole-image indices (must lie in `extent`).
  size_t index(int i, int j, int k) const {
    return (static_cast<size_t>(k - extent[4]) * size(1) + (j - extent[2])) * size(0) +
           (i - extent[0]);
  }
};

/// Voxelizes the set on a dims[0] x dims[1] x dims[2] grid over the box (periodic images wrap
/// around). Labels come from the exact region of each voxel centre (modifiers included);
/// `fraction` is exact for voxels wholly inside or outside a core (decided by a certified
/// clearance bound) and sampled on a subsamples^3 grid for the others. Parallel over z planes
/// (TBB); the result does not depend on the number of threads.
VoxelImage voxelize(const InclusionSet& set, const std::array<int, 3>& dims,
                    const VoxelOptions& options = {});

/// The image voxelize() makes, without its arrays: dims, extent, origin, spacing, phases.
VoxelImage voxel_layout(const InclusionSet& set, const std::array<int, 3>& dims,
                        const VoxelOptions& options = {});

/// voxelize() into arrays the caller owns (layout.count() values each, x fastest over
/// layout.extent; `fraction` null for labels only), so a caller such as the VTK source fills its
/// own arrays without a copy. Returns the number of conflicts.
long long voxelize_into(const InclusionSet& set, const VoxelImage& layout,
                        const VoxelOptions& options, uint8_t* phase, int32_t* inclusion_id,
                        float* fraction);

/// Volume fraction of each phase label in the image (by centre labels).
std::vector<double> label_fractions(const VoxelImage& image);
/// Mean of `fraction` (the partial-volume estimate of the core volume fraction).
double partial_volume_fraction(const VoxelImage& image);

}  // namespace rvegen
