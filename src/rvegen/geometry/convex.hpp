// Distance and penetration between two convex shapes from their support functions:
// GJK (Gilbert-Johnson-Keerthi) for the separation, EPA (expanding polytope) for the depth.
// Used for the pairs that have no closed form: cylinder end disks against another cylinder
// (after the paper's Algorithm 4 has ruled out the lateral cases) and cylinder-ellipsoid.
#pragma once

#include "rvegen/geometry/shapes.hpp"

namespace rvegen {

struct ConvexQuery {
  /// True when a separating plane was found (the shapes are disjoint; touching counts as
  /// not separated). This is a certificate, not a threshold decision.
  bool separated = false;
  /// When separated: a lower bound on the distance, within `tolerance` of the true distance
  /// if the query ran to convergence. 0 when not separated.
  double distance = 0.0;
  /// When not separated: the penetration depth (the length of the smallest translation of b
  /// that makes the shapes touch), an upper bound within max(tolerance, depth_rel depth) of the
  /// true value. 0 when separated.
  double depth = 0.0;
  /// Unit direction: translating b along +normal increases the separation.
  Vec3 normal = Vec3::UnitX();
  /// Witness points on a and b (closest points when separated, deepest points otherwise).
  Vec3 point_a = Vec3::Zero();
  Vec3 point_b = Vec3::Zero();
};

/// A piece of a sheared fibre (a wavy or bent one, whose sections normal to its axis are disks
/// along a curved centre line): the Minkowski sum of the disk of radius `radius` about `center`
/// normal to the unit vector `normal`, the segment center +- half_axis (a chord of the centre
/// line) and the ball of radius `round`. The slice of the fibre between the planes normal to
/// `normal` through the chord's ends lies in it when `radius` holds the fibre's radius and the
/// centre line's departure from the chord (that departure is normal to the axis too). Convex.
struct ShearedPiece {
  Vec3 center = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();
  Vec3 half_axis = Vec3::Zero();
  double radius = 0.0, round = 0.0;
  /// Where a chain's centre line bows off its chord: the disk's centre moves, besides along
  /// the chord, by b in [bow_lo[k], bow_hi[k]] along each unit direction bow[k] normal to
  /// `normal` (the wave's and the bend's; zero: none). The piece is the disk swept over the
  /// chord and both ranges, then grown by the ball.
  Vec3 bow[2] = {Vec3::Zero(), Vec3::Zero()};
  double bow_lo[2] = {0.0, 0.0}, bow_hi[2] = {0.0, 0.0};
  /// The largest distance the bows move the disk's centre.
  double bow_reach() const;
  double bounding_radius() const;
  /// The support function h(d) = max over the piece of d . x, and a point where it is reached.
  double support_value(const Vec3& d) const;
  Vec3 support(const Vec3& d) const;
  /// The distance from x to the piece without its ball (0 inside), and whether x lies in it.
  double distance_to_core(const Vec3& x) const;
  bool contains(const Vec3& x) const;
  ShearedPiece translated(const Vec3& t) const {
    ShearedPiece p = *this;
    p.center += t;
    return p;
  }
};

/// Runs GJK, then EPA when the shapes are not separated.
/// `tolerance` is an absolute length (callers use a small multiple of the shapes' size).
/// `need_distance`: when false, stops as soon as a separating plane is found.
/// `depth_rel`: EPA stops once its depth (an upper bound) is within max(tolerance,
/// depth_rel * depth) of the polytope's lower bound.
ConvexQuery convex_query(const Shape& a, const Shape& b, double tolerance, bool need_distance,
                         double depth_rel);

/// The same for a sheared piece against a shape or another piece.
ConvexQuery convex_query(const ShearedPiece& a, const Shape& b, double tolerance,
                         bool need_distance, double depth_rel);
ConvexQuery convex_query(const ShearedPiece& a, const ShearedPiece& b, double tolerance,
                         bool need_distance, double depth_rel);

/// Squared distance between the segments [p1, q1] and [p2, q2] (either may be a point).
double segment_distance2(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2);
/// The same, with the closest points' parameters: p1 + s (q1 - p1) and p2 + t (q2 - p2).
double segment_closest(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2, double* s,
                       double* t);

}  // namespace rvegen
