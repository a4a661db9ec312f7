// Slivers remade with their neighbours by flips (one of the sliver repairs of slivers.cpp):
// the elements about a sliver's edge or face replaced by fewer, better ones, and a sliver's
// near-crossing edges collapsed.
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

namespace {

// A retriangulation of some elements: the elements it replaces, the new ones (positive) and
// the region (index of an old element whose phase and inclusion it takes) of each.
struct Remake {
  double worst = -1.0;  // least angle of the new elements (-1: none valid)
  int below = 0;        // new elements under the angle
  std::vector<int32_t> old;
  std::vector<std::array<int32_t, 4>> tets;
  std::vector<int32_t> like;
  bool moves_interface = false;
};

// The distance between the lines through p0-p1 and q0-q1 (the larger of the two endpoints'
// distances when they are parallel).
double line_distance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
  const Vec3 n = (p1 - p0).cross(q1 - q0);
  if (n.norm() > kParallelSine * (p1 - p0).norm() * (q1 - q0).norm()) {
    return std::abs((q0 - p0).dot(n.normalized()));
  }
  const Vec3 d = (p1 - p0).normalized();
  const Vec3 r = q0 - p0;
  return (r - r.dot(d) * d).norm();
}

bool has(const std::array<int32_t, 4>& t, int32_t n) {
  return t[0] == n || t[1] == n || t[2] == n || t[3] == n;
}

// The closed ring of elements around an edge (u, v): the polygon w of their other nodes in
// order, the element between w[k] and w[k + 1], and where the ring's two runs of regions
// meet (split: the runs are w[0..split] and w[split..n]; n when the ring is in one region).
struct EdgeRing {
  std::vector<int32_t> elements;
  std::vector<int32_t> w;
  std::vector<int32_t> tet_of;
  int split = 0;
};

// One round of remakes over a mesh: the elements under the angle, worst first, each replaced
// with its neighbours by the best of the remakes about it, where that lifts it.
class RemakeRound {
 public:
  RemakeRound(TetMesh* mesh, const std::vector<std::array<int8_t, 3>>& ends, double angle)
      : mesh_(*mesh), ends_(ends), angle_(angle) {
    bad_ = elements_under(mesh_, angle_, &least_);
    // The worst first; the same order on every run.
    std::sort(bad_.begin(), bad_.end(), [&](int32_t a, int32_t b) {
      return least_[a] < least_[b] || (least_[a] == least_[b] && a < b);
    });
    elements_around(mesh_, &start_, &around_);
    gone_.assign(mesh_.tets.size(), 0);
  }

  bool any_under() const { return !bad_.empty(); }

  // Remakes what it can; returns how many remakes were made.
  long long run() {
    long long made = 0;
    for (int32_t e : bad_) {
      if (gone_[e]) continue;
      const Remake best = best_about(e);
      if (best.worst < 0.0 || !lifts(best)) continue;
      for (int32_t o : best.old) gone_[o] = 1;
      for (size_t i = 0; i < best.tets.size(); ++i) {
        const int32_t phase = mesh_.phase[best.like[i]], id = mesh_.inclusion_id[best.like[i]];
        mesh_.tets.push_back(best.tets[i]);
        mesh_.phase.push_back(phase);
        mesh_.inclusion_id.push_back(id);
      }
      ++made;
    }
    drop_elements(&mesh_, gone_);
    return made;
  }

 private:
  bool same_face(int32_t a, int32_t b) const {
    for (int x = 0; x < 3; ++x) {
      if (ends_[a][x] >= 0 && ends_[a][x] == ends_[b][x]) return true;
    }
    return false;
  }

  // The least dihedral angle of t, turned positive; -1 when flat.
  double quality(std::array<int32_t, 4>* t) const {
    const double v = tet_volume(mesh_.nodes, *t);
    if (!(v != 0.0)) return -1.0;
    if (v < 0.0) std::swap((*t)[0], (*t)[1]);
    return least_dihedral(mesh_, *t);
  }

  void score(Remake* r) const {
    r->worst = 180.0;
    r->below = 0;
    for (auto& t : r->tets) {
      const double q = quality(&t);
      r->worst = std::min(r->worst, q);
      r->below += q < angle_;
    }
  }

  // The best remake about element e by least angle; at a tie, the one that keeps the
  // interfaces.
  Remake best_about(int32_t e) const {
    Remake best;
    auto consider = [&](Remake&& r) {
      if (r.worst > best.worst ||
          (r.worst == best.worst && best.moves_interface && !r.moves_interface)) {
        best = std::move(r);
      }
    };
    const auto t = mesh_.tets[e];
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) {
        Remake r;
        if (remove_edge(t[i], t[j], &r)) consider(std::move(r));
      }
      Remake r;
      if (split_face(e, i, &r)) consider(std::move(r));
    }
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 4; ++j) {
        Remake r;
        if (i != j && collapse(t[i], t[j], &r)) consider(std::move(r));
      }
    }
    return best;
  }

  // Taken when it lifts every element over the angle, or raises the least angle with fewer
  // elements under it.
  bool lifts(const Remake& r) const {
    double was = 180.0;
    int was_below = 0;
    for (int32_t o : r.old) {
      was = std::min(was, least_[o]);
      was_below += least_[o] < angle_;
    }
    return r.worst >= angle_ || (r.worst > was && r.below < was_below);
  }

  // The ring about edge (u, v), closed (an open one lies in a box face), of 3 to 12 elements
  // none gone, whose polygon visits no node twice.
  bool edge_ring(int32_t u, int32_t v, EdgeRing* out) const {
    std::vector<int32_t>& ring = out->elements;
    for (int32_t i = start_[u]; i < start_[u + 1]; ++i) {
      const int32_t f = around_[i];
      if (has(mesh_.tets[f], v)) {
        if (gone_[f]) return false;
        ring.push_back(f);
      }
    }
    const int n = static_cast<int>(ring.size());
    if (n < 3 || n > 12) return false;
    // The link: each element's two other nodes; a closed cycle.
    std::vector<std::array<int32_t, 2>> link(n);
    for (int k = 0; k < n; ++k) {
      int c = 0;
      for (int32_t m : mesh_.tets[ring[k]]) {
        if (m != u && m != v) link[k][c++] = m;
      }
    }
    std::vector<int32_t>& w = out->w;
    w = {link[0][0], link[0][1]};
    out->tet_of = {ring[0]};
    std::vector<uint8_t> used(n, 0);
    used[0] = 1;
    while (static_cast<int>(w.size()) <= n) {
      int next = -1;
      for (int k = 0; k < n && next < 0; ++k) {
        if (!used[k] && (link[k][0] == w.back() || link[k][1] == w.back())) next = k;
      }
      if (next < 0) return false;  // open: the edge lies in a box face
      used[next] = 1;
      out->tet_of.push_back(ring[next]);
      w.push_back(link[next][0] == w.back() ? link[next][1] : link[next][0]);
    }
    if (w.back() != w.front()) return false;
    w.pop_back();
    std::vector<int32_t> sorted = w;
    std::sort(sorted.begin(), sorted.end());
    return std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end();
  }

  // The ring's runs of regions: one, or two whose new interface (the diagonal between the
  // runs' ends) lies nearly in the plane of the old one's two triangles: the lines u-v and
  // a-b within kFlipReach of the shorter apart, so the interface moves by no more than the
  // flat element between them. Rotates the ring to start at the first run.
  bool split_runs(int32_t u, int32_t v, EdgeRing* ring) const {
    const int n = static_cast<int>(ring->w.size());
    std::vector<int> cuts;
    for (int k = 0; k < n; ++k) {
      if (region_of(mesh_, ring->tet_of[k]) != region_of(mesh_, ring->tet_of[(k + n - 1) % n])) {
        cuts.push_back(k);
      }
    }
    if (cuts.size() != 0 && cuts.size() != 2) return false;
    ring->split = n;
    if (cuts.empty()) return true;
    std::rotate(ring->w.begin(), ring->w.begin() + cuts[0], ring->w.end());
    std::rotate(ring->tet_of.begin(), ring->tet_of.begin() + cuts[0], ring->tet_of.end());
    ring->split = cuts[1] - cuts[0];
    const int32_t a = ring->w[0], b = ring->w[ring->split];
    if (same_face(a, b)) return false;
    const Vec3 &pu = mesh_.nodes[u], &pv = mesh_.nodes[v];
    const Vec3 &pa = mesh_.nodes[a], &pb = mesh_.nodes[b];
    const double shorter = std::min((pv - pu).norm(), (pb - pa).norm());
    return line_distance(pu, pv, pa, pb) <= kFlipReach * shorter;
  }

  // Edge removal: the elements around edge (u, v), a closed ring in one region or in two
  // (each a run of the ring), replaced by a triangulation of the ring's polygon joined to u
  // and to v, the one whose least angle is largest (Klincsek's dynamic programme). In two
  // regions the triangulation keeps the diagonal between the two runs' ends, which becomes
  // the interface: the interface's edge (u, v) is flipped (see split_runs).
  bool remove_edge(int32_t u, int32_t v, Remake* out) const {
    EdgeRing ring;
    if (!edge_ring(u, v, &ring) || !split_runs(u, v, &ring)) return false;
    const int n = static_cast<int>(ring.w.size()), split = ring.split;
    std::vector<int32_t>& w = ring.w;
    w.push_back(w[0]);
    // The side of u: the sign that the fan's volumes (triangle with u, less triangle with
    // v) add up to; every new element with u must have it.
    auto vol = [&](int32_t p, int32_t q, int32_t r, int32_t s) {
      return tet_volume(mesh_.nodes, {p, q, r, s});
    };
    double sum = 0.0;
    for (int k = 1; k + 1 < n; ++k) {
      sum += vol(w[0], w[k], w[k + 1], u) - vol(w[0], w[k], w[k + 1], v);
    }
    if (!(sum != 0.0)) return false;
    const double sign = sum > 0.0 ? 1.0 : -1.0;
    auto triangle = [&](int i, int k, int j) {
      const int32_t p = w[i], q = w[k], r = w[j];
      if (!(sign * vol(p, q, r, u) > 0.0 && sign * vol(p, q, r, v) < 0.0)) return -1.0;
      std::array<int32_t, 4> tu = {p, q, r, u}, tv = {p, q, r, v};
      return std::min(quality(&tu), quality(&tv));
    };
    // best[i][j]: the largest least angle over triangulations of w[i..j]; pick[i][j] its apex.
    const int m = n + 1;
    std::vector<double> best(m * m, 180.0);
    std::vector<int> pick(m * m, -1);
    auto solve = [&](int lo, int hi) {
      for (int len = 2; len <= hi - lo; ++len) {
        for (int i = lo; i + len <= hi; ++i) {
          const int j = i + len;
          double b = -1.0;
          for (int k = i + 1; k < j; ++k) {
            const double q = std::min({triangle(i, k, j), best[i * m + k], best[k * m + j]});
            if (q > b) {
              b = q;
              pick[i * m + j] = k;
            }
          }
          best[i * m + j] = b;
        }
      }
    };
    std::vector<std::array<int, 3>> parts;  // (lo, hi, the ring element whose region)
    if (split == n) {
      solve(0, n - 1);  // w[0..n-1]: its side w[n-1]-w[0] closes it
      parts.push_back({0, n - 1, 0});
    } else {
      solve(0, split);
      solve(split, n);
      parts.push_back({0, split, 0});
      parts.push_back({split, n, split});
    }
    Remake r;
    r.old = ring.elements;
    r.moves_interface = split != n;
    for (const auto& part : parts) {
      const int32_t like = ring.tet_of[part[2]];
      if (part[1] - part[0] < 2) {
        // A run of one element goes, and its faces away from the edge become the interface:
        // both must face elements of its own region (not a box face, not a third region).
        const int32_t a = w[part[0]], b = w[part[1]];
        for (int32_t c : {u, v}) {
          const int32_t f = element_on(mesh_, start_, around_, a, b, c, like);
          if (f < 0 || gone_[f] || region_of(mesh_, f) != region_of(mesh_, like)) return false;
        }
        continue;
      }
      if (!(best[part[0] * m + part[1]] > 0.0)) return false;
      std::vector<std::array<int, 2>> stack = {{part[0], part[1]}};
      while (!stack.empty()) {
        const auto [i, j] = stack.back();
        stack.pop_back();
        if (j - i < 2) continue;
        const int k = pick[i * m + j];
        r.tets.push_back({w[i], w[k], w[j], u});
        r.tets.push_back({w[i], w[k], w[j], v});
        r.like.push_back(like);
        r.like.push_back(like);
        stack.push_back({i, k});
        stack.push_back({k, j});
      }
    }
    score(&r);
    *out = std::move(r);
    return true;
  }

  // Two elements of one region on either side of face k of e, made three about the line
  // between their other nodes (where it crosses the face).
  bool split_face(int32_t e, int k, Remake* out) const {
    const auto& t = mesh_.tets[e];
    const int32_t p = t[(k + 1) % 4], q = t[(k + 2) % 4], r = t[(k + 3) % 4], d = t[k];
    const int32_t f = element_on(mesh_, start_, around_, p, q, r, e);
    if (f < 0 || gone_[f] || region_of(mesh_, f) != region_of(mesh_, e)) return false;
    int32_t x = -1;
    for (int32_t c : mesh_.tets[f]) {
      if (c != p && c != q && c != r) x = c;
    }
    const double s1 = tet_volume(mesh_.nodes, {p, q, d, x});
    const double s2 = tet_volume(mesh_.nodes, {q, r, d, x});
    const double s3 = tet_volume(mesh_.nodes, {r, p, d, x});
    if (!((s1 > 0.0 && s2 > 0.0 && s3 > 0.0) || (s1 < 0.0 && s2 < 0.0 && s3 < 0.0))) {
      return false;
    }
    Remake m;
    m.old = {e, f};
    m.tets = {{p, q, d, x}, {q, r, d, x}, {r, p, d, x}};
    m.like = {e, e, e};
    score(&m);
    *out = std::move(m);
    return true;
  }

  // Whether moving v to u moves the interfaces about v by little: each of v's triangles must
  // lie between two elements (v lies inside the mesh), and those of an interface that do not
  // hold u must have u within kCollapseReach of the mean length of v's other edges from
  // their plane.
  bool interfaces_stay(int32_t v, int32_t u, const std::vector<int32_t>& star,
                       double mean_edge) const {
    std::map<std::pair<int32_t, int32_t>, std::vector<uint64_t>> sides;
    for (int32_t f : star) {
      const auto& t = mesh_.tets[f];
      for (int i = 0; i < 4; ++i) {
        for (int j = i + 1; j < 4; ++j) {
          if (t[i] == v || t[j] == v) continue;
          sides[{std::min(t[i], t[j]), std::max(t[i], t[j])}].push_back(region_of(mesh_, f));
        }
      }
    }
    const double reach = kCollapseReach * mean_edge;
    const Vec3& x = mesh_.nodes[v];
    for (const auto& [pq, by] : sides) {
      if (by.size() != 2) return false;
      if (by[0] == by[1] || pq.first == u || pq.second == u) continue;
      const Vec3 n = (mesh_.nodes[pq.first] - x).cross(mesh_.nodes[pq.second] - x);
      if (!(std::abs((mesh_.nodes[u] - x).dot(n)) <= reach * n.norm())) return false;
    }
    return true;
  }

  // An edge collapsed into one of its nodes u: its other node v (inside the box) goes, the
  // elements around the edge go, v's other elements take u instead. v must lie in one region
  // (nothing but the elements changes), or on one interface whose two regions both meet the
  // edge and which moves little (interfaces_stay: a short edge, or one along a flat
  // interface).
  bool collapse(int32_t v, int32_t u, Remake* out) const {
    if (ends_[v][0] >= 0 || ends_[v][1] >= 0 || ends_[v][2] >= 0) return false;
    std::vector<int32_t> star;
    std::vector<uint64_t> regions, on_edge;
    double others = 0.0;
    int count = 0;
    for (int32_t i = start_[v]; i < start_[v + 1]; ++i) {
      const int32_t f = around_[i];
      if (gone_[f]) return false;
      star.push_back(f);
      const uint64_t r = region_of(mesh_, f);
      if (std::find(regions.begin(), regions.end(), r) == regions.end()) regions.push_back(r);
      if (has(mesh_.tets[f], u)) {
        if (std::find(on_edge.begin(), on_edge.end(), r) == on_edge.end()) on_edge.push_back(r);
        continue;
      }
      for (int32_t m : mesh_.tets[f]) {
        if (m == v) continue;
        others += (mesh_.nodes[m] - mesh_.nodes[v]).norm();
        ++count;
      }
    }
    if (regions.size() > 2 || on_edge.size() != regions.size() || count == 0) return false;
    if (!interfaces_stay(v, u, star, others / count)) return false;
    Remake r;
    r.old = star;
    r.moves_interface = regions.size() == 2;
    for (int32_t f : star) {
      auto t = mesh_.tets[f];
      if (has(t, u)) continue;
      std::replace(t.begin(), t.end(), v, u);
      if (!(tet_volume(mesh_.nodes, t) > 0.0)) return false;
      r.tets.push_back(t);
      r.like.push_back(f);
    }
    score(&r);
    *out = std::move(r);
    return true;
  }

  TetMesh& mesh_;
  const std::vector<std::array<int8_t, 3>>& ends_;
  const double angle_;
  std::vector<double> least_;
  std::vector<int32_t> bad_;
  // The elements around each node n: around_[start_[n]] to around_[start_[n + 1] - 1].
  std::vector<int32_t> start_, around_;
  std::vector<uint8_t> gone_;
};

}  // namespace

long long remake_slivers(TetMesh* mesh, double angle) {
  const std::vector<std::array<int8_t, 3>> ends = node_ends(*mesh);
  long long remakes = 0;
  for (int round = 0; round < kRemakeRounds; ++round) {
    RemakeRound remake(mesh, ends, angle);
    if (!remake.any_under()) break;
    const long long made = remake.run();
    remakes += made;
    if (made == 0) break;
  }
  drop_unused_nodes(mesh);  // the collapsed nodes
  return remakes;
}

}  // namespace rvegen
