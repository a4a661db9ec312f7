#include "rvegen/femesh/periodic_faces.hpp"

#include <gmsh.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <vector>

#include "rvegen/femesh/mesh_parts.hpp"
#include "rvegen/femesh/mesh_tolerances.hpp"
#include "rvegen/femesh/tet_mesh.hpp"

namespace rvegen::mesh_parts {

namespace {

Vec3 point_of(int tag) {
  std::vector<double> xyz;
  gmsh::model::getValue(0, tag, {}, xyz);
  return Vec3(xyz[0], xyz[1], xyz[2]);
}

// A curve's end points and the point at the middle of its parameter range.
struct CurveProbe {
  int tag;
  std::vector<Vec3> ends;
  Vec3 mid;
};

CurveProbe probe_curve(int tag) {
  CurveProbe p;
  p.tag = tag;
  std::vector<int> up, down;
  gmsh::model::getAdjacencies(1, tag, up, down);
  for (const int v : down) p.ends.push_back(point_of(v));
  std::vector<double> lo, hi, xyz;
  gmsh::model::getParametrizationBounds(1, tag, lo, hi);
  gmsh::model::getValue(1, tag, {0.5 * (lo[0] + hi[0])}, xyz);
  p.mid = Vec3(xyz[0], xyz[1], xyz[2]);
  return p;
}

std::vector<int> boundary_curves(int face) {
  gmsh::vectorpair b;
  gmsh::model::getBoundary({{2, face}}, b, false, false, false);
  std::vector<int> out;
  for (const auto& dt : b) {
    if (std::find(out.begin(), out.end(), std::abs(dt.second)) == out.end())
      out.push_back(std::abs(dt.second));
  }
  return out;
}

}  // namespace

// Ties every curve of the upper patches to its image on the lower one (Gmsh then meshes it as a
// copy). Gmsh's own pairing of two periodic surfaces matches their curves by end points and,
// where two curves share both, takes the first whose middle or bounding box agrees within 1e-3
// of the curve's size. The line and the arc that bound the cut of a fibre's end by a box face
// share both end points, and where the arc is monotone along the face's axes their bounding
// boxes agree within that; the copied faces then missed nodes ("Could not find periodic
// counterpart of triangle nodes", seen with fibres). Here each curve is paired with the image
// whose end points match and whose curve passes nearest its middle. A curve on two upper faces
// (a box edge) is tied by the first axis only: its image then has fewer coordinates at an upper
// end, so the ties make no cycle.
void tie_face_curves(const std::vector<FacePair>& pairs, const Vec3& len, double tol) {
  std::set<int> tied;
  for (const FacePair& fp : pairs) {
    Vec3 shift = Vec3::Zero();
    shift[fp.axis] = len[fp.axis];
    std::vector<CurveProbe> lower;
    for (const int c : boundary_curves(fp.lower)) lower.push_back(probe_curve(c));
    std::vector<double> T = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    T[4 * fp.axis + 3] = len[fp.axis];
    for (const int c : boundary_curves(fp.upper)) {
      if (tied.count(c)) continue;
      const CurveProbe u = probe_curve(c);
      int match = -1;
      double best = 1e300;
      for (const CurveProbe& l : lower) {
        if (l.ends.size() != u.ends.size()) continue;
        bool ends = true;
        for (const Vec3& e : u.ends) {
          bool found = false;
          for (const Vec3& f : l.ends) found = found || (e - shift - f).norm() <= tol;
          ends = ends && found;
        }
        if (!ends) continue;
        std::vector<double> closest, param;
        const Vec3 m = u.mid - shift;
        gmsh::model::getClosestPoint(1, l.tag, {m[0], m[1], m[2]}, closest, param);
        const double d = (Vec3(closest[0], closest[1], closest[2]) - m).norm();
        if (d < best) {
          best = d;
          match = l.tag;
        }
      }
      if (match < 0 || best > tol) {
        throw MeshError("mesh_tet: a curve of the upper box face normal to " +
                        std::string(1, "xyz"[fp.axis]) + " has no image on the lower face");
      }
      gmsh::model::mesh::setPeriodic(1, {c}, {match}, T);
      tied.insert(c);
    }
  }
}

namespace {

// Nodes of a face's boundary (its curves and their end points): tag and position.
std::vector<std::pair<std::size_t, Vec3>> boundary_nodes(int face) {
  std::vector<std::pair<std::size_t, Vec3>> out;
  for (const int c : boundary_curves(face)) {
    std::vector<std::size_t> tags;
    std::vector<double> xyz, param;
    gmsh::model::mesh::getNodes(tags, xyz, param, 1, c, true, false);
    for (size_t i = 0; i < tags.size(); ++i) {
      out.push_back({tags[i], Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2])});
    }
  }
  return out;
}

// The largest tag of the model's nodes (Gmsh 4.8 has no call for it): new nodes take the next.
std::size_t largest_node_tag() {
  std::vector<std::size_t> tags;
  std::vector<double> xyz, param;
  gmsh::model::mesh::getNodes(tags, xyz, param, -1, -1, false, false);
  return tags.empty() ? 0 : *std::max_element(tags.begin(), tags.end());
}

}  // namespace

// Replaces each upper patch's triangles with the translate of its lower patch's: the same
// triangles, on the upper patch's own boundary nodes (the curves are copies of the lower ones)
// and on new nodes translated from the lower patch's inside.
void copy_face_meshes(const std::vector<FacePair>& pairs, const Vec3& len, double tol) {
  std::size_t next_tag = largest_node_tag();
  for (const FacePair& fp : pairs) {
    Vec3 shift = Vec3::Zero();
    shift[fp.axis] = len[fp.axis];
    // The upper boundary's nodes, found by position on a grid of cells of the tolerance.
    const auto key = [tol](const Vec3& p, int dx, int dy, int dz) {
      return std::array<long long, 3>{static_cast<long long>(std::floor(p[0] / tol)) + dx,
                                      static_cast<long long>(std::floor(p[1] / tol)) + dy,
                                      static_cast<long long>(std::floor(p[2] / tol)) + dz};
    };
    std::map<std::array<long long, 3>, std::vector<std::pair<std::size_t, Vec3>>> grid;
    for (const auto& n : boundary_nodes(fp.upper)) grid[key(n.second, 0, 0, 0)].push_back(n);
    std::set<std::size_t> on_lower_boundary;
    for (const auto& n : boundary_nodes(fp.lower)) on_lower_boundary.insert(n.first);

    std::vector<std::size_t> tags;
    std::vector<double> xyz, param;
    gmsh::model::mesh::getNodes(tags, xyz, param, 2, fp.lower, true, false);
    std::map<std::size_t, std::size_t> image;
    std::vector<std::size_t> new_tags;
    std::vector<double> new_xyz;
    for (size_t i = 0; i < tags.size(); ++i) {
      const Vec3 p = Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]) + shift;
      if (!on_lower_boundary.count(tags[i])) {
        image[tags[i]] = ++next_tag;
        new_tags.push_back(next_tag);
        new_xyz.insert(new_xyz.end(), {p[0], p[1], p[2]});
        continue;
      }
      std::size_t found = 0;
      double best = tol;
      for (int d = 0; d < 27; ++d) {
        const auto it = grid.find(key(p, d % 3 - 1, d / 3 % 3 - 1, d / 9 - 1));
        if (it == grid.end()) continue;
        for (const auto& [t, q] : it->second) {
          if ((q - p).norm() <= best) {
            best = (q - p).norm();
            found = t;
          }
        }
      }
      if (!found) {
        throw MeshError(
            "mesh_tet: a node on the boundary of a lower box face patch has no image "
            "on the upper patch's boundary (normal to " +
            std::string(1, "xyz"[fp.axis]) + ")");
      }
      image[tags[i]] = found;
    }
    std::vector<int> types;
    std::vector<std::vector<std::size_t>> etags, enodes;
    gmsh::model::mesh::getElements(types, etags, enodes, 2, fp.lower);
    std::vector<std::size_t> triangles;
    for (size_t b = 0; b < types.size(); ++b) {
      if (types[b] != 2) throw MeshError("mesh_tet: the surface mesher gave other than triangles");
      for (const std::size_t n : enodes[b]) triangles.push_back(image.at(n));
    }
    std::vector<double> uv;
    if (!new_xyz.empty()) gmsh::model::getParametrization(2, fp.upper, new_xyz, uv);
    gmsh::model::mesh::clear({{2, fp.upper}});
    if (!new_tags.empty()) gmsh::model::mesh::addNodes(2, fp.upper, new_tags, new_xyz, uv);
    gmsh::model::mesh::addElementsByType(fp.upper, 2, {}, triangles);
  }
}

namespace {

// Flips each of `chords` (edges of triangles flat in a box face) that joins two triangles of
// the surface, one of them with a node off that face: triangles (u, v, w1) and (v, u, w2)
// become (u, w2, w1) and (v, w1, w2). Such an edge is a chord of the face's cut of the surface
// and lies in the face, over the face's own triangles on one side of the cut or the other,
// which the volume mesher refuses ("A segment and a facet intersect", "Two segments
// intersect"); splitting the flat triangle about a node off the face keeps it. Flipped only
// where both new triangles face the way the two old ones do, and the new edge is not one
// already. Returns the edges flipped.
template <class FacesOf>
long long flip_chords(std::vector<std::array<std::size_t, 3>>* triangles,
                      const std::vector<std::array<std::size_t, 2>>& chords,
                      const std::unordered_map<std::size_t, Vec3>& at, const FacesOf& faces_of) {
  auto& tris = *triangles;
  auto key = [](std::size_t a, std::size_t b) {
    return std::make_pair(std::min(a, b), std::max(a, b));
  };
  auto normal = [&](std::size_t a, std::size_t b, std::size_t c) {
    const Vec3 n = (at.at(b) - at.at(a)).cross(at.at(c) - at.at(a));
    return Vec3(n / std::max(n.norm(), kNoDirection));
  };
  std::map<std::pair<std::size_t, std::size_t>, std::vector<size_t>> edges;
  for (size_t t = 0; t < tris.size(); ++t) {
    for (int k = 0; k < 3; ++k) edges[key(tris[t][k], tris[t][(k + 1) % 3])].push_back(t);
  }
  long long flipped = 0;
  for (const auto& [u0, v0] : chords) {
    const auto it = edges.find(key(u0, v0));
    if (it == edges.end() || it->second.size() != 2) continue;
    // t1 holds the edge as u -> v, t2 as v -> u.
    size_t t1 = it->second[0], t2 = it->second[1];
    int k1 = 0;
    while (k1 < 3 && !(tris[t1][k1] == u0 || tris[t1][k1] == v0)) ++k1;
    if (tris[t1][(k1 + 1) % 3] != u0 && tris[t1][(k1 + 1) % 3] != v0) k1 = (k1 + 2) % 3;
    const std::size_t u = tris[t1][k1], v = tris[t1][(k1 + 1) % 3], w1 = tris[t1][(k1 + 2) % 3];
    std::size_t w2 = 0;
    for (const std::size_t x : tris[t2]) {
      if (x != u && x != v) w2 = x;
    }
    const int face = faces_of(at.at(u)) & faces_of(at.at(v));
    if ((face & faces_of(at.at(w1)) & faces_of(at.at(w2))) != 0) continue;
    if (edges.count(key(w1, w2))) continue;
    const Vec3 before = normal(u, v, w1) + normal(v, u, w2);
    if (normal(u, w2, w1).dot(before) <= 0.0 || normal(v, w1, w2).dot(before) <= 0.0) continue;
    tris[t1] = {u, w2, w1};
    tris[t2] = {v, w1, w2};
    // The edges' triangles as they are now: u-v is gone, w1-w2 is new, v-w1 moved to t2 and
    // u-w2 to t1.
    edges.erase(key(u, v));
    edges[key(w1, w2)] = {t1, t2};
    std::replace(edges[key(v, w1)].begin(), edges[key(v, w1)].end(), t1, t2);
    std::replace(edges[key(u, w2)].begin(), edges[key(u, w2)].end(), t2, t1);
    ++flipped;
  }
  return flipped;
}

}  // namespace

// A curved surface's triangle whose three nodes lie on one box face is flat in that face, over
// the cut the face makes there (the surface meets the face along a curve, and where a strip of
// the surface between the face and another curve is thinner than the elements, the surface
// mesher joins three nodes of that curve). The face's own triangles then lie under it: two
// facets that overlap, which the volume mesher refuses ("Found two exactly self-intersecting
// facets", seen with fibres). Each such triangle gets a node on the surface, at the point of
// the surface nearest its centre, and is split into three about it (those whose nearest surface
// point is not inside the box are left); then its edges that are not on a curve are flipped off
// the face (flip_chords; counted in `flipped`). Returns the triangles split.
long long raise_flat_triangles(const Box& box, double tol, long long* flipped) {
  long long raised = 0;
  std::size_t next_tag = 0;
  gmsh::vectorpair surfaces;
  gmsh::model::getEntities(surfaces, 2);
  for (const auto& s : surfaces) {
    std::string type;
    gmsh::model::getType(2, s.second, type);
    if (type == "Plane") continue;
    std::vector<int> types;
    std::vector<std::vector<std::size_t>> etags, enodes;
    gmsh::model::mesh::getElements(types, etags, enodes, 2, s.second);
    std::vector<std::size_t> tags;
    std::vector<double> xyz, param;
    gmsh::model::mesh::getNodes(tags, xyz, param, 2, s.second, true, false);
    std::unordered_map<std::size_t, Vec3> at;
    for (size_t i = 0; i < tags.size(); ++i) {
      at[tags[i]] = Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    }
    // A bit per box face: the faces a point lies on.
    const auto faces_of = [&](const Vec3& p) {
      int bits = 0;
      for (int a = 0; a < 3; ++a) {
        if (std::abs(p[a] - box.origin[a]) <= tol) bits |= 1 << (2 * a);
        if (std::abs(p[a] - box.origin[a] - box.size[a]) <= tol) bits |= 2 << (2 * a);
      }
      return bits;
    };
    // The surface's triangles (Gmsh gives them as one block of type 2), and which lie flat.
    const auto block = std::find(types.begin(), types.end(), 2);
    if (block == types.end()) continue;
    const std::vector<std::size_t>& tri = enodes[block - types.begin()];
    std::vector<char> flat(tri.size() / 3);
    for (size_t e = 0; e < flat.size(); ++e) {
      flat[e] = (faces_of(at[tri[3 * e]]) & faces_of(at[tri[3 * e + 1]]) &
                 faces_of(at[tri[3 * e + 2]])) != 0;
    }
    if (std::find(flat.begin(), flat.end(), 1) == flat.end()) continue;
    if (next_tag == 0) next_tag = largest_node_tag();
    // The surface's own nodes, to put back after its mesh is cleared, and its triangles, with
    // each flat one split about its new node.
    std::vector<std::size_t> own;
    std::vector<double> own_xyz, own_uv;
    gmsh::model::mesh::getNodes(own, own_xyz, own_uv, 2, s.second, false, true);
    std::vector<std::array<std::size_t, 3>> triangles;
    std::vector<std::array<std::size_t, 2>> chords;  // the flat triangles' edges
    for (size_t e = 0; e < flat.size(); ++e) {
      const std::size_t* n = &tri[3 * e];
      bool split = false;
      if (flat[e]) {
        for (int k = 0; k < 3; ++k) chords.push_back({n[k], n[(k + 1) % 3]});
        const Vec3 c = (at[n[0]] + at[n[1]] + at[n[2]]) / 3.0;
        std::vector<double> near, uv;
        gmsh::model::getClosestPoint(2, s.second, {c[0], c[1], c[2]}, near, uv);
        const Vec3 m(near[0], near[1], near[2]);
        const Vec3 lo = m - box.origin, hi = box.origin + box.size - m;
        if (uv.size() == 2 && std::min(lo.minCoeff(), hi.minCoeff()) > tol) {
          own.push_back(++next_tag);
          own_xyz.insert(own_xyz.end(), {m[0], m[1], m[2]});
          own_uv.insert(own_uv.end(), {uv[0], uv[1]});
          at[next_tag] = m;
          for (int k = 0; k < 3; ++k) triangles.push_back({n[k], n[(k + 1) % 3], next_tag});
          split = true;
          ++raised;
        }
      }
      if (!split) triangles.push_back({n[0], n[1], n[2]});
    }
    *flipped += flip_chords(&triangles, chords, at, faces_of);
    gmsh::model::mesh::clear({{2, s.second}});
    if (!own.empty()) gmsh::model::mesh::addNodes(2, s.second, own, own_xyz, own_uv);
    std::vector<std::size_t> flat_list;
    for (const auto& t : triangles) flat_list.insert(flat_list.end(), t.begin(), t.end());
    gmsh::model::mesh::addElementsByType(s.second, 2, {}, flat_list);
  }
  return raised;
}

std::vector<FacePair> pair_box_patches(const Box& box, double tol) {
  const Vec3 o = box.origin, len = box.size;
  const double side = len.minCoeff();
  gmsh::vectorpair surfaces;
  gmsh::model::getEntities(surfaces, 2);
  std::vector<FacePair> face_pairs;
  for (int a = 0; a < 3; ++a) {
    std::vector<std::pair<int, std::array<double, 7>>> lower, upper;
    for (const auto& s : surfaces) {
      std::string type;
      gmsh::model::getType(2, s.second, type);
      if (type != "Plane") continue;
      double com[3];
      gmsh::model::occ::getCenterOfMass(2, s.second, com[0], com[1], com[2]);
      for (int end = 0; end < 2; ++end) {
        const double v = o[a] + (end ? len[a] : 0.0);
        if (std::abs(com[a] - v) > tol) continue;
        std::vector<double> lo, hi, normal;
        gmsh::model::getParametrizationBounds(2, s.second, lo, hi);
        gmsh::model::getNormal(s.second, {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])}, normal);
        if (normal.size() < 3 || std::abs(std::abs(normal[a]) - 1.0) > kOnFace) continue;
        double b[6];
        gmsh::model::getBoundingBox(2, s.second, b[0], b[1], b[2], b[3], b[4], b[5]);
        std::array<double, 7> key;
        for (int k = 0; k < 6; ++k) key[k] = b[k];
        gmsh::model::occ::getMass(2, s.second, key[6]);
        (end ? upper : lower).push_back({s.second, key});
      }
    }
    if (upper.size() != lower.size()) {
      throw MeshError("mesh_tet: the box faces normal to " + std::string(1, "xyz"[a]) +
                      " were cut into " + std::to_string(lower.size()) + " and " +
                      std::to_string(upper.size()) + " patches");
    }
    std::set<int> used;
    for (const auto& [tag, key] : upper) {
      // The lower patch nearest to this one's image, each taken once (OpenCASCADE's centres of
      // mass and areas of small patches differ from their images' by a little more than
      // rounding: matched within kPatchKeyMatch).
      int match = -1;
      double best = std::numeric_limits<double>::infinity();
      for (const auto& [ltag, lkey] : lower) {
        double d = 0.0;
        for (int k = 0; k < 6; ++k) {
          d = std::max(d, std::abs(key[k] - (k % 3 == a ? len[a] : 0.0) - lkey[k]) / side);
        }
        d = std::max(d,
                     std::abs(key[6] - lkey[6]) / std::max(key[6], kPatchTolerance * side * side));
        if (d < best) {
          best = d;
          match = ltag;
        }
      }
      if (best > kPatchKeyMatch || !used.insert(match).second) match = -1;
      if (match < 0) {
        throw MeshError("mesh_tet: a patch of the upper box face normal to " +
                        std::string(1, "xyz"[a]) + " has no image on the lower face");
      }
      face_pairs.push_back({tag, match, a});
    }
  }
  return face_pairs;
}

}  // namespace rvegen::mesh_parts
