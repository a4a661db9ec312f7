// The cell of the mesh (cell.cpp): the box moved off the inclusions its faces and edges would
// graze, and the inclusions every cell grazes nudged off it (Gmsh-free).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "femesh_fixtures.hpp"
#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/geometry/pair.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/neighbours.hpp"

namespace rvegen {
namespace {

using namespace femesh_test;

// Every pair of inclusions (periodic images too) at least `gap` apart.
void expect_apart(const InclusionSet& set, double gap) {
  for (size_t i = 0; i < set.inclusions.size(); ++i) {
    const Shape& a = set.inclusions[i].shape;
    for (size_t j = i + 1; j < set.inclusions.size(); ++j) {
      const Shape& b = set.inclusions[j].shape;
      for_each_image(set.box, a.center, a.bounding_radius() + gap, b.center, b.bounding_radius(),
                     [&](const Vec3& shift) {
                       EXPECT_TRUE(clear_of(a, b.translated(shift), gap)) << i << " " << j;
                     });
    }
  }
}

TEST(TetMesh, ACellFaceGrazingASphereIsMovedOffIt) {
  // The sphere's lowest point 0.001 above the face z = 0 (a cap of 3.6 degrees once cut), its
  // other extremes far from every face.
  const InclusionSet set = one_of(Shape::sphere({0.5, 0.5, 0.101}, 0.1));
  EXPECT_NEAR(face_clearance(set, set.box.origin), 0.01, 1e-9);
  const Vec3 o = cell_origin(set);
  EXPECT_EQ(o[0], 0.0);  // x and y were already clear
  EXPECT_EQ(o[1], 0.0);
  // Along z the best position lies halfway between the sphere's extremes and their images
  // (0.001 + 0.5 of the gap left, 0.8): clearance 4, the face at z = 0.601 (moved by -0.399).
  EXPECT_NEAR(o[2], -0.399, 1e-9);
  EXPECT_NEAR(face_clearance(set, o), 4.0, 1e-9);
}

TEST(TetMesh, ACellEdgeGrazingASphereIsMovedOffIt) {
  // The edge y = z = 0 passes 0.00055 outside the sphere (its faces cut it well inside).
  const double c = 0.0711;
  const InclusionSet set = one_of(Shape::sphere({0.5, c, c}, 0.1));
  EXPECT_GT(face_clearance(set, set.box.origin), 0.25);
  EXPECT_NEAR(edge_clearance(set, set.box.origin), (std::sqrt(2.0) * c - 0.1) / 0.1, 1e-12);
  const Vec3 o = cell_origin(set);
  EXPECT_GE(face_clearance(set, o), kGoodClearance);
  EXPECT_GE(edge_clearance(set, o), kGoodClearance);
  // And a corner 0.001 inside an ellipsoid.
  const Mat3 turn = Eigen::AngleAxisd(0.3, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  const Vec3 semi(0.12, 0.08, 0.05);
  Vec3 centre = turn * Vec3(0.0, 0.0, 0.05 - 0.001);  // the corner (0,0,0) in the frame
  const InclusionSet grain = one_of(Shape::ellipsoid(-centre, semi, turn));
  EXPECT_LT(edge_clearance(grain, grain.box.origin), 0.03);
  const Vec3 g = cell_origin(grain);
  EXPECT_GE(std::min(face_clearance(grain, g), edge_clearance(grain, g)), kGoodClearance);
}

TEST(TetMesh, ACellFaceNearlyAlongATiltedFibreEndIsMovedOffIt) {
  // A fibre nearly along z (10 degrees), its upper end disk 0.0005 above the face z = 1 at its
  // centre: the face would cross the disk at 10 degrees. The disk's span along z and both rims'
  // extremes are kept clear.
  const Vec3 u(std::sin(0.1745), 0.0, std::cos(0.1745));
  const Shape fibre = Shape::cylinder(Vec3(0.5, 0.5, 1.0 - 0.0005 - 0.2 * u[2]), 0.02, 0.2 * u);
  const InclusionSet set = one_of(fibre);
  EXPECT_EQ(face_clearance(set, set.box.origin), 0.0);
  const Vec3 o = cell_origin(set);
  EXPECT_GE(face_clearance(set, o), kGoodClearance);
  // The faces left the disk's span (0.00347 either side of its centre, 0.0005 below z = 1).
  EXPECT_GT(std::abs(o[2] - set.box.origin[2]), 0.0035);
}

TEST(TetMesh, ACellFaceAlongAFibreNearlyParallelToItIsMovedOffTheMantle) {
  // A fibre tilted by 4 degrees from the face z = 1: the line of its mantle furthest along z
  // rises from 1 - 0.01395 to 1 + 0.01395 over its length, so the face is tangent to the
  // mantle where it crosses that line and cuts a wedge of 4 degrees. Its rims' extremes lie
  // 0.7 radii from the face, which alone would keep the box.
  const double tilt = 4.0 * M_PI / 180.0, r = 0.02, h = 0.2;
  const Vec3 u(std::cos(tilt), 0.0, std::sin(tilt));
  const double top = r * std::cos(tilt), span = h * std::sin(tilt);
  const InclusionSet set = one_of(Shape::cylinder(Vec3(0.5, 0.5, 1.0 - top), r, h * u));
  EXPECT_EQ(face_clearance(set, set.box.origin), 0.0);
  const Vec3 o = cell_origin(set);
  EXPECT_EQ(o[0], 0.0);
  EXPECT_EQ(o[1], 0.0);
  EXPECT_GE(face_clearance(set, o), kGoodClearance);
  // The face left both lines' spans (about z = 1 and z = 1 - 2 top).
  const double z = o[2] - std::floor(o[2]);
  for (const double line : {1.0, 1.0 - 2.0 * top}) {
    double d = std::abs(z - line);
    d = std::min(d, 1.0 - d);
    EXPECT_GE(d, span + kGoodClearance * r) << line;
  }
}

TEST(TetMesh, WhereShallowFibresCoverTheAxisTheShallowestAreStillAvoided) {
  // Twelve fibres 7 degrees off the z faces, at heights k / 12: their mantle lines' spans cover
  // every height, and their rims leave the best room for a face about z = 0.0218, between the
  // first one's upper rim and the second one's lower. A long fibre 3 degrees off the faces has
  // its upper line's span about that height (its rims far from it). No face position misses
  // every span, so the least shallow are let go, and the cell's z faces miss the 3-degree
  // fibre's lines.
  const double r = 0.02;
  InclusionSet set = shallow_fibres(r);
  const double shallow = 3.0 * M_PI / 180.0, top = r * std::cos(shallow);
  const double span = 2.0 * std::sin(shallow), room = 0.0218;
  set.inclusions.push_back(tilted_fibre(3.0, r, 2.0, room - top));
  const Vec3 o = cell_origin(set);
  const double z = o[2] - std::floor(o[2]);
  for (const double line : {room, room - 2.0 * top}) {
    double d = std::abs(z - line);
    d = std::min(d, 1.0 - d);
    EXPECT_GT(d, span) << line;
  }
}

// The fibre of AFibreGrazingAFaceOfTheCellIsNudgedOffItWhereThereIsRoom (test_tet_mesh.cpp)
// between two flat ellipsoids (plates), 0.003 below and above it:
// no translation of it alone clears the face and keeps min_gap. It moves down off the face and
// pushes the lower plate, which had room.
TEST(TetMesh, AFibreBoxedInOffAFaceOfTheCellPushesWhatBoxesItIn) {
  const double tilt = 1.5 * M_PI / 180.0, r = 0.02, h = 0.2, gap = 0.002;
  const Vec3 u(std::cos(tilt), 0.0, std::sin(tilt));
  InclusionSet set = one_of(Shape::cylinder(Vec3(0.5, 0.5, 1.0 - r * std::cos(tilt)), r, h * u));
  Vec3 lo, hi;
  set.inclusions[0].shape.aabb(&lo, &hi);
  const double t = 0.02;  // the plates' half thickness
  for (const double z : {lo[2] - 0.003 - t, hi[2] + 0.003 + t - 1.0}) {
    Inclusion plate;
    plate.shape = Shape::ellipsoid(Vec3(0.5, 0.5, z), Vec3(0.45, 0.45, t), Mat3::Identity());
    set.inclusions.push_back(plate);
  }
  const InclusionSet before = set;
  const Vec3 o = set.box.origin;
  ASSERT_EQ(face_clearance(set, o), 0.0);
  const Nudged n = nudge_off_cell(&set, o, gap);
  EXPECT_EQ(n.stuck, 0);
  EXPECT_EQ(n.moved, 2);  // the fibre and the lower plate
  EXPECT_GE(std::min(face_clearance(set, o), edge_clearance(set, o)), kGoodClearance);
  const Vec3 fibre = set.inclusions[0].shape.center - before.inclusions[0].shape.center;
  const Vec3 lower = set.inclusions[1].shape.center - before.inclusions[1].shape.center;
  EXPECT_LT(fibre[2], 0.0);
  EXPECT_LT(lower[2], 0.0);
  EXPECT_LE(fibre.norm(), 4.0 * r);
  EXPECT_LE(lower.norm(), 2.0 * t);
  EXPECT_EQ(set.inclusions[2].shape.center, before.inclusions[2].shape.center);
  expect_apart(set, gap);
  for (size_t i = 0; i < set.inclusions.size(); ++i) {
    const Shape& a = set.inclusions[i].shape;
    const Shape& a0 = before.inclusions[i].shape;
    EXPECT_EQ(a.half_axis, a0.half_axis);
    EXPECT_EQ(a.semi_axes, a0.semi_axes);
  }
  // The same set, nudged again: the same result (the order is the index order).
  InclusionSet again = before;
  nudge_off_cell(&again, o, gap);
  for (size_t i = 0; i < set.inclusions.size(); ++i)
    EXPECT_EQ(again.inclusions[i].shape.center, set.inclusions[i].shape.center);
  // A fibre whose band along z is wider than the moves allowed (half length 0.4, 7 degrees off
  // the faces, radius 0.01: 4.9 radii each way from the face through its middle) stays, and
  // is counted.
  InclusionSet wide =
      one_of(Shape::cylinder(Vec3(0.5, 0.5, 0.0), 0.01,
                             0.4 * Vec3(std::cos(7 * M_PI / 180), 0.0, std::sin(7 * M_PI / 180))));
  ASSERT_LT(face_clearance(wide, o), kGoodClearance);
  const Nudged m = nudge_off_cell(&wide, o, gap);
  EXPECT_EQ(m.moved, 0);
  EXPECT_EQ(m.stuck, 1);
  EXPECT_EQ(wide.inclusions[0].shape.center, Vec3(0.5, 0.5, 0.0));
}

// A fibre whose end disk a face crosses at 22 degrees, 0.2 radius from the disk's centre, cuts
// off a chip of the end (beyond the face) as thin as a fifth of the radius: in the 2,484-fibre
// scene at chord error 0.1 such a chip left four elements of 2.1-4.7 degrees. A disk within 30
// degrees of the face counts as grazing it (its span along the normal), so the fibre is moved
// off the face, by a fraction of its radius.
TEST(TetMesh, AFaceCrossingAnEndDiskAt22DegreesGrazesItAndTheFibreIsNudgedOff) {
  const double r = 0.02, h = 0.2, gap = 0.002;
  const double top = 1.0 - 0.2 * r;  // the upper end's centre
  InclusionSet set = one_of(Shape::sphere(Vec3(0.5, 0.5, 0.5), 0.01));
  set.inclusions = {tilted_fibre(68.0, r, h, top - h * std::sin(68.0 * M_PI / 180.0))};
  const Vec3 o = set.box.origin;
  // The rim's extreme lies 0.175 radius beyond the face: clear by that measure alone.
  ASSERT_LT(face_clearance(set, o), kGoodClearance);
  const InclusionSet before = set;
  const Nudged n = nudge_off_cell(&set, o, gap);
  EXPECT_EQ(n.moved, 1);
  EXPECT_EQ(n.stuck, 0);
  EXPECT_GE(std::min(face_clearance(set, o), edge_clearance(set, o)), kGoodClearance);
  const Vec3 d = set.inclusions[0].shape.center - before.inclusions[0].shape.center;
  EXPECT_LE(d.norm(), 1.5 * r);
  EXPECT_EQ(set.inclusions[0].shape.half_axis, before.inclusions[0].shape.half_axis);
}

// Twelve fibres 7 degrees off the z faces at heights k / 12 (as in the test above): their
// mantle lines' spans cover every height, so every cell grazes some of them. After the rounds,
// the cell chosen for the moved set grazes none, nothing is within min_gap of another, and
// another round at that cell moves nothing.
TEST(TetMesh, InclusionsEveryCellGrazesAreNudgedOffTheCellChosenAfterwards) {
  const double r = 0.02, gap = 0.002;
  InclusionSet set = shallow_fibres(r);
  const InclusionSet before = set;
  const Vec3 o0 = cell_origin(set);
  ASSERT_LT(std::min(face_clearance(set, o0), edge_clearance(set, o0)), kGoodClearance);
  const Nudged n = nudge_off_chosen_cell(&set, gap);
  EXPECT_GE(n.moved, 1);
  EXPECT_EQ(n.stuck, 0);
  const Vec3 o = cell_origin(set);
  EXPECT_GE(std::min(face_clearance(set, o), edge_clearance(set, o)), kGoodClearance);
  for (size_t i = 0; i < set.inclusions.size(); ++i) {
    const Shape& a = set.inclusions[i].shape;
    EXPECT_EQ(a.half_axis, before.inclusions[i].shape.half_axis) << i;
    Vec3 moved = a.center - before.inclusions[i].shape.center;  // (periodic)
    for (int k = 0; k < 3; ++k) moved[k] -= std::round(moved[k]);
    EXPECT_LE(moved.norm(), 4 * 1.5 * r + 1e-12) << i;
  }
  expect_apart(set, gap);
  InclusionSet again = set;
  EXPECT_EQ(nudge_off_cell(&again, o, gap).moved, 0);
}

}  // namespace
}  // namespace rvegen
