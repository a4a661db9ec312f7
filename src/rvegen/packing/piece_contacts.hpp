// The contact of two bodies given by convex pieces (a chain's pieces, or one body's single
// shape), one function for the packer's contact pass and for the audit, so that the two decide
// alike.
#pragma once

#include <functional>
#include <vector>

#include "rvegen/geometry/pair.hpp"
#include "rvegen/geometry/shapes.hpp"

namespace rvegen {

/// A capsule holding a shape: the segment p-q and a radius (a cylinder's axis and radius; other
/// shapes: their centre and bounding radius).
struct Capsule {
  Vec3 p, q;
  double r;
};
Capsule capsule_of(const Shape& s);
bool capsules_meet(const Capsule& a, const Capsule& b);

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
bool piece_contacts(const std::vector<const Shape*>& a, const std::vector<Shape>& b,
                    const Grain* grain_a, const Grain* grain_b, bool first_only,
                    std::vector<Contact>* found);

}  // namespace rvegen
