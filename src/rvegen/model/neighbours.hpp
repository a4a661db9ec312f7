// The broad phase: which inclusions (and which of their periodic images) may meet. One grid
// serves the packers (RSA by queries, MD by sphere_pairs over the spheres that cover its
// bodies), the audit and the statistics.
#pragma once

#include <array>
#include <functional>
#include <vector>

#include "rvegen/model/inclusion_set.hpp"

namespace rvegen {

/// Calls f(shift) for every lattice translation `shift` of a periodic box such that the
/// bounding spheres of a (at ca, radius ra) and of b translated by shift (at cb + shift,
/// radius rb) intersect. Enumerates every image, even for inclusions longer than half the box.
/// Non-periodic boxes yield only the zero shift (when the spheres intersect).
void for_each_image(const Box& box, const Vec3& ca, double ra, const Vec3& cb, double rb,
                    const std::function<void(const Vec3&)>& f);

/// Moves the difference d = c_b - c_a to b's nearest periodic image (unchanged in a closed box)
/// and returns that image's lattice shift k, in box sizes: b is taken at c_b + k * size.
std::array<int, 3> to_nearest_image(const Box& box, Vec3* d);

/// Cell coordinate of x along `axis` in a grid of n cells of `width` from the box origin:
/// wrapped in a periodic box, clamped otherwise (clamping keeps points within a cell width of
/// each other in the same or adjacent cells).
int cell_coordinate(const Box& box, int n, double width, double x, int axis);

/// Uniform grid over inclusion centres for neighbour queries; periodic-aware.
/// `reach` must be at least the largest sum of two bounding radii that will be queried.
/// `expected_count` bounds the number of cells (about two per stored inclusion).
class NeighbourGrid {
 public:
  NeighbourGrid(const Box& box, double reach, size_t expected_count);
  void insert(int index, const Vec3& center);
  /// Stores `index` in every cell that a ball of `radius` about `center` reaches (for bodies
  /// larger than the cells): a point within `radius` of center then finds it in its own cell.
  void insert_reaching(int index, const Vec3& center, double radius);
  /// Calls f(index) for every stored index whose centre may lie within `reach` of c
  /// (a superset; images are the caller's business through for_each_image). Each stored
  /// (index, cell) entry is visited at most once.
  template <class F>
  void for_each_candidate(const Vec3& c, F&& f) const {
    if (cells_.empty()) return;
    for_each_neighbour_cell(c, [&](size_t cell) {
      for (int idx : cells_[cell]) f(idx);
    });
  }
  /// Calls f(index) for every index stored in the cell of c (see insert_reaching).
  template <class F>
  void for_each_in_cell(const Vec3& c, F&& f) const {
    if (cells_.empty()) return;
    for (int idx : cells_[cell_index(c)]) f(idx);
  }
  /// The cells: their number, the cell of a point, and f(cell) for the cell of c and its
  /// neighbours (each cell once). For callers that keep their own per-cell storage.
  size_t cell_count() const { return static_cast<size_t>(n_[0]) * n_[1] * n_[2]; }
  size_t cell_index(const Vec3& c) const;
  template <class F>
  void for_each_neighbour_cell(const Vec3& c, F&& f) const {
    int lo[3], hi[3];
    neighbour_range(c, lo, hi);
    for (int z = lo[2]; z <= hi[2]; ++z) {
      const int zz = (z + n_[2]) % n_[2];
      for (int y = lo[1]; y <= hi[1]; ++y) {
        const int yy = (y + n_[1]) % n_[1];
        for (int x = lo[0]; x <= hi[0]; ++x) {
          f((static_cast<size_t>(zz) * n_[1] + yy) * n_[0] + (x + n_[0]) % n_[0]);
        }
      }
    }
  }
  /// True when a candidate's nearest periodic image is the only one within `reach`: every
  /// periodic axis has at least 3 cells (so the box is at least 3 reaches wide).
  bool nearest_image_suffices() const;

 private:
  int cell_of(const Vec3& c, int axis) const;
  void neighbour_range(const Vec3& c, int lo[3], int hi[3]) const;
  Box box_;
  int n_[3];
  double cell_[3];
  std::vector<std::vector<int>> cells_;  // allocated at the first insert
};

/// Sphere j, translated by the lattice vector (k[0] size[0], k[1] size[1], k[2] size[2]),
/// intersects sphere i.
struct SpherePair {
  int i, j;
  std::array<int, 3> k;
};

/// Every intersecting pair of spheres (centre c[i], radius r[i]) of a box, periodic images
/// included, into *out (cleared first; its capacity is reused). Each pair of distinct spheres
/// and image is reported once (as (i, j, k) or (j, i, -k)); a sphere meeting its own image k
/// is reported as k and as -k. Small spheres go through a NeighbourGrid by queries; spheres of
/// more than twice the median radius are registered in every cell they reach, so one large
/// sphere does not coarsen the grid for all. `tick` (optional) is called every 1024 spheres (a
/// time budget may throw from it).
void sphere_pairs(const Box& box, const std::vector<Vec3>& c, const std::vector<double>& r,
                  std::vector<SpherePair>* out, const std::function<void()>& tick = nullptr);

/// The same pairs, in the same order, handed to f one by one; f returns false to stop (then
/// this returns false). Near-linear in the number of spheres and pairs for any size ratio.
bool for_each_sphere_pair(const Box& box, const std::vector<Vec3>& c, const std::vector<double>& r,
                          const std::function<bool(const SpherePair&)>& f,
                          const std::function<void()>& tick = nullptr);

}  // namespace rvegen
