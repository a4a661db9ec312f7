#include "rvegen/geometry/shapes.hpp"

#include <algorithm>
#include <cmath>

#include "rvegen/geometry/tolerances.hpp"

namespace rvegen {

const char* shape_name(ShapeKind kind) {
  switch (kind) {
    case ShapeKind::Sphere:
      return "sphere";
    case ShapeKind::Cylinder:
      return "cylinder";
    case ShapeKind::Ellipsoid:
      return "ellipsoid";
  }
  return "?";
}

bool parse_shape_name(const std::string& name, ShapeKind* kind) {
  if (name == "sphere") {
    *kind = ShapeKind::Sphere;
  } else if (name == "cylinder") {
    *kind = ShapeKind::Cylinder;
  } else if (name == "ellipsoid") {
    *kind = ShapeKind::Ellipsoid;
  } else {
    return false;
  }
  return true;
}

Shape Shape::sphere(const Vec3& p, double r) {
  Shape s;
  s.kind = ShapeKind::Sphere;
  s.center = p;
  s.radius = r;
  return s;
}

Shape Shape::cylinder(const Vec3& p, double r, const Vec3& l) {
  Shape s;
  s.kind = ShapeKind::Cylinder;
  s.center = p;
  s.radius = r;
  s.half_axis = l;
  return s;
}

Shape Shape::ellipsoid(const Vec3& p, const Vec3& semi, const Mat3& rot) {
  Shape s;
  s.kind = ShapeKind::Ellipsoid;
  s.center = p;
  s.semi_axes = semi;
  s.rotation = rot;
  return s;
}

double Shape::bounding_radius() const {
  switch (kind) {
    case ShapeKind::Sphere:
      return radius;
    case ShapeKind::Cylinder:
      return std::sqrt(half_axis.squaredNorm() + radius * radius);
    case ShapeKind::Ellipsoid:
      return semi_axes.maxCoeff();
  }
  return 0.0;
}

double Shape::min_size() const {
  switch (kind) {
    case ShapeKind::Sphere:
      return radius;
    case ShapeKind::Cylinder:
      return std::min(radius, half_axis.norm());
    case ShapeKind::Ellipsoid:
      return semi_axes.minCoeff();
  }
  return 0.0;
}

double Shape::volume() const {
  switch (kind) {
    case ShapeKind::Sphere:
      return 4.0 / 3.0 * M_PI * radius * radius * radius;
    case ShapeKind::Cylinder:
      return M_PI * radius * radius * 2.0 * half_axis.norm();
    case ShapeKind::Ellipsoid:
      return 4.0 / 3.0 * M_PI * semi_axes.prod();
  }
  return 0.0;
}

Vec3 Shape::support(const Vec3& d) const {
  switch (kind) {
    case ShapeKind::Sphere:
      return center + radius * d.normalized();
    case ShapeKind::Cylinder: {
      // End disk on the side of d, then the rim point furthest along d's radial part.
      const double h = half_axis.norm();
      const Vec3 u = half_axis / h;
      const double du = d.dot(u);
      Vec3 x = center + (du >= 0.0 ? half_axis : Vec3(-half_axis));
      Vec3 radial = d - du * u;
      // Second Gram-Schmidt pass: when d is nearly axial, the cancellation above leaves an
      // axial residue comparable to |radial| itself, which would put x off the rim.
      radial -= radial.dot(u) * u;
      const double rn = radial.norm();
      // When d is (numerically) along the axis every rim point is a support point; the disk
      // centre is then returned, which is also one (h(d) is the same).
      if (rn > kRoundoff * d.norm()) x += radius * radial / rn;
      return x;
    }
    case ShapeKind::Ellipsoid: {
      // x = p + M d / sqrt(d^T M d), M = R diag(a^2) R^T.
      const Vec3 dl = rotation.transpose() * d;
      const Vec3 md = semi_axes.cwiseProduct(semi_axes).cwiseProduct(dl);
      const double s = std::sqrt(dl.dot(md));
      return center + rotation * (md / s);
    }
  }
  return center;
}

bool Shape::contains(const Vec3& x) const {
  const Vec3 d = x - center;
  switch (kind) {
    case ShapeKind::Sphere:
      return d.squaredNorm() <= radius * radius;
    case ShapeKind::Cylinder: {
      const double h2 = half_axis.squaredNorm();
      const double xl = d.dot(half_axis);  // = X |l|
      if (xl * xl > h2 * h2) return false;
      const double l2 = d.squaredNorm() - xl * xl / h2;
      return l2 <= radius * radius;
    }
    case ShapeKind::Ellipsoid: {
      const Vec3 q = (rotation.transpose() * d).cwiseQuotient(semi_axes);
      return q.squaredNorm() <= 1.0;
    }
  }
  return false;
}

void Shape::aabb(Vec3* lo, Vec3* hi) const {
  Vec3 e = Vec3::Zero();
  switch (kind) {
    case ShapeKind::Sphere:
      e.setConstant(radius);
      break;
    case ShapeKind::Cylinder: {
      const Vec3 u = half_axis.normalized();
      for (int i = 0; i < 3; ++i) {
        e[i] = std::abs(half_axis[i]) + radius * std::sqrt(std::max(0.0, 1.0 - u[i] * u[i]));
      }
      break;
    }
    case ShapeKind::Ellipsoid: {
      for (int i = 0; i < 3; ++i) {
        double s = 0.0;
        for (int k = 0; k < 3; ++k) s += std::pow(rotation(i, k) * semi_axes[k], 2);
        e[i] = std::sqrt(s);
      }
      break;
    }
  }
  *lo = center - e;
  *hi = center + e;
}

Vec3 any_orthogonal(const Vec3& u) {
  // Cross with the coordinate axis least aligned with u.
  Vec3 a = Vec3::UnitX();
  if (std::abs(u.y()) < std::abs(u.x()) && std::abs(u.y()) <= std::abs(u.z())) {
    a = Vec3::UnitY();
  } else if (std::abs(u.z()) < std::abs(u.x())) {
    a = Vec3::UnitZ();
  }
  return u.cross(a).normalized();
}

Vec3 principal_axis(const Shape& s) {
  switch (s.kind) {
    case ShapeKind::Sphere:
      return Vec3::Zero();
    case ShapeKind::Cylinder:
      return s.half_axis.normalized();
    case ShapeKind::Ellipsoid: {
      int k = 0;
      s.semi_axes.maxCoeff(&k);
      return s.rotation.col(k);
    }
  }
  return Vec3::Zero();
}

double ellipsoid_distance(const Shape& e, const Vec3& x, Vec3* nearest) {
  const Vec3 y = e.rotation.transpose() * (x - e.center);
  const Vec3& a = e.semi_axes;
  if (y.cwiseQuotient(a).squaredNorm() <= 1.0) {
    if (nearest) *nearest = x;
    return 0.0;
  }
  // The closest point is z_i = a_i^2 y_i / (s + a_i^2) with s > 0 the root of
  // F(s) = sum (a_i y_i / (s + a_i^2))^2 - 1, decreasing in s (bisection, then exact point).
  auto F = [&](double s) {
    double sum = 0.0;
    for (int i = 0; i < 3; ++i) sum += std::pow(a[i] * y[i] / (s + a[i] * a[i]), 2);
    return sum - 1.0;
  };
  double lo = 0.0, hi = a.maxCoeff() * y.norm() + a.maxCoeff() * a.maxCoeff();
  for (int it = 0; it < 200 && hi - lo > kRootStop * (hi + kNoDirection); ++it) {
    const double mid = 0.5 * (lo + hi);
    (F(mid) > 0.0 ? lo : hi) = mid;
  }
  const double s = 0.5 * (lo + hi);
  Vec3 z;
  for (int i = 0; i < 3; ++i) z[i] = a[i] * a[i] * y[i] / (s + a[i] * a[i]);
  if (nearest) *nearest = e.center + e.rotation * z;
  return (y - z).norm();
}

// From the Gaussian and mean curvatures at the surface point p (x^T diag(a)^-2 x = 1):
// K = 1 / (abc h^2)^2 and H = (a^2 + b^2 + c^2 - |p|^2) / (2 (abc)^2 h^3), h^2 = sum p_i^2 / a_i^4;
// the larger principal curvature is H + sqrt(H^2 - K).
double ellipsoid_least_curvature_radius(const Vec3& a, const Vec3& p) {
  const double q = p.cwiseQuotient(a).norm();
  if (!(q > 0.0)) return a.minCoeff() * a.minCoeff() / a.maxCoeff();
  const Vec3 x = p / q;
  const double abc = a[0] * a[1] * a[2];
  const double h2 = x.cwiseQuotient(a.cwiseProduct(a)).squaredNorm();
  const double K = 1.0 / (abc * abc * h2 * h2);
  const double H = (a.squaredNorm() - x.squaredNorm()) / (2.0 * abc * abc * h2 * std::sqrt(h2));
  return 1.0 / (H + std::sqrt(std::max(0.0, H * H - K)));
}

double least_curvature_radius(const Shape& s, const Vec3& x) {
  if (s.kind != ShapeKind::Ellipsoid) return s.radius;
  return ellipsoid_least_curvature_radius(s.semi_axes, s.rotation.transpose() * (x - s.center));
}

}  // namespace rvegen
