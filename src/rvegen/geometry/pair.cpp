#include "rvegen/geometry/pair.hpp"

#include <algorithm>
#include <cmath>

#include "rvegen/geometry/convex.hpp"

namespace rvegen {

const char* contact_type_name(ContactType t) {
  switch (t) {
    case ContactType::kNone:
      return "none";
    case ContactType::kSS:
      return "ss";
    case ContactType::kSC1:
      return "sc1";
    case ContactType::kSC2:
      return "sc2";
    case ContactType::kSC3:
      return "sc3";
    case ContactType::kSC4:
      return "sc4";
    case ContactType::kCC1:
      return "cc1";
    case ContactType::kCD1:
      return "cd1";
    case ContactType::kCD2:
      return "cd2";
    case ContactType::kCD3:
      return "cd3";
    case ContactType::kD1:
      return "d1";
    case ContactType::kD2:
      return "d2";
    case ContactType::kPW:
      return "pw";
    case ContactType::kCE:
      return "ce";
    case ContactType::kSupport:
      return "support";
  }
  return "?";
}

double contact_tolerance(const Shape& a, const Shape& b) {
  return kContactRelTolerance * std::min(a.min_size(), b.min_size());
}

Contact intersect_sphere_sphere(const Shape& s1, const Shape& s2) {
  Contact c;
  const Vec3 d = s2.center - s1.center;
  const double dist = d.norm();
  const double depth = s1.radius + s2.radius - dist;
  if (!(depth > contact_tolerance(s1, s2))) return c;
  c.overlap = true;
  c.type = ContactType::kSS;
  c.depth = depth;
  // Coincident centres: every direction separates equally well; pick a fixed one.
  c.normal = dist > 0.0 ? Vec3(d / dist) : Vec3::UnitX();
  c.point = s1.center + c.normal * (s1.radius - 0.5 * depth);
  return c;
}

// Algorithm 1 of the paper, made exact: the overlap decision uses the exact signed distance from
// the sphere centre to the solid cylinder, the paper's X and L give the type.
Contact intersect_sphere_cylinder(const Shape& s, const Shape& cyl) {
  Contact c;
  const double h = cyl.half_axis.norm();
  const Vec3 u = cyl.half_axis / h;
  const Vec3 d = s.center - cyl.center;
  const double X = d.dot(u);  // paper: X, signed axial coordinate of p_s
  const Vec3 w = d - X * u;   // radial offset of p_s from the axis
  const double L = w.norm();  // paper: L, distance of p_s to the axis
  const double r = cyl.radius;
  // Sphere centre on the axis: any radial direction is a nearest one; choose a fixed one.
  const Vec3 e = L > 1e-14 * (h + r) ? Vec3(w / L) : any_orthogonal(u);
  const double sgn = X >= 0.0 ? 1.0 : -1.0;
  const double ax = std::abs(X) - h;  // > 0: beyond an end plane
  const double rd = L - r;            // > 0: outside the infinite cylinder
  double sd;                          // signed distance from p_s to the solid cylinder
  Vec3 g;                             // unit direction from the cylinder towards p_s
  if (ax <= 0.0 && rd <= 0.0) {       // centre inside: leave through the nearest face
    if (rd >= ax) {
      sd = rd;
      g = e;
    } else {
      sd = ax;
      g = sgn * u;
    }
  } else if (ax <= 0.0) {
    sd = rd;
    g = e;
  } else if (rd <= 0.0) {
    sd = ax;
    g = sgn * u;
  } else {
    sd = std::hypot(ax, rd);
    g = (ax * sgn * u + rd * e) / sd;
  }
  const double depth = s.radius - sd;  // exact minimal separating translation
  if (!(depth > contact_tolerance(s, cyl))) return c;
  c.overlap = true;
  c.depth = depth;
  c.normal = -g;
  c.point = s.center - g * (s.radius - 0.5 * depth);
  const double far = std::hypot(std::abs(X) + h, L + r);  // farthest cylinder point from p_s
  if (far <= s.radius) {
    c.type = ContactType::kSC1;
  } else if (std::abs(X) < h) {
    c.type = ContactType::kSC2;
  } else {
    c.type = L < r ? ContactType::kSC3 : ContactType::kSC4;
  }
  return c;
}

namespace {

struct Disk {
  Vec3 p;  // centre
  double r;
  Vec3 n;  // unit normal
};

// Algorithm 3 of the paper (cylinder against an end disk of another cylinder), used to name
// the contact once the overlap has been established exactly.
ContactType classify_cylinder_disk(const Shape& cyl, const Disk& dk) {
  const double h = cyl.half_axis.norm();
  const Vec3 u = cyl.half_axis / h;
  const double nl = dk.n.dot(cyl.half_axis);
  // Axis parallel to the disk plane: the axis never meets it; no cd-type contact.
  if (std::abs(nl) <= 1e-12 * h) return ContactType::kNone;
  const double t = dk.n.dot(dk.p - cyl.center) / nl;
  const Vec3 a = cyl.center + t * cyl.half_axis;  // axis meets the disk plane
  const Vec3 ad = a - dk.p;
  const double dist_a = ad.norm();
  if (dist_a <= 1e-14 * dk.r) return std::abs(t) <= 1.0 ? ContactType::kCD3 : ContactType::kNone;
  const Vec3 pt = dk.p + dk.r * ad / dist_a;  // rim point nearest a
  const double X = (pt - cyl.center).dot(u);
  const Vec3 b = cyl.center + X * u;
  const double rim_to_axis = (b - pt).norm();
  if (std::abs(X) < h && rim_to_axis < cyl.radius) {
    return dist_a > dk.r ? ContactType::kCD1 : ContactType::kCD2;
  }
  if (dist_a < dk.r && std::abs(t) <= 1.0) return ContactType::kCD3;
  return ContactType::kNone;
}

// Algorithm 2 of the paper (disk against disk), again only to name the contact.
// Note: the paper writes t = n_d2 . (p_d1 - p_d2) / (n_d2 . v); the point p_d1 + t v lies on
// the second disk's plane only with the opposite sign, which is used here.
ContactType classify_disk_disk(const Disk& d1, const Disk& d2) {
  const Vec3 n = d1.n.cross(d2.n);
  if (n.norm() <= 1e-12) return ContactType::kNone;  // parallel planes: no common line
  const Vec3 v = n.cross(d1.n);
  const double t = d2.n.dot(d2.p - d1.p) / d2.n.dot(v);
  const Vec3 pt = d1.p + t * v;
  const double q1 = (pt - d1.p).squaredNorm(), q2 = (pt - d2.p).squaredNorm();
  if (q1 <= d1.r * d1.r && q2 <= d2.r * d2.r) {
    return d1.r * d1.r - q1 > d2.r * d2.r - q2 ? ContactType::kD1 : ContactType::kD2;
  }
  return ContactType::kNone;
}

void end_disks(const Shape& c, Disk out[2]) {
  const Vec3 u = c.half_axis.normalized();
  out[0] = {c.center + c.half_axis, c.radius, u};
  out[1] = {c.center - c.half_axis, c.radius, -u};
}

// Names an end-disk contact: the paper's Algorithm 3 both ways, then Algorithm 2; when the
// paper's criteria name nothing (they look at one rim point only), the witness points decide.
ContactType classify_end_contact(const Shape& c1, const Shape& c2, const ConvexQuery& q) {
  Disk k1[2], k2[2];
  end_disks(c1, k1);
  end_disks(c2, k2);
  for (const Disk& dk : k2) {
    const ContactType t = classify_cylinder_disk(c1, dk);
    if (t != ContactType::kNone) return t;
  }
  for (const Disk& dk : k1) {
    const ContactType t = classify_cylinder_disk(c2, dk);
    if (t != ContactType::kNone) return t;
  }
  for (const Disk& a : k1) {
    for (const Disk& b : k2) {
      const ContactType t = classify_disk_disk(a, b);
      if (t != ContactType::kNone) return t;
    }
  }
  auto on_cap = [](const Shape& c, const Vec3& x) {
    const double h = c.half_axis.norm();
    return std::abs((x - c.center).dot(c.half_axis) / h) >= h * (1.0 - 1e-6);
  };
  const bool cap1 = on_cap(c1, q.point_a), cap2 = on_cap(c2, q.point_b);
  if (cap1 && cap2) return c1.radius >= c2.radius ? ContactType::kD1 : ContactType::kD2;
  return ContactType::kCD1;
}

}  // namespace

// Algorithm 4 of the paper with its degenerate cases:
//  - parallel and anti-parallel axes (including coaxial, end to end): closed form, since the
//    Minkowski difference is itself a cylinder;
//  - lateral crossing (cc1): exact when the closest points of the axis lines lie within both
//    segments (the intersection of the infinite cylinders is symmetric about the common
//    perpendicular, so without any end disk involved it is centred on pt_1 and pt_2);
//  - otherwise an end disk is involved: the overlap is decided by GJK/EPA on the exact support
//    functions and named by Algorithms 2-3.
Contact intersect_cylinder_cylinder(const Shape& c1, const Shape& c2) {
  Contact c;
  const double tol = contact_tolerance(c1, c2);
  const Vec3 d = c2.center - c1.center;
  const double h1 = c1.half_axis.norm(), h2 = c2.half_axis.norm();
  const Vec3 u1 = c1.half_axis / h1, u2 = c2.half_axis / h2;
  const double r1 = c1.radius, r2 = c2.radius;
  const Vec3 cr = u1.cross(u2);
  const double s = cr.norm();
  if (s <= 1e-12) {
    // Parallel axes: D = c1 - c2 is a cylinder of radius r1+r2 and half-length h1+h2.
    const double X = d.dot(u1);
    const Vec3 w = d - X * u1;
    const double delta = w.norm();
    const double rad = r1 + r2 - delta;
    const double ax = h1 + h2 - std::abs(X);
    if (!(std::min(rad, ax) > tol)) return c;
    c.overlap = true;
    const Vec3 e = delta > 1e-14 * (r1 + r2) ? Vec3(w / delta) : any_orthogonal(u1);
    // Middle of the overlap, radially and axially, in c1's frame.
    const double mr = 0.5 * (std::max(-r1, delta - r2) + std::min(r1, delta + r2));
    const double mx = 0.5 * (std::max(-h1, X - h2) + std::min(h1, X + h2));
    c.point = c1.center + mx * u1 + mr * e;
    if (rad <= ax) {  // side by side
      c.type = ContactType::kCC1;
      c.depth = rad;
      c.normal = e;
    } else {  // end to end (coaxial included)
      c.type = r1 >= r2 ? ContactType::kD1 : ContactType::kD2;
      c.depth = ax;
      c.normal = X >= 0.0 ? u1 : Vec3(-u1);
    }
    return c;
  }
  const Vec3 n = cr / s;
  const double dn = d.dot(n);
  const double rho = std::abs(dn);  // paper: rho, distance between the axis lines
  if (!(r1 + r2 - rho > tol)) return c;
  // Closest points of the axis lines (paper: pt_1 = p_1 + t_1 l_1, pt_2 = p_2 + t_2 l_2).
  const double b = u1.dot(u2), e1 = u1.dot(d), e2 = u2.dot(d);
  const double den = s * s;
  const double s1 = (e1 - b * e2) / den, s2 = (b * e1 - e2) / den;
  if (std::abs(s1) <= h1 && std::abs(s2) <= h2) {
    c.overlap = true;
    c.type = ContactType::kCC1;
    c.depth = r1 + r2 - rho;
    // Axes that touch (rho = 0): n itself is still a valid separating direction.
    c.normal = dn >= 0.0 ? n : Vec3(-n);
    const Vec3 pt1 = c1.center + s1 * u1;
    c.point = pt1 + c.normal * (r1 - 0.5 * c.depth);
    return c;
  }
  const ConvexQuery q = convex_query(c1, c2, tol, false);
  if (q.separated || !(q.depth > tol)) return c;
  c.overlap = true;
  c.depth = q.depth;
  c.normal = q.normal;
  c.point = 0.5 * (q.point_a + q.point_b);
  c.type = classify_end_contact(c1, c2, q);
  return c;
}

namespace {
Mat3 shape_matrix_inverse(const Shape& e) {
  // M = R diag(a^2) R^T: x in E  <=>  (x-p)^T M^{-1} (x-p) <= 1.
  if (e.kind == ShapeKind::Sphere) return Mat3::Identity() * (e.radius * e.radius);
  return e.rotation * e.semi_axes.cwiseProduct(e.semi_axes).asDiagonal() * e.rotation.transpose();
}
}  // namespace

double perram_wertheim(const Shape& e1, const Shape& e2, double* lambda_out, double stop_above) {
  const Mat3 A = shape_matrix_inverse(e1), B = shape_matrix_inverse(e2);
  const Vec3 r = e2.center - e1.center;
  if (r.squaredNorm() == 0.0) {
    if (lambda_out) *lambda_out = 0.5;
    return 0.0;
  }
  // F(l) = l (1-l) r^T G^{-1} r with G = (1-l) A + l B is concave on [0, 1]; its derivative
  // F'(l) = z^T ((1-l)^2 A - l^2 B) z, z = G^{-1} r, decreases from > 0 to < 0. Its root is
  // bracketed and found by regula falsi with the Illinois modification (superlinear), falling
  // back to bisection when an update barely shrinks the bracket. Since F(l) <= max F, the
  // search may stop as soon as some F(l) >= stop_above.
  auto eval = [&](double l, double* F) {
    const Mat3 G = (1.0 - l) * A + l * B;
    const Vec3 z = G.llt().solve(r);
    *F = l * (1.0 - l) * r.dot(z);
    return z.dot(((1.0 - l) * (1.0 - l)) * (A * z) - (l * l) * (B * z));
  };
  double lo = 0.0, hi = 1.0;
  double flo = r.dot(A.llt().solve(r)), fhi = -r.dot(B.llt().solve(r));
  double best_l = 0.5, best_F = -1.0;
  int side = 0;
  for (int it = 0; it < 100 && hi - lo > 1e-13; ++it) {
    double l = (lo * fhi - hi * flo) / (fhi - flo);
    const double w = hi - lo;
    if (!(l > lo + 1e-3 * w && l < hi - 1e-3 * w) || it % 8 == 7) l = 0.5 * (lo + hi);
    double F;
    const double d = eval(l, &F);
    if (F > best_F) {
      best_F = F;
      best_l = l;
    }
    if (best_F >= stop_above) break;
    if (d > 0.0) {
      lo = l;
      flo = d;
      if (side == 1) fhi *= 0.5;
      side = 1;
    } else if (d < 0.0) {
      hi = l;
      fhi = d;
      if (side == -1) flo *= 0.5;
      side = -1;
    } else {
      lo = hi = l;
    }
  }
  if (best_F < stop_above) {
    const double l = 0.5 * (lo + hi);
    double F;
    eval(l, &F);
    if (F > best_F) {
      best_F = F;
      best_l = l;
    }
  }
  if (lambda_out) *lambda_out = best_l;
  return best_F;
}

Contact intersect_perram_wertheim(const Shape& e1, const Shape& e2) {
  Contact c;
  double l = 0.5;
  const double F = perram_wertheim(e1, e2, &l, 1.0);
  if (!(F < 1.0)) return c;
  const Mat3 A = shape_matrix_inverse(e1), B = shape_matrix_inverse(e2);
  const Vec3 r = e2.center - e1.center;
  Vec3 n;
  if (r.squaredNorm() == 0.0) {
    n = Vec3::UnitX();  // coincident centres: fixed direction
  } else {
    n = ((1.0 - l) * A + l * B).llt().solve(r).normalized();  // normal at the PW contact point
  }
  // Translation of e2 along n that separates them: h_1(n) + h_2(-n) - n.r.
  const double depth = std::sqrt(n.dot(A * n)) + std::sqrt(n.dot(B * n)) - n.dot(r);
  if (!(depth > contact_tolerance(e1, e2))) return c;
  c.overlap = true;
  c.type = ContactType::kPW;
  c.depth = depth;
  c.normal = n;
  c.point = 0.5 * (e1.support(n) + e2.support(-n));
  return c;
}

Contact intersect_convex(const Shape& a, const Shape& b) {
  Contact c;
  const double tol = contact_tolerance(a, b);
  const ConvexQuery q = convex_query(a, b, tol, false);
  if (q.separated || !(q.depth > tol)) return c;
  c.overlap = true;
  c.type = ContactType::kCE;
  c.depth = q.depth;
  c.normal = q.normal;
  c.point = 0.5 * (q.point_a + q.point_b);
  return c;
}

Contact intersect(const Shape& a, const Shape& b) {
  const double reach = a.bounding_radius() + b.bounding_radius();
  if ((b.center - a.center).squaredNorm() >= reach * reach) return Contact{};
  auto swapped = [](Contact c) {
    c.normal = -c.normal;
    return c;
  };
  using K = ShapeKind;
  const K ka = a.kind, kb = b.kind;
  if (ka == K::Sphere && kb == K::Sphere) return intersect_sphere_sphere(a, b);
  if (ka == K::Sphere && kb == K::Cylinder) return intersect_sphere_cylinder(a, b);
  if (ka == K::Cylinder && kb == K::Sphere) return swapped(intersect_sphere_cylinder(b, a));
  if (ka == K::Cylinder && kb == K::Cylinder) return intersect_cylinder_cylinder(a, b);
  if (ka == K::Cylinder || kb == K::Cylinder) return intersect_convex(a, b);
  return intersect_perram_wertheim(a, b);  // ellipsoid with ellipsoid or sphere
}

}  // namespace rvegen

namespace rvegen {
bool clear_of(const Shape& a, const Shape& b, double gap) {
  if (gap <= 0.0) return !intersect(a, b).overlap;
  const double reach = a.bounding_radius() + b.bounding_radius() + gap;
  const double d2 = (b.center - a.center).squaredNorm();
  if (d2 >= reach * reach) return true;
  const double tol = contact_tolerance(a, b);
  if (a.kind == ShapeKind::Sphere && b.kind == ShapeKind::Sphere) {
    return std::sqrt(d2) - a.radius - b.radius >= gap - tol;
  }
  const ConvexQuery q = convex_query(a, b, tol, true);
  return q.separated && q.distance >= gap - tol;
}
}  // namespace rvegen
