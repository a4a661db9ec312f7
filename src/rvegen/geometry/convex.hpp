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

/// Runs GJK, then EPA when the shapes are not separated.
/// `tolerance` is an absolute length (callers use a small multiple of the shapes' size).
/// `need_distance`: when false, stops as soon as a separating plane is found.
/// `depth_rel`: EPA stops once its depth (an upper bound) is within max(tolerance,
/// depth_rel * depth) of the polytope's lower bound.
ConvexQuery convex_query(const Shape& a, const Shape& b, double tolerance, bool need_distance,
                         double depth_rel);

/// Squared distance between the segments [p1, q1] and [p2, q2] (either may be a point).
double segment_distance2(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2);
/// The same, with the closest points' parameters: p1 + s (q1 - p1) and p2 + t (q2 - p2).
double segment_closest(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2, double* s,
                       double* t);

}  // namespace rvegen
