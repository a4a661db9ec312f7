// The tetrahedral mesh and its topology, without Gmsh: conformity, merged nodes, periodic
// images on the box faces, second-order nodes (mesh_topology.cpp, tet_mesh.hpp).
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

namespace rvegen {
namespace {

using namespace femesh_test;

TEST(TetMesh, ACubeOfSixTetrahedraConforms) {
  EXPECT_NO_THROW(check_conforming(kuhn_cube()));
}

TEST(TetMesh, ASecondNodeAtOnePositionCracksTheMeshAndIsMerged) {
  TetMesh m = kuhn_cube();
  // The centre diagonal's end 7 given again as node 8, used by one element: a crack along the
  // faces that element shares with its neighbours.
  m.nodes.push_back(m.nodes[7]);
  std::replace(m.tets[2].begin(), m.tets[2].end(), 7, 8);
  // And a node no element uses.
  m.nodes.push_back(Vec3(0.5, 0.5, 0.5));
  EXPECT_THROW(check_conforming(m), MeshError);
  EXPECT_EQ(merge_coincident_nodes(&m), 1);
  EXPECT_EQ(m.nodes.size(), 8u);
  EXPECT_EQ(std::count(m.tets[2].begin(), m.tets[2].end(), 7), 1);
  EXPECT_NO_THROW(check_conforming(m));
}

// Gmsh placed a node of a curve on the upper face x (273 ellipsoids at 0.4, seed 16) 1.3e-8 off
// the translate of its image on the lower face, and the periodic pairs (within 1e-9 of the box)
// then missed it. Nodes on upper faces are put at their images' translates; those without an
// image near stay where they are.
TEST(TetMesh, NodesOnUpperFacesArePutAtTheTranslatesOfTheirImages) {
  TetMesh m;
  m.box.origin = Vec3(-0.5, 0.25, 0.0);
  m.box.size = Vec3(1, 1, 2);
  m.nodes = {Vec3(-0.5, 0.6, 0.7),                   // 0: on the lower face x
             Vec3(0.5, 0.6 - 9.4e-9, 0.7 - 8.8e-9),  // 1: its image, 1.3e-8 off
             Vec3(-0.5, 0.25, 1.1),                  // 2: on the lower edge of x and y
             Vec3(0.5, 1.25, 1.1 + 4e-9),            // 3: its image on the upper edge
             Vec3(0.5, 0.9, 0.3),                    // 4: on the face x, no image near
             Vec3(-0.5, 0.9, 0.3 + 2e-6),            //    (this one is 2e-6 away)
             Vec3(0.1, 0.6, 0.7),                    // 6: inside
             Vec3(-0.5, 0.3, 0.2),                   // 7: on the lower face x
             Vec3(0.5, 0.3 + 1e-12, 0.2)};           // 8: its image, a rounding error off
  const std::vector<Vec3> before = m.nodes;
  EXPECT_EQ(snap_periodic_nodes(&m), 2);  // 1 and 3 (8 is moved, not counted)
  EXPECT_EQ(m.nodes[1], Vec3(0.5, 0.6, 0.7));
  EXPECT_EQ(m.nodes[3], Vec3(0.5, 1.25, 1.1));
  EXPECT_EQ(m.nodes[8], Vec3(0.5, 0.3, 0.2));
  for (int n : {0, 2, 4, 5, 6, 7}) EXPECT_EQ(m.nodes[n], before[n]) << n;
  EXPECT_EQ(snap_periodic_nodes(&m), 0);  // nothing left to move
}

TEST(TetMesh, AMissingElementIsAHole) {
  TetMesh m = kuhn_cube();
  m.tets.pop_back();
  EXPECT_THROW(check_conforming(m), MeshError);
}

TEST(TetMesh, AnEmptyOrInvertedMeshDoesNotFillTheBox) {
  TetMesh empty = kuhn_cube();
  empty.tets.clear();
  EXPECT_THROW(check_conforming(empty), MeshError);
  TetMesh inverted = kuhn_cube();
  std::swap(inverted.tets[0][0], inverted.tets[0][1]);
  EXPECT_THROW(check_conforming(inverted), MeshError);
}

TEST(TetMesh, AnElementCollapsedByTheMergeIsRefused) {
  TetMesh m = kuhn_cube();
  m.nodes.push_back(m.nodes[0]);  // node 8 at node 0's place, in an element with node 0
  m.tets[1] = {0, 8, 5, 7};
  EXPECT_THROW(merge_coincident_nodes(&m), MeshError);
}

// Second order: one node in the middle of each edge, shared by the elements around it. The cube
// of six has 19 edges: 12 of the cube, 6 face diagonals, the centre diagonal.
TEST(TetMesh, SecondOrderPutsOneNodeInTheMiddleOfEachEdge) {
  TetMesh m = kuhn_cube();
  add_midside_nodes(&m);
  ASSERT_EQ(m.mid.size(), m.tets.size());
  EXPECT_EQ(m.nodes.size(), 8u + 19u);
  std::vector<int> uses(m.nodes.size(), 0);
  for (size_t e = 0; e < m.tets.size(); ++e) {
    for (int k = 0; k < 6; ++k) {
      const int32_t n = m.mid[e][k];
      ASSERT_GE(n, 8);
      ++uses[n];
      const Vec3 middle =
          0.5 * (m.nodes[m.tets[e][kTetEdges[k][0]]] + m.nodes[m.tets[e][kTetEdges[k][1]]]);
      EXPECT_EQ(m.nodes[n], middle) << "element " << e << ", edge " << k;
    }
  }
  // Every midside node is used; the centre diagonal's by all six elements.
  for (size_t n = 8; n < m.nodes.size(); ++n) EXPECT_GT(uses[n], 0) << n;
  EXPECT_EQ(*std::max_element(uses.begin(), uses.end()), 6);
  // The corners are untouched, and a second call adds nothing.
  EXPECT_EQ(m.nodes[7], Vec3(1, 1, 1));
  add_midside_nodes(&m);
  EXPECT_EQ(m.nodes.size(), 27u);
  EXPECT_NO_THROW(check_conforming(m));
}

}  // namespace
}  // namespace rvegen
