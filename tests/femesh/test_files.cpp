// The tetrahedral mesh's files (io/fe_mesh.cpp): nodes, elements and periodic pairs in every
// format.
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
#include "rvegen/io/fe_mesh.hpp"
#include "rvegen/io/writers.hpp"

namespace rvegen {
namespace {

using namespace femesh_test;

// What a writer puts in a FILE, as a string.
std::string written(const std::function<void(std::FILE*)>& write) {
  char* buf = nullptr;
  size_t len = 0;
  std::FILE* f = open_memstream(&buf, &len);
  write(f);
  std::fclose(f);
  std::string text(buf, len);
  std::free(buf);
  return text;
}

// The lines of `text` after the line `head` up to the next keyword line (starting with '*' or
// '$'), counted when `keep` says so.
int lines_after(const std::string& text, const std::string& head,
                const std::function<bool(const std::string&)>& keep) {
  size_t at = text.find("\n" + head + "\n");
  if (at == std::string::npos) return -1;
  at += head.size() + 2;
  int n = 0;
  while (at < text.size() && text[at] != '*' && text[at] != '$') {
    const size_t end = text.find('\n', at);
    if (keep(text.substr(at, end - at))) ++n;
    at = end + 1;
  }
  return n;
}

// The mesh files and the decks of a tetrahedral mesh, first and second order: every node,
// element and periodic pair reaches each format. (The command-line test writes them from real
// meshes; this one also runs in the sanitizer build, where that test does not.)
TEST(TetMeshFiles, NodesElementsAndPeriodicPairsReachEveryFormat) {
  InclusionSet none;
  none.box.size = Vec3(1, 1, 1);
  for (const int order : {1, 2}) {
    TetMesh m = kuhn_cube();
    m.phases = phase_table(none);
    if (order == 2) add_midside_nodes(&m);
    // Each node on an upper face tied to the node at its coordinates brought to the lower ends.
    for (size_t k = 0; k < m.nodes.size(); ++k) {
      const Vec3 image = m.nodes[k].unaryExpr([](double x) { return x == 1.0 ? 0.0 : x; });
      if (image == m.nodes[k]) continue;
      const auto at = std::find(m.nodes.begin(), m.nodes.end(), image);
      ASSERT_NE(at, m.nodes.end());
      m.periodic.push_back({static_cast<int32_t>(k), static_cast<int32_t>(at - m.nodes.begin())});
    }
    const size_t pairs = m.periodic.size();
    EXPECT_EQ(pairs, order == 2 ? 19u : 7u);
    const int nodes = order == 2 ? 27 : 8;
    const std::string inp = written([&](std::FILE* f) { write_abaqus_tet_mesh(m, f); });
    const auto any = [](const std::string&) { return true; };
    // The mesh's nodes and the three reference nodes; the six elements in the matrix's set.
    EXPECT_EQ(lines_after(inp, "*NODE, NSET=ALLNODES", any), nodes + 3) << order;
    const std::string type = order == 2 ? "C3D10" : "C3D4";
    EXPECT_EQ(lines_after(inp, "*ELEMENT, TYPE=" + type + ", ELSET=matrix", any), 6) << inp;
    EXPECT_NE(inp.find("*NSET, NSET=ORIGIN\n1\n"), std::string::npos);
    const std::string msh = written([&](std::FILE* f) { write_gmsh_tet_mesh(m, f); });
    EXPECT_NE(msh.find("$Periodic"), std::string::npos);
    EXPECT_NE(msh.find("$EndPeriodic"), std::string::npos);
    const std::string vtu = written([&](std::FILE* f) { write_tet_mesh_vtu(m, f); });
    EXPECT_NE(vtu.find("NumberOfPoints=\"" + std::to_string(nodes) + "\" NumberOfCells=\"6\""),
              std::string::npos)
        << vtu.substr(0, 400);
    // The decks: one equation per periodic pair and degree of freedom (a line with no comma
    // gives an equation's number of terms).
    Scene scene;
    scene.box = none.box;
    Material matrix;
    matrix.conductivity = 2.0;
    matrix.young = 3.0;
    matrix.poisson = 0.3;
    scene.materials = {{"matrix", matrix}};
    const auto equation = [](const std::string& line) {
      return line.find(',') == std::string::npos;
    };
    for (const bool elastic : {false, true}) {
      const std::string deck = abaqus_tet_deck(scene, none, m, elastic);
      EXPECT_EQ(lines_after(deck, "*EQUATION", equation),
                static_cast<int>(pairs) * (elastic ? 3 : 1))
          << deck;
    }
  }
}

}  // namespace
}  // namespace rvegen
