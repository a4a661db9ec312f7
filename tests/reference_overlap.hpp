// Independent reference for the pair tests: Minkowski Portal Refinement (Snethen's
// XenoCollide) over support functions written here from the shapes' raw parameters, sharing no
// code with the library's pair tests (neither its GJK/EPA, nor its closed forms, nor its
// support functions). Used only by tests and benchmarks.
#pragma once

#include <algorithm>
#include <cmath>

#include "rvegen/geometry/convex.hpp"
#include "rvegen/geometry/shapes.hpp"

namespace rvegen::reference {

/// Support point of a shape in direction d, computed in the shape's local frame.
inline Vec3 support(const Shape& s, const Vec3& d) {
  switch (s.kind) {
    case ShapeKind::Sphere:
      return s.center + d * (s.radius / d.norm());
    case ShapeKind::Cylinder: {
      // Local frame (e1, e2, u); local support = (r cos, r sin, +-h).
      const double h = s.half_axis.norm();
      const Vec3 u = s.half_axis / h;
      const Vec3 tmp = std::abs(u.x()) < 0.6 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
      const Vec3 e1 = (tmp - tmp.dot(u) * u).normalized();
      const Vec3 e2 = u.cross(e1);
      const double a = d.dot(e1), b = d.dot(e2), c = d.dot(u);
      const double rho = std::sqrt(a * a + b * b);
      Vec3 x = s.center + (c >= 0 ? h : -h) * u;
      if (rho > 0) x += s.radius * (a / rho * e1 + b / rho * e2);
      return x;
    }
    case ShapeKind::Ellipsoid: {
      // x = c + R diag(a) y / |y| with y = diag(a) R^T d.
      const Vec3 y = s.semi_axes.cwiseProduct(s.rotation.transpose() * d);
      return s.center + s.rotation * s.semi_axes.cwiseProduct(y / y.norm());
    }
  }
  return s.center;
}

/// Support point of a sheared piece: in the frame (e1, e2, n) of its disk, the disk's rim
/// point (r cos, r sin, 0), plus the end of the chord on the side of d, plus the ball's point.
inline Vec3 support(const ShearedPiece& p, const Vec3& d) {
  const Vec3 n = p.normal.normalized();
  const Vec3 tmp = std::abs(n.x()) < 0.6 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
  const Vec3 e1 = (tmp - tmp.dot(n) * n).normalized();
  const Vec3 e2 = n.cross(e1);
  const double a = d.dot(e1), b = d.dot(e2);
  const double rho = std::sqrt(a * a + b * b);
  Vec3 x = p.center + (d.dot(p.half_axis) >= 0 ? p.half_axis : Vec3(-p.half_axis));
  if (rho > 0) x += p.radius * (a / rho * e1 + b / rho * e2);
  // The bows: the disk's centre moved over a segment along each direction.
  for (int k = 0; k < 2; ++k) x += (d.dot(p.bow[k]) >= 0 ? p.bow_hi[k] : p.bow_lo[k]) * p.bow[k];
  return x + d * (p.round / d.norm());
}

/// True when the closed shapes a and b (shapes or sheared pieces) intersect (MPR).
/// Configurations within about 1e-12 of the combined size from tangency may go either way.
template <class A, class B>
bool overlap(const A& a, const B& b) {
  auto S = [&](const Vec3& n) -> Vec3 { return support(b, n) - support(a, -n); };  // D = b - a
  const double scale = 1.0 + (b.center - a.center).norm();
  const double eps = 1e-13 * scale;
  Vec3 v0 = b.center - a.center;
  if (v0.norm() <= eps) return true;  // coincident centres: both contain the point
  Vec3 n = -v0;
  Vec3 v1 = S(n);
  if (v1.dot(n) <= 0) return false;
  n = v1.cross(v0);
  // v0, v1 and the origin collinear: v1 . v0 < 0 was just checked, so the origin lies on the
  // segment v0-v1, inside D (within round-off of it).
  if (n.norm() <= 1e-12 * v1.norm() * v0.norm()) return true;
  Vec3 v2 = S(n);
  if (v2.dot(n) <= 0) return false;
  n = (v1 - v0).cross(v2 - v0);
  if (n.dot(v0) > 0) {
    std::swap(v1, v2);
    n = -n;
  }
  Vec3 v3;
  for (int it = 0;; ++it) {
    if (it > 1000) return false;
    v3 = S(n);
    if (v3.dot(n) <= 0) return false;
    if (v1.cross(v3).dot(v0) < 0) {
      v2 = v3;
      n = (v1 - v0).cross(v3 - v0);
      continue;
    }
    if (v3.cross(v2).dot(v0) < 0) {
      v1 = v3;
      n = (v3 - v0).cross(v2 - v0);
      continue;
    }
    break;
  }
  for (int it = 0; it < 2000; ++it) {
    n = (v2 - v1).cross(v3 - v1);
    const double nn = n.norm();
    if (nn == 0) return true;
    n /= nn;
    if (n.dot(v1) >= 0) return true;  // origin inside the portal
    const Vec3 v4 = S(n);
    if (v4.dot(n) <= 0) return false;  // separating plane
    // Converged: the new support plane is within eps of the portal; origin outside within eps.
    const double dv4 = v4.dot(n);
    if (std::min({dv4 - v1.dot(n), dv4 - v2.dot(n), dv4 - v3.dot(n)}) <= eps) return false;
    const double d1 = v4.cross(v1).dot(v0);
    const double d2 = v4.cross(v2).dot(v0);
    const double d3 = v4.cross(v3).dot(v0);
    if (d1 < 0) {
      if (d2 < 0) {
        v1 = v4;
      } else {
        v3 = v4;
      }
    } else {
      if (d3 < 0) {
        v2 = v4;
      } else {
        v1 = v4;
      }
    }
  }
  return false;
}

}  // namespace rvegen::reference
