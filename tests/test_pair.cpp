// Unit tests of the pair tests: every intersection type of the paper and the degenerate
// configurations it leaves to the implementer.
#include <gtest/gtest.h>

#include <cmath>

#include "rvegen/geometry/convex.hpp"
#include "rvegen/geometry/pair.hpp"
#include "rvegen/geometry/random.hpp"

using namespace rvegen;

namespace {

// EPA depth accuracy asked for where a test checks depths to 1e-6.
constexpr double kTightDepth = 1e-8;

const Shape kCyl =
    Shape::cylinder(Vec3::Zero(), 1.0, Vec3(0, 0, 2));  // radius 1, length 4, along z

void expect_vec_near(const Vec3& a, const Vec3& b, double tol) {
  EXPECT_NEAR((a - b).norm(), 0.0, tol)
      << "got (" << a.transpose() << ") want (" << b.transpose() << ")";
}

TEST(SphereSphere, OverlapDepthNormal) {
  const Contact c = intersect(Shape::sphere({0, 0, 0}, 1), Shape::sphere({1.5, 0, 0}, 0.7));
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kSS);
  EXPECT_NEAR(c.depth, 0.2, 1e-12);
  expect_vec_near(c.normal, Vec3(1, 0, 0), 1e-12);
}

TEST(SphereSphere, TangentIsNotOverlap) {
  EXPECT_FALSE(intersect(Shape::sphere({0, 0, 0}, 1), Shape::sphere({2, 0, 0}, 1)).overlap);
  EXPECT_FALSE(intersect(Shape::sphere({0, 0, 0}, 1), Shape::sphere({2.1, 0, 0}, 1)).overlap);
}

TEST(SphereSphere, ToleranceIsRelativeToSize) {
  for (double scale : {1e-3, 1.0, 1e3}) {
    const Shape a = Shape::sphere({0, 0, 0}, scale);
    // Penetration of half the tolerance: touching. Twice the tolerance: overlapping.
    const double tol = kContactRelTolerance * scale;
    EXPECT_FALSE(intersect(a, Shape::sphere({2 * scale - 0.5 * tol, 0, 0}, scale)).overlap);
    EXPECT_TRUE(intersect(a, Shape::sphere({2 * scale - 4 * tol, 0, 0}, scale)).overlap);
  }
}

TEST(SphereSphere, CoincidentCentres) {
  const Contact c = intersect(Shape::sphere({1, 1, 1}, 1), Shape::sphere({1, 1, 1}, 0.5));
  ASSERT_TRUE(c.overlap);
  EXPECT_NEAR(c.depth, 1.5, 1e-12);
  EXPECT_NEAR(c.normal.norm(), 1.0, 1e-12);
}

// Algorithm 1.
TEST(SphereCylinder, Sc2LateralSurface) {
  const Contact c = intersect(Shape::sphere({1.5, 0, 0.3}, 0.6), kCyl);
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kSC2);
  EXPECT_NEAR(c.depth, 0.1, 1e-12);
  expect_vec_near(c.normal, Vec3(-1, 0, 0), 1e-12);  // from the sphere towards the cylinder
}

TEST(SphereCylinder, Sc3EndDiskCentreWithinInfiniteCylinder) {
  const Contact c = intersect(Shape::sphere({0.5, 0, 2.5}, 0.6), kCyl);
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kSC3);
  EXPECT_NEAR(c.depth, 0.1, 1e-12);
  expect_vec_near(c.normal, Vec3(0, 0, -1), 1e-12);
}

TEST(SphereCylinder, Sc4RimAndRimTangency) {
  const double s = std::sqrt(0.5);
  // Sphere centred on the bisector of the rim at distance 0.5 from the rim circle: tangent.
  EXPECT_FALSE(intersect(Shape::sphere({1 + 0.5 * s, 0, 2 + 0.5 * s}, 0.5), kCyl).overlap);
  const Contact c = intersect(Shape::sphere({1 + 0.5 * s, 0, 2 + 0.5 * s}, 0.51), kCyl);
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kSC4);
  EXPECT_NEAR(c.depth, 0.01, 1e-12);
  expect_vec_near(c.normal, Vec3(-s, 0, -s), 1e-12);
  // The same sphere against the rim, but not reaching: no overlap (the paper's sc4 test is
  // exact; a bounding-box test would say otherwise).
  EXPECT_FALSE(intersect(Shape::sphere({1.3, 0, 2.3}, 0.42), kCyl).overlap);
}

TEST(SphereCylinder, Sc1CylinderInsideSphere) {
  const Contact c = intersect(Shape::sphere({0.1, 0, 0}, 3.0), kCyl);
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kSC1);
}

TEST(SphereCylinder, SphereCentreOnTheAxisInside) {
  const Contact c = intersect(Shape::sphere({0, 0, 0.5}, 0.2), kCyl);
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kSC2);
  EXPECT_NEAR(c.depth, 1.2, 1e-12);  // leave through the lateral surface (1 away)
  EXPECT_NEAR(c.normal.norm(), 1.0, 1e-12);
  EXPECT_NEAR(c.normal.z(), 0.0, 1e-12);
}

TEST(SphereCylinder, ArgumentOrderFlipsNormalOnly) {
  const Shape s = Shape::sphere({1.5, 0, 0.3}, 0.6);
  const Contact a = intersect(s, kCyl), b = intersect(kCyl, s);
  EXPECT_EQ(a.type, b.type);
  EXPECT_DOUBLE_EQ(a.depth, b.depth);
  expect_vec_near(a.normal, -b.normal, 1e-15);
}

// Algorithm 4 and its degenerate cases.
TEST(CylinderCylinder, Cc1Crossing) {
  const Contact c = intersect(kCyl, Shape::cylinder({1.5, 0, 0.5}, 0.6, Vec3(0, 2, 0)));
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kCC1);
  EXPECT_NEAR(c.depth, 0.1, 1e-12);
  expect_vec_near(c.normal, Vec3(1, 0, 0), 1e-12);
  EXPECT_FALSE(intersect(kCyl, Shape::cylinder({1.6, 0, 0.5}, 0.6, Vec3(0, 2, 0))).overlap);
}

TEST(CylinderCylinder, PerpendicularAxesThatTouch) {
  // rho = 0: the axes intersect; n = u1 x u2 must still give a valid direction.
  const Contact c = intersect(kCyl, Shape::cylinder({0, 0, 0}, 0.5, Vec3(0, 2, 0)));
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kCC1);
  EXPECT_NEAR(c.depth, 1.5, 1e-12);
  EXPECT_NEAR(std::abs(c.normal.x()), 1.0, 1e-12);
}

TEST(CylinderCylinder, ParallelAndAntiParallelSideBySide) {
  for (double sign : {1.0, -1.0}) {
    const Contact c = intersect(kCyl, Shape::cylinder({1.9, 0, 1}, 1.0, Vec3(0, 0, 2 * sign)));
    ASSERT_TRUE(c.overlap);
    EXPECT_EQ(c.type, ContactType::kCC1);
    EXPECT_NEAR(c.depth, 0.1, 1e-12);
    expect_vec_near(c.normal, Vec3(1, 0, 0), 1e-12);
    EXPECT_FALSE(intersect(kCyl, Shape::cylinder({2.0, 0, 1}, 1.0, Vec3(0, 0, 2 * sign))).overlap);
  }
}

TEST(CylinderCylinder, CoaxialEndToEnd) {
  const Contact c = intersect(kCyl, Shape::cylinder({0, 0, 2.9}, 0.5, Vec3(0, 0, 1)));
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kD1);  // the first disk is the larger one
  EXPECT_NEAR(c.depth, 0.1, 1e-12);
  expect_vec_near(c.normal, Vec3(0, 0, 1), 1e-12);
  EXPECT_FALSE(intersect(kCyl, Shape::cylinder({0, 0, 3.0}, 0.5, Vec3(0, 0, 1))).overlap);
  EXPECT_FALSE(intersect(kCyl, Shape::cylinder({0, 0, -3.0}, 0.5, Vec3(0, 0, -1))).overlap);
}

TEST(CylinderCylinder, CoincidentIdenticalCylinders) {
  const Contact c = intersect(kCyl, kCyl);
  ASSERT_TRUE(c.overlap);
  EXPECT_NEAR(c.depth, 2.0, 1e-12);  // radial escape (2) is shorter than axial (4)
  EXPECT_NEAR(c.normal.norm(), 1.0, 1e-12);
}

TEST(CylinderCylinder, OneInsideTheOther) {
  const Contact c = intersect(kCyl, Shape::cylinder({0.1, 0.1, 0.5}, 0.2, Vec3(0.3, 0.1, 0.2)));
  EXPECT_TRUE(c.overlap);
  EXPECT_GT(c.depth, 0.5);
}

TEST(CylinderCylinder, EndDiskIntoLateralSurfaceTJunction) {
  // The disk plane is parallel to the other's axis: the paper's Algorithm 3 divides by zero.
  // (A tight EPA depth is asked for: the default stops within 1e-3 of it, see below.)
  const Contact c =
      intersect(kCyl, Shape::cylinder({2.4, 0, 0.3}, 0.5, Vec3(1.5, 0, 0)), kTightDepth);
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kCD1);
  EXPECT_NEAR(c.depth, 0.1, 1e-6);
  expect_vec_near(c.normal, Vec3(1, 0, 0), 1e-4);
  EXPECT_FALSE(
      intersect(kCyl, Shape::cylinder({2.5 + 1e-6, 0, 0.3}, 0.5, Vec3(1.5, 0, 0))).overlap);
}

TEST(CylinderCylinder, Cd3AxisThroughEndDisk) {
  // A wide, slightly tilted cylinder whose lower end disk is pierced by kCyl's axis.
  const double t = 0.1;
  const Contact c = intersect(
      kCyl, Shape::cylinder({0, 0, 2.4}, 3.0, Vec3(0.5 * std::sin(t), 0, 0.5 * std::cos(t))));
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kCD3);
}

TEST(CylinderCylinder, CoplanarAxesCornerToCorner) {
  // Axes in the plane y = 0, 90 degrees apart, corners meeting: only end disks are involved.
  const Shape c2 = Shape::cylinder({1 + 2 - 0.05, 0, 2 + 1 - 0.05}, 1.0, Vec3(2, 0, 0));
  const Contact c = intersect(kCyl, c2, kTightDepth);
  ASSERT_TRUE(c.overlap);
  EXPECT_NEAR(c.depth, 0.05, 1e-6);
  EXPECT_FALSE(intersect(kCyl, c2.translated(Vec3(0.06, 0, 0))).overlap);
}

TEST(CylinderCylinder, NearlyParallelLongFibres) {
  // A small angle between long fibres side by side: the closest points of the axis lines are
  // far outside the segments, the lateral surfaces still overlap near the ends.
  const Shape a = Shape::cylinder({0, 0, 0}, 0.1, Vec3(0, 0, 5));
  const double ang = 1e-7;
  const Shape b =
      Shape::cylinder({0.199, 0, 0}, 0.1, Vec3(5 * std::sin(ang), 0, 5 * std::cos(ang)));
  EXPECT_TRUE(intersect(a, b).overlap);
  EXPECT_FALSE(intersect(a, b.translated(Vec3(0.0011, 0, 0))).overlap);
}

// Ellipsoids: Perram-Wertheim.
TEST(PerramWertheim, SpheresMatchClosedForm) {
  const Shape a = Shape::sphere({0, 0, 0}, 1.0), b = Shape::sphere({2.5, 0, 0}, 0.5);
  EXPECT_NEAR(perram_wertheim(a, b), std::pow(2.5 / 1.5, 2), 1e-12);
}

TEST(PerramWertheim, AlignedEllipsoidsTouchAtSemiAxisSums) {
  const Vec3 semi(3, 2, 1);
  const Shape a = Shape::ellipsoid({0, 0, 0}, semi, Mat3::Identity());
  for (int axis = 0; axis < 3; ++axis) {
    Vec3 d = Vec3::Zero();
    d[axis] = 2 * semi[axis];
    EXPECT_NEAR(perram_wertheim(a, a.translated(d)), 1.0, 1e-12);
    EXPECT_TRUE(intersect(a, a.translated(d * (1 - 1e-6))).overlap);
    EXPECT_FALSE(intersect(a, a.translated(d * (1 + 1e-6))).overlap);
    EXPECT_FALSE(intersect(a, a.translated(d)).overlap);  // tangent
  }
}

TEST(PerramWertheim, CrossedEllipsoids) {
  // Long ellipsoid along x and one along y, centred 1.9 apart along z: thickness 1 each.
  const Shape a = Shape::ellipsoid({0, 0, 0}, Vec3(4, 1, 1), Mat3::Identity());
  Mat3 r;
  r << 0, -1, 0, 1, 0, 0, 0, 0, 1;  // rotation by 90 degrees about z
  const Shape b = Shape::ellipsoid({0, 0, 1.9}, Vec3(4, 1, 1), r);
  const Contact c = intersect(a, b);
  ASSERT_TRUE(c.overlap);
  EXPECT_EQ(c.type, ContactType::kPW);
  EXPECT_NEAR(c.depth, 0.1, 1e-9);
  expect_vec_near(c.normal, Vec3(0, 0, 1), 1e-9);
  EXPECT_FALSE(intersect(a, b.translated(Vec3(0, 0, 0.1 + 1e-7))).overlap);
}

TEST(CylinderEllipsoid, LateralContact) {
  const Shape e = Shape::ellipsoid({0, 0, 0}, Vec3(1, 2, 3), Mat3::Identity());
  const Shape c = Shape::cylinder({1.4, 0, 0}, 0.5, Vec3(0, 0, 1));
  const Contact k = intersect(e, c, kTightDepth);
  ASSERT_TRUE(k.overlap);
  EXPECT_EQ(k.type, ContactType::kCE);
  EXPECT_NEAR(k.depth, 0.1, 1e-6);
  expect_vec_near(k.normal, Vec3(1, 0, 0), 1e-4);
  EXPECT_FALSE(intersect(e, c.translated(Vec3(0.1 + 1e-6, 0, 0))).overlap);
}

TEST(Convex, DistanceOfSeparatedShapes) {
  const Shape a = Shape::cylinder({0, 0, 0}, 1.0, Vec3(0, 0, 2));
  const Shape b = Shape::ellipsoid({3.5, 0, 0}, Vec3(1, 2, 3), Mat3::Identity());
  const ConvexQuery q = convex_query(a, b, 1e-10, true, kTightDepth);
  EXPECT_TRUE(q.separated);
  EXPECT_NEAR(q.distance, 1.5, 1e-9);
  EXPECT_TRUE(clear_of(a, b, 1.4));
  EXPECT_FALSE(clear_of(a, b, 1.6));
}

TEST(Convex, DefaultDepthIsATightUpperBound) {
  // The default EPA accuracy (kDepthRelTolerance) changes neither the decision nor, beyond that
  // fraction, the depth: on overlapping pairs that go through EPA (end disks, cylinder-ellipsoid)
  // the default depth lies in [tight depth, tight depth (1 + 1e-3)] and still separates.
  Random rng(5);
  int epa_pairs = 0;
  for (int i = 0; i < 4000; ++i) {
    const double r = rng.uniform(0.3, 1.0);
    const Shape a = Shape::cylinder(Vec3::Zero(), r, rng.unit_vector() * r * rng.uniform(0.5, 6));
    const Shape b =
        i % 2 == 0
            ? Shape::cylinder(rng.unit_vector() * rng.uniform(0.5, 3), rng.uniform(0.3, 1),
                              rng.unit_vector() * rng.uniform(0.3, 4))
            : Shape::ellipsoid(rng.unit_vector() * rng.uniform(0.5, 3),
                               Vec3(rng.uniform(0.3, 2), rng.uniform(0.3, 2), 0.5), rng.rotation());
    const Contact fast = intersect(a, b), tight = intersect(a, b, kTightDepth);
    ASSERT_EQ(fast.overlap, tight.overlap) << i;
    if (!fast.overlap || fast.type == ContactType::kCC1 || fast.type == ContactType::kSC2) continue;
    ++epa_pairs;
    EXPECT_GE(fast.depth, tight.depth * (1 - 1e-7)) << i;
    EXPECT_LE(fast.depth, tight.depth * (1 + kDepthRelTolerance) + 1e-12) << i;
    EXPECT_FALSE(intersect(a, b.translated((fast.depth * (1 + 1e-7)) * fast.normal)).overlap) << i;
  }
  EXPECT_GT(epa_pairs, 500);
}

TEST(Contact, NamesAreThePapers) {
  EXPECT_STREQ(contact_type_name(ContactType::kSC1), "sc1");
  EXPECT_STREQ(contact_type_name(ContactType::kCC1), "cc1");
  EXPECT_STREQ(contact_type_name(ContactType::kCD3), "cd3");
  EXPECT_STREQ(contact_type_name(ContactType::kD2), "d2");
}

}  // namespace
