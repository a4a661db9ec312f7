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

}  // namespace

long long remake_slivers(TetMesh* mesh, double angle) {
  const std::vector<std::array<int8_t, 3>> ends = node_ends(*mesh);
  auto same_face = [&](int32_t a, int32_t b) {
    for (int x = 0; x < 3; ++x) {
      if (ends[a][x] >= 0 && ends[a][x] == ends[b][x]) return true;
    }
    return false;
  };
  long long remakes = 0;
  for (int round = 0; round < 4; ++round) {
    const size_t ne = mesh->tets.size();
    std::vector<double> least;
    std::vector<int32_t> bad = elements_under(*mesh, angle, &least);
    if (bad.empty()) break;
    // The worst first; the same order on every run.
    std::sort(bad.begin(), bad.end(), [&](int32_t a, int32_t b) {
      return least[a] < least[b] || (least[a] == least[b] && a < b);
    });
    // The elements around each node: around[start[n]] to around[start[n + 1] - 1].
    std::vector<int32_t> start, around;
    elements_around(*mesh, &start, &around);
    std::vector<uint8_t> gone(ne, 0);
    auto has = [](const std::array<int32_t, 4>& t, int32_t n) {
      return t[0] == n || t[1] == n || t[2] == n || t[3] == n;
    };
    auto quality = [&](std::array<int32_t, 4>* t) {
      const double v = tet_volume(mesh->nodes, *t);
      if (!(v != 0.0)) return -1.0;
      if (v < 0.0) std::swap((*t)[0], (*t)[1]);
      return least_dihedral(*mesh, *t);
    };
    auto score = [&](Remake* r) {
      r->worst = 180.0;
      r->below = 0;
      for (auto& t : r->tets) {
        const double q = quality(&t);
        r->worst = std::min(r->worst, q);
        r->below += q < angle;
      }
    };

    // Edge removal: the elements around edge (u, v), a closed ring in one region or in two
    // (each a run of the ring), replaced by a triangulation of the ring's polygon joined to u
    // and to v, the one whose least angle is largest (Klincsek's dynamic programme). In two
    // regions the triangulation keeps the diagonal between the two runs' ends, which becomes
    // the interface: the interface's edge (u, v) is flipped, allowed only where its two
    // triangles nearly lie in one plane (the lines u-v and a-b within a tenth of the shorter
    // apart), so the interface moves by no more than the flat element between them.
    auto remove_edge = [&](int32_t u, int32_t v, Remake* out) {
      std::vector<int32_t> ring;
      for (int32_t i = start[u]; i < start[u + 1]; ++i) {
        const int32_t f = around[i];
        if (has(mesh->tets[f], v)) {
          if (gone[f]) return false;
          ring.push_back(f);
        }
      }
      const int n = static_cast<int>(ring.size());
      if (n < 3 || n > 12) return false;
      // The link: each element's two other nodes; a closed cycle.
      std::vector<std::array<int32_t, 2>> link(n);
      for (int k = 0; k < n; ++k) {
        int c = 0;
        for (int32_t m : mesh->tets[ring[k]]) {
          if (m != u && m != v) link[k][c++] = m;
        }
      }
      std::vector<int32_t> w = {link[0][0], link[0][1]};
      std::vector<int32_t> tet_of = {ring[0]};  // element between w[i] and w[i + 1]
      std::vector<uint8_t> used(n, 0);
      used[0] = 1;
      while (static_cast<int>(w.size()) <= n) {
        int next = -1;
        for (int k = 0; k < n && next < 0; ++k) {
          if (!used[k] && (link[k][0] == w.back() || link[k][1] == w.back())) next = k;
        }
        if (next < 0) return false;  // open: the edge lies in a box face
        used[next] = 1;
        tet_of.push_back(ring[next]);
        w.push_back(link[next][0] == w.back() ? link[next][1] : link[next][0]);
      }
      if (w.back() != w.front()) return false;
      w.pop_back();
      {
        std::vector<int32_t> sorted = w;
        std::sort(sorted.begin(), sorted.end());
        if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) return false;
      }
      // The runs of regions around the ring.
      std::vector<int> cuts;
      for (int k = 0; k < n; ++k) {
        if (region_of(*mesh, tet_of[k]) != region_of(*mesh, tet_of[(k + n - 1) % n])) {
          cuts.push_back(k);
        }
      }
      if (cuts.size() != 0 && cuts.size() != 2) return false;
      int split = n;  // the polygon 0..split and split..n (w[n] = w[0])
      if (cuts.size() == 2) {
        std::rotate(w.begin(), w.begin() + cuts[0], w.end());
        std::rotate(tet_of.begin(), tet_of.begin() + cuts[0], tet_of.end());
        split = cuts[1] - cuts[0];
        const int32_t a = w[0], b = w[split];
        if (same_face(a, b)) return false;
        const Vec3 &pu = mesh->nodes[u], &pv = mesh->nodes[v];
        const Vec3 &pa = mesh->nodes[a], &pb = mesh->nodes[b];
        const double shorter = std::min((pv - pu).norm(), (pb - pa).norm());
        if (!(line_distance(pu, pv, pa, pb) <= 0.1 * shorter)) return false;
      }
      w.push_back(w[0]);
      // The side of u: the sign that the fan's volumes (triangle with u, less triangle with
      // v) add up to; every new element with u must have it.
      auto vol = [&](int32_t p, int32_t q, int32_t r, int32_t s) {
        return tet_volume(mesh->nodes, {p, q, r, s});
      };
      double sum = 0.0;
      for (int k = 1; k + 1 < n; ++k)
        sum += vol(w[0], w[k], w[k + 1], u) - vol(w[0], w[k], w[k + 1], v);
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
      r.old = ring;
      r.moves_interface = split != n;
      for (const auto& part : parts) {
        if (part[1] - part[0] < 2) {
          // A run of one element goes, and its faces away from the edge become the interface:
          // both must face elements of its own region (not a box face, not a third region).
          const int32_t one = tet_of[part[2]], a = w[part[0]], b = w[part[1]];
          for (int32_t c : {u, v}) {
            const int32_t f = element_on(*mesh, start, around, a, b, c, one);
            if (f < 0 || gone[f] || region_of(*mesh, f) != region_of(*mesh, one)) return false;
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
          r.like.push_back(tet_of[part[2]]);
          r.like.push_back(tet_of[part[2]]);
          stack.push_back({i, k});
          stack.push_back({k, j});
        }
      }
      score(&r);
      *out = std::move(r);
      return true;
    };

    // Two elements of one region on either side of a face, made three about the line between
    // their other nodes (where it crosses the face).
    auto split_face = [&](int32_t e, int k, Remake* out) {
      const auto& t = mesh->tets[e];
      const int32_t p = t[(k + 1) % 4], q = t[(k + 2) % 4], r = t[(k + 3) % 4], d = t[k];
      const int32_t f = element_on(*mesh, start, around, p, q, r, e);
      if (f < 0 || gone[f] || region_of(*mesh, f) != region_of(*mesh, e)) return false;
      int32_t x = -1;
      for (int32_t c : mesh->tets[f]) {
        if (c != p && c != q && c != r) x = c;
      }
      const double s1 = tet_volume(mesh->nodes, {p, q, d, x});
      const double s2 = tet_volume(mesh->nodes, {q, r, d, x});
      const double s3 = tet_volume(mesh->nodes, {r, p, d, x});
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
    };

    // An edge collapsed into one of its nodes u: its other node v (inside the box) goes, the
    // elements around the edge go, v's other elements take u instead. v must lie in one region
    // (nothing but the elements changes), or on one interface whose two regions both meet the
    // edge, where u lies within a tenth of the mean length of v's other edges of the plane of
    // each of v's interface triangles (the interface then moves by no more than that: a short
    // edge, or one along a flat interface).
    auto collapse = [&](int32_t v, int32_t u, Remake* out) {
      if (ends[v][0] >= 0 || ends[v][1] >= 0 || ends[v][2] >= 0) return false;
      std::vector<int32_t> star;
      std::vector<uint64_t> regions, on_edge;
      double others = 0.0;
      int count = 0;
      for (int32_t i = start[v]; i < start[v + 1]; ++i) {
        const int32_t f = around[i];
        if (gone[f]) return false;
        star.push_back(f);
        const uint64_t r = region_of(*mesh, f);
        if (std::find(regions.begin(), regions.end(), r) == regions.end()) regions.push_back(r);
        if (has(mesh->tets[f], u)) {
          if (std::find(on_edge.begin(), on_edge.end(), r) == on_edge.end()) on_edge.push_back(r);
          continue;
        }
        for (int32_t m : mesh->tets[f]) {
          if (m == v) continue;
          others += (mesh->nodes[m] - mesh->nodes[v]).norm();
          ++count;
        }
      }
      if (regions.size() > 2 || on_edge.size() != regions.size() || count == 0) return false;
      // v's triangles (v, p, q) and the regions of the elements on them: two each (v lies
      // inside the mesh), of two regions where v's interface passes.
      std::map<std::pair<int32_t, int32_t>, std::vector<uint64_t>> sides;
      for (int32_t f : star) {
        const auto& t = mesh->tets[f];
        for (int i = 0; i < 4; ++i) {
          for (int j = i + 1; j < 4; ++j) {
            if (t[i] == v || t[j] == v) continue;
            sides[{std::min(t[i], t[j]), std::max(t[i], t[j])}].push_back(region_of(*mesh, f));
          }
        }
      }
      const double reach = 0.1 * others / count;
      const Vec3& x = mesh->nodes[v];
      for (const auto& [pq, by] : sides) {
        if (by.size() != 2) return false;
        if (by[0] == by[1] || pq.first == u || pq.second == u) continue;
        const Vec3 n = (mesh->nodes[pq.first] - x).cross(mesh->nodes[pq.second] - x);
        if (!(std::abs((mesh->nodes[u] - x).dot(n)) <= reach * n.norm())) return false;
      }
      Remake r;
      r.old = star;
      r.moves_interface = regions.size() == 2;
      for (int32_t f : star) {
        auto t = mesh->tets[f];
        if (has(t, u)) continue;
        std::replace(t.begin(), t.end(), v, u);
        if (!(tet_volume(mesh->nodes, t) > 0.0)) return false;
        r.tets.push_back(t);
        r.like.push_back(f);
      }
      score(&r);
      *out = std::move(r);
      return true;
    };

    long long this_round = 0;
    for (int32_t e : bad) {
      if (gone[e]) continue;
      Remake best;
      // The best by least angle; at a tie, the one that keeps the interfaces.
      auto consider = [&](Remake&& r) {
        if (r.worst > best.worst ||
            (r.worst == best.worst && best.moves_interface && !r.moves_interface)) {
          best = std::move(r);
        }
      };
      const auto t = mesh->tets[e];
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
      if (best.worst < 0.0) continue;
      double was = 180.0;
      int was_below = 0;
      for (int32_t o : best.old) {
        was = std::min(was, least[o]);
        was_below += least[o] < angle;
      }
      // Taken when it lifts every element over the angle, or raises the least angle with
      // fewer elements under it.
      if (!(best.worst >= angle || (best.worst > was && best.below < was_below))) continue;
      for (int32_t o : best.old) gone[o] = 1;
      for (size_t i = 0; i < best.tets.size(); ++i) {
        const int32_t phase = mesh->phase[best.like[i]], id = mesh->inclusion_id[best.like[i]];
        mesh->tets.push_back(best.tets[i]);
        mesh->phase.push_back(phase);
        mesh->inclusion_id.push_back(id);
      }
      ++this_round;
    }
    drop_elements(mesh, gone);
    remakes += this_round;
    if (this_round == 0) break;
  }
  drop_unused_nodes(mesh);  // the collapsed nodes
  return remakes;
}

}  // namespace rvegen
