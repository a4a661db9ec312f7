// Exact pair tests between inclusions.
//
// Sphere/cylinder pairs follow the paper's Algorithms 1-4 and report its intersection types
// (sc1..sc4, cc1, cd1..cd3, d1, d2); ellipsoid pairs (and sphere-ellipsoid) use the
// Perram-Wertheim contact function; cylinder-ellipsoid pairs, which have neither, use GJK/EPA on
// the exact support functions. Every path decides overlap exactly up to the tolerance below.
//
// Tolerance: two shapes overlap when their penetration depth exceeds
//   kContactRelTolerance * min(a.min_size(), b.min_size()).
// Tangent contact (depth 0) and depths below that bound count as touching, not overlapping.
#pragma once

#include <cmath>
#include <string>

#include "rvegen/geometry/convex.hpp"
#include "rvegen/geometry/shapes.hpp"

namespace rvegen {

constexpr double kContactRelTolerance = 1e-9;
/// Relative accuracy of the depth where it comes from EPA (end disks, cylinder-ellipsoid): the
/// reported depth is an upper bound within this fraction of the minimal translation. Forces
/// need no more; pass a smaller value to the tests below for a tighter depth.
constexpr double kDepthRelTolerance = 1e-3;

enum class ContactType {
  kNone = 0,
  kSS,       // sphere-sphere
  kSC1,      // cylinder inside the sphere (paper: sc1)
  kSC2,      // sphere against the lateral surface (sc2)
  kSC3,      // sphere cuts an end disk, centre within the infinite cylinder (sc3)
  kSC4,      // sphere cuts an end disk rim, centre outside the infinite cylinder (sc4)
  kCC1,      // lateral surfaces cross (cc1)
  kCD1,      // an end disk grazes the other's lateral surface (cd1)
  kCD2,      // an end disk reaches past the other's axis (cd2)
  kCD3,      // the other cylinder passes through an end disk (cd3)
  kD1,       // end disk against end disk, first disk's rim inside the second (d1)
  kD2,       // end disk against end disk, second disk's rim inside the first (d2)
  kPW,       // ellipsoid-ellipsoid or sphere-ellipsoid (Perram-Wertheim)
  kCE,       // cylinder-ellipsoid (GJK/EPA)
  kSupport,  // deformed spheres: certified support functions along the line of centres
  kPiece,    // a sheared piece of a wavy or bent fibre's chain (GJK/EPA)
};

/// Short name as used in reports ("sc2", "cc1", "pw", ...).
const char* contact_type_name(ContactType t);

struct Contact {
  bool overlap = false;
  ContactType type = ContactType::kNone;
  /// Penetration measure (length): translating b by depth * normal separates the pair.
  /// Exact (the minimal translation) for sphere pairs and sphere-cylinder; an upper bound
  /// otherwise. 0 when not overlapping.
  double depth = 0.0;
  /// Unit separating direction, from a towards b.
  Vec3 normal = Vec3::UnitX();
  /// Point of application of the contact force (same point for both bodies).
  Vec3 point = Vec3::Zero();
};

/// Overlap tolerance for a pair (see file comment).
double contact_tolerance(const Shape& a, const Shape& b);

/// The contact a GJK/EPA query found (none unless its depth exceeds tol), of the given type.
Contact contact_of(const ConvexQuery& q, double tol, ContactType type);

/// Exact overlap test of a and b with intersection type, depth, direction and point.
Contact intersect(const Shape& a, const Shape& b, double depth_rel = kDepthRelTolerance);

// The individual tests, exposed for tests and benchmarks. Argument order matters for the
// normal (from the first towards the second).
Contact intersect_sphere_sphere(const Shape& s1, const Shape& s2);
Contact intersect_sphere_cylinder(const Shape& s, const Shape& c);  // Algorithm 1
Contact intersect_cylinder_cylinder(const Shape& c1, const Shape& c2,
                                    double depth_rel = kDepthRelTolerance);  // Algorithms 2-4
Contact intersect_perram_wertheim(const Shape& e1, const Shape& e2);         // ellipsoids, spheres
Contact intersect_convex(const Shape& a, const Shape& b,
                         double depth_rel = kDepthRelTolerance);  // GJK/EPA

/// Perram-Wertheim contact function max_lambda F(lambda) for two ellipsoids (spheres allowed):
/// < 1 overlap, = 1 tangent, > 1 disjoint. sqrt(F) is the factor by which both must be scaled
/// about their centres to touch. Writes the maximising lambda when asked. The search stops early
/// (returning a value >= stop_above, a lower bound of the maximum) once the maximum is known to
/// be at least stop_above.
double perram_wertheim(const Shape& e1, const Shape& e2, double* lambda_out = nullptr,
                       double stop_above = HUGE_VAL);

}  // namespace rvegen

namespace rvegen {
/// True when the surfaces of a and b are at least `gap` apart (gap = 0: they do not overlap;
/// touching is allowed). Exact: closed form for spheres, GJK distance otherwise.
bool clear_of(const Shape& a, const Shape& b, double gap);
}  // namespace rvegen
