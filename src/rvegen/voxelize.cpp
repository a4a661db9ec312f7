#include "rvegen/voxelize.hpp"

#include <cmath>

namespace rvegen {

VoxelImage voxelize(const InclusionSet& set, const std::array<int, 3>& dims) {
  VoxelImage img;
  img.dims = dims;
  img.origin = set.box.origin;
  for (int a = 0; a < 3; ++a) img.spacing[a] = set.box.size[a] / dims[a];
  const size_t n = static_cast<size_t>(dims[0]) * dims[1] * dims[2];
  img.phase.assign(n, 0);
  img.inclusion_id.assign(n, -1);
  for (const auto& inc : set.inclusions) {
    Vec3 lo, hi;
    inc.shape.aabb(&lo, &hi);
    int i0[3], i1[3];
    for (int a = 0; a < 3; ++a) {
      // Voxel centres x = origin + (i + 0.5) h within [lo, hi].
      i0[a] = static_cast<int>(std::ceil((lo[a] - img.origin[a]) / img.spacing[a] - 0.5));
      i1[a] = static_cast<int>(std::floor((hi[a] - img.origin[a]) / img.spacing[a] - 0.5));
      if (!set.box.periodic) {
        i0[a] = std::max(i0[a], 0);
        i1[a] = std::min(i1[a], dims[a] - 1);
      } else if (i1[a] - i0[a] + 1 > dims[a]) {
        i1[a] = i0[a] + dims[a] - 1;  // wider than the box: each voxel once
      }
    }
    for (int k = i0[2]; k <= i1[2]; ++k) {
      const double z = img.origin[2] + (k + 0.5) * img.spacing[2];
      const int kk = ((k % dims[2]) + dims[2]) % dims[2];
      for (int j = i0[1]; j <= i1[1]; ++j) {
        const double y = img.origin[1] + (j + 0.5) * img.spacing[1];
        const int jj = ((j % dims[1]) + dims[1]) % dims[1];
        for (int i = i0[0]; i <= i1[0]; ++i) {
          const double x = img.origin[0] + (i + 0.5) * img.spacing[0];
          if (!inc.shape.contains(Vec3(x, y, z))) continue;
          const int ii = ((i % dims[0]) + dims[0]) % dims[0];
          const size_t idx = img.index(ii, jj, kk);
          img.phase[idx] = static_cast<uint8_t>(inc.family + 1);
          img.inclusion_id[idx] = inc.id;
        }
      }
    }
  }
  return img;
}

}  // namespace rvegen
