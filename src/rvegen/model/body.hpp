// Geometry of one inclusion with its modifiers (coating, waviness, deformation, debonding):
// which region a point lies in, how far it is from the nearest region boundary, the exact
// volume of each region, and the convex envelope the packers keep apart.
//
// Regions: the core (the inclusion's material), the interphase shell (points within `coating`
// of the core), the debonding void. Plain inclusions have a core only and every function below
// is exact for them. Modified geometry stays inside the inclusion's envelope, so envelopes that
// do not overlap guarantee bodies that do not overlap.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "rvegen/geometry/convex.hpp"
#include "rvegen/model/inclusion_set.hpp"

namespace rvegen {

enum class Region : uint8_t { kOutside = 0, kCore = 1, kShell = 2, kVoid = 3 };

/// The convex shape the packers keep apart: it holds the core, the void and the shell, grown by
/// Modifiers::packing_pad. With shells_may_touch it holds the core only (grown by the pad, half
/// the largest touching coating of the scene): such a shell reaches at most one pad beyond the
/// envelope, and every other body lies one pad inside its own, so only touching shells meet.
Shape envelope(const Inclusion& inc);
/// A convex shape holding every region of the inclusion (the envelope with the whole shell).
Shape outer_bound(const Inclusion& inc);
/// A convex shape holding every point within t >= 0 of the straight shape s: a sphere or a
/// cylinder grown by t in radius (and half length), an ellipsoid scaled by 1 + t over its least
/// semi-axis.
Shape padded(const Shape& s, double t);

/// The box axis (0, 1, 2) a continuous fibre (Modifiers::through) runs along; -1 for every
/// other inclusion.
int through_axis(const Inclusion& inc);
/// True when b shifted by `shift` continues the continuous fibre a along its axis (a itself,
/// or another continuous fibre along the same axis met again across the box): not a pair to
/// test, since the image without that shift spans the same length beside a.
inline bool continues_along(const Inclusion& a, const Inclusion& b, const Vec3& shift) {
  const int k = through_axis(a);
  return k >= 0 && k == through_axis(b) && shift[k] != 0.0;
}

/// Wavy and bent fibres are sheared straight cylinders: the cross-section at axial coordinate s
/// (|s| <= h, the half length) is displaced sideways by centre_offset(s), the sum of
///  - the wave A sin(k s + phase) v, and
///  - the bend (Rc - sqrt(Rc^2 - s^2) - m) w: the centre line is a circular arc of radius Rc
///    (its radius of curvature), m = (Rc - sqrt(Rc^2 - h^2)) / 2 centres the arc's offsets on
///    the axis (they lie in [-m, m] over the fibre). The offset is held constant beyond
///    |s| = h + coating (where the shell ends), so the shear is Lipschitz everywhere.
/// The offsets over the fibre and its shell stay within lateral_reach of the axis; their
/// slope within A k + s_max / sqrt(Rc^2 - s_max^2) and their second derivative within
/// A k^2 + Rc^2 / (Rc^2 - s_max^2)^(3/2) (s_max = h + coating).
/// Height of the arc of radius R over the half chord c <= R: R - sqrt(R^2 - c^2), written so
/// that no square of R is formed (a radius of 1e300 is a straight fibre, not an overflow).
inline double arc_sagitta(double R, double c) {
  const double q = c / R;
  return c * q / (1.0 + std::sqrt((1.0 - q) * (1.0 + q)));
}

/// Bound on the second derivative of a centre line's offsets over |s| <= s_max: a wave of
/// amplitude A and angular wavenumber k plus a bend of radius Rc (0: none), A k^2 +
/// Rc^2 / (Rc^2 - s_max^2)^(3/2), written without squares of Rc.
inline double centre_line_curvature(double A, double k, double Rc, double s_max) {
  if (Rc <= 0.0) return A * k * k;
  const double q = s_max / Rc;
  return A * k * k + 1.0 / (Rc * std::pow((1.0 - q) * (1.0 + q), 1.5));
}

struct CentreLine {
  explicit CentreLine(const Inclusion& inc);
  Vec3 offset(double s) const {
    Vec3 o = Vec3::Zero();
    if (A > 0.0) o += A * std::sin(k * s + phase) * v;
    if (Rc > 0.0) {
      const double c = std::clamp(s, -s_max, s_max);
      o += (arc_sagitta(Rc, c) - mid) * w;
    }
    return o;
  }
  double reach() const;                       // bound on |offset|
  double slope() const;                       // bound on |offset'|
  double curvature() const;                   // bound on |offset''|
  Vec3 v = Vec3::UnitX(), w = Vec3::UnitX();  // wave and bend directions (unit, across the axis)
  double A = 0.0, k = 0.0, phase = 0.0;       // wave
  double Rc = 0.0, h = 0.0, mid = 0.0, s_max = 0.0;  // bend
};
inline Vec3 centre_offset(const Inclusion& inc, double s) {
  return CentreLine(inc).offset(s);
}
/// Largest |bend offset| over |s| <= s_max of a fibre of half length h bent to radius Rc.
double bend_reach(double bend_radius, double h, double s_max);
/// CentreLine(inc).reach() without the frame (0 for shapes other than cylinders).
inline double lateral_reach(const Inclusion& inc) {
  const Modifiers& m = inc.mod;
  if (inc.shape.kind != ShapeKind::Cylinder) return 0.0;
  const double h = inc.shape.half_axis.norm();
  return m.wave_amplitude + (m.bent() ? bend_reach(m.bend_radius, h, h + m.coating) : 0.0);
}

/// Wavy and bent fibres whose offsets reach far are packed and audited as chains of sheared
/// pieces, not by the envelope (the cylinder of radius r + reach, four times the fibre's
/// volume when a wave's A = r). The fibre (with its shell unless shells may touch: the sheared
/// straight cylinder of radius R = r + t, half length H = h + t) is cut along its axis into n
/// equal slices; over a slice the offsets depart from their chord by at most the sagitta
/// K ds^2 / 8 (K the bound on their second derivative above), so the slice's sections, disks of
/// radius R normal to the axis, lie in the disks of radius R + sagitta about the chord. Each
/// piece is that sheared piece (geometry/convex.hpp: the disk swept along the chord), grown by
/// the packing pad: together they hold the fibre, within the sagitta. (Round cylinders about the
/// chords, as before, held far more than the fibre, the more so the more waves: a section normal
/// to a steep chord is an ellipse, not a disk.) n keeps the sagitta below kChainSagitta of R.
/// Chains pay where the envelope is far larger than the fibre: for waves from a lateral reach of
/// kChainFrom times R (below it the envelope packs as densely at a fraction of the cost), and for
/// every bend (a few pieces follow it, where the envelope wastes the bend's sagitta all along).
/// The measurements behind kChainFrom: docs/benchmarks.md, deformed and wavy inclusions.
constexpr double kChainSagitta = 0.03, kChainFrom = 0.75;
/// The pieces of a chain cut from a straight cylinder of half length H and radius R whose
/// centre line bends by at most K (second derivative of the offsets): pieces of length ds with
/// K ds^2 / 8 <= kChainSagitta R (a ratio of lengths, the same at every scale; kCountRounding
/// keeps an exact integer from rounding either way). As a double: it may be far beyond what is
/// packed.
constexpr double kCountRounding = 1e-9;
inline double chain_piece_count(double H, double R, double K) {
  const double span = 2.0 * H * std::sqrt(K / (8.0 * kChainSagitta * R));
  return std::max(1.0, std::ceil(span * (1.0 - kCountRounding)));
}
/// The most pieces a fibre's chain may have: a wave far shorter than the fibre's radius makes a
/// chain of thousands of pieces and a pair of fibres millions of piece pairs (the scene is
/// refused up front, naming the wavelength).
constexpr double kMaxChainPieces = 256;
inline bool packs_as_chain(const Inclusion& inc) {
  const Modifiers& m = inc.mod;
  return inc.shape.kind == ShapeKind::Cylinder &&
         (m.bent() ||
          (m.wavy() && m.wave_amplitude >= kChainFrom * (inc.shape.radius +
                                                         (m.shells_may_touch ? 0.0 : m.coating))));
}
/// Rings along a fibre of length `length` and radius r for its surface mesh: 1 when straight,
/// 16 per wavelength when wavy (wave_length > 0), and for a bend (bend_radius > 0) enough that
/// the chords depart from the arc by at most 1 % of r.
inline double fibre_rings(double length, double r, double wave_length, double bend_radius) {
  double rings = 1.0;
  if (wave_length > 0.0) rings = std::max(rings, std::ceil(16.0 * length / wave_length));
  if (bend_radius > 0.0)
    rings = std::max(rings, std::ceil(length / std::sqrt(0.08 * r * bend_radius)));
  return rings;
}
/// The pieces of a wavy or bent fibre's chain (world coordinates), appended to *out.
void chain_pieces(const Inclusion& inc, std::vector<ShearedPiece>* out);
/// A straight cylinder about the fibre's axis holding every piece of its chain (the bound the
/// broad phases and walls use).
Shape chain_bound(const Inclusion& inc);

/// The drawn inclusion (core at the origin, modifiers at scale 1) placed and turned as
/// `packed`, its envelope after packing, and scaled by `scale` about its centre (modifier
/// lengths too).
Inclusion place_like(const Inclusion& drawn, const Shape& packed, double scale);

/// An inclusion prepared for many point queries (frames and matrices computed once). Keeps a
/// reference to the inclusion, which must outlive it.
class BodyQuery {
 public:
  explicit BodyQuery(const Inclusion& inc);
  /// Region of the point x (core first, then void, then shell).
  Region region(const Vec3& x) const;
  /// A lower bound on the distance from x to the nearest boundary between two regions of the
  /// inclusion (including the outer boundary): a ball of that radius about x lies in one region.
  double clearance(const Vec3& x) const;
  /// Signed distance to the core's surface (negative inside): exact for spheres, straight
  /// cylinders and outside ellipsoids; for wavy and bent fibres measured in their sheared frame,
  /// for deformed shapes radially (|y| - R(n)) a_min, inside ellipsoids (q - 1) a_min. The sign is
  /// always exact (it agrees with region()).
  double core_distance(const Vec3& x) const;
  /// Signed distance to the interphase shell (negative inside it): max(d - t, -d) with d the
  /// core distance above (exact for spheres and straight cylinders).
  double shell_distance(const Vec3& x) const {
    const double d = core_distance(x);
    return std::max(d - m_.coating, -d);
  }
  /// True for an inclusion without modifiers (a core only, exact line intersections).
  bool plain() const { return !m_.any(); }
  /// True when the core is the straight convex shape (not wavy or bent, not deformed): x_interval
  /// applies to it whatever shell or void surrounds it.
  bool straight_core() const { return !m_.curved() && !m_.deformed(); }
  /// Straight cores: the parameters [t0, t1] where the line p + t e_x lies in the core;
  /// false when it misses the core.
  bool x_interval(const Vec3& p, double* t0, double* t1) const;

 private:
  double cylinder_sdf(const Vec3& x) const;  // in the sheared frame of a wavy or bent fibre
  double cone_distance(const Vec3& d, double rho) const;
  const Modifiers& m_;
  const Shape& s_;
  Vec3 c_;
  Mat3 to_unit_ = Mat3::Identity();  // sphere, ellipsoid: y = to_unit (x - c)
  double amin_ = 0.0, amax_ = 0.0;
  Vec3 u_ = Vec3::UnitZ();  // cylinder axis
  CentreLine line_;
  double h_ = 0.0, lipschitz_ = 1.0;
  double kmax_ = 0.0;  // largest deformation wavenumber
  double cos_cap_ = 1.0, theta_cap_ = 0.0;
};

struct RegionVolumes {
  double core = 0.0;
  double shell = 0.0;
  double void_ = 0.0;
};
/// Volumes of the regions: closed forms for spheres and cylinders (the shell by Steiner's
/// formula; shearing a wavy fibre keeps volumes), converged quadrature for ellipsoid shells;
/// a deformed core keeps the volume of its undeformed shape.
RegionVolumes region_volumes(const Inclusion& inc);

/// Deformation field g(n) of the inclusion for a unit direction n in its own frame, |g| <= 1.
double deformation_field(const Modifiers& m, const Vec3& n);
/// Radius of a deformed shape's surface in its normalised frame along unit n:
/// deform_scale (1 + deform_amplitude g(n)) (1 for an undeformed one).
double deformed_radius(const Modifiers& m, const Vec3& n);
/// Scale that gives a deformed shape (|y| <= scale (1 + e g)) the volume of the unit ball.
double deformation_volume_scale(const Modifiers& m);

}  // namespace rvegen
