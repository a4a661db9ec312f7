// The mesh and its topology, without Gmsh: the faces' keys, nodes no element uses, the
// periodic images of nodes on the box faces (snapped to their translates, merged where the
// mesher left two at one position), the conformity check, the midside nodes of second-order
// elements and the elements' least dihedral angles.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <set>
#include <unordered_map>
#include <vector>

#include "rvegen/femesh/mesh_parts.hpp"
#include "rvegen/femesh/mesh_tolerances.hpp"
#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/geometry/pair.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/errors.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/model/parallel.hpp"

namespace rvegen {

namespace mesh_parts {

// A face's key: its three node numbers in any order, mixed into 64 bits.
uint64_t face_key(int32_t a, int32_t b, int32_t c) {
  if (a > b) std::swap(a, b);
  if (b > c) std::swap(b, c);
  if (a > b) std::swap(a, b);
  auto mix = [](uint64_t x) {  // splitmix64's finaliser
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
  };
  return mix(mix(mix(static_cast<uint64_t>(a)) + static_cast<uint32_t>(b)) +
             static_cast<uint32_t>(c));
}

// Drops the nodes in no element; the others keep their order.
void drop_unused_nodes(TetMesh* mesh) {
  std::vector<int32_t> number(mesh->nodes.size(), -1);
  for (const auto& t : mesh->tets) {
    for (int32_t n : t) number[n] = 0;
  }
  int32_t kept = 0;
  for (size_t i = 0; i < number.size(); ++i) {
    if (number[i] < 0) continue;
    number[i] = kept;
    mesh->nodes[kept++] = mesh->nodes[i];
  }
  if (static_cast<size_t>(kept) == mesh->nodes.size()) return;
  mesh->nodes.resize(kept);
  for (auto& t : mesh->tets) {
    for (int32_t& n : t) n = number[n];
  }
}

// Each node on an upper box face (within `on` of it) and the node on the lower faces nearest
// its translate there, within `reach` (-1 when none), in the order of the nodes. The candidates
// are the nodes within `reach` of a lower face and on no upper one, on a grid of cells of
// `reach`.
std::vector<std::pair<int32_t, int32_t>> lower_images(const TetMesh& mesh, double on,
                                                      double reach) {
  const Box& box = mesh.box;
  struct KeyHash {
    size_t operator()(const std::array<long long, 3>& k) const {
      return std::hash<long long>()(k[0] * 73856093LL ^ k[1] * 19349663LL ^ k[2] * 83492791LL);
    }
  };
  // The cell of x, or its neighbour d (0 to 26, 13 itself).
  auto cell = [&](const Vec3& x, int d) {
    const int step[3] = {d % 3 - 1, d / 3 % 3 - 1, d / 9 - 1};
    std::array<long long, 3> k;
    for (int a = 0; a < 3; ++a) {
      k[a] = static_cast<long long>(std::floor((x[a] - box.origin[a]) / reach)) + step[a];
    }
    return k;
  };
  auto upper = [&](const Vec3& x, int a) {
    return std::abs(x[a] - box.origin[a] - box.size[a]) <= on;
  };
  std::unordered_map<std::array<long long, 3>, std::vector<int32_t>, KeyHash> grid;
  std::vector<std::pair<int32_t, int32_t>> out;
  for (size_t i = 0; i < mesh.nodes.size(); ++i) {
    const Vec3& x = mesh.nodes[i];
    bool up = false, low = false;
    for (int a = 0; a < 3; ++a) {
      up = up || upper(x, a);
      low = low || std::abs(x[a] - box.origin[a]) <= reach;
    }
    if (up) {
      out.push_back({static_cast<int32_t>(i), -1});
    } else if (low) {
      grid[cell(x, 13)].push_back(static_cast<int32_t>(i));
    }
  }
  for (auto& [i, master] : out) {
    Vec3 x = mesh.nodes[i];
    for (int a = 0; a < 3; ++a) {
      if (upper(mesh.nodes[i], a)) x[a] -= box.size[a];
    }
    double best = reach;
    for (int d = 0; d < 27; ++d) {
      const auto it = grid.find(cell(x, d));
      if (it == grid.end()) continue;
      for (const int32_t m : it->second) {
        const double dist = (mesh.nodes[m] - x).norm();
        if (dist <= best) {
          best = dist;
          master = m;
        }
      }
    }
  }
  return out;
}

}  // namespace mesh_parts

using namespace mesh_parts;

long long snap_periodic_nodes(TetMesh* mesh) {
  const double side = mesh->box.size.minCoeff(), on = kOnFace * side;
  long long moved = 0;
  for (const auto& [i, master] : lower_images(*mesh, on, kSnapReach * side)) {
    if (master < 0) continue;
    // The master's position, moved along the axes whose upper face i lies on.
    Vec3 exact = mesh->nodes[master];
    for (int a = 0; a < 3; ++a) {
      if (std::abs(mesh->nodes[i][a] - mesh->box.origin[a] - mesh->box.size[a]) <= on)
        exact[a] += mesh->box.size[a];
    }
    if ((exact - mesh->nodes[i]).norm() > on) ++moved;
    mesh->nodes[i] = exact;
  }
  return moved;
}

// The volume mesher rarely leaves two nodes at one position, each used by elements on its own
// side (a crack in the mesh: seen on the test scene). Such nodes are merged
// (the lowest number kept); nodes no element uses are dropped and the rest renumbered in order.
long long merge_coincident_nodes(TetMesh* mesh) {
  std::vector<int32_t> order(mesh->nodes.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int32_t>(i);
  auto less = [&](int32_t a, int32_t b) {
    const Vec3 &p = mesh->nodes[a], &q = mesh->nodes[b];
    if (p[0] != q[0]) return p[0] < q[0];
    if (p[1] != q[1]) return p[1] < q[1];
    if (p[2] != q[2]) return p[2] < q[2];
    return a < b;
  };
  std::sort(order.begin(), order.end(), less);
  std::vector<int32_t> same(mesh->nodes.size());
  long long merged = 0;
  for (size_t k = 0; k < order.size(); ++k) {
    const bool repeat = k > 0 && mesh->nodes[order[k]] == mesh->nodes[order[k - 1]];
    same[order[k]] = repeat ? same[order[k - 1]] : order[k];
    merged += repeat;
  }
  for (auto& t : mesh->tets) {
    for (int32_t& n : t) n = same[n];
  }
  drop_unused_nodes(mesh);
  for (const auto& t : mesh->tets) {
    for (int c = 0; c < 4; ++c) {
      for (int d = c + 1; d < 4; ++d) {
        if (t[c] == t[d]) throw MeshError("mesh_tet: an element with two nodes at one position");
      }
    }
  }
  return merged;
}

// A conforming mesh of the box: every face of an element is the face of one other element, or
// lies in a box face. Checked without storing the faces: interior faces come in pairs, so the
// XOR of the keys of all elements' faces equals the XOR of those of the faces in box faces;
// a face left alone (a crack, a hole) breaks the equality (but for a 2^-64 chance).
void check_conforming(const TetMesh& mesh) {
  // Per node, bits of the box faces it lies on.
  const std::vector<std::array<int8_t, 3>> ends = node_ends(mesh);
  std::vector<uint8_t> plane(ends.size(), 0);
  for (size_t n = 0; n < ends.size(); ++n) {
    for (int a = 0; a < 3; ++a) {
      if (ends[n][a] >= 0) plane[n] |= static_cast<uint8_t>(1 << (2 * a + ends[n][a]));
    }
  }
  uint64_t all = 0, outer = 0;
  for (const auto& t : mesh.tets) {
    for (int skip = 0; skip < 4; ++skip) {
      int32_t f[3], n = 0;
      for (int c = 0; c < 4; ++c) {
        if (c != skip) f[n++] = t[c];
      }
      const uint64_t k = face_key(f[0], f[1], f[2]);
      all ^= k;
      if (plane[f[0]] & plane[f[1]] & plane[f[2]]) outer ^= k;
    }
  }
  if (all != outer) {
    throw MeshError(
        "mesh_tet: the mesh is not conforming (an element face is shared by no other "
        "element and lies in no box face)");
  }
  // And the elements fill the box: their volumes (each positive) add up to it.
  double total = 0.0, least = 1e300;
  for (const auto& t : mesh.tets) {
    const double v = tet_volume(mesh.nodes, t);
    total += v;
    least = std::min(least, v);
  }
  if (!(least > 0.0) || std::abs(total / mesh.box.volume() - 1.0) > kVolumeRoundoff) {
    throw MeshError("mesh_tet: the elements do not fill the box (their volume " +
                    std::to_string(total) + ", the box " + std::to_string(mesh.box.volume()) +
                    ", least element " + std::to_string(mesh.tets.empty() ? 0.0 : least) + ")");
  }
}

// The edges as sorted keys (lower node in the high half), sorted and made unique: an edge's
// midside node is the corners' count plus its rank among them. No hash table: 8 bytes an edge
// for the elements' six, then the edges alone.
void add_midside_nodes(TetMesh* mesh) {
  if (!mesh->mid.empty()) return;
  // Each edge (a, b), a < b, listed under a: its rank among the edges in (a, b) order is the
  // number of edges listed under the nodes before a, plus its place in a's sorted list. (A
  // sort of all six edges of every element and a binary search of each was slower.)
  const size_t nn = mesh->nodes.size(), ne = mesh->tets.size();
  std::vector<int64_t> start(nn + 1, 0);
  for (const auto& t : mesh->tets) {
    for (const auto& e : kTetEdges) ++start[std::min(t[e[0]], t[e[1]]) + 1];
  }
  for (size_t a = 0; a < nn; ++a) start[a + 1] += start[a];
  std::vector<int32_t> list(static_cast<size_t>(start[nn]));
  {
    std::vector<int64_t> fill(start.begin(), start.end() - 1);
    for (const auto& t : mesh->tets) {
      for (const auto& e : kTetEdges) {
        const int32_t a = std::min(t[e[0]], t[e[1]]), b = std::max(t[e[0]], t[e[1]]);
        list[fill[a]++] = b;
      }
    }
  }
  std::vector<int32_t> count(nn);
  parallel_for(size_t{0}, nn, [&](size_t a) {
    const auto first = list.begin() + start[a], last = list.begin() + start[a + 1];
    std::sort(first, last);
    count[a] = static_cast<int32_t>(std::unique(first, last) - first);
  });
  std::vector<int64_t> rank(nn + 1, 0);  // the edges listed under the nodes before a
  for (size_t a = 0; a < nn; ++a) rank[a + 1] = rank[a] + count[a];
  const size_t corners = nn, edges = static_cast<size_t>(rank[nn]);
  if (corners + edges > static_cast<size_t>(std::numeric_limits<int32_t>::max())) {
    throw MeshError("mesh_tet: too many nodes for second order (" +
                    std::to_string(corners + edges) + ")");
  }
  mesh->nodes.resize(corners + edges);
  parallel_for(size_t{0}, nn, [&](size_t a) {
    for (int32_t k = 0; k < count[a]; ++k) {
      const int32_t b = list[start[a] + k];
      mesh->nodes[corners + rank[a] + k] = 0.5 * (mesh->nodes[a] + mesh->nodes[b]);
    }
  });
  mesh->mid.resize(ne);
  parallel_for(size_t{0}, ne, [&](size_t e) {
    const auto& t = mesh->tets[e];
    for (int k = 0; k < 6; ++k) {
      const int32_t a = std::min(t[kTetEdges[k][0]], t[kTetEdges[k][1]]);
      const int32_t b = std::max(t[kTetEdges[k][0]], t[kTetEdges[k][1]]);
      const auto first = list.begin() + start[a], last = first + count[a];
      mesh->mid[e][k] =
          static_cast<int32_t>(corners + rank[a] + (std::lower_bound(first, last, b) - first));
    }
  });
}

namespace mesh_parts {

// The least dihedral angle of a tetrahedron, in degrees: at each edge, the angle between the
// other two vertices seen across it.
double least_dihedral(const Vec3 (&p)[4]) {
  // The least angle has the largest cosine: one arc cosine, of that (acos is monotonic, so the
  // angle is the same to the last bit as the least of the six).
  double m = -1.0;
  for (int i = 0; i < 4; ++i) {
    for (int j = i + 1; j < 4; ++j) {
      int other[2], n = 0;
      for (int k = 0; k < 4; ++k) {
        if (k != i && k != j) other[n++] = k;
      }
      const Vec3 axis = (p[j] - p[i]).normalized();
      Vec3 u = p[other[0]] - p[i], w = p[other[1]] - p[i];
      u -= u.dot(axis) * axis;
      w -= w.dot(axis) * axis;
      m = std::max(m, std::clamp(u.normalized().dot(w.normalized()), -1.0, 1.0));
    }
  }
  return std::acos(m) * 180.0 / M_PI;
}

double least_dihedral(const TetMesh& mesh, const std::array<int32_t, 4>& t) {
  const Vec3 p[4] = {mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]], mesh.nodes[t[3]]};
  return least_dihedral(p);
}

}  // namespace mesh_parts

TetQuality tet_quality(const TetMesh& mesh) {
  TetQuality q;
  q.phase_volume.assign(mesh.phases.size(), 0.0);
  q.dihedral_counts.assign(TetQuality::kBins.size(), 0);
  q.min_volume = mesh.tets.empty() ? 0.0 : 1e300;
  std::vector<double> least(mesh.tets.size());
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    Vec3 p[4];
    for (int c = 0; c < 4; ++c) p[c] = mesh.nodes[mesh.tets[e][c]];
    const double v = tet_volume(mesh.nodes, mesh.tets[e]);
    q.min_volume = std::min(q.min_volume, v);
    const int label = mesh.phase[e];
    if (label >= 0 && label < static_cast<int>(q.phase_volume.size())) q.phase_volume[label] += v;
    const double m = least_dihedral(p);
    least[e] = m;
    size_t bin = 0;
    while (bin + 1 < TetQuality::kBins.size() && m >= TetQuality::kBins[bin + 1]) ++bin;
    ++q.dihedral_counts[bin];
    q.below_5_degrees += m < 5.0;
  }
  if (!least.empty()) {
    std::sort(least.begin(), least.end());
    q.min_dihedral = least.front();
    const double at[3] = {0.01, 0.05, 0.5};
    for (int k = 0; k < 3; ++k)
      q.quantiles[k] = least[static_cast<size_t>(at[k] * (least.size() - 1))];
  }
  return q;
}

}  // namespace rvegen
