// The repair of slivers (elements with a dihedral angle under 5 degrees) that the volume
// mesher leaves: flat elements in a box face removed, nodes inside one region moved, slivers
// remade with their neighbours by flips, nodes inserted where none can move; in rounds until
// one changes nothing.
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

using namespace mesh_parts;

namespace mesh_parts {

// Drops the elements marked in `gone` (the first gone.size() elements; those after it stay),
// keeping the order of the rest.
void drop_elements(TetMesh* mesh, const std::vector<uint8_t>& gone) {
  size_t w = 0;
  for (size_t e = 0; e < mesh->tets.size(); ++e) {
    if (e < gone.size() && gone[e]) continue;
    mesh->tets[w] = mesh->tets[e];
    mesh->phase[w] = mesh->phase[e];
    mesh->inclusion_id[w] = mesh->inclusion_id[e];
    ++w;
  }
  mesh->tets.resize(w);
  mesh->phase.resize(w);
  mesh->inclusion_id.resize(w);
}

}  // namespace mesh_parts

namespace {

// For each node on a box face of axis a (ends: node_ends), the node on the opposite face of that
// axis with the same other coordinates (within kOnFace of the box's smallest side, the rounding of
// the key taken into account); -1 for the others.
std::vector<int32_t> images_across(const TetMesh& mesh,
                                   const std::vector<std::array<int8_t, 3>>& ends, int a) {
  const double tol = kOnFace * mesh.box.size.minCoeff();
  auto key = [&](size_t n, int end) {
    const Vec3& x = mesh.nodes[n];
    return std::array<long long, 3>{end, std::llround(x[(a + 1) % 3] / tol),
                                    std::llround(x[(a + 2) % 3] / tol)};
  };
  std::map<std::array<long long, 3>, int32_t> at;
  for (size_t n = 0; n < mesh.nodes.size(); ++n) {
    if (ends[n][a] >= 0) at[key(n, ends[n][a])] = static_cast<int32_t>(n);
  }
  std::vector<int32_t> image(mesh.nodes.size(), -1);
  for (size_t n = 0; n < mesh.nodes.size(); ++n) {
    if (ends[n][a] < 0) continue;
    const std::array<long long, 3> k = key(n, 1 - ends[n][a]);
    for (int d1 = -1; d1 <= 1 && image[n] < 0; ++d1) {
      for (int d2 = -1; d2 <= 1 && image[n] < 0; ++d2) {
        const auto it = at.find({k[0], k[1] + d1, k[2] + d2});
        if (it != at.end()) image[n] = it->second;
      }
    }
  }
  return image;
}

}  // namespace

long long remove_flat_face_elements(TetMesh* mesh) {
  const size_t nn = mesh->nodes.size(), ne = mesh->tets.size();
  const std::vector<std::array<int8_t, 3>> ends = node_ends(*mesh);
  // The box face (axis, end) all four nodes of e lie on, or -1.
  auto flat_face = [&](size_t e) {
    const auto& t = mesh->tets[e];
    for (int a = 0; a < 3; ++a) {
      const int8_t end = ends[t[0]][a];
      if (end < 0) continue;
      if (ends[t[1]][a] == end && ends[t[2]][a] == end && ends[t[3]][a] == end) return 2 * a + end;
    }
    return -1;
  };
  std::vector<size_t> flat;
  for (size_t e = 0; e < ne; ++e) {
    if (flat_face(e) >= 0) flat.push_back(e);
  }
  if (flat.empty()) return 0;
  // The elements around each node.
  std::vector<std::vector<int32_t>> around(nn);
  for (size_t e = 0; e < ne; ++e) {
    for (int32_t n : mesh->tets[e]) around[n].push_back(static_cast<int32_t>(e));
  }
  auto has = [](const std::array<int32_t, 4>& t, int32_t n) {
    return std::find(t.begin(), t.end(), n) != t.end();
  };
  // The elements other than `skip` with nodes a, b and c.
  auto with_face = [&](int32_t a, int32_t b, int32_t c, int32_t skip) {
    std::vector<int32_t> out;
    for (int32_t f : around[a]) {
      if (f != skip && has(mesh->tets[f], b) && has(mesh->tets[f], c)) out.push_back(f);
    }
    return out;
  };
  // Each face node's image on the opposite face, per axis.
  std::array<std::vector<int32_t>, 3> images;
  for (int a = 0; a < 3; ++a) images[a] = images_across(*mesh, ends, a);
  auto image_of = [&](int32_t n, int a) { return images[a][n]; };
  std::vector<uint8_t> gone(ne, 0);
  long long removed = 0;
  for (size_t e : flat) {
    if (gone[e]) continue;
    const auto t = mesh->tets[e];
    const int a = flat_face(e) / 2;
    // Its faces on the box face: those no other element shares.
    std::vector<std::array<int32_t, 3>> outer, inner;
    for (int k = 0; k < 4; ++k) {
      const std::array<int32_t, 3> f = {t[(k + 1) % 4], t[(k + 2) % 4], t[(k + 3) % 4]};
      (with_face(f[0], f[1], f[2], static_cast<int32_t>(e)).empty() ? outer : inner).push_back(f);
    }
    if (outer.size() != 2 || inner.size() != 2) continue;
    // The outer diagonal (p, q) and the two other corners (u, v).
    int32_t p = -1, q = -1, u = -1, v = -1;
    for (int32_t n : t) {
      const bool in0 = std::count(outer[0].begin(), outer[0].end(), n) > 0;
      const bool in1 = std::count(outer[1].begin(), outer[1].end(), n) > 0;
      if (in0 && in1) {
        (p < 0 ? p : q) = n;
      } else {
        (u < 0 ? u : v) = n;
      }
    }
    if (q < 0 || v < 0) continue;
    // The images, and the two elements on the image triangles (p' q' u') and (p' q' v').
    const int32_t pi = image_of(p, a), qi = image_of(q, a), ui = image_of(u, a),
                  vi = image_of(v, a);
    if (pi < 0 || qi < 0 || ui < 0 || vi < 0) continue;
    const std::vector<int32_t> f1 = with_face(pi, qi, ui, -1), f2 = with_face(pi, qi, vi, -1);
    if (f1.size() != 1 || f2.size() != 1 || gone[f1[0]] || gone[f2[0]]) continue;
    if (region_of(*mesh, f1[0]) != region_of(*mesh, f2[0])) continue;
    auto apex = [&](int32_t f, int32_t x) {
      for (int32_t n : mesh->tets[f]) {
        if (n != pi && n != qi && n != x) return n;
      }
      return int32_t(-1);
    };
    const int32_t r = apex(f1[0], ui);
    if (r < 0 || r != apex(f2[0], vi)) continue;
    // The flip: (p' q' u' r), (p' q' v' r) become (u' v' p' r), (u' v' q' r).
    std::array<int32_t, 4> n1 = {ui, vi, pi, r}, n2 = {ui, vi, qi, r};
    if (tet_volume(mesh->nodes, n1) < 0.0) std::swap(n1[0], n1[1]);
    if (tet_volume(mesh->nodes, n2) < 0.0) std::swap(n2[0], n2[1]);
    const double before =
        tet_volume(mesh->nodes, mesh->tets[f1[0]]) + tet_volume(mesh->nodes, mesh->tets[f2[0]]);
    const double v1 = tet_volume(mesh->nodes, n1), v2 = tet_volume(mesh->nodes, n2);
    if (!(v1 > 0.0 && v2 > 0.0) || std::abs(v1 + v2 - before) > kVolumeRoundoff * before) continue;
    mesh->tets[f1[0]] = n1;
    mesh->tets[f2[0]] = n2;
    // (A node's list may keep an element that no longer has it: each search checks the nodes.)
    for (int32_t f : {f1[0], f2[0]}) {
      for (int32_t n : mesh->tets[f]) {
        if (std::find(around[n].begin(), around[n].end(), f) == around[n].end()) {
          around[n].push_back(f);
        }
      }
    }
    gone[e] = 1;
    ++removed;
  }
  if (removed > 0) drop_elements(mesh, gone);
  return removed;
}

namespace {

constexpr uint64_t kNoRegion = std::numeric_limits<uint64_t>::max();

// How each node may move (see lift_slivers): the first two regions it meets (`met`), whether it
// must stay (`stays`: a third region, a box edge, a box face without an image of the same
// regions), and for a node on one box face, its image on the opposite face (-1 if none) and
// the face's axis.
struct NodeFreedom {
  std::vector<std::array<uint64_t, 2>> met;
  std::vector<uint8_t> stays;
  std::vector<std::array<int8_t, 3>> ends;
  std::vector<int32_t> image;
  std::vector<int8_t> face;
  // The node that moves n: the lower of n and its image.
  int32_t leader(int32_t n) const { return image[n] >= 0 && ends[n][face[n]] == 1 ? image[n] : n; }
};

NodeFreedom node_freedom(const TetMesh& mesh) {
  const size_t nn = mesh.nodes.size();
  NodeFreedom f;
  f.met.assign(nn, {kNoRegion, kNoRegion});
  f.stays.assign(nn, 0);
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    const uint64_t r = region_of(mesh, e);
    for (int32_t n : mesh.tets[e]) {
      auto& m = f.met[n];
      if (m[0] == kNoRegion || m[0] == r) {
        m[0] = r;
      } else if (m[1] == kNoRegion || m[1] == r) {
        m[1] = r;
      } else {
        f.stays[n] = 1;
      }
    }
  }
  // A node on one box face (not an edge) moves with its image on the opposite face; the lower
  // one leads. Nodes on edges stay.
  f.ends = node_ends(mesh);
  f.image.assign(nn, -1);
  f.face.assign(nn, -1);
  for (int a = 0; a < 3; ++a) {
    const std::vector<int32_t> across = images_across(mesh, f.ends, a);
    for (size_t i = 0; i < nn; ++i) {
      const int32_t j = across[i];
      if (j < 0 || f.ends[i][(a + 1) % 3] >= 0 || f.ends[i][(a + 2) % 3] >= 0) continue;  // edges
      // The same regions on both sides (an inclusion's image keeps its id).
      const auto &mi = f.met[i], &mj = f.met[j];
      if (mi != mj && !(mi[0] == mj[1] && mi[1] == mj[0])) continue;
      f.image[i] = j;
      f.face[i] = static_cast<int8_t>(a);
    }
  }
  for (size_t i = 0; i < nn; ++i) {
    if (f.ends[i][0] >= 0 || f.ends[i][1] >= 0 || f.ends[i][2] >= 0) {
      if (f.image[i] < 0) f.stays[i] = 1;
    }
  }
  for (size_t i = 0; i < nn; ++i) {
    if (f.image[i] >= 0 && (f.stays[i] || f.stays[f.image[i]]))
      f.stays[i] = f.stays[f.image[i]] = 1;
  }
  return f;
}

// The leaders of the nodes that may move in the elements under the angle, each with its ball:
// the elements around it and around the image it leads, in the elements' order (an element
// once for each of its nodes led).
std::map<int32_t, std::vector<int32_t>> balls_under(const TetMesh& mesh, const NodeFreedom& f,
                                                    const std::vector<double>& least, double angle,
                                                    std::vector<int32_t>* start,
                                                    std::vector<int32_t>* around) {
  std::map<int32_t, std::vector<int32_t>> ball;  // by node: the same moves on every run
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    if (least[e] >= angle) continue;
    for (int32_t n : mesh.tets[e]) {
      if (!f.stays[n]) ball[f.leader(n)];
    }
  }
  if (ball.empty()) return ball;
  if (start->empty()) elements_around(mesh, start, around);
  for (auto& [n, elements] : ball) {
    const int32_t led = f.image[n] >= 0 && f.leader(f.image[n]) == n ? f.image[n] : -1;
    const auto a0 = around->begin() + (*start)[n], a1 = around->begin() + (*start)[n + 1];
    if (led < 0) {
      elements.assign(a0, a1);
    } else {
      std::merge(a0, a1, around->begin() + (*start)[led], around->begin() + (*start)[led + 1],
                 std::back_inserter(elements));
    }
  }
  return ball;
}

// One node's move (see lift_slivers): where it may go, and the search for the place where its
// ball's least angle is largest.
class NodeMove {
 public:
  NodeMove(TetMesh* mesh, const NodeFreedom& f, int32_t n, const std::vector<int32_t>& ball)
      : mesh_(*mesh),
        n_(n),
        ball_(ball),
        x_(mesh->nodes[n]),
        axis_(f.face[n]),
        follower_(f.image[n] >= 0 ? &mesh->nodes[f.image[n]] : nullptr) {}

  // The node slides on the surface of `shape` grown by `grown`, at `offset` from it.
  void slide_on(const Shape& shape, double grown, double offset) {
    slides_ = true;
    surface_ = shape;
    grown_ = grown;
    offset_ = offset;
  }

  // A pattern search from where the node is, along the axes and towards the centroid of its
  // neighbours, in steps from a quarter of its shortest edge down to kLeastStep of it; a step
  // is taken only when it raises the ball's least angle. Returns whether the node moved.
  bool search() {
    double shortest = std::numeric_limits<double>::infinity();
    Vec3 centroid = Vec3::Zero();
    int neighbours = 0;
    for (int32_t e : ball_) {
      const auto& t = mesh_.tets[e];
      if (std::find(t.begin(), t.end(), n_) == t.end()) continue;  // the image's
      for (int32_t m : t) {
        if (m == n_) continue;
        shortest = std::min(shortest, (mesh_.nodes[m] - x_).norm());
        centroid += mesh_.nodes[m];
        ++neighbours;
      }
    }
    centroid /= std::max(1, neighbours);
    const double start = worst(x_);
    double best = start;
    Vec3 at = x_;
    const Vec3 to_centroid =
        (centroid - x_).norm() > 0.0 ? Vec3((centroid - x_).normalized()) : Vec3::UnitX();
    const Vec3 dirs[8] = {to_centroid,   -to_centroid,   Vec3::UnitX(), -Vec3::UnitX(),
                          Vec3::UnitY(), -Vec3::UnitY(), Vec3::UnitZ(), -Vec3::UnitZ()};
    int tries = 0;
    for (double h = 0.25 * shortest; h > kLeastStep * shortest && tries < kMaxTries;) {
      bool better = false;
      for (const Vec3& d : dirs) {
        Vec3 y;
        if (!step(at, d, h, &y)) continue;
        const double w = worst(y);
        ++tries;
        if (w > best) {
          best = w;
          at = y;
          better = true;
          break;
        }
      }
      if (!better) h *= 0.5;
    }
    if (!(best > start)) return false;
    place(at);
    return true;
  }

 private:
  static constexpr int kMaxTries = 400;
  static constexpr int kNewtonSteps = 8;

  // The node at y; its image follows on the coordinates other than the face's axis.
  void place(const Vec3& y) {
    x_ = y;
    if (follower_) {
      const double keep = (*follower_)[axis_];
      *follower_ = y;
      (*follower_)[axis_] = keep;
    }
  }

  // The ball's least angle with the node at y (-1 if an element is not positive).
  double worst(const Vec3& y) {
    const Vec3 keep = x_, keep_image = follower_ ? *follower_ : x_;
    place(y);
    double w = 180.0;
    for (int32_t e : ball_) {
      const auto& t = mesh_.tets[e];
      w = tet_volume(mesh_.nodes, t) > 0.0 ? std::min(w, least_dihedral(mesh_, t)) : -1.0;
      if (w < 0.0) break;
    }
    x_ = keep;
    if (follower_) *follower_ = keep_image;
    return w;
  }

  // A step of h along d from p: in the tangent plane, then back to the offset, for a sliding
  // node; in the face for a node on one.
  bool step(const Vec3& p, const Vec3& d, double h, Vec3* y) const {
    if (axis_ >= 0) return step_in_face(p, d, h, y);
    if (!slides_) {
      *y = p + h * d;
      return true;
    }
    Vec3 nrm;
    bool feature;
    surface_distance(surface_, grown_, p, &nrm, &feature);
    const Vec3 t = d - d.dot(nrm) * nrm;
    if (!(t.norm() > kShortDirection)) return false;
    Vec3 q = p + h * t.normalized();
    const double off = surface_distance(surface_, grown_, q, &nrm, &feature) - offset_;
    if (feature) return false;
    *y = q - off * nrm;
    return true;
  }

  // In the face: the direction's part in it; along the face's cut of the surface when
  // sliding, brought back to both (the surface, then the face) until they agree.
  bool step_in_face(const Vec3& p, const Vec3& d, double h, Vec3* y) const {
    const int a = axis_;
    Vec3 t = d;
    t[a] = 0.0;
    Vec3 nrm;
    bool feature = false;
    if (slides_) {
      surface_distance(surface_, grown_, p, &nrm, &feature);
      const Vec3 along = Vec3::Unit(a).cross(nrm);
      if (!(along.norm() > kShallowTangent)) return false;  // the face nearly tangent to it
      t = along.normalized() * (along.normalized().dot(t) >= 0.0 ? 1.0 : -1.0);
    }
    if (!(t.norm() > kShortDirection)) return false;
    Vec3 q = p + h * t.normalized();
    if (slides_) {
      // Newton's steps in the face, along the normal's part in it.
      double off = 1.0;
      for (int k = 0; k < kNewtonSteps && std::abs(off) > kNewtonStop * h; ++k) {
        off = surface_distance(surface_, grown_, q, &nrm, &feature) - offset_;
        if (feature) return false;
        Vec3 m = nrm;
        m[a] = 0.0;
        if (!(m.squaredNorm() > kShortDirection)) return false;
        q -= (off / m.squaredNorm()) * m;
        q[a] = p[a];
      }
      if (!(std::abs(off) <= kNewtonReach * h)) return false;
    }
    q[a] = p[a];
    *y = q;
    return true;
  }

  TetMesh& mesh_;
  const int32_t n_;
  const std::vector<int32_t>& ball_;
  Vec3& x_;
  const int axis_;  // the box face's axis, -1 off the faces
  Vec3* follower_;  // the image on the opposite face
  bool slides_ = false;
  Shape surface_;
  double grown_ = 0.0, offset_ = 0.0;
};

}  // namespace

// The nodes a relocation may move, and how. A node inside one region (every element around in
// one inclusion and phase) moves freely: no phase's volume or interface changes. A node on one
// curved interface (a core against the matrix or its shell, a shell against the matrix) slides
// along it, at its signed distance from the exact surface (keep_phase_volumes set it): the
// phases' volumes change only by the surface's curvature over a step. A node on one box face
// moves with its image on the opposite face (the faces' triangulations stay translates of each
// other): in the face, or along the face's cut of one curved interface (a cut's own vertex,
// where the geometry kernel starts a closed curve, can lie a hair from a rim's crossing, and
// its elements are slivers: seen in a debonded sphere cut by a face). Nodes on box edges, on
// flat ends, on two interfaces or between two inclusions stay. Elements under `angle` have each
// such node moved where the least angle of its ball (the elements around it) is largest
// (NodeMove::search, in the surface's tangent plane for a sliding node), every element
// positive. Rounds until none is left under `angle` or a round moves nothing (at most
// kLiftRounds): a move can help an element next to it.
long long lift_slivers(TetMesh* mesh, const InclusionSet& set, double angle) {
  const size_t ne = mesh->tets.size();
  const NodeFreedom freedom = node_freedom(*mesh);
  const std::unordered_map<int32_t, int> by_id = index_by_id(set);
  // The surface a node on two regions slides on (interface_surface); -1 where it may not move.
  auto surface_of = [&](int32_t n) {
    const auto& met = freedom.met[n];
    const uint32_t label[2] = {static_cast<uint32_t>(met[0]), static_cast<uint32_t>(met[1])};
    if (label[0] >= mesh->phases.size() || label[1] >= mesh->phases.size()) return -1;
    return interface_surface(by_id, static_cast<int32_t>(met[0] >> 32), mesh->phases[label[0]].kind,
                             static_cast<int32_t>(met[1] >> 32), mesh->phases[label[1]].kind);
  };
  std::vector<double> least(ne);
  parallel_for(size_t{0}, ne, [&](size_t e) { least[e] = least_dihedral(*mesh, mesh->tets[e]); });
  long long moved = 0;
  std::vector<int32_t> start, around_all;  // elements_around, made once needed
  for (int round = 0; round < kLiftRounds; ++round) {
    const auto balls = balls_under(*mesh, freedom, least, angle, &start, &around_all);
    if (balls.empty()) break;
    long long this_round = 0;
    for (const auto& [n, around] : balls) {
      NodeMove move(mesh, freedom, n, around);
      if (freedom.met[n][1] != kNoRegion) {
        // A sliding node: its surface (the periodic image nearest it) and its distance from it.
        const int which = surface_of(n);
        if (which < 0) continue;
        const Inclusion& in = set.inclusions[which / 2];
        const double grown = (which & 1) ? outer_offset(in.mod) : 0.0;
        bool feature;
        double offset;
        const Vec3& x = mesh->nodes[n];
        const Vec3 shift = nearest_image(in.shape, grown, set.box.size, x, &offset, &feature);
        if (feature) continue;                                    // on a flat end: stays
        if ((which & 1) && on_void_cone(in, shift, x)) continue;  // on a void's cone: stays
        move.slide_on(in.shape.translated(shift), grown, offset);
      }
      if (move.search()) {
        ++this_round;
        for (int32_t e : around) least[e] = least_dihedral(*mesh, mesh->tets[e]);
      }
    }
    moved += this_round;
    if (this_round == 0) break;
  }
  return moved;
}

namespace mesh_parts {

// The elements whose least dihedral angle is under `angle` degrees, in order; *least: every
// element's least angle.
std::vector<int32_t> elements_under(const TetMesh& mesh, double angle, std::vector<double>* least) {
  least->resize(mesh.tets.size());
  parallel_for(size_t{0}, mesh.tets.size(),
               [&](size_t e) { (*least)[e] = least_dihedral(mesh, mesh.tets[e]); });
  std::vector<int32_t> bad;
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    if ((*least)[e] < angle) bad.push_back(static_cast<int32_t>(e));
  }
  return bad;
}

// The elements around each node n of the mesh: (*around)[(*start)[n]] to
// (*around)[(*start)[n + 1] - 1], in element order.
void elements_around(const TetMesh& mesh, std::vector<int32_t>* start,
                     std::vector<int32_t>* around) {
  start->assign(mesh.nodes.size() + 1, 0);
  around->resize(4 * mesh.tets.size());
  for (const auto& t : mesh.tets) {
    for (int32_t n : t) ++(*start)[n + 1];
  }
  for (size_t i = 1; i < start->size(); ++i) (*start)[i] += (*start)[i - 1];
  std::vector<int32_t> fill(start->begin(), start->end() - 1);
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    for (int32_t n : mesh.tets[e]) (*around)[fill[n]++] = static_cast<int32_t>(e);
  }
}

// The element other than `except` that has face (a, b, c), -1 if none (start and around:
// elements_around).
int32_t element_on(const TetMesh& mesh, const std::vector<int32_t>& start,
                   const std::vector<int32_t>& around, int32_t a, int32_t b, int32_t c,
                   int32_t except) {
  for (int32_t i = start[a]; i < start[a + 1]; ++i) {
    const int32_t f = around[i];
    if (f == except) continue;
    const auto& u = mesh.tets[f];
    if (std::count(u.begin(), u.end(), b) > 0 && std::count(u.begin(), u.end(), c) > 0) return f;
  }
  return -1;
}

// The centre of a tetrahedron's circumscribed sphere (its centroid when the tetrahedron is flat
// to rounding).
Vec3 circumcentre(const Vec3 (&p)[4]) {
  const Vec3 a = p[1] - p[0], b = p[2] - p[0], c = p[3] - p[0];
  const double det = 2.0 * a.dot(b.cross(c));
  const double scale = a.norm() * b.norm() * c.norm();
  if (!(std::abs(det) > kParallelSine * scale)) return 0.25 * (p[0] + p[1] + p[2] + p[3]);
  return p[0] + (a.squaredNorm() * b.cross(c) + b.squaredNorm() * c.cross(a) +
                 c.squaredNorm() * a.cross(b)) /
                    det;
}

}  // namespace mesh_parts

long long insert_nodes_in_slivers(TetMesh* mesh, double angle) {
  long long inserted = 0;
  for (int round = 0; round < 3; ++round) {
    const size_t ne = mesh->tets.size();
    std::vector<double> least;
    std::vector<int32_t> bad = elements_under(*mesh, angle, &least);
    if (bad.empty()) break;
    // The elements around each node: around[start[n]] to around[start[n + 1] - 1].
    std::vector<int32_t> start, around;
    elements_around(*mesh, &start, &around);
    // Elements replaced in this round. A face of a kept element whose other side was replaced
    // finds the replaced element (the new ones are not in `around`), which counts as outside.
    std::vector<uint8_t> gone(ne, 0);
    // The element across face k of e (the face without corner k), -1 if none.
    auto across = [&](int32_t e, int k) {
      const auto& t = mesh->tets[e];
      return element_on(*mesh, start, around, t[(k + 1) % 4], t[(k + 2) % 4], t[(k + 3) % 4], e);
    };
    auto tet_points = [&](const std::array<int32_t, 4>& t, Vec3(&p)[4]) {
      for (int k = 0; k < 4; ++k) p[k] = mesh->nodes[t[k]];
    };
    long long this_round = 0;
    for (int32_t e : bad) {
      if (gone[e]) continue;
      const uint64_t region = region_of(*mesh, e);
      Vec3 pe[4];
      tet_points(mesh->tets[e], pe);
      // Candidates: the circumcentre and the centroid of the element, and the centroid of its
      // neighbours in its region.
      std::vector<Vec3> candidates = {circumcentre(pe), 0.25 * (pe[0] + pe[1] + pe[2] + pe[3])};
      {
        Vec3 sum = Vec3::Zero();
        int n = 0;
        for (int k = 0; k < 4; ++k) {
          const int32_t f = across(e, k);
          if (f < 0 || gone[f] || region_of(*mesh, f) != region) continue;
          for (int32_t m : mesh->tets[f]) sum += mesh->nodes[m];
          n += 4;
        }
        if (n > 0) candidates.push_back(sum / n);
      }
      struct Best {
        double worst = -1.0;
        int below = 0;
        std::vector<int32_t> cavity;
        std::vector<std::array<int32_t, 4>> tets;
        Vec3 p;
      } best;
      double old_worst = 0.0;
      int old_below = 0;
      for (const Vec3& p : candidates) {
        // The cavity: the elements of the region connected to e whose circumscribed sphere
        // holds p (e always).
        std::vector<int32_t> cavity = {e};
        std::set<int32_t> in(cavity.begin(), cavity.end());
        for (size_t q = 0; q < cavity.size() && cavity.size() < 200; ++q) {
          for (int k = 0; k < 4; ++k) {
            const int32_t f = across(cavity[q], k);
            if (f < 0 || gone[f] || in.count(f) || region_of(*mesh, f) != region) continue;
            Vec3 pf[4];
            tet_points(mesh->tets[f], pf);
            const Vec3 cc = circumcentre(pf);
            if ((p - cc).squaredNorm() < (pf[0] - cc).squaredNorm() * (1.0 - kRoundoff)) {
              cavity.push_back(f);
              in.insert(f);
            }
          }
        }
        // Each face of the cavity's boundary with p: its element with the opposite corner
        // replaced by p (positive when p sees the face from inside). An element with a face
        // that p does not see leaves the cavity (unless it is e), until p sees every face.
        const int32_t pn = static_cast<int32_t>(mesh->nodes.size());
        mesh->nodes.push_back(p);
        std::vector<std::array<int32_t, 4>> made;
        double volume_old = 0.0, volume_new = 0.0, worst = 180.0, was = 180.0;
        int below = 0, was_below = 0;
        bool ok = false;
        for (int pass = 0; pass < 64 && !ok; ++pass) {
          made.clear();
          volume_old = volume_new = 0.0;
          worst = was = 180.0;
          below = was_below = 0;
          std::vector<int32_t> blind;
          for (int32_t c : cavity) {
            volume_old += tet_volume(mesh->nodes, mesh->tets[c]);
            was = std::min(was, least[c]);
            was_below += least[c] < angle;
            for (int k = 0; k < 4; ++k) {
              const int32_t f = across(c, k);
              if (f >= 0 && in.count(f)) continue;
              std::array<int32_t, 4> t = mesh->tets[c];
              t[k] = pn;
              const double v = tet_volume(mesh->nodes, t);
              if (!(v > 0.0)) {
                blind.push_back(c);
                break;
              }
              volume_new += v;
              const double a = least_dihedral(*mesh, t);
              worst = std::min(worst, a);
              below += a < angle;
              made.push_back(t);
            }
          }
          if (blind.empty()) {
            ok = true;
            break;
          }
          if (std::count(blind.begin(), blind.end(), e)) break;
          for (int32_t c : blind) in.erase(c);
          cavity.erase(
              std::remove_if(cavity.begin(), cavity.end(), [&](int32_t c) { return !in.count(c); }),
              cavity.end());
        }
        mesh->nodes.pop_back();
        ok = ok && std::abs(volume_new - volume_old) <= kVolumeRoundoff * volume_old;
        if (!ok) continue;
        if (best.worst < 0.0 || worst > best.worst) {
          best = {worst, below, cavity, made, p};
          old_worst = was;
          old_below = was_below;
        }
      }
      if (best.worst < 0.0) continue;
      // Taken when it lifts every element over the angle, or raises the least angle with
      // fewer elements under it.
      if (!(best.worst >= angle || (best.worst > old_worst && best.below < old_below))) continue;
      mesh->nodes.push_back(best.p);
      for (int32_t c : best.cavity) gone[c] = 1;
      const int32_t phase = mesh->phase[e], id = mesh->inclusion_id[e];
      for (const auto& t : best.tets) {  // made with the node at its index now
        mesh->tets.push_back(t);
        mesh->phase.push_back(phase);
        mesh->inclusion_id.push_back(id);
      }
      ++this_round;
    }
    drop_elements(mesh, gone);  // the elements replaced
    inserted += this_round;
    if (this_round == 0) break;
  }
  return inserted;
}

int repair_slivers(TetMesh* mesh, const InclusionSet& set, double angle) {
  std::vector<double> least;
  size_t before = elements_under(*mesh, angle, &least).size();
  int rounds = 0;
  // A round may leave more than it found (an inserted node's new elements) and the next lift
  // them: on meshes of spheres and fibres saved before the repairs, the first round left more
  // elements under 5 degrees than it found, and the second none. The rounds end when one
  // changes nothing.
  while (before > 0 && rounds < 4) {
    ++rounds;
    const long long lifted = lift_slivers(mesh, set, angle);
    const long long remade = remake_slivers(mesh, angle);
    const long long inserted = insert_nodes_in_slivers(mesh, angle);
    mesh->relocated_nodes += lifted;
    mesh->remade_slivers += remade;
    mesh->inserted_nodes += inserted;
    if (lifted == 0 && remade == 0 && inserted == 0) break;
    before = elements_under(*mesh, angle, &least).size();
  }
  return rounds;
}

}  // namespace rvegen
