// Certified bounds of a deformed inclusion's own shape, tighter than the ball of radius
// deform_scale (1 + deform_amplitude) that |g| <= 1 gives.
//
// Both rest on one fact: at the maximum of a smooth function f on the unit sphere its gradient
// vanishes, so a sample within angle delta of it is at most M delta^2 / 2 below it (M bounds f''
// along great circles). The samples are the nodes of a cube map with n cells a face side: every
// direction lies within angle sqrt(2) / n of one.
//
// The support function h(u) = max over the surface x of x . u is sublinear: h(sum b_i c_i) <=
// sum b_i h(c_i) for b_i >= 0. A table of certified h at the nodes of a coarser cube map, read
// with bilinear weights on the cube face, is therefore a certified upper bound for every u; the
// error is of second order in the cell size (its size at kCells: docs/benchmarks.md).
#pragma once

#include <algorithm>
#include <limits>
#include <memory>
#include <vector>

#include "rvegen/model/inclusion_set.hpp"

namespace rvegen {

/// A certified upper bound of the maximum of the deformation field g over the unit sphere
/// (never above the sum of the wave weights, the bound |g| <= 1 gives).
double deformation_peak(const Modifiers& m);

/// Certified support function of a deformed sphere whose undeformed radius is 1 (the surface
/// |y| = deform_scale (1 + deform_amplitude g(y / |y|)) about the centre).
class DeformedSupport {
 public:
  /// The table for a deformation, or null when the deformation is too rough (wavenumbers too
  /// high) for the table to beat the ball of radius deform_scale (1 + amplitude peak).
  static std::shared_ptr<const DeformedSupport> make(const Modifiers& m);

  /// An upper bound of h(u) for any vector u (h is positively homogeneous: h(t u) = t h(u)).
  double operator()(const Vec3& u) const;
  /// Cells per face side of the table, and of the sample grid behind it.
  static constexpr int kCells = 16;

 private:
  DeformedSupport() = default;
  std::vector<float> h_;  // 6 faces x (kCells + 1)^2 nodes: h at the node vector on the face
};

/// The table of an inclusion packed and audited by its support function: a deformed sphere
/// without a debonding void whose table exists (see DeformedSupport::make); null otherwise.
std::shared_ptr<const DeformedSupport> support_table(const Inclusion& inc);

/// The support bound of a body made of a deformed core of radius `core_radius` grown by `extra`
/// and held in a ball of radius `ball` about the same centre, along u: the smaller of the two
/// certified bounds (the table's, near the peak, can exceed the ball's by its margin).
inline double bounded_support(const DeformedSupport& table, double core_radius, double extra,
                              double ball, const Vec3& u) {
  const double len = u.norm();
  return std::min(ball * len, core_radius * table(u) + extra * len);
}

/// The gap along the plane normal to the direction n from `centre` to the nearest point of the
/// cylinder `piece`'s axis, between the piece and a body about `centre` whose support function
/// about it is at most support(n): >= 0 when that plane separates them, -infinity when there is
/// no such direction (not a cylinder, or the centre on its axis). *normal = n.
/// The same for any piece with an axis (center +- half_axis) and a support_value: a cylinder, a
/// sheared piece.
template <class Piece, class Support>
double axis_plane_gap(const Vec3& centre, const Piece& piece, const Support& support,
                      Vec3* normal) {
  const double h2 = piece.half_axis.squaredNorm();
  const double t =
      h2 > 0.0 ? std::clamp((centre - piece.center).dot(piece.half_axis) / h2, -1.0, 1.0) : 0.0;
  Vec3 n = piece.center + t * piece.half_axis - centre;
  const double len = n.norm();
  if (!(len > 0.0)) return -std::numeric_limits<double>::infinity();
  n /= len;
  *normal = n;
  return -piece.support_value(-n) - n.dot(centre) - support(n);
}
template <class Support>
double plane_gap(const Vec3& centre, const Shape& piece, const Support& support, Vec3* normal) {
  if (piece.kind != ShapeKind::Cylinder) return -std::numeric_limits<double>::infinity();
  return axis_plane_gap(centre, piece, support, normal);
}

/// The support function of such an inclusion's packing envelope about its centre along u:
/// bounded_support with the core radius, the envelope's extra thickness (the shell unless
/// shells may touch, and the packing pad) and the envelope's ball.
double envelope_support(const Inclusion& inc, const DeformedSupport& table, const Vec3& u);

}  // namespace rvegen
