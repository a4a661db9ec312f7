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
  (void)total;
}

std::array<int, 3> to_nearest_image(const Box& box, Vec3* d) {
  std::array<int, 3> k = {0, 0, 0};
  if (!box.periodic) return k;
  for (int a = 0; a < 3; ++a) {
    const int m = static_cast<int>(std::floor((*d)[a] / box.size[a] + 0.5));
    (*d)[a] -= m * box.size[a];
    k[a] = -m;
  }
  return k;
}

int cell_coordinate(const Box& box, int n, double width, double x, int axis) {
  int i = static_cast<int>(std::floor((x - box.origin[axis]) / width));
  if (box.periodic) {
    i %= n;
    if (i < 0) i += n;
  } else {
    i = std::clamp(i, 0, n - 1);
  }
  return i;
}

int NeighbourGrid::cell_of(const Vec3& c, int k) const {
  return cell_coordinate(box_, n_[k], cell_[k], c[k], k);
}

size_t NeighbourGrid::cell_index(const Vec3& c) const {
  return (static_cast<size_t>(cell_of(c, 2)) * n_[1] + cell_of(c, 1)) * n_[0] + cell_of(c, 0);
}

void NeighbourGrid::insert(int index, const Vec3& center) {
  if (cells_.empty()) cells_.resize(cell_count());
  cells_[cell_index(center)].push_back(index);
}

void NeighbourGrid::insert_reaching(int index, const Vec3& center, double radius) {
  if (cells_.empty()) cells_.resize(cell_count());
  int lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = static_cast<int>(std::floor((center[k] - radius - box_.origin[k]) / cell_[k]));
    hi[k] = static_cast<int>(std::floor((center[k] + radius - box_.origin[k]) / cell_[k]));
    if (box_.periodic) {
      if (hi[k] - lo[k] + 1 >= n_[k]) {
        lo[k] = 0;
        hi[k] = n_[k] - 1;
      }
    } else {
      lo[k] = std::clamp(lo[k], 0, n_[k] - 1);
      hi[k] = std::clamp(hi[k], 0, n_[k] - 1);
    }
  }
  for (int z = lo[2]; z <= hi[2]; ++z) {
    const int zz = (z % n_[2] + n_[2]) % n_[2];
    for (int y = lo[1]; y <= hi[1]; ++y) {
      const int yy = (y % n_[1] + n_[1]) % n_[1];
      for (int x = lo[0]; x <= hi[0]; ++x) {
        const int xx = (x % n_[0] + n_[0]) % n_[0];
        cells_[(static_cast<size_t>(zz) * n_[1] + yy) * n_[0] + xx].push_back(index);
      }
    }
  }
}

void NeighbourGrid::neighbour_range(const Vec3& c, int lo[3], int hi[3]) const {
  for (int k = 0; k < 3; ++k) {
    const int ci = cell_of(c, k);
    if (n_[k] == 1) {
      lo[k] = hi[k] = 0;
    } else if (box_.periodic) {
      lo[k] = ci - 1;
      hi[k] = ci + 1;
    } else {
      lo[k] = std::max(0, ci - 1);
      hi[k] = std::min(n_[k] - 1, ci + 1);
    }
  }
}

bool NeighbourGrid::nearest_image_suffices() const {
  if (!box_.periodic) return true;
  return n_[0] >= 3 && n_[1] >= 3 && n_[2] >= 3;
}

void sphere_pairs(const Box& box, const std::vector<Vec3>& c, const std::vector<double>& r,
                  std::vector<SpherePair>* pairs, const std::function<void()>& tick) {
  pairs->clear();
  for_each_sphere_pair(
      box, c, r,
      [pairs](const SpherePair& p) {
        pairs->push_back(p);
        return true;
      },
      tick);
}

bool for_each_sphere_pair(const Box& box, const std::vector<Vec3>& c, const std::vector<double>& r,
                          const std::function<bool(const SpherePair&)>& f,
                          const std::function<void()>& tick) {
  const size_t n = c.size();
  if (n == 0) return true;
  bool go = true;  // false once f asked to stop
  auto emit = [&](const SpherePair& p) {
    if (go) go = f(p);
  };
  // Spheres up to twice the median radius are "small": the grid's cells are sized for them.
  std::vector<double> radii(r);
  std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
  const double r_cut = 2.0 * radii[radii.size() / 2];
  std::vector<int> small, large;
  for (size_t p = 0; p < n; ++p) (r[p] <= r_cut ? small : large).push_back(static_cast<int>(p));
  if (large.size() > 2000) {
    // Too many large spheres for the direct large-large pass: one level for all.
    small.clear();
    large.clear();
    for (size_t p = 0; p < n; ++p) small.push_back(static_cast<int>(p));
  }
  double r_small = 0.0;
  for (int p : small) r_small = std::max(r_small, r[p]);
  // The grid's cells, filled by a counting sort (the spheres are all known: no per-cell lists).
  NeighbourGrid grid(box, 2.0 * r_small, 4 * small.size());
  std::vector<int> start(grid.cell_count() + 1, 0), cell_of(small.size()), order(small.size());
  for (size_t t = 0; t < small.size(); ++t) {
    cell_of[t] = static_cast<int>(grid.cell_index(c[small[t]]));
    ++start[cell_of[t] + 1];
  }
  for (size_t k = 0; k + 1 < start.size(); ++k) start[k + 1] += start[k];
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (size_t t = 0; t < small.size(); ++t) order[fill[cell_of[t]]++] = small[t];
  }
  auto lattice = [&](const Vec3& shift) {
    std::array<int, 3> k = {0, 0, 0};
    if (box.periodic) {
      for (int a = 0; a < 3; ++a) k[a] = static_cast<int>(std::floor(shift[a] / box.size[a] + 0.5));
    }
    return k;
  };
  auto all_images = [&](int p, int q) {
    for_each_image(box, c[p], r[p], c[q], r[q], [&](const Vec3& s) {
      const std::array<int, 3> k = lattice(s);
      if (p == q && k[0] == 0 && k[1] == 0 && k[2] == 0) return;
      emit({p, q, k});
    });
  };
  const bool nearest = grid.nearest_image_suffices();
  auto candidate = [&](int p, int q) {
    if (q < p) return;
    if (!nearest) {
      all_images(p, q);
      return;
    }
    if (q == p) return;  // a small sphere cannot reach its own image (3 cells per axis)
    // Only the nearest image of q can be within reach: the box is at least 3 reaches wide.
    Vec3 d = c[q] - c[p];
    const std::array<int, 3> k = to_nearest_image(box, &d);
    const double rr = r[p] + r[q];
    if (d.squaredNorm() <= rr * rr) emit({p, q, k});
  };
  for (size_t t = 0; t < small.size() && go; ++t) {
    if (tick && (t & 1023) == 0) tick();
    const int p = small[t];
    grid.for_each_neighbour_cell(c[p], [&](size_t cell) {
      for (int u = start[cell]; u < start[cell + 1]; ++u) candidate(p, order[u]);
    });
  }
  if (large.empty() || !go) return go;
  // Large spheres: registered in every cell within their radius plus r_small, so a small
  // sphere that meets one finds it in its own cell.
  NeighbourGrid reach_grid(box, 2.0 * r_small, 4 * small.size());
  for (int q : large) reach_grid.insert_reaching(q, c[q], r[q] + r_small);
  for (size_t t = 0; t < small.size() && go; ++t) {
    if (tick && (t & 1023) == 0) tick();
    reach_grid.for_each_in_cell(c[small[t]], [&](int q) { all_images(small[t], q); });
  }
  for (size_t u = 0; u < large.size() && go; ++u) {
    if (tick) tick();
    for (size_t v = u; v < large.size() && go; ++v) all_images(large[u], large[v]);
  }
  return go;
}

}  // namespace rvegen
