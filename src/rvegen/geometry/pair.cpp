#include "rvegen/geometry/pair.hpp"

#include <algorithm>
#include <cmath>

#include "rvegen/geometry/convex.hpp"
#include "rvegen/geometry/tolerances.hpp"

namespace rvegen {

namespace {
// A contact point this near a cylinder's end plane (relative to the half length) is on the cap:
// it names the contact type only (the paper's d1, d2 against cd1), not the overlap decision.
constexpr double kOnCapRel = 1e-6;
}  // namespace

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
    case ContactType::kPiece:
      return "piece";
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
  const Vec3 e = L > kRoundoff * (h + r) ? Vec3(w / L) : any_orthogonal(u);
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
  if (std::abs(nl) <= kParallelSine * h) return ContactType::kNone;
  const double t = dk.n.dot(dk.p - cyl.center) / nl;
  const Vec3 a = cyl.center + t * cyl.half_axis;  // axis meets the disk plane
  const Vec3 ad = a - dk.p;
  const double dist_a = ad.norm();
  if (dist_a <= kRoundoff * dk.r)
    return std::abs(t) <= 1.0 ? ContactType::kCD3 : ContactType::kNone;
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
  if (n.norm() <= kParallelSine) return ContactType::kNone;  // parallel planes: no common line
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
    return std::abs((x - c.center).dot(c.half_axis) / h) >= h * (1.0 - kOnCapRel);
  };
  const bool cap1 = on_cap(c1, q.point_a), cap2 = on_cap(c2, q.point_b);
  if (cap1 && cap2) return c1.radius >= c2.radius ? ContactType::kD1 : ContactType::kD2;
  return ContactType::kCD1;
}

// Half width of a cylinder's projection on the unit direction m: |l.m| + r sqrt(1 - (u.m)^2).
double projected_half_width(const Shape& cyl, double h, const Vec3& m) {
  const double lm = cyl.half_axis.dot(m), um = lm / h;
  return std::abs(lm) + cyl.radius * std::sqrt(std::max(0.0, 1.0 - um * um));
}

// A cheap certificate of disjointness before GJK: the projections of the two cylinders on a
// direction do not meet. Tried on the direction joining the closest points of the axis
// segments (disjoint capsules are caught there too), each axis and the line of centres.
// Finding none proves nothing; GJK/EPA then decides.
bool separating_axis_found(const Shape& c1, double h1, const Shape& c2, double h2) {
  const Vec3 d = c2.center - c1.center;
  double s, t;
  const Vec3 p1 = c1.center - c1.half_axis, p2 = c2.center - c2.half_axis;
  segment_closest(p1, c1.center + c1.half_axis, p2, c2.center + c2.half_axis, &s, &t);
  const Vec3 gap = (p2 + 2.0 * t * c2.half_axis) - (p1 + 2.0 * s * c1.half_axis);
  const Vec3 axes[4] = {gap, c1.half_axis, c2.half_axis, d};
  for (const Vec3& a : axes) {
    const double len = a.norm();
    if (!(len > 0.0)) continue;
    const Vec3 m = a / len;
    if (std::abs(d.dot(m)) > projected_half_width(c1, h1, m) + projected_half_width(c2, h2, m)) {
      return true;
    }
  }
  return false;
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
Contact intersect_cylinder_cylinder(const Shape& c1, const Shape& c2, double depth_rel) {
  Contact c;
  const double tol = contact_tolerance(c1, c2);
  const Vec3 d = c2.center - c1.center;
  const double h1 = c1.half_axis.norm(), h2 = c2.half_axis.norm();
  const Vec3 u1 = c1.half_axis / h1, u2 = c2.half_axis / h2;
  const double r1 = c1.radius, r2 = c2.radius;
  const Vec3 cr = u1.cross(u2);
  const double s = cr.norm();
  if (s <= kParallelSine) {
    // Parallel axes: D = c1 - c2 is a cylinder of radius r1+r2 and half-length h1+h2.
    const double X = d.dot(u1);
    const Vec3 w = d - X * u1;
    const double delta = w.norm();
    const double rad = r1 + r2 - delta;
    const double ax = h1 + h2 - std::abs(X);
    if (!(std::min(rad, ax) > tol)) return c;
    c.overlap = true;
    const Vec3 e = delta > kRoundoff * (r1 + r2) ? Vec3(w / delta) : any_orthogonal(u1);
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
  if (separating_axis_found(c1, h1, c2, h2)) return c;
  const ConvexQuery q = convex_query(c1, c2, tol, false, depth_rel);
  if (q.separated || !(q.depth > tol)) return c;
  c.overlap = true;
  c.depth = q.depth;
  c.normal = q.normal;
  c.point = 0.5 * (q.point_a + q.point_b);
  c.type = classify_end_contact(c1, c2, q);
  return c;
}

namespace {

// Perram-Wertheim contact function in closed form. With A, B the shape matrices of e1 and e2
// (x in E <=> (x - p)^T M^{-1} (x - p) <= 1) and r = p2 - p1,
//   F(l) = l (1 - l) r^T G(l)^{-1} r,   G(l) = (1 - l) A + l B,   l in [0, 1].
// In the frame where e1 is the unit ball, G = A^{1/2} ((1 - l) I + l B') A^{1/2} with
// B' = A^{-1/2} B A^{-1/2} = Q diag(beta) Q^T, so with c = Q^T A^{-1/2} r and
// D_i = 1 - l + l beta_i
//   F = l (1 - l) sum c_i^2 / D_i,  F' = sum c_i^2 ((1 - l)^2 - l^2 beta_i) / D_i^2,
//   F'' = -2 sum c_i^2 beta_i / D_i^3 < 0,
// three terms each: F is concave and its maximum is found by safeguarded Newton steps.
// A^{-1/2} = R diag(1 / a) R^T comes from e1's axes directly; B' needs a 3x3 symmetric
// eigensolver unless one of the two is a sphere (then the roles are swapped so that the sphere
// is e1 and B' = B / r^2 is diagonal in e2's axes). Swapping maps l to 1 - l and r to -r.
struct PwFrame {
  Vec3 c2;    // c_i^2
  Vec3 beta;  // eigenvalues of B'
  Mat3 back;  // A^{-1/2} Q: G^{-1} r = back * (c / D)
  Vec3 c;     // c
  bool swapped = false;

  PwFrame(const Shape& e1, const Shape& e2) {
    const Shape* a = &e1;
    const Shape* b = &e2;
    if (e2.kind == ShapeKind::Sphere && e1.kind != ShapeKind::Sphere) {
      std::swap(a, b);
      swapped = true;
    }
    const Vec3 r = swapped ? Vec3(e1.center - e2.center) : Vec3(e2.center - e1.center);
    if (a->kind == ShapeKind::Sphere) {
      const double inv = 1.0 / a->radius;
      if (b->kind == ShapeKind::Sphere) {
        beta = Vec3::Constant(b->radius * b->radius * inv * inv);
        back = Mat3::Identity() * inv;
        c = r * inv;
      } else {
        beta = b->semi_axes.cwiseProduct(b->semi_axes) * (inv * inv);
        back = b->rotation * inv;
        c = b->rotation.transpose() * r * inv;
      }
    } else {
      const Mat3 a_inv_half =
          a->rotation * a->semi_axes.cwiseInverse().asDiagonal() * a->rotation.transpose();
      Mat3 bm;
      if (b->kind == ShapeKind::Sphere) {
        bm = Mat3::Identity() * (b->radius * b->radius);
      } else {
        bm = b->rotation * b->semi_axes.cwiseProduct(b->semi_axes).asDiagonal() *
             b->rotation.transpose();
      }
      const Mat3 bp = a_inv_half * bm * a_inv_half;
      const Eigen::SelfAdjointEigenSolver<Mat3> es(0.5 * (bp + bp.transpose()));
      beta = es.eigenvalues();
      back = a_inv_half * es.eigenvectors();
      c = es.eigenvectors().transpose() * (a_inv_half * r);
    }
    c2 = c.cwiseProduct(c);
  }
  // F, F' and F'' at l in the frame's own order (e1 of the frame first).
  void derivatives(double l, double* F, double* d1, double* d2) const {
    double s0 = 0.0, s1 = 0.0, s2 = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double D = 1.0 - l + l * beta[i], inv = 1.0 / D;
      s0 += c2[i] * inv;
      s1 += c2[i] * ((1.0 - l) * (1.0 - l) - l * l * beta[i]) * inv * inv;
      s2 += c2[i] * beta[i] * inv * inv * inv;
    }
    *F = l * (1.0 - l) * s0;
    *d1 = s1;
    *d2 = -2.0 * s2;
  }
  // Contact normal (from e1 towards e2 of the caller) at the caller's lambda.
  Vec3 normal(double lambda) const {
    const double l = swapped ? 1.0 - lambda : lambda;
    const Vec3 D = Vec3::Constant(1.0 - l) + l * beta;
    const Vec3 n = back * c.cwiseQuotient(D);
    return swapped ? Vec3(-n) : n;
  }
};

Mat3 shape_matrix(const Shape& e) {
  // M = R diag(a^2) R^T: x in E  <=>  (x-p)^T M^{-1} (x-p) <= 1.
  if (e.kind == ShapeKind::Sphere) return Mat3::Identity() * (e.radius * e.radius);
  return e.rotation * e.semi_axes.cwiseProduct(e.semi_axes).asDiagonal() * e.rotation.transpose();
}

// max F over [0, 1] by Newton steps kept inside the bracket of F' (bisection when a step
// leaves it). Stops when F(l) >= stop_above (F(l) is a lower bound of the maximum), or when
// the step no longer moves l.
double pw_maximum(const PwFrame& f, double* l_out, double stop_above) {
  // For concentric-sphere-like pairs the maximiser is 1 / (1 + sqrt(beta)): start there with
  // the c^2-weighted beta.
  const double cs = f.c2.sum();
  const double bmean = cs > 0.0 ? f.c2.dot(f.beta) / cs : f.beta.mean();
  double l = 1.0 / (1.0 + std::sqrt(bmean));
  double lo = 0.0, hi = 1.0, best_F = -1.0, best_l = l;
  for (int it = 0; it < 60; ++it) {
    double F, d1, d2;
    f.derivatives(l, &F, &d1, &d2);
    if (F > best_F) {
      best_F = F;
      best_l = l;
    }
    if (best_F >= stop_above) break;
    if (d1 > 0.0) {
      lo = l;
    } else if (d1 < 0.0) {
      hi = l;
    } else {
      break;
    }
    double next = d2 < 0.0 ? l - d1 / d2 : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - l) <= kRootStop * std::max(l, kNoDirection) || hi - lo <= kRootStop) break;
    l = next;
  }
  *l_out = f.swapped ? 1.0 - best_l : best_l;
  return best_F;
}

}  // namespace

double perram_wertheim(const Shape& e1, const Shape& e2, double* lambda_out, double stop_above) {
  if ((e2.center - e1.center).squaredNorm() == 0.0) {
    if (lambda_out) *lambda_out = 0.5;
    return 0.0;
  }
  const PwFrame f(e1, e2);
  double l = 0.5;
  const double F = pw_maximum(f, &l, stop_above);
  if (lambda_out) *lambda_out = l;
  return F;
}

Contact intersect_perram_wertheim(const Shape& e1, const Shape& e2) {
  Contact c;
  const Vec3 r = e2.center - e1.center;
  Vec3 n;
  if (r.squaredNorm() == 0.0) {
    n = Vec3::UnitX();  // coincident centres: fixed direction
  } else {
    const PwFrame f(e1, e2);
    double l = 0.5;
    if (!(pw_maximum(f, &l, 1.0) < 1.0)) return c;
    n = f.normal(l).normalized();  // normal at the PW contact point
  }
  const Mat3 A = shape_matrix(e1), B = shape_matrix(e2);
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

Contact contact_of(const ConvexQuery& q, double tol, ContactType type) {
  Contact c;
  if (q.separated || !(q.depth > tol)) return c;
  c.overlap = true;
  c.type = type;
  c.depth = q.depth;
  c.normal = q.normal;
  c.point = 0.5 * (q.point_a + q.point_b);
  return c;
}

Contact intersect_convex(const Shape& a, const Shape& b, double depth_rel) {
  const double tol = contact_tolerance(a, b);
  return contact_of(convex_query(a, b, tol, false, depth_rel), tol, ContactType::kCE);
}

Contact intersect(const Shape& a, const Shape& b, double depth_rel) {
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
  if (ka == K::Cylinder && kb == K::Cylinder) return intersect_cylinder_cylinder(a, b, depth_rel);
  if (ka == K::Cylinder || kb == K::Cylinder) return intersect_convex(a, b, depth_rel);
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
  const ConvexQuery q = convex_query(a, b, tol, true, kDepthRelTolerance);
  return q.separated && q.distance >= gap - tol;
}
}  // namespace rvegen
