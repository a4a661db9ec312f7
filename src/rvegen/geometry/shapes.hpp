// Inclusion shapes in the notation of the paper (Lemaitre et al., CFM 2017, section 2):
// sphere S(p, r), cylinder C(p, r, l) with flat end disks and half-axis vector l
// (length 2|l|, aspect ratio a = |l| / r), and ellipsoid E(p, semi-axes, rotation).
#pragma once

#include <Eigen/Dense>
#include <string>

namespace rvegen {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

enum class ShapeKind { Sphere = 0, Cylinder = 1, Ellipsoid = 2 };

/// Name used in files ("sphere", "cylinder", "ellipsoid").
const char* shape_name(ShapeKind kind);
/// Parses a shape name; returns false when unknown.
bool parse_shape_name(const std::string& name, ShapeKind* kind);

/// One convex inclusion. Only the fields of its kind are meaningful:
/// sphere: center, radius; cylinder: center, radius, half_axis;
/// ellipsoid: center, semi_axes, rotation (columns are the principal axes in world coordinates,
/// semi-axis semi_axes[0] along column 0).
struct Shape {
  ShapeKind kind = ShapeKind::Sphere;
  Vec3 center = Vec3::Zero();
  double radius = 0.0;
  Vec3 half_axis = Vec3::Zero();
  Vec3 semi_axes = Vec3::Zero();
  Mat3 rotation = Mat3::Identity();

  static Shape sphere(const Vec3& p, double r);
  static Shape cylinder(const Vec3& p, double r, const Vec3& l);
  static Shape ellipsoid(const Vec3& p, const Vec3& semi, const Mat3& rot);

  /// Radius of the smallest sphere about `center` that contains the shape.
  double bounding_radius() const;
  /// Smallest characteristic length (sphere radius, min(cylinder radius, |l|), smallest semi-axis).
  /// Tolerances are taken relative to it.
  double min_size() const;
  double volume() const;
  /// Support point: a point of the shape maximising d . x (d need not be unit; d != 0).
  Vec3 support(const Vec3& d) const;
  /// Support value h(d) = max_{x in shape} d . x.
  double support_value(const Vec3& d) const { return d.dot(support(d)); }
  /// True when x lies in the closed shape.
  bool contains(const Vec3& x) const;
  /// Axis-aligned bounding box (exact for all three kinds).
  void aabb(Vec3* lo, Vec3* hi) const;
  /// Copy scaled by f about its centre.
  Shape scaled(double f) const {
    Shape s = *this;
    s.radius *= f;
    s.half_axis *= f;
    s.semi_axes *= f;
    return s;
  }
  /// Copy translated by t.
  Shape translated(const Vec3& t) const {
    Shape s = *this;
    s.center += t;
    return s;
  }
};

/// Any unit vector orthogonal to unit vector u (deterministic).
Vec3 any_orthogonal(const Vec3& u);

/// Unit axis of an inclusion's shape: cylinder axis, ellipsoid's longest principal axis,
/// zero for spheres.
Vec3 principal_axis(const Shape& s);

/// Exact Euclidean distance from x to an ellipsoid (0 inside), and the point of the ellipsoid
/// nearest x when `nearest` is given (x itself inside).
double ellipsoid_distance(const Shape& e, const Vec3& x, Vec3* nearest = nullptr);

/// The least principal radius of curvature of the surface of the ellipsoid of semi-axes `a`
/// (principal frame) at the radial projection of p != 0 onto it.
double ellipsoid_least_curvature_radius(const Vec3& a, const Vec3& p);

/// The least principal radius of curvature of a shape's surface near x: the radius of a sphere
/// or of a cylinder's mantle; for an ellipsoid, at the radial projection of x onto its surface.
double least_curvature_radius(const Shape& s, const Vec3& x);

}  // namespace rvegen
