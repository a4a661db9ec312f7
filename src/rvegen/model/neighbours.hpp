// The broad phase: which inclusions (and which of their periodic images) may meet. One grid
// serves the packers, the audit and the statistics.
#pragma once

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

/// Uniform grid over inclusion centres for neighbour queries; periodic-aware.
/// `reach` must be at least the largest sum of two bounding radii that will be queried.
/// `expected_count` bounds the number of cells (about two per stored inclusion).
class NeighbourGrid {
 public:
  NeighbourGrid(const Box& box, double reach, size_t expected_count);
  void insert(int index, const Vec3& center);
  /// Calls f(index) for every stored index whose centre may lie within `reach` of c
  /// (a superset; images are the caller's business through for_each_image).
  void for_each_candidate(const Vec3& c, const std::function<void(int)>& f) const;

 private:
  int cell_of(const Vec3& c, int axis) const;
  Box box_;
  int n_[3];
  double cell_[3];
  std::vector<std::vector<int>> cells_;
};

}  // namespace rvegen
