// The contact of two bodies, one function per kind of pair, called by the packer's contact pass
// and by the audit, so that the two decide alike (the sweep of tests/test_contacts.cpp checks
// it for every kind):
//   plain convex shapes       intersect (geometry/pair.hpp)
//   round bodies              round_contact: balls and deformed spheres (grains)
//   anything with a chain     piece_contacts: a chain's pieces against the other's pieces, a
//                             plain shape or a grain
#pragma once

#include <functional>
#include <vector>

#include "rvegen/geometry/convex.hpp"
#include "rvegen/geometry/pair.hpp"
#include "rvegen/geometry/shapes.hpp"

namespace rvegen {

/// Two round bodies: balls or deformed spheres, each by a certified bound of its support function
/// along a unit direction (a ball's: its radius), scaled by fa and fb; b's centre is a's + d, at
/// the distance dist = |d|. A plane normal to the line of centres separates them when their
/// supports along it sum to at most dist + tol; otherwise the contact has the excess as its depth,
/// the line of centres (a to b) as its normal and its point on a's support plane. *ha and *hb
/// receive the unscaled supports along the normal.
template <class SupportA, class SupportB>
Contact round_contact(const Vec3& ca, const Vec3& d, double dist, double fa,
                      const SupportA& support_a, double fb, const SupportB& support_b, double tol,
                      double* ha, double* hb) {
  Contact c;
  const Vec3 u = dist > 0.0 ? Vec3(d / dist) : Vec3::UnitX();
  *ha = support_a(u);
  *hb = support_b(Vec3(-u));
  const double reach = fa * *ha + fb * *hb;
  if (reach - dist <= tol) return c;
  c.overlap = true;
  c.type = ContactType::kSupport;
  c.depth = reach - dist;
  c.normal = u;
  c.point = ca + fa * *ha * u;
  return c;
}

/// A capsule holding a shape: the segment p-q and a radius (a cylinder's axis and radius; other
/// shapes: their centre and bounding radius).
struct Capsule {
  Vec3 p, q;
  double r;
};
Capsule capsule_of(const Shape& s);
bool capsules_meet(const Capsule& a, const Capsule& b);

/// What the piece-by-piece contacts test: a chain's sheared piece, or a body's own shape (a
/// plain shape, or a grain's bounding ball).
struct Piece {
  bool sheared = false;
  ShearedPiece part;   // when sheared
  Shape shape;         // otherwise
  double bound = 0.0;  // the bounding radius (worked out once: pieces meet many pieces)
  static Piece of(const ShearedPiece& p) {
    Piece q;
    q.sheared = true;
    q.part = p;
    q.bound = p.bounding_radius();
    return q;
  }
  static Piece of(const Shape& s) {
    Piece q;
    q.shape = s;
    q.bound = s.bounding_radius();
    return q;
  }
  const Vec3& center() const { return sheared ? part.center : shape.center; }
  double bounding_radius() const { return bound; }
  Piece translated(const Vec3& t) const {
    Piece q = *this;
    if (sheared) {
      q.part.center += t;
    } else {
      q.shape.center += t;
    }
    return q;
  }
  bool contains(const Vec3& x) const { return sheared ? part.contains(x) : shape.contains(x); }
  /// h(d) = max over the piece of d . x.
  double support_value(const Vec3& d) const {
    return sheared ? part.support_value(d) : shape.support_value(d);
  }
};
/// A piece's capsule: a sheared piece's chord with its disk's radius and ball.
Capsule capsule_of(const Piece& p);
/// The exact overlap test of two pieces (intersect for two shapes; GJK and EPA on the support
/// functions otherwise, to the tolerance of the smaller).
Contact intersect_pieces(const Piece& a, const Piece& b);

/// A deformed grain met by pieces: its piece is its bounding ball, and a plane that separates the
/// grain (its centre and certified support function) from a piece separates the pair.
struct Grain {
  Vec3 centre;
  std::function<double(const Vec3&)> support;
};

/// The contacts between the pieces `a` and `b` (b already shifted to its image): every pair of
/// pieces whose bounding spheres and capsules meet and that overlap by the exact test, except,
/// when one side is a grain (grain_a or grain_b: at most one), those the grain's plane separates;
/// there the contact takes the plane's depth and normal when they are shallower. Appends them to
/// *found (when not null; only the first when first_only) and returns whether there is any.
bool piece_contacts(const std::vector<const Piece*>& a, const std::vector<Piece>& b,
                    const Grain* grain_a, const Grain* grain_b, bool first_only,
                    std::vector<Contact>* found);

}  // namespace rvegen
