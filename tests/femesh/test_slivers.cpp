// Sliver repair (slivers.cpp, remake_slivers.cpp): nodes moved inside a region, on a box face
// with their image and along an interface; nodes inserted; elements remade by flips and
// collapses; the repairs' rounds. Hand-made meshes, without Gmsh.
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
#include "rvegen/model/neighbours.hpp"

namespace rvegen {
namespace {

using namespace femesh_test;

// The unit cube as twelve tetrahedra from a node inside it to the halves of its faces.
TetMesh cube_around(const Vec3& inside) {
  TetMesh m;
  m.box.origin = Vec3(0, 0, 0);
  m.box.size = Vec3(1, 1, 1);
  for (int k = 0; k < 8; ++k) m.nodes.push_back(Vec3(k & 1, (k >> 1) & 1, (k >> 2) & 1));
  m.nodes.push_back(inside);
  for (int a = 0; a < 3; ++a) {
    const int b = 1 << ((a + 1) % 3), c = 1 << ((a + 2) % 3);
    for (int end : {0, 1 << a}) {
      const int q[4] = {end, end | b, end | b | c, end | c};
      for (const auto& tri : {std::array<int, 3>{q[0], q[1], q[2]}, {q[0], q[2], q[3]}}) {
        std::array<int32_t, 4> t = {tri[0], tri[1], tri[2], 8};
        if (tet_volume(m.nodes, t) < 0.0) std::swap(t[0], t[1]);
        m.tets.push_back(t);
        m.phase.push_back(0);
        m.inclusion_id.push_back(-1);
      }
    }
  }
  return m;
}

double least_angle(const TetMesh& m) {
  TetQuality q = tet_quality(m);
  return q.min_dihedral;
}

// The unit cube as tetrahedra from its centre to its faces' triangles: the faces z = 0 and
// z = 1 fanned about a node at (x, y) on each (images of each other), the others halved.
TetMesh cube_with_face_node(double x, double y) {
  TetMesh m;
  m.box.origin = Vec3(0, 0, 0);
  m.box.size = Vec3(1, 1, 1);
  for (int k = 0; k < 8; ++k) m.nodes.push_back(Vec3(k & 1, (k >> 1) & 1, (k >> 2) & 1));
  m.nodes.push_back(Vec3(0.5, 0.5, 0.5));  // 8: the centre
  m.nodes.push_back(Vec3(x, y, 0.0));      // 9: on the face z = 0
  m.nodes.push_back(Vec3(x, y, 1.0));      // 10: its image
  auto add = [&](std::array<int32_t, 4> t) {
    if (tet_volume(m.nodes, t) < 0.0) std::swap(t[0], t[1]);
    m.tets.push_back(t);
    m.phase.push_back(0);
    m.inclusion_id.push_back(-1);
  };
  for (int a = 0; a < 3; ++a) {
    const int b = 1 << ((a + 1) % 3), c = 1 << ((a + 2) % 3);
    for (int end : {0, 1 << a}) {
      const int q[4] = {end, end | b, end | b | c, end | c};
      if (a == 2) {
        const int32_t f = end ? 10 : 9;
        for (int k = 0; k < 4; ++k) add({q[k], q[(k + 1) % 4], f, 8});
      } else {
        add({q[0], q[1], q[2], 8});
        add({q[0], q[2], q[3], 8});
      }
    }
  }
  return m;
}

// The element faces no other element shares (node numbers sorted).
std::set<std::array<int32_t, 3>> boundary_faces(const TetMesh& m) {
  std::map<std::array<int32_t, 3>, int> seen;
  for (const auto& t : m.tets) {
    for (int k = 0; k < 4; ++k) {
      std::array<int32_t, 3> f = {t[(k + 1) % 4], t[(k + 2) % 4], t[(k + 3) % 4]};
      std::sort(f.begin(), f.end());
      ++seen[f];
    }
  }
  std::set<std::array<int32_t, 3>> once;
  for (const auto& [f, n] : seen) {
    if (n == 1) once.insert(f);
  }
  return once;
}

// An octahedron cut into a sliver: its equator's four points lifted and lowered by turns by
// `lift`, its apexes at z = 1 and z = -bottom; the elements (the sliver, the two above it, the
// two below) in the inclusions `ids` (-1: the matrix, phase 0; others phase 1). The mesh's box
// is the unit box: the nodes at 0 or 1 lie on its faces.
TetMesh octahedron_with_sliver(double lift, double bottom, const std::array<int, 5>& ids) {
  TetMesh m;
  m.nodes = {{1, 0, lift},   {0, 1, -lift}, {-1, 0, lift},
             {0, -1, -lift}, {0, 0, 1},     {0, 0, -bottom}};
  const std::array<int32_t, 4> tets[5] = {
      {0, 1, 2, 3},  // the sliver
      {0, 2, 1, 4},
      {0, 2, 3, 4},  // the faces the raised points share, to the upper apex
      {1, 3, 0, 5},
      {1, 3, 2, 5}};  // the lowered points' faces, to the lower apex
  for (int k = 0; k < 5; ++k) {
    std::array<int32_t, 4> t = tets[k];
    if (tet_volume(m.nodes, t) < 0.0) std::swap(t[0], t[1]);
    m.tets.push_back(t);
    m.phase.push_back(ids[k] < 0 ? 0 : 1);
    m.inclusion_id.push_back(ids[k]);
  }
  return m;
}

// A node inside the matrix, near a face, flattens the elements on that face to slivers; it is
// moved to where they are lifted over 5 degrees, the box's faces and volume as they were. A node
// on an interface (two regions meet at it) or on a box face stays.
TEST(TetMesh, SliversAreLiftedByMovingTheNodesInsideOneRegion) {
  TetMesh m = cube_around(Vec3(0.45, 0.55, 0.02));
  ASSERT_NO_THROW(check_conforming(m));
  ASSERT_LT(least_angle(m), 5.0);
  EXPECT_EQ(lift_slivers(&m, InclusionSet{}), 1);
  EXPECT_GE(least_angle(m), 5.0);
  EXPECT_NO_THROW(check_conforming(m));
  for (int k = 0; k < 8; ++k) EXPECT_EQ(m.nodes[k], Vec3(k & 1, (k >> 1) & 1, (k >> 2) & 1));

  // The same node on an interface: half the elements in an inclusion.
  TetMesh two = cube_around(Vec3(0.45, 0.55, 0.02));
  for (size_t e = 0; e < 6; ++e) two.inclusion_id[e] = 3, two.phase[e] = 1;
  EXPECT_EQ(lift_slivers(&two, InclusionSet{}), 0);
  EXPECT_EQ(two.nodes[8], Vec3(0.45, 0.55, 0.02));
  // On a box face (a degenerate cube: the slivers stay).
  TetMesh face = cube_around(Vec3(0.45, 0.55, 0.0));
  EXPECT_EQ(lift_slivers(&face, InclusionSet{}), 0);
}

// A node on a box face near one of its edges flattens the elements there to slivers: it moves
// in the face, and its image on the opposite face with it (the faces stay translates of each
// other); on a curved interface, along the face's cut of that surface.
TEST(TetMesh, ANodeOnABoxFaceSlidesInItWithItsImage) {
  TetMesh m = cube_with_face_node(0.5, 0.01);
  ASSERT_NO_THROW(check_conforming(m));
  ASSERT_LT(least_angle(m), 5.0);
  EXPECT_GE(lift_slivers(&m, InclusionSet{}), 1);
  EXPECT_GE(least_angle(m), 5.0);
  EXPECT_NO_THROW(check_conforming(m));
  EXPECT_EQ(m.nodes[9].z(), 0.0);
  EXPECT_EQ(m.nodes[10].z(), 1.0);
  EXPECT_EQ(m.nodes[9].x(), m.nodes[10].x());
  EXPECT_EQ(m.nodes[9].y(), m.nodes[10].y());
  EXPECT_GT(m.nodes[9].y(), 0.01);
  for (int k = 0; k < 8; ++k) EXPECT_EQ(m.nodes[k], Vec3(k & 1, (k >> 1) & 1, (k >> 2) & 1));

  // The node where the face cuts a sphere (centre (0.5, 0.5, 0), radius 0.49): the elements
  // of the fan's two triangles on the side of x = 1 are the sphere's. It slides along the
  // circle, away from the edge.
  InclusionSet set;
  set.box = m.box;
  Inclusion ball;
  ball.id = 0;
  ball.shape = Shape::sphere(Vec3(0.5, 0.5, 0.0), 0.49);
  set.inclusions.push_back(ball);
  TetMesh cut = cube_with_face_node(0.5, 0.01);
  cut.phases = phase_table(set);
  for (size_t e = 0; e < cut.tets.size(); ++e) {
    const auto& t = cut.tets[e];
    const bool fan = std::count(t.begin(), t.end(), 9) || std::count(t.begin(), t.end(), 10);
    bool right = false;
    for (int32_t n : t) right = right || (n < 8 && (n & 1) && !((n >> 1) & 1));
    if (fan && right) cut.inclusion_id[e] = 0, cut.phase[e] = 1;
  }
  ASSERT_LT(least_angle(cut), 5.0);
  EXPECT_GE(lift_slivers(&cut, set), 1);
  EXPECT_GT(least_angle(cut), least_angle(cube_with_face_node(0.5, 0.01)));
  EXPECT_NO_THROW(check_conforming(cut));
  EXPECT_NEAR((cut.nodes[9] - Vec3(0.5, 0.5, 0.0)).norm(), 0.49, 1e-12);
  EXPECT_EQ(cut.nodes[9].z(), 0.0);
  EXPECT_EQ(cut.nodes[10].z(), 1.0);
  EXPECT_EQ(cut.nodes[9].x(), cut.nodes[10].x());
  EXPECT_EQ(cut.nodes[9].y(), cut.nodes[10].y());
  EXPECT_GT(cut.nodes[9].y(), 0.01);
}

// The unit cube, its face z = 0 triangulated along the diagonal (0,0)-(1,1) and the elements
// above it along the other, with the flat element of its four corners between (what the volume
// mesher now and then leaves); the face z = 1 triangulated as z = 0 is, its two elements
// sharing the centre. The flat element goes, z = 0 takes the other diagonal, and z = 1 takes it
// too by a flip of its two elements: the faces stay translates of each other, every element is
// positive and the mesh conforms.
TEST(TetMesh, AFlatElementInABoxFaceIsRemovedAndTheOppositeFaceFlipped) {
  TetMesh m;
  m.box.origin = Vec3(0, 0, 0);
  m.box.size = Vec3(1, 1, 1);
  for (int k = 0; k < 8; ++k) m.nodes.push_back(Vec3(k & 1, (k >> 1) & 1, (k >> 2) & 1));
  m.nodes.push_back(Vec3(0.5, 0.5, 0.5));  // 8: the centre
  auto add = [&](std::array<int32_t, 4> t) {
    if (tet_volume(m.nodes, t) < 0.0) std::swap(t[0], t[1]);
    m.tets.push_back(t);
    m.phase.push_back(0);
    m.inclusion_id.push_back(-1);
  };
  m.tets.push_back({0, 1, 3, 2});  // flat, in z = 0
  m.phase.push_back(0);
  m.inclusion_id.push_back(-1);
  add({0, 1, 2, 8});  // above z = 0, along the diagonal 1-2
  add({1, 3, 2, 8});
  add({4, 5, 7, 8});  // above z = 1's triangles (4 5 7) and (4 7 6), along 4-7 as z = 0's
  add({4, 7, 6, 8});
  for (int a = 0; a < 2; ++a) {  // the faces x and y, halved
    const int b = 1 << ((a + 1) % 3), c = 1 << ((a + 2) % 3);
    for (int end : {0, 1 << a}) {
      const int q[4] = {end, end | b, end | b | c, end | c};
      add({q[0], q[1], q[2], 8});
      add({q[0], q[2], q[3], 8});
    }
  }
  // The triangles of the face at z (sorted node positions' x, y).
  auto face = [&](const TetMesh& mesh, double z) {
    std::set<std::vector<std::pair<double, double>>> out;
    for (const auto& f : boundary_faces(mesh)) {
      bool in = true;
      std::vector<std::pair<double, double>> xy;
      for (int32_t i : f) {
        in = in && mesh.nodes[i].z() == z;
        xy.emplace_back(mesh.nodes[i].x(), mesh.nodes[i].y());
      }
      std::sort(xy.begin(), xy.end());
      if (in) out.insert(xy);
    }
    return out;
  };
  ASSERT_EQ(least_angle(m), 0.0);
  ASSERT_EQ(face(m, 0.0), face(m, 1.0));
  EXPECT_THROW(check_conforming(m), MeshError);  // an element not positive
  EXPECT_EQ(remove_flat_face_elements(&m), 1);
  EXPECT_EQ(m.tets.size(), 12u);
  for (const auto& t : m.tets) EXPECT_GT(tet_volume(m.nodes, t), 0.0);
  EXPECT_EQ(face(m, 0.0), face(m, 1.0));
  EXPECT_EQ(face(m, 0.0).size(), 2u);
  EXPECT_NO_THROW(check_conforming(m));
  EXPECT_EQ(remove_flat_face_elements(&m), 0);
}

// An octahedron cut into a sliver (its equator's four points, lifted and lowered by turns)
// and the four elements from its apexes to the sliver's faces: every node on the region's
// boundary, so none may move. A node at the sliver's circumcentre, joined to the octahedron's
// eight faces, lifts it; the faces and the volume stay. Where the four elements belong to
// another region, the sliver alone is no better with a node inside, and stays.
TEST(TetMesh, ANodeInsertedInARegionLiftsASliverWhoseNodesCannotMove) {
  auto octahedron = [](int apex_region) {
    const int a = apex_region;
    return octahedron_with_sliver(0.02, 1.0, {-1, a, a, a, a});
  };
  auto volume = [](const TetMesh& m) {
    double v = 0.0;
    for (const auto& t : m.tets) v += tet_volume(m.nodes, t);
    return v;
  };
  TetMesh m = octahedron(-1);
  const auto faces = boundary_faces(m);
  const double v = volume(m);
  ASSERT_EQ(faces.size(), 8u);
  ASSERT_LT(least_angle(m), 5.0);
  EXPECT_EQ(lift_slivers(&m, InclusionSet{}), 0);  // no node inside the region
  EXPECT_EQ(insert_nodes_in_slivers(&m), 1);
  EXPECT_EQ(m.nodes.size(), 7u);
  EXPECT_EQ(m.tets.size(), 8u);
  EXPECT_GT(least_angle(m), 30.0);
  EXPECT_EQ(boundary_faces(m), faces);
  EXPECT_NEAR(volume(m), v, 1e-12);
  for (const auto& t : m.tets) EXPECT_GT(tet_volume(m.nodes, t), 0.0);

  TetMesh two = octahedron(3);
  EXPECT_EQ(insert_nodes_in_slivers(&two), 0);
  EXPECT_EQ(two.tets.size(), 5u);
  EXPECT_EQ(two.nodes.size(), 6u);
}

// The octahedron above, every element in one region: no node may move, but the elements
// around one of the sliver's edges (the sliver and the two above it, which share the raised
// points) remade as two about the lowered points' edge lift it, with no node added.
TEST(TetMesh, ASliverIsRemadeWithItsNeighboursByAFlip) {
  TetMesh m = octahedron_with_sliver(0.02, 1.0, {-1, -1, -1, -1, -1});
  m.box.origin = Vec3(-2, -2, -2);  // no node on a box face
  m.box.size = Vec3(4, 4, 4);
  const auto faces = boundary_faces(m);
  ASSERT_LT(least_angle(m), 5.0);
  EXPECT_EQ(remake_slivers(&m), 1);
  EXPECT_EQ(m.nodes.size(), 6u);
  EXPECT_EQ(m.tets.size(), 4u);
  EXPECT_GT(least_angle(m), 30.0);
  EXPECT_EQ(boundary_faces(m), faces);
  double v = 0.0;
  for (const auto& t : m.tets) v += tet_volume(m.nodes, t);
  EXPECT_NEAR(v, 4.0 / 3.0, 1e-12);  // the octahedron's, |x| + |y| + |z| <= 1 to the lift
  EXPECT_EQ(remake_slivers(&m), 0);
}

// The sliver lies on an interface: above it an inclusion's two elements, below it the matrix's
// (the sliver's) two, their apex near the equator so that remaking the matrix side alone gives
// at best 25 degrees. Flipping the interface's edge between the raised points to the one between
// the lowered points (the four points nearly in one plane) gives the inclusion the sliver's
// volume and every element over 50 degrees. Where the interface bends at that edge (the points
// raised and lowered by 0.35), it stays.
TEST(TetMesh, ASliverFlatOnAnInterfaceGoesByFlippingTheInterfaceEdge) {
  auto octahedron = [](double lift) {
    TetMesh m = octahedron_with_sliver(lift, 0.3, {-1, 3, 3, -1, -1});
    m.box.origin = Vec3(-2, -2, -2);  // no node on a box face
    m.box.size = Vec3(4, 4, 4);
    return m;
  };
  auto volume_of = [](const TetMesh& m, int id) {
    double v = 0.0;
    for (size_t e = 0; e < m.tets.size(); ++e) {
      if (m.inclusion_id[e] == id) v += tet_volume(m.nodes, m.tets[e]);
    }
    return v;
  };
  // The faces between the two regions.
  auto interface = [](const TetMesh& m) {
    std::map<std::array<int32_t, 3>, std::set<int>> by;
    for (size_t e = 0; e < m.tets.size(); ++e) {
      const auto& t = m.tets[e];
      for (int k = 0; k < 4; ++k) {
        std::array<int32_t, 3> f = {t[(k + 1) % 4], t[(k + 2) % 4], t[(k + 3) % 4]};
        std::sort(f.begin(), f.end());
        by[f].insert(m.inclusion_id[e]);
      }
    }
    std::set<std::array<int32_t, 3>> out;
    for (const auto& [f, ids] : by) {
      if (ids.size() == 2) out.insert(f);
    }
    return out;
  };
  TetMesh m = octahedron(0.02);
  const double sliver = tet_volume(m.nodes, m.tets[0]);
  const double inclusion = volume_of(m, 3), matrix = volume_of(m, -1);
  const auto faces = boundary_faces(m);
  ASSERT_LT(least_angle(m), 5.0);
  using Face = std::array<int32_t, 3>;
  ASSERT_EQ(interface(m), (std::set<Face>{{0, 1, 2}, {0, 2, 3}}));
  EXPECT_EQ(remake_slivers(&m), 1);
  EXPECT_EQ(m.tets.size(), 4u);
  EXPECT_GT(least_angle(m), 20.0);
  EXPECT_EQ(boundary_faces(m), faces);
  EXPECT_EQ(interface(m), (std::set<Face>{{0, 1, 3}, {1, 2, 3}}));
  EXPECT_NEAR(volume_of(m, 3), inclusion + sliver, 1e-12);
  EXPECT_NEAR(volume_of(m, -1), matrix - sliver, 1e-12);

  // Bent: the lines between the raised and the lowered points 0.7 apart (a third of the
  // diagonals), the lower apex at -1. Every element under 30 degrees counts: the interface flip
  // would do best (it is taken when the flatness bound is lifted), but it is refused, and the
  // matrix side alone is remade, its interface faces kept.
  TetMesh bent = octahedron_with_sliver(0.35, 1.0, {-1, 3, 3, -1, -1});
  bent.box = m.box;
  const auto bent_interface = interface(bent);
  ASSERT_EQ(bent_interface.size(), 2u);
  EXPECT_EQ(remake_slivers(&bent, 30.0), 1);
  EXPECT_EQ(interface(bent), bent_interface);
}

// The cube about its centre (twelve elements from the centre to the faces' triangles), with a
// second node a hair (0.02) from the centre inside one of them: the elements about the short
// edge are needles. The second node is collapsed into the centre, which gives the twelve back.
// A node on a box face is not collapsed.
TEST(TetMesh, ANodeAHairFromAnotherIsCollapsedIntoIt) {
  TetMesh m;
  for (int i = 0; i < 8; ++i) m.nodes.emplace_back(i & 1, (i >> 1) & 1, (i >> 2) & 1);
  m.nodes.emplace_back(0.5, 0.5, 0.5);
  const int quads[6][4] = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    for (const std::array<int32_t, 4> t0 : {std::array<int32_t, 4>{q[0], q[1], q[2], 8},
                                            std::array<int32_t, 4>{q[0], q[2], q[3], 8}}) {
      auto t = t0;
      if (tet_volume(m.nodes, t) < 0.0) std::swap(t[0], t[1]);
      m.tets.push_back(t);
      m.phase.push_back(0);
      m.inclusion_id.push_back(-1);
    }
  }
  const double before = least_angle(m);
  const auto faces = boundary_faces(m);
  TetMesh split = m;
  const auto host = split.tets[0];
  Vec3 centroid = Vec3::Zero();
  for (int32_t n : host) centroid += 0.25 * split.nodes[n];
  split.nodes.push_back(split.nodes[8] + 0.02 * (centroid - split.nodes[8]).normalized());
  split.tets.erase(split.tets.begin());
  split.phase.pop_back();
  split.inclusion_id.pop_back();
  for (int k = 0; k < 4; ++k) {
    auto t = host;
    t[k] = 9;
    ASSERT_GT(tet_volume(split.nodes, t), 0.0);
    split.tets.push_back(t);
    split.phase.push_back(0);
    split.inclusion_id.push_back(-1);
  }
  ASSERT_EQ(split.tets.size(), 15u);
  ASSERT_NO_THROW(check_conforming(split));
  ASSERT_LT(least_angle(split), 5.0);
  EXPECT_EQ(remake_slivers(&split), 1);
  EXPECT_EQ(split.nodes.size(), 9u);
  EXPECT_EQ(split.tets.size(), 12u);
  EXPECT_NEAR(least_angle(split), before, 1e-9);
  EXPECT_EQ(boundary_faces(split), faces);
  EXPECT_NO_THROW(check_conforming(split));

  // Corner 1 slid along the cube's edge to 0.02 from corner 0: both nodes of the short edge lie
  // on box faces, so neither goes.
  TetMesh corner = m;
  corner.nodes[1] = Vec3(0.02, 0.0, 0.0);
  corner.box.size = Vec3(1, 1, 1);
  const double corner_least = least_angle(corner);
  ASSERT_LT(corner_least, 5.0);
  const size_t nodes = corner.nodes.size();
  remake_slivers(&corner);
  EXPECT_EQ(corner.nodes.size(), nodes);  // neither corner goes
}

// The repairs run in rounds: none on a mesh with no element under 5 degrees; one where a round
// lifts them all (a node inside the region moved, or elements remade where no node may move); and a
// round that changes nothing ends them (the sliver between two regions, which no pass may lift).
TEST(TetMesh, SliverRepairsRunInRoundsUntilNoneIsLeftOrARoundLiftsNone) {
  TetMesh clean = kuhn_cube();
  const std::vector<Vec3> nodes = clean.nodes;
  EXPECT_EQ(repair_slivers(&clean, InclusionSet{}), 0);
  EXPECT_EQ(clean.nodes, nodes);

  TetMesh moved = cube_around(Vec3(0.45, 0.55, 0.02));
  ASSERT_LT(least_angle(moved), 5.0);
  EXPECT_EQ(repair_slivers(&moved, InclusionSet{}), 1);
  EXPECT_EQ(moved.relocated_nodes, 1);
  EXPECT_GE(least_angle(moved), 5.0);

  TetMesh remade = octahedron_with_sliver(0.02, 1.0, {-1, -1, -1, -1, -1});
  ASSERT_LT(least_angle(remade), 5.0);
  EXPECT_EQ(repair_slivers(&remade, InclusionSet{}), 1);
  EXPECT_EQ(remade.relocated_nodes, 0);
  EXPECT_EQ(remade.remade_slivers, 1);
  EXPECT_GT(least_angle(remade), 30.0);

  TetMesh stuck = octahedron_with_sliver(0.02, 1.0, {-1, 3, 3, 3, 3});
  ASSERT_LT(least_angle(stuck), 5.0);
  EXPECT_EQ(repair_slivers(&stuck, InclusionSet{}), 1);
  EXPECT_LT(least_angle(stuck), 5.0);
  EXPECT_EQ(stuck.tets.size(), 5u);
}

}  // namespace
}  // namespace rvegen
