#include "rvegen/model/body.hpp"

#include <algorithm>
#include <cmath>

#include "rvegen/geometry/quadrature.hpp"
#include "rvegen/geometry/tolerances.hpp"

namespace rvegen {
namespace {

// Frame of a cylinder: unit axis u, half length h.
struct FibreFrame {
  Vec3 u;
  double h;
};

FibreFrame fibre_frame(const Inclusion& inc) {
  FibreFrame f;
  f.h = inc.shape.half_axis.norm();
  f.u = inc.shape.half_axis / f.h;
  return f;
}

// Grows a straight shape: sphere and ellipsoid by the factor `f` (f >= 1), cylinders by dr in
// radius and dl in half length.
Shape grown_cylinder(const Shape& s, double dr, double dl) {
  const double h = s.half_axis.norm();
  return Shape::cylinder(s.center, s.radius + dr, s.half_axis * ((h + dl) / h));
}

// Envelope with a shell of thickness t (convex; holds every point within t of the body).
Shape grown(const Inclusion& inc, double t) {
  const Shape& s = inc.shape;
  const Modifiers& m = inc.mod;
  switch (s.kind) {
    case ShapeKind::Sphere: {
      double r = s.radius;
      if (m.deformed()) r *= m.deform_scale * (1.0 + m.deform_amplitude * m.deform_peak);
      if (m.debonded()) r += m.debond_gap;
      return Shape::sphere(s.center, r + t);
    }
    case ShapeKind::Cylinder:
      // A continuous fibre has no ends to grow past: its images continue it.
      return grown_cylinder(s, lateral_reach(inc) + t, m.through ? 0.0 : t);
    case ShapeKind::Ellipsoid: {
      Shape e = s;
      if (m.deformed()) e = e.scaled(m.deform_scale * (1.0 + m.deform_amplitude * m.deform_peak));
      return padded(e, t);
    }
  }
  return s;
}

// Distance from x, at distance d from a convex core known to lie in [lo, hi], to the level
// d = level: a lower bound.
double gap_to_level(double lo, double hi, double level) {
  if (level < lo) return lo - level;
  if (level > hi) return level - hi;
  return 0.0;
}

}  // namespace

int through_axis(const Inclusion& inc) {
  if (!inc.mod.through || inc.shape.kind != ShapeKind::Cylinder) return -1;
  int k = 0;
  inc.shape.half_axis.cwiseAbs().maxCoeff(&k);
  return k;
}

double deformation_field(const Modifiers& m, const Vec3& n) {
  double g = 0.0;
  for (const auto& wv : m.deform_waves) {
    g += wv.weight * std::cos(wv.wavenumber * n.dot(wv.direction) + wv.phase);
  }
  return g;
}

double deformed_radius(const Modifiers& m, const Vec3& n) {
  return m.deform_scale * (1.0 + m.deform_amplitude * deformation_field(m, n));
}

double deformation_volume_scale(const Modifiers& m) {
  double k = 0.0;
  for (const auto& wv : m.deform_waves) k = std::max(k, wv.wavenumber);
  const int n = 24 + 2 * static_cast<int>(std::ceil(k));
  const double e = m.deform_amplitude;
  // Volume of |y| <= 1 + e g(n): (1/3) int (1 + e g)^3 dn; the unit ball has 4 pi / 3.
  const double v = sphere_integral(
      n, [&](const Vec3& u) { return std::pow(1.0 + e * deformation_field(m, u), 3); });
  return std::cbrt(4.0 * M_PI / v);
}

double bend_reach(double bend_radius, double h, double s_max) {
  // The bend's offset grows with |s| from -m at s = 0 to at least +m at |s| = h.
  return arc_sagitta(bend_radius, s_max) - 0.5 * arc_sagitta(bend_radius, h);
}

CentreLine::CentreLine(const Inclusion& inc) {
  const Modifiers& m = inc.mod;
  if (inc.shape.kind != ShapeKind::Cylinder || !m.curved()) return;
  const FibreFrame f = fibre_frame(inc);
  const Vec3 e1 = any_orthogonal(f.u), e2 = f.u.cross(e1);
  if (m.wavy()) {
    A = m.wave_amplitude;
    k = 2.0 * M_PI / m.wave_length;
    phase = m.wave_phase;
    v = std::cos(m.wave_angle) * e1 + std::sin(m.wave_angle) * e2;
  }
  if (m.bent()) {
    Rc = m.bend_radius;
    h = f.h;
    s_max = f.h + m.coating;
    mid = 0.5 * arc_sagitta(Rc, f.h);
    w = std::cos(m.bend_angle) * e1 + std::sin(m.bend_angle) * e2;
  }
}

double CentreLine::reach() const {
  return A + (Rc > 0.0 ? bend_reach(Rc, h, s_max) : 0.0);
}

double CentreLine::slope() const {
  if (Rc <= 0.0) return A * k;
  const double q = s_max / Rc;
  return A * k + q / std::sqrt((1.0 - q) * (1.0 + q));
}

double CentreLine::curvature() const {
  return centre_line_curvature(A, k, Rc, s_max);
}

Shape padded(const Shape& s, double t) {
  switch (s.kind) {
    case ShapeKind::Sphere:
      return Shape::sphere(s.center, s.radius + t);
    case ShapeKind::Cylinder:
      return grown_cylinder(s, t, t);
    case ShapeKind::Ellipsoid:
      // E + ball(t) lies inside E scaled by 1 + t / a_min: h_E(d) + t |d| <= (1 + t / a_min)
      // h_E(d) because h_E(d) >= a_min |d|.
      return t > 0.0 ? s.scaled(1.0 + t / s.semi_axes.minCoeff()) : s;
  }
  return s;
}

Shape envelope(const Inclusion& inc) {
  const Modifiers& m = inc.mod;
  if (!m.any() && m.packing_pad == 0.0) return inc.shape;
  // Touching shells: the core alone, padded; other shells whole, padded.
  return grown(inc, (m.shells_may_touch ? 0.0 : m.coating) + m.packing_pad);
}

namespace {
// What a chain is cut from: the sheared straight cylinder of radius R, half length H (the core
// with its shell unless shells may touch), n pieces of axial length ds and sagitta sag; the
// offsets' bounds: reach, slope.
struct ChainPlan {
  double R, H, pad, reach, slope, ds, sag;
  int n;
};
ChainPlan chain_plan(const Inclusion& inc, const CentreLine& line) {
  const Modifiers& m = inc.mod;
  ChainPlan c;
  // The shell is the sheared image of the straight fibre's offset, which the straight cylinder of
  // radius r + t and half length h + t holds: the chain follows that cylinder, sheared.
  const double shell = m.shells_may_touch ? 0.0 : m.coating;
  c.pad = m.packing_pad;
  c.R = inc.shape.radius + shell;
  c.H = inc.shape.half_axis.norm() + shell;
  c.reach = line.reach();
  c.slope = line.slope();
  const double K = line.curvature();
  c.n = static_cast<int>(std::min(chain_piece_count(c.H, c.R, K), kMaxChainPieces));
  c.ds = 2.0 * c.H / c.n;
  c.sag = std::min(2.0 * c.reach, K * c.ds * c.ds / 8.0);
  return c;
}
}  // namespace

Shape chain_bound(const Inclusion& inc) {
  const CentreLine line(inc);
  const ChainPlan c = chain_plan(inc, line);
  const FibreFrame f = fibre_frame(inc);
  // A piece's points lie within R + sag + pad of its chord extended by e = (R + sag) sin(alpha)
  // + pad at each end; chord points are within `reach` of the axis and the extension moves
  // e sin(alpha) sideways and e along the axis (sin(alpha) <= slope / sqrt(1 + slope^2)).
  const double sin_a = c.slope / std::sqrt(1.0 + c.slope * c.slope);
  const double e = (c.R + c.sag) * sin_a + c.pad, reach = c.R + c.sag + c.pad;
  const double radius = (c.reach + e * sin_a + reach) * (1.0 + kBoundMargin);
  const double half = (c.H + e + reach) * (1.0 + kBoundMargin);
  return Shape::cylinder(inc.shape.center, radius, f.u * half);
}

namespace {
// The largest |sin x| over [x0, x1]: 1 where a crest (pi / 2 + j pi) lies in it, otherwise the
// larger of its ends.
double max_abs_sin(double x0, double x1) {
  const double crest = M_PI / 2.0 + M_PI * std::ceil((x0 - M_PI / 2.0) / M_PI);
  return crest <= x1 ? 1.0 : std::max(std::abs(std::sin(x0)), std::abs(std::sin(x1)));
}
}  // namespace

void chain_pieces(const Inclusion& inc, std::vector<ShearedPiece>* out) {
  const FibreFrame f = fibre_frame(inc);
  const CentreLine line(inc);
  const ChainPlan c = chain_plan(inc, line);
  const double H = c.H, ds = c.ds;
  const int n = c.n;
  auto point = [&](double s) -> Vec3 { return inc.shape.center + s * f.u + line.offset(s); };
  for (int i = 0; i < n; ++i) {
    const double s0 = -H + i * ds, s1 = (i + 1 == n) ? H : s0 + ds;
    const Vec3 p0 = point(s0), p1 = point(s1);
    // The slice's sections are disks of radius R normal to the axis, about centre-line points
    // that leave the chord (like the offsets, normal to the axis) along the wave's direction v
    // and the bend's w, each part by at most its own sagitta (the bound on its second
    // derivative over the slice, times ds^2 / 8) and on the side its curvature gives: a part
    // whose second derivative keeps one sign lies on one side of its chord (the arc below it;
    // the wave above it where sin > 0). So the disk of radius R swept along the chord and over
    // those two ranges (the piece's bows) holds the slice. Grown by a relative 1e-12 against
    // rounding (the exact tests decide to 1e-9 of the size). The bows keep the pieces closer to
    // the fibre than the fibre's largest sagitta added to every piece's radius would.
    ShearedPiece p;
    const double len2 = (s1 - s0) * (s1 - s0) / 8.0;
    if (line.A > 0.0) {
      const double x0 = line.k * s0 + line.phase, x1 = line.k * s1 + line.phase;
      // (Each part's sagitta is at most twice its reach, so the two add up to at most c.sag,
      // which chain_bound allows for.)
      const double sag =
          std::min(2.0 * line.A, line.A * line.k * line.k * max_abs_sin(x0, x1) * len2);
      // sin keeps one sign over [x0, x1] unless a multiple of pi lies inside it; the wave's
      // second derivative is -A k^2 sin, so where sin >= 0 the wave lies above its chord.
      const double j = std::floor(x0 / M_PI);
      const bool one_sign = (j + 1.0) * M_PI >= x1;
      const bool above = std::fmod(std::abs(j), 2.0) == 0.0;
      p.bow[0] = line.v;
      p.bow_lo[0] = (one_sign && above ? 0.0 : -sag) * (1.0 + kBoundMargin);
      p.bow_hi[0] = (one_sign && !above ? 0.0 : sag) * (1.0 + kBoundMargin);
    }
    if (line.Rc > 0.0) {
      const double at = std::min(line.s_max, std::max(std::abs(s0), std::abs(s1)));
      const double sag = std::min(2.0 * (line.reach() - line.A),
                                  centre_line_curvature(0.0, 0.0, line.Rc, at) * len2);
      p.bow[1] = line.w;
      p.bow_lo[1] = -sag * (1.0 + kBoundMargin);  // the arc lies below its chord
    }
    p.center = 0.5 * (p0 + p1);
    p.normal = f.u;
    p.half_axis = 0.5 * (p1 - p0) * (1.0 + kBoundMargin);
    p.radius = c.R * (1.0 + kBoundMargin);
    p.round = c.pad * (1.0 + kBoundMargin);
    out->push_back(p);
  }
}

Shape outer_bound(const Inclusion& inc) {
  return inc.mod.any() ? grown(inc, inc.mod.coating) : inc.shape;
}

Inclusion place_like(const Inclusion& drawn, const Shape& packed, double scale) {
  Inclusion out = drawn;
  Shape core = drawn.shape;
  core.center = packed.center;
  if (core.kind == ShapeKind::Cylinder) {
    core.half_axis = packed.half_axis.normalized() * drawn.shape.half_axis.norm();
  } else if (core.kind == ShapeKind::Ellipsoid) {
    core.rotation = packed.rotation;
  }
  out.shape = core.scaled(scale);
  Modifiers& m = out.mod;
  m.coating *= scale;
  m.wave_amplitude *= scale;
  m.wave_length *= scale;
  m.bend_radius *= scale;
  m.debond_gap *= scale;
  m.packing_pad *= scale;
  return out;
}

BodyQuery::BodyQuery(const Inclusion& inc) : m_(inc.mod), s_(inc.shape), line_(inc) {
  c_ = s_.center;
  switch (s_.kind) {
    case ShapeKind::Sphere:
      to_unit_ = Mat3::Identity() / s_.radius;
      amin_ = amax_ = s_.radius;
      break;
    case ShapeKind::Ellipsoid:
      to_unit_ = s_.semi_axes.cwiseInverse().asDiagonal() * s_.rotation.transpose();
      amin_ = s_.semi_axes.minCoeff();
      amax_ = s_.semi_axes.maxCoeff();
      break;
    case ShapeKind::Cylinder: {
      const FibreFrame f = fibre_frame(inc);
      u_ = f.u;
      h_ = f.h;
      // The shear x -> x - offset(s) and its inverse stretch distances by at most 1 + slope.
      lipschitz_ = 1.0 + line_.slope();
      break;
    }
  }
  for (const auto& wv : m_.deform_waves) kmax_ = std::max(kmax_, wv.wavenumber);
  if (m_.debonded()) {
    cos_cap_ = m_.debond_cos_cap();
    theta_cap_ = std::acos(cos_cap_);
  }
}

double BodyQuery::cylinder_sdf(const Vec3& x) const {
  const Vec3 d = x - c_;
  const double s = d.dot(u_);
  Vec3 t = d - s * u_;
  if (m_.curved()) t -= line_.offset(s);
  // A continuous fibre has no ends (its images continue it): the lateral distance alone.
  const double d_ax = m_.through ? -HUGE_VAL : std::abs(s) - h_, d_rad = t.norm() - s_.radius;
  if (d_ax > 0.0 || d_rad > 0.0) {
    return std::hypot(std::max(d_ax, 0.0), std::max(d_rad, 0.0));
  }
  return std::max(d_ax, d_rad);
}

double BodyQuery::cone_distance(const Vec3& d, double rho) const {
  if (rho == 0.0) return 0.0;
  const double theta = std::acos(std::clamp(d.dot(m_.debond_axis) / rho, -1.0, 1.0));
  const double a = std::abs(theta - theta_cap_);
  return a < 0.5 * M_PI ? rho * std::sin(a) : rho;
}

Region BodyQuery::region(const Vec3& x) const {
  switch (s_.kind) {
    case ShapeKind::Sphere:
    case ShapeKind::Ellipsoid: {
      const Vec3 y = to_unit_ * (x - c_);
      const double q2 = y.squaredNorm();
      if (m_.deformed()) {
        if (q2 == 0.0) return Region::kCore;
        const double rho = std::sqrt(q2);
        return rho <= deformed_radius(m_, y / rho) ? Region::kCore : Region::kOutside;
      }
      if (q2 <= 1.0) return Region::kCore;
      if (!m_.coated() && !m_.debonded()) return Region::kOutside;
      if (s_.kind == ShapeKind::Sphere) {
        const Vec3 d = x - c_;
        const double rho = d.norm(), dist = rho - s_.radius;
        if (m_.debonded() && dist <= m_.debond_gap && d.dot(m_.debond_axis) >= cos_cap_ * rho) {
          return Region::kVoid;
        }
        return m_.coated() && dist <= m_.coating ? Region::kShell : Region::kOutside;
      }
      // Coated ellipsoid: cheap bounds on the distance first, the exact distance in between.
      const double q = std::sqrt(q2);
      if ((q - 1.0) * amin_ > m_.coating) return Region::kOutside;
      if ((q - 1.0) * amax_ <= m_.coating) return Region::kShell;
      return ellipsoid_distance(s_, x) <= m_.coating ? Region::kShell : Region::kOutside;
    }
    case ShapeKind::Cylinder: {
      const double d = cylinder_sdf(x);
      if (d <= 0.0) return Region::kCore;
      return m_.coated() && d <= m_.coating ? Region::kShell : Region::kOutside;
    }
  }
  return Region::kOutside;
}

double BodyQuery::clearance(const Vec3& x) const {
  switch (s_.kind) {
    case ShapeKind::Sphere:
    case ShapeKind::Ellipsoid: {
      const Vec3 y = to_unit_ * (x - c_);
      const double q = y.norm();
      if (m_.deformed()) {
        // Boundary at |y| = R(n) = lambda (1 + e g(n)), R in [lambda (1 - e), lambda (1 + e)],
        // |grad_S g| <= k (the largest wavenumber). Where |y| >= rb / 2 (rb = lambda (1 - e)),
        // phi = |y| - R(n) has |grad phi| <= L = sqrt(1 + (2 e k / (1 - e))^2) in y; inside
        // |y| < rb / 2 the ball of radius rb is in the core. Distances in y map to at least
        // a_min times them in space.
        const double e = m_.deform_amplitude, lam = m_.deform_scale, rb = lam * (1.0 - e);
        if (q < 0.5 * rb) return (rb - q) * amin_;
        const double phi = q - deformed_radius(m_, y / q);
        const double L = std::sqrt(1.0 + std::pow(2.0 * e * kmax_ / (1.0 - e), 2));
        return std::min(std::abs(phi) / L, 0.5 * rb) * amin_;
      }
      if (s_.kind == ShapeKind::Sphere) {
        const Vec3 d = x - c_;
        const double rho = d.norm(), dist = rho - s_.radius;
        double c = std::abs(dist);
        if (m_.coated()) c = std::min(c, std::abs(dist - m_.coating));
        if (m_.debonded()) {
          c = std::min({c, std::abs(dist - m_.debond_gap), cone_distance(d, rho)});
        }
        return c;
      }
      // Ellipsoid: the surface of qE lies at distance [|q - 1| a_min, |q - 1| a_max] from E's.
      const double lo = std::abs(q - 1.0) * amin_, hi = std::abs(q - 1.0) * amax_;
      double c = lo;
      if (m_.coated() && q > 1.0) c = std::min(c, gap_to_level(lo, hi, m_.coating));
      return c;
    }
    case ShapeKind::Cylinder: {
      // Exact for straight fibres; the shear of a curved one stretches distances by at most L.
      const double d = cylinder_sdf(x);
      double c = std::abs(d);
      if (m_.coated()) c = std::min(c, std::abs(d - m_.coating));
      return c / lipschitz_;
    }
  }
  return 0.0;
}

namespace {
// Solutions of a t^2 + b t + c <= 0 (a >= 0, and b = 0 whenever a = 0: the line is then
// parallel to the axis of a cylinder and the set is everything when c <= 0, else nothing).
bool quadratic_interval(double a, double b, double c, double* t0, double* t1) {
  if (a <= 0.0) {
    if (c > 0.0) return false;
    *t0 = -HUGE_VAL;
    *t1 = HUGE_VAL;
    return true;
  }
  const double disc = b * b - 4.0 * a * c;
  if (disc < 0.0) return false;
  const double sq = std::sqrt(disc);
  *t0 = (-b - sq) / (2.0 * a);
  *t1 = (-b + sq) / (2.0 * a);
  return true;
}
}  // namespace

bool BodyQuery::x_interval(const Vec3& p, double* t0, double* t1) const {
  const Vec3 d = p - c_;
  switch (s_.kind) {
    case ShapeKind::Sphere:
    case ShapeKind::Ellipsoid: {
      // |w + t a|^2 <= 1 with w = A d, a = A e_x.
      const Vec3 w = to_unit_ * d, a = to_unit_.col(0);
      return quadratic_interval(a.squaredNorm(), 2.0 * a.dot(w), w.squaredNorm() - 1.0, t0, t1);
    }
    case ShapeKind::Cylinder: {
      // Lateral: |P (d + t e_x)|^2 <= r^2, P = I - u u^T; ends: |u . (d + t e_x)| <= h.
      const Vec3 pd = d - d.dot(u_) * u_, pe = Vec3::UnitX() - u_.x() * u_;
      double a, b;
      if (!quadratic_interval(pe.squaredNorm(), 2.0 * pd.dot(pe),
                              pd.squaredNorm() - s_.radius * s_.radius, &a, &b)) {
        return false;
      }
      const double s0 = d.dot(u_), ux = u_.x();
      if (std::abs(ux) < kRoundoff) {
        if (std::abs(s0) > h_) return false;
      } else {
        double e0 = (-h_ - s0) / ux, e1 = (h_ - s0) / ux;
        if (e0 > e1) std::swap(e0, e1);
        a = std::max(a, e0);
        b = std::min(b, e1);
      }
      if (a > b) return false;
      *t0 = a;
      *t1 = b;
      return true;
    }
  }
  return false;
}

double BodyQuery::core_distance(const Vec3& x) const {
  switch (s_.kind) {
    case ShapeKind::Sphere:
    case ShapeKind::Ellipsoid: {
      const Vec3 y = to_unit_ * (x - c_);
      const double q = y.norm();
      if (m_.deformed()) {
        if (q == 0.0) return -m_.deform_scale * (1.0 - m_.deform_amplitude) * amin_;
        return (q - deformed_radius(m_, y / q)) * amin_;
      }
      if (s_.kind == ShapeKind::Sphere) return (x - c_).norm() - s_.radius;
      return q > 1.0 ? ellipsoid_distance(s_, x) : (q - 1.0) * amin_;
    }
    case ShapeKind::Cylinder:
      return cylinder_sdf(x);
  }
  return 0.0;
}

RegionVolumes region_volumes(const Inclusion& inc) {
  const Shape& s = inc.shape;
  const Modifiers& m = inc.mod;
  RegionVolumes v;
  v.core = s.volume();
  const double t = m.coating;
  if (m.coated()) {
    // Steiner: V(K + tB) - V(K) = S t + M t^2 + 4 pi t^3 / 3, M = integral of the support
    // function over the unit sphere.
    double S = 0.0, M = 0.0;
    switch (s.kind) {
      case ShapeKind::Sphere:
        S = 4.0 * M_PI * s.radius * s.radius;
        M = 4.0 * M_PI * s.radius;
        break;
      case ShapeKind::Cylinder: {
        const double L = 2.0 * s.half_axis.norm(), r = s.radius;
        if (m.through) {
          // A tube without caps: its images continue it across the box.
          v.shell = M_PI * ((r + t) * (r + t) - r * r) * L;
          break;
        }
        S = 2.0 * M_PI * r * r + 2.0 * M_PI * r * L;
        M = M_PI * L + M_PI * M_PI * r;
        break;
      }
      case ShapeKind::Ellipsoid: {
        // x = A n on the unit sphere, A = diag(a): dS = det(A) |A^-1 n| dn, h(u) = |A u|.
        const Vec3 a = s.semi_axes;
        S = a.prod() *
            sphere_integral(96, [&](const Vec3& n) { return n.cwiseQuotient(a).norm(); });
        M = sphere_integral(96, [&](const Vec3& n) { return n.cwiseProduct(a).norm(); });
        break;
      }
    }
    if (!m.through) v.shell = S * t + M * t * t + 4.0 / 3.0 * M_PI * t * t * t;
  }
  if (m.debonded()) {
    const double r = s.radius, g = m.debond_gap;
    v.void_ = m.debond_fraction * 4.0 / 3.0 * M_PI * (std::pow(r + g, 3) - r * r * r);
  }
  return v;
}

}  // namespace rvegen
