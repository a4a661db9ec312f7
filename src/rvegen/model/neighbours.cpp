#include "rvegen/model/neighbours.hpp"

#include <algorithm>
#include <cmath>

namespace rvegen {

void for_each_image(const Box& box, const Vec3& ca, double ra, const Vec3& cb, double rb,
                    const std::function<void(const Vec3&)>& f) {
  const Vec3 d = cb - ca;
  const double reach = ra + rb;
  if (!box.periodic) {
    if (d.squaredNorm() < reach * reach) f(Vec3::Zero());
    return;
  }
  int lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = static_cast<int>(std::ceil((-reach - d[k]) / box.size[k]));
    hi[k] = static_cast<int>(std::floor((reach - d[k]) / box.size[k]));
  }
  for (int i = lo[0]; i <= hi[0]; ++i) {
    for (int j = lo[1]; j <= hi[1]; ++j) {
      for (int k = lo[2]; k <= hi[2]; ++k) {
        const Vec3 shift(i * box.size[0], j * box.size[1], k * box.size[2]);
        if ((d + shift).squaredNorm() < reach * reach) f(shift);
      }
    }
  }
}

NeighbourGrid::NeighbourGrid(const Box& box, double reach, size_t expected_count) : box_(box) {
  size_t total = 1;
  // Cells no smaller than `reach`, and no more than about two per inclusion.
  const double min_cell =
      std::max(reach, std::cbrt(box.volume() / (2.0 * std::max<size_t>(expected_count, 1))));
  for (int k = 0; k < 3; ++k) {
    int n = min_cell > 0.0 ? static_cast<int>(std::floor(box.size[k] / min_cell)) : 1;
    n = std::clamp(n, 1, 1024);
    // With fewer than 3 periodic cells the +-1 neighbours would alias: use one cell.
    if (box.periodic && n < 3) n = 1;
    n_[k] = n;
    cell_[k] = box.size[k] / n;
    total *= static_cast<size_t>(n);
  }
  cells_.resize(total);
}

int NeighbourGrid::cell_of(const Vec3& c, int k) const {
  const double x = (c[k] - box_.origin[k]) / cell_[k];
  int i = static_cast<int>(std::floor(x));
  if (box_.periodic) {
    i %= n_[k];
    if (i < 0) i += n_[k];
  } else {
    i = std::clamp(i, 0, n_[k] - 1);
  }
  return i;
}

void NeighbourGrid::insert(int index, const Vec3& center) {
  const int i = cell_of(center, 0), j = cell_of(center, 1), k = cell_of(center, 2);
  cells_[(static_cast<size_t>(k) * n_[1] + j) * n_[0] + i].push_back(index);
}

void NeighbourGrid::for_each_candidate(const Vec3& c, const std::function<void(int)>& f) const {
  const int ci[3] = {cell_of(c, 0), cell_of(c, 1), cell_of(c, 2)};
  int lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    if (n_[k] == 1) {
      lo[k] = hi[k] = 0;
    } else if (box_.periodic) {
      lo[k] = ci[k] - 1;
      hi[k] = ci[k] + 1;
    } else {
      lo[k] = std::max(0, ci[k] - 1);
      hi[k] = std::min(n_[k] - 1, ci[k] + 1);
    }
  }
  for (int z = lo[2]; z <= hi[2]; ++z) {
    const int zz = (z + n_[2]) % n_[2];
    for (int y = lo[1]; y <= hi[1]; ++y) {
      const int yy = (y + n_[1]) % n_[1];
      for (int x = lo[0]; x <= hi[0]; ++x) {
        const int xx = (x + n_[0]) % n_[0];
        for (int idx : cells_[(static_cast<size_t>(zz) * n_[1] + yy) * n_[0] + xx]) f(idx);
      }
    }
  }
}

}  // namespace rvegen
