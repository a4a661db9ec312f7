#include "rvegen/packing/body_contacts.hpp"

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

bool piece_contacts(const std::vector<const Shape*>& a, const std::vector<Shape>& b,
                    const Grain* grain_a, const Grain* grain_b, bool first_only,
                    std::vector<Contact>* found) {
  bool any = false;
  for (const Shape* pa : a) {
    for (const Shape& pb : b) {
      if ((pa->center - pb.center).squaredNorm() >=
          std::pow(pa->bounding_radius() + pb.bounding_radius(), 2)) {
        continue;
      }
      if (!capsules_meet(capsule_of(*pa), capsule_of(pb))) continue;
      Contact c = intersect(*pa, pb);
      if (!c.overlap) continue;
      if (grain_a || grain_b) {
        Vec3 n;
        const double gap = grain_a ? plane_gap(grain_a->centre, pb, grain_a->support, &n)
                                   : plane_gap(grain_b->centre, *pa, grain_b->support, &n);
        if (gap >= 0.0) continue;
        if (gap > -c.depth) {
          c.depth = -gap;
          c.normal = grain_a ? n : Vec3(-n);
        }
      }
      any = true;
      if (found) found->push_back(c);
      if (first_only) return true;
    }
  }
  return any;
}

}  // namespace rvegen
