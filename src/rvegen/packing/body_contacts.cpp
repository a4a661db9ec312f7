#include "rvegen/packing/body_contacts.hpp"

#include <algorithm>
#include <cmath>

#include "rvegen/geometry/convex.hpp"
#include "rvegen/model/deformed_support.hpp"

namespace rvegen {

Capsule capsule_of(const Shape& s) {
  if (s.kind == ShapeKind::Cylinder)
    return {s.center - s.half_axis, s.center + s.half_axis, s.radius};
  const double r = s.bounding_radius();
  return {s.center, s.center, r};
}

bool capsules_meet(const Capsule& a, const Capsule& b) {
  return segment_distance2(a.p, a.q, b.p, b.q) < (a.r + b.r) * (a.r + b.r);
}

Capsule capsule_of(const Piece& p) {
  if (!p.sheared) return capsule_of(p.shape);
  const ShearedPiece& s = p.part;
  return {s.center - s.half_axis, s.center + s.half_axis, s.radius + s.bow_reach() + s.round};
}

namespace {

double piece_size(const Piece& p) {
  return p.sheared ? p.part.radius + p.part.round : p.shape.min_size();
}

// plane_gap (deformed_support.hpp) for a piece: the plane normal to the direction from
// `centre` to the nearest point of the piece's axis or chord.
template <class Support>
double piece_plane_gap(const Vec3& centre, const Piece& piece, const Support& support,
                       Vec3* normal) {
  return piece.sheared ? axis_plane_gap(centre, piece.part, support, normal)
                       : plane_gap(centre, piece.shape, support, normal);
}

}  // namespace

Contact intersect_pieces(const Piece& a, const Piece& b) {
  if (!a.sheared && !b.sheared) return intersect(a.shape, b.shape);
  const double tol = kContactRelTolerance * std::min(piece_size(a), piece_size(b));
  if (a.sheared && b.sheared) {
    return contact_of(convex_query(a.part, b.part, tol, false, kDepthRelTolerance), tol,
                      ContactType::kPiece);
  }
  if (a.sheared) {
    return contact_of(convex_query(a.part, b.shape, tol, false, kDepthRelTolerance), tol,
                      ContactType::kPiece);
  }
  Contact c = contact_of(convex_query(b.part, a.shape, tol, false, kDepthRelTolerance), tol,
                         ContactType::kPiece);
  c.normal = -c.normal;
  return c;
}

bool piece_contacts(const std::vector<const Piece*>& a, const std::vector<Piece>& b,
                    const Grain* grain_a, const Grain* grain_b, bool first_only,
                    std::vector<Contact>* found) {
  bool any = false;
  for (const Piece* pa : a) {
    const Capsule cap_a = capsule_of(*pa);
    for (const Piece& pb : b) {
      if ((pa->center() - pb.center()).squaredNorm() >=
          std::pow(pa->bounding_radius() + pb.bounding_radius(), 2)) {
        continue;
      }
      if (!capsules_meet(cap_a, capsule_of(pb))) continue;
      // A grain's plane first: where it separates the pair, the exact test is not needed.
      Vec3 n;
      double gap = 0.0;
      if (grain_a || grain_b) {
        gap = grain_a ? piece_plane_gap(grain_a->centre, pb, grain_a->support, &n)
                      : piece_plane_gap(grain_b->centre, *pa, grain_b->support, &n);
        if (gap >= 0.0) continue;
      }
      if ((pa->sheared || pb.sheared) && !grain_a && !grain_b) {
        // The plane normal to the line of the pieces' centres first: where it separates them,
        // the exact test would find them apart too.
        const Vec3 d = pb.center() - pa->center();
        const double len = d.norm();
        if (len > 0.0) {
          const Vec3 u = d / len;
          if (pa->support_value(u) + pb.support_value(-u) < 0.0) continue;
        }
      }
      Contact c = intersect_pieces(*pa, pb);
      if (!c.overlap) continue;
      if ((grain_a || grain_b) && gap > -c.depth) {
        c.depth = -gap;
        c.normal = grain_a ? n : Vec3(-n);
      }
      any = true;
      if (found) found->push_back(c);
      if (first_only) return true;
    }
  }
  return any;
}

}  // namespace rvegen
