#include "rvegen/geometry/convex.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "rvegen/geometry/tolerances.hpp"

namespace rvegen {
namespace {

// Shapes whose centres are this near (relative to their bounding radii) start GJK from a fixed
// direction: their difference has none.
constexpr double kCoincidentCentres = 1e-13;

// A vertex of the Minkowski difference D = a - b with the support points that made it.
struct Vertex {
  Vec3 w, pa, pb;
};

// A shape's support function (the same maps as Shape::support) with what depends on the shape
// alone worked out once per query instead of at every call: the cylinder's unit axis and half
// length, the ellipsoid's squared semi-axes.
class SupportMap {
 public:
  explicit SupportMap(const Shape& s) : s_(s) {
    if (s.kind == ShapeKind::Cylinder) {
      u_ = s.half_axis / s.half_axis.norm();
      top_ = s.center + s.half_axis;
      bottom_ = s.center - s.half_axis;
    } else if (s.kind == ShapeKind::Ellipsoid) {
      a2_ = s.semi_axes.cwiseProduct(s.semi_axes);
    }
  }
  Vec3 operator()(const Vec3& d) const {
    switch (s_.kind) {
      case ShapeKind::Sphere:
        return s_.center + (s_.radius / d.norm()) * d;
      case ShapeKind::Cylinder: {
        const double du = d.dot(u_);
        Vec3 x = du >= 0.0 ? top_ : bottom_;
        Vec3 radial = d - du * u_;
        radial -= radial.dot(u_) * u_;  // second Gram-Schmidt pass, as in Shape::support
        const double rn2 = radial.squaredNorm();
        if (rn2 > kRoundoff2 * d.squaredNorm()) x += (s_.radius / std::sqrt(rn2)) * radial;
        return x;
      }
      case ShapeKind::Ellipsoid: {
        const Vec3 dl = s_.rotation.transpose() * d;
        const Vec3 md = a2_.cwiseProduct(dl);
        return s_.center + s_.rotation * (md / std::sqrt(dl.dot(md)));
      }
    }
    return s_.center;
  }

 private:
  const Shape& s_;
  Vec3 u_ = Vec3::Zero(), a2_ = Vec3::Zero();
  Vec3 top_ = Vec3::Zero(), bottom_ = Vec3::Zero();  // end disk centres of a cylinder
};

// A sheared piece's support function (ShearedPiece::support).
class PieceSupport {
 public:
  explicit PieceSupport(const ShearedPiece& p) : p_(p) {}
  Vec3 operator()(const Vec3& d) const { return p_.support(d); }

 private:
  const ShearedPiece& p_;
};

// The pair's supports: a's in direction d, b's in -d.
template <class MapA, class MapB>
struct PairSupport {
  MapA a;
  MapB b;
  Vertex operator()(const Vec3& d) const {
    Vertex v;
    v.pa = a(d);
    v.pb = b(-d);
    v.w = v.pa - v.pb;
    return v;
  }
};

struct Simplex {
  std::array<Vertex, 4> v;
  std::array<double, 4> lambda{};
  int n = 0;
  bool contains_origin = false;

  void keep(std::initializer_list<std::pair<int, double>> kept) {
    const std::array<Vertex, 4> old = v;
    int k = 0;
    for (const auto& [i, l] : kept) {
      v[k] = old[i];
      lambda[k] = l;
      ++k;
    }
    n = k;
  }
  Vec3 point() const {
    Vec3 p = Vec3::Zero();
    for (int i = 0; i < n; ++i) p += lambda[i] * v[i].w;
    return p;
  }
};

// Closest point of segment (i, j) of s to the origin (Ericson, "Real-Time Collision
// Detection" 5.1.2).
void solve_segment(Simplex& s, int i, int j) {
  const Vec3& A = s.v[i].w;
  const Vec3 ab = s.v[j].w - A;
  const double den = ab.squaredNorm();
  const double t = den > 0.0 ? -A.dot(ab) / den : 0.0;
  if (t <= 0.0) {
    s.keep({{i, 1.0}});
  } else if (t >= 1.0) {
    s.keep({{j, 1.0}});
  } else {
    s.keep({{i, 1.0 - t}, {j, t}});
  }
}

// Closest point of triangle (i, j, k) to the origin (Ericson 5.1.5), reducing to the feature.
void solve_triangle(Simplex& s, int i, int j, int k) {
  const Vec3 &A = s.v[i].w, &B = s.v[j].w, &C = s.v[k].w;
  const Vec3 ab = B - A, ac = C - A;
  const double d1 = -ab.dot(A), d2 = -ac.dot(A);
  if (d1 <= 0.0 && d2 <= 0.0) return s.keep({{i, 1.0}});
  const double d3 = -ab.dot(B), d4 = -ac.dot(B);
  if (d3 >= 0.0 && d4 <= d3) return s.keep({{j, 1.0}});
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double t = d1 / (d1 - d3);
    return s.keep({{i, 1.0 - t}, {j, t}});
  }
  const double d5 = -ab.dot(C), d6 = -ac.dot(C);
  if (d6 >= 0.0 && d5 <= d6) return s.keep({{k, 1.0}});
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double t = d2 / (d2 - d6);
    return s.keep({{i, 1.0 - t}, {k, t}});
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return s.keep({{j, 1.0 - t}, {k, t}});
  }
  const double den = va + vb + vc;
  if (!(den > 0.0)) {
    // Degenerate (zero-area) triangle: fall back to its longest edge.
    return solve_segment(s, i, j);
  }
  const double v = vb / den, w = vc / den;
  s.keep({{i, 1.0 - v - w}, {j, v}, {k, w}});
}

// Tetrahedron: if the origin is inside, flags it; otherwise the closest face feature.
void solve_tetrahedron(Simplex& s) {
  static const int faces[4][4] = {{0, 1, 2, 3}, {0, 2, 3, 1}, {0, 3, 1, 2}, {1, 3, 2, 0}};
  bool any_outside = false;
  double best = std::numeric_limits<double>::infinity();
  Simplex best_s = s;
  for (const auto& f : faces) {
    const Vec3 &A = s.v[f[0]].w, &B = s.v[f[1]].w, &C = s.v[f[2]].w, &D = s.v[f[3]].w;
    const Vec3 n = (B - A).cross(C - A);
    const double sd = n.dot(D - A);
    const double so = -n.dot(A);
    // The origin is outside this face when it is strictly on the other side from D; a
    // degenerate (flat) tetrahedron makes every face a candidate.
    const double scale = n.norm() * ((D - A).norm() + A.norm());
    const bool flat = std::abs(sd) <= kRoundoff * scale;
    if (!flat && so * sd >= 0.0) continue;
    any_outside = true;
    Simplex t = s;
    solve_triangle(t, f[0], f[1], f[2]);
    const double d2 = t.point().squaredNorm();
    if (d2 < best) {
      best = d2;
      best_s = t;
    }
  }
  if (!any_outside) {
    s.contains_origin = true;
    return;
  }
  s = best_s;
}

void solve(Simplex& s) {
  switch (s.n) {
    case 1:
      s.lambda[0] = 1.0;
      break;
    case 2:
      solve_segment(s, 0, 1);
      break;
    case 3:
      solve_triangle(s, 0, 1, 2);
      break;
    case 4:
      solve_tetrahedron(s);
      break;
    default:
      break;
  }
}

// Grows a simplex that touches the origin to a non-degenerate tetrahedron of support points.
template <class Support>
bool grow_to_tetrahedron(const Support& support, Simplex& s, double eps) {
  static const Vec3 axes[6] = {Vec3::UnitX(),  Vec3::UnitY(),  Vec3::UnitZ(),
                               -Vec3::UnitX(), -Vec3::UnitY(), -Vec3::UnitZ()};
  if (s.n == 1) {
    for (const auto& d : axes) {
      Vertex v = support(d);
      if ((v.w - s.v[0].w).norm() > eps) {
        s.v[s.n++] = v;
        break;
      }
    }
  }
  if (s.n == 2) {
    const Vec3 line = (s.v[1].w - s.v[0].w).normalized();
    const Vec3 e1 = any_orthogonal(line);
    const Vec3 e2 = line.cross(e1);
    for (int k = 0; k < 6 && s.n == 2; ++k) {
      const double th = k * M_PI / 3.0;
      const Vec3 d = std::cos(th) * e1 + std::sin(th) * e2;
      Vertex v = support(d);
      const Vec3 r = v.w - s.v[0].w;
      if ((r - r.dot(line) * line).norm() > eps) s.v[s.n++] = v;
    }
  }
  if (s.n == 3) {
    const Vec3 nrm = (s.v[1].w - s.v[0].w).cross(s.v[2].w - s.v[0].w).normalized();
    Vertex v = support(nrm);
    if (std::abs((v.w - s.v[0].w).dot(nrm)) <= eps) v = support(-nrm);
    if (std::abs((v.w - s.v[0].w).dot(nrm)) > eps) s.v[s.n++] = v;
  }
  return s.n == 4;
}

// EPA works in fixed storage (no heap allocation): a polytope grown from a tetrahedron by at
// most kEpaIterations support points has at most kEpaVertices vertices and, being convex and
// triangulated, at most 2 V - 4 live faces; the faces made in one expansion are added before the
// ones they replace are freed, hence the margin.
constexpr int kEpaIterations = 124;
constexpr int kEpaVertices = kEpaIterations + 4;
constexpr int kEpaFaces = 2 * kEpaVertices + 64;

// A face keeps its neighbours (as Bullet's and libccd's EPA do), so an expansion visits only
// the faces that see the new vertex and their rim, not every face of the polytope.
struct Face {
  int i[3];         // vertices, counter-clockwise seen from outside
  int adj[3];       // the face across edge e = (i[e], i[e + 1])
  int adj_edge[3];  // that edge's index in the adjacent face
  Vec3 n;           // outward unit normal (zero for a degenerate face)
  double d;         // distance of the face's plane to the origin (+inf for a degenerate face)
  int pass;         // last expansion that visited the face
};

struct Polytope {
  std::array<Vertex, kEpaVertices> v;
  std::array<Face, kEpaFaces> f;
  // Plane distance of each slot's face, +inf for a free slot: the nearest-face scan reads only
  // this array.
  std::array<double, kEpaFaces> dist;
  std::array<int, kEpaFaces> free_slots;
  std::array<int, kEpaFaces> dead;
  int nv = 0, nslots = 0, nfree = 0, ndead = 0;
  Vec3 centre = Vec3::Zero();
  // The horizon of the expansion under way: its first and latest new faces.
  int first = -1, last = -1, made = 0;

  // Face (i0, i1, i2) with its outward unit normal and its plane's distance to the origin, in
  // a free slot; -1 when the storage is full. A degenerate (zero-area) face gets an infinite
  // distance and is never the nearest, nor seen by a vertex.
  int make(int i0, int i1, int i2) {
    int k;
    if (nfree > 0) {
      k = free_slots[--nfree];
    } else if (nslots < kEpaFaces) {
      k = nslots++;
    } else {
      return -1;
    }
    Face& fc = f[k];
    fc.i[0] = i0;
    fc.i[1] = i1;
    fc.i[2] = i2;
    fc.pass = 0;
    fc.n = Vec3::Zero();
    fc.d = std::numeric_limits<double>::infinity();
    const Vec3 n = (v[i1].w - v[i0].w).cross(v[i2].w - v[i0].w);
    const double len2 = n.squaredNorm();
    if (len2 > 0.0) {
      fc.n = n * (1.0 / std::sqrt(len2));
      fc.d = fc.n.dot(v[i0].w);
      // Keep the normal outward even for slivers (the winding stays, for the neighbours).
      if (fc.n.dot(v[i0].w - centre) < 0.0) {
        fc.n = -fc.n;
        fc.d = -fc.d;
      }
    }
    dist[k] = fc.d;
    return k;
  }
  void bind(int fa, int ea, int fb, int eb) {
    f[fa].adj[ea] = fb;
    f[fa].adj_edge[ea] = eb;
    f[fb].adj[eb] = fa;
    f[fb].adj_edge[eb] = ea;
  }
  // Walks from face fk, entered through its edge e, over the faces that see vertex wi: those
  // are marked dead, and each edge of the rim (a face that does not see wi) gets a new face to
  // wi, linked to its neighbours along the horizon. False when the storage is full.
  bool expand(int pass, int wi, int fk, int e) {
    if (f[fk].pass == pass) return true;
    const int e1 = (e + 1) % 3;
    const Face& g = f[fk];
    const Vec3& w = v[wi].w;
    if (!(g.n.dot(w) - g.d > kRoundoff * (1.0 + std::abs(g.d)))) {
      const int nf = make(g.i[e1], g.i[e], wi);
      if (nf < 0) return false;
      bind(nf, 0, fk, e);
      if (last >= 0) {
        bind(last, 1, nf, 2);
      } else {
        first = nf;
      }
      last = nf;
      ++made;
      return true;
    }
    const int e2 = (e + 2) % 3;
    f[fk].pass = pass;
    dead[ndead++] = fk;
    return expand(pass, wi, f[fk].adj[e1], f[fk].adj_edge[e1]) &&
           expand(pass, wi, f[fk].adj[e2], f[fk].adj_edge[e2]);
  }
  int nearest() const {
    int best = -1;
    double dmin = std::numeric_limits<double>::infinity();
    for (int k = 0; k < nslots; ++k) {
      if (dist[k] < dmin) {
        dmin = dist[k];
        best = k;
      }
    }
    return best;
  }
};

// Expanding polytope algorithm from a tetrahedron that contains the origin (possibly on its
// boundary). Fills depth, normal and witness points of q. The depth is the least directional
// depth h_D(n) met, so translating b by it along its n separates the pair whatever the
// convergence. The polytope's nearest face is a lower bound: the search stops when the
// decision is certain and the depth within rel of it, or the bounds are within tol / 100.
template <class Support>
void epa(const Support& support, const Simplex& s, double tol, double rel, ConvexQuery* q) {
  Polytope P;
  for (int k = 0; k < 4; ++k) P.v[k] = s.v[k];
  // Positive orientation, so that the faces below wind counter-clockwise seen from outside.
  if ((P.v[0].w - P.v[3].w).dot((P.v[1].w - P.v[3].w).cross(P.v[2].w - P.v[3].w)) < 0.0) {
    std::swap(P.v[0], P.v[1]);
  }
  P.nv = 4;
  P.centre = 0.25 * (P.v[0].w + P.v[1].w + P.v[2].w + P.v[3].w);
  P.make(0, 1, 2);
  P.make(1, 0, 3);
  P.make(2, 1, 3);
  P.make(0, 2, 3);
  P.bind(0, 0, 1, 0);
  P.bind(0, 1, 2, 0);
  P.bind(0, 2, 3, 0);
  P.bind(1, 1, 3, 2);
  P.bind(1, 2, 2, 1);
  P.bind(2, 2, 3, 1);
  double upper = std::numeric_limits<double>::infinity();
  Vec3 best_n = Vec3::UnitX();
  Face best_face{{-1, -1, -1}, {0, 0, 0}, {0, 0, 0}, Vec3::Zero(), 0.0, 0};
  for (int iter = 0; iter < kEpaIterations; ++iter) {
    const int fi = P.nearest();
    if (fi < 0) break;
    const double dmin = P.dist[fi];
    const Vec3 n = P.f[fi].n;
    const Vertex w = support(n);
    const double hw = w.w.dot(n);  // directional depth along n: an upper bound on the depth
    if (hw < upper) {
      upper = hw;
      best_n = n;
      best_face = P.f[fi];
    }
    // Stop once the decision (depth > tol) is certain and the depth within rel of the lower
    // bound, or once the bounds are within tol / 100 of each other (a depth that close to tol
    // is decided by the upper bound).
    if (upper <= tol || (dmin > tol && upper - dmin <= rel * upper) || upper - dmin <= 0.01 * tol) {
      break;
    }
    // w does not see the nearest face beyond round-off: numerically converged.
    if (!(hw - dmin > kRoundoff * (1.0 + std::abs(dmin)))) break;
    // Expand: the faces that see w die, the horizon is stitched to w.
    const int wi = P.nv;
    P.v[P.nv++] = w;
    P.first = P.last = -1;
    P.made = 0;
    P.ndead = 0;
    const int pass = iter + 1;
    Face& root = P.f[fi];
    root.pass = pass;
    P.dead[P.ndead++] = fi;
    bool ok = true;
    for (int e = 0; e < 3 && ok; ++e) ok = P.expand(pass, wi, root.adj[e], root.adj_edge[e]);
    if (!ok || P.made < 3) break;  // storage full or no proper horizon: keep what is known
    P.bind(P.last, 1, P.first, 2);
    for (int k = 0; k < P.ndead; ++k) {
      P.dist[P.dead[k]] = std::numeric_limits<double>::infinity();
      P.free_slots[P.nfree++] = P.dead[k];
    }
  }
  q->depth = std::max(0.0, upper);
  q->normal = best_n;
  // Witness points: barycentric coordinates of the origin's projection on the best face.
  if (best_face.i[0] >= 0) {
    const Face& f = best_face;
    const Vec3 p = f.d * f.n;
    const Vec3 &A = P.v[f.i[0]].w, &B = P.v[f.i[1]].w, &C = P.v[f.i[2]].w;
    const Vec3 v0 = B - A, v1 = C - A, v2 = p - A;
    const double d00 = v0.dot(v0), d01 = v0.dot(v1), d11 = v1.dot(v1);
    const double d20 = v2.dot(v0), d21 = v2.dot(v1);
    const double den = d00 * d11 - d01 * d01;
    if (den > 0.0) {
      const double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
      const double u = 1.0 - v - w;
      q->point_a = u * P.v[f.i[0]].pa + v * P.v[f.i[1]].pa + w * P.v[f.i[2]].pa;
      q->point_b = u * P.v[f.i[0]].pb + v * P.v[f.i[1]].pb + w * P.v[f.i[2]].pb;
      return;
    }
  }
  q->point_a = support.a(best_n);
  q->point_b = support.b(-best_n);
}

// GJK, then EPA, on the pair's supports; ca, cb: points of a and of b, scale: the sum of their
// bounding radii.
template <class Support>
ConvexQuery gjk_epa(const Support& support, const Vec3& ca, const Vec3& cb, double scale,
                    double tolerance, bool need_distance, double depth_rel) {
  ConvexQuery q;
  const double tiny = kCoincidentCentres * scale;
  Simplex s;
  Vec3 v = ca - cb;  // a point of D = a - b
  if (v.norm() <= tiny) v = Vec3::UnitX() * tiny;
  s.v[0] = support(-v);
  s.n = 1;
  s.lambda[0] = 1.0;
  v = s.v[0].w;
  double lower = 0.0;
  bool enclosed = false;
  for (int iter = 0; iter < 200; ++iter) {
    const double vn = v.norm();
    if (vn <= tiny) break;  // the origin lies on the simplex
    const Vertex w = support(-v);
    const double vw = v.dot(w.w);
    if (vw > 0.0) {
      lower = std::max(lower, vw / vn);
      q.separated = true;
      if (!need_distance) break;
    }
    // Converged: the support point does not improve on the current closest point.
    if (vn * vn - vw <= kIterationStop * vn * vn || vn - lower <= 0.25 * tolerance) break;
    bool duplicate = false;
    for (int i = 0; i < s.n; ++i) duplicate |= (s.v[i].w - w.w).squaredNorm() <= tiny * tiny;
    if (duplicate) break;
    s.v[s.n++] = w;
    solve(s);
    if (s.contains_origin) {
      enclosed = true;
      break;
    }
    v = s.point();
  }
  if (q.separated) {
    q.distance = need_distance ? std::max(lower, 0.0) : lower;
    q.normal = (-v).normalized();  // from a towards b
    q.point_a = Vec3::Zero();
    q.point_b = Vec3::Zero();
    for (int i = 0; i < s.n; ++i) {
      q.point_a += s.lambda[i] * s.v[i].pa;
      q.point_b += s.lambda[i] * s.v[i].pb;
    }
    return q;
  }
  if (!enclosed && !grow_to_tetrahedron(support, s, tiny)) {
    q.depth = 0.0;  // cannot build a polytope: touching within round-off
    return q;
  }
  epa(support, s, tolerance, depth_rel, &q);
  return q;
}

}  // namespace

ConvexQuery convex_query(const Shape& a, const Shape& b, double tolerance, bool need_distance,
                         double depth_rel) {
  return gjk_epa(PairSupport<SupportMap, SupportMap>{SupportMap(a), SupportMap(b)}, a.center,
                 b.center, a.bounding_radius() + b.bounding_radius(), tolerance, need_distance,
                 depth_rel);
}

ConvexQuery convex_query(const ShearedPiece& a, const Shape& b, double tolerance,
                         bool need_distance, double depth_rel) {
  return gjk_epa(PairSupport<PieceSupport, SupportMap>{PieceSupport(a), SupportMap(b)}, a.center,
                 b.center, a.bounding_radius() + b.bounding_radius(), tolerance, need_distance,
                 depth_rel);
}

ConvexQuery convex_query(const ShearedPiece& a, const ShearedPiece& b, double tolerance,
                         bool need_distance, double depth_rel) {
  return gjk_epa(PairSupport<PieceSupport, PieceSupport>{PieceSupport(a), PieceSupport(b)},
                 a.center, b.center, a.bounding_radius() + b.bounding_radius(), tolerance,
                 need_distance, depth_rel);
}

double ShearedPiece::bow_reach() const {
  return std::max(std::abs(bow_lo[0]), std::abs(bow_hi[0])) +
         std::max(std::abs(bow_lo[1]), std::abs(bow_hi[1]));
}

double ShearedPiece::bounding_radius() const {
  // The farthest point of the disk about an end of the segment, then the bows and the ball.
  const double along = half_axis.dot(normal);
  const double across = std::sqrt(std::max(0.0, half_axis.squaredNorm() - along * along));
  return std::sqrt(along * along + (across + radius) * (across + radius)) + bow_reach() + round;
}

double ShearedPiece::support_value(const Vec3& d) const {
  const double dn = d.dot(normal);
  const double across = std::sqrt(std::max(0.0, d.squaredNorm() - dn * dn));
  double h = d.dot(center) + std::abs(d.dot(half_axis)) + radius * across + round * d.norm();
  for (int k = 0; k < 2; ++k) {
    const double dv = d.dot(bow[k]);
    h += std::max(bow_lo[k] * dv, bow_hi[k] * dv);
  }
  return h;
}

Vec3 ShearedPiece::support(const Vec3& d) const {
  Vec3 x = center + (d.dot(half_axis) >= 0.0 ? half_axis : Vec3(-half_axis));
  for (int k = 0; k < 2; ++k) x += (d.dot(bow[k]) >= 0.0 ? bow_hi[k] : bow_lo[k]) * bow[k];
  Vec3 radial = d - d.dot(normal) * normal;
  radial -= radial.dot(normal) * normal;  // second Gram-Schmidt pass, as in Shape::support
  const double rn2 = radial.squaredNorm(), d2 = d.squaredNorm();
  if (rn2 > kRoundoff2 * d2) x += (radius / std::sqrt(rn2)) * radial;
  if (round > 0.0 && d2 > 0.0) x += (round / std::sqrt(d2)) * d;
  return x;
}

namespace {

// The distance from a point z of the plane spanned by two vectors to the parallelogram
// {a v + b w : a in [a0, a1], b in [b0, b1]} (a segment or a point where a range or a vector is
// zero): 0 inside, else the least distance to its four sides.
double parallelogram_distance(const Vec3& z, const Vec3& v, double a0, double a1, const Vec3& w,
                              double b0, double b1) {
  auto segment = [&](const Vec3& p, const Vec3& q) {
    return std::sqrt(segment_distance2(p, q, z, z));
  };
  const Vec3 p00 = a0 * v + b0 * w, p10 = a1 * v + b0 * w, p01 = a0 * v + b1 * w,
             p11 = a1 * v + b1 * w;
  // Inside: z = a v + b w with a, b in range (v and w independent), when both ranges are open.
  const double vv = v.squaredNorm(), ww = w.squaredNorm(), vw = v.dot(w);
  const double det = vv * ww - vw * vw;
  if (a1 > a0 && b1 > b0 && det > 1e-12 * vv * ww) {
    const double zv = z.dot(v), zw = z.dot(w);
    const double a = (zv * ww - zw * vw) / det, b = (zw * vv - zv * vw) / det;
    if (a >= a0 && a <= a1 && b >= b0 && b <= b1) return 0.0;
  }
  return std::min({segment(p00, p10), segment(p10, p11), segment(p11, p01), segment(p01, p00)});
}

}  // namespace

double ShearedPiece::distance_to_core(const Vec3& x) const {
  // The distance to the disk about center + t half_axis, swept over the bows, is convex in t:
  // golden-section search. At each t, the distance within the disk's plane is the distance from
  // the point to the bows' parallelogram less the radius.
  const Vec3 y = x - center;
  auto in_plane = [&](const Vec3& z) {
    const Vec3 p = z - z.dot(normal) * normal;
    return parallelogram_distance(p, bow[0], bow_lo[0], bow_hi[0], bow[1], bow_lo[1], bow_hi[1]);
  };
  auto at = [&](double t) {
    const Vec3 z = y - t * half_axis;
    const double dz = z.dot(normal);
    return std::hypot(dz, std::max(0.0, in_plane(z) - radius));
  };
  // Where the disk's plane holds x (the chord crosses the planes normal to `normal`), x is at
  // its distance from the swept disk's rim, or inside.
  const double hn = half_axis.dot(normal);
  if (std::abs(hn) > 0.0) {
    const double t = y.dot(normal) / hn;
    const Vec3 z = y - t * half_axis;
    if (t >= -1.0 && t <= 1.0 && in_plane(z) <= radius) return 0.0;
  }
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double lo = -1.0, hi = 1.0;
  double t1 = hi - g * (hi - lo), t2 = lo + g * (hi - lo), f1 = at(t1), f2 = at(t2);
  for (int it = 0; it < 80; ++it) {
    if (f1 <= f2) {
      hi = t2, t2 = t1, f2 = f1, t1 = hi - g * (hi - lo), f1 = at(t1);
    } else {
      lo = t1, t1 = t2, f1 = f2, t2 = lo + g * (hi - lo), f2 = at(t2);
    }
  }
  return std::min({f1, f2, at(-1.0), at(1.0)});
}

bool ShearedPiece::contains(const Vec3& x) const {
  // The piece lies within radius + bows + round of its chord: most points are told apart there.
  const double reach = radius + bow_reach() + round;
  if (segment_distance2(center - half_axis, center + half_axis, x, x) > reach * reach) {
    return false;
  }
  return distance_to_core(x) <= round;
}

// Squared distance between segments [p1, q1] and [p2, q2] (Ericson, Real-Time Collision
// Detection, 5.1.9).
double segment_distance2(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2) {
  double s, t;
  return segment_closest(p1, q1, p2, q2, &s, &t);
}

double segment_closest(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2,
                       double* s_out, double* t_out) {
  const Vec3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0.0, t = 0.0;
  if (a <= kNoDirection && e <= kNoDirection) {
    *s_out = *t_out = 0.0;
    return r.squaredNorm();
  }
  if (a <= kNoDirection) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= kNoDirection) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), den = a * e - b * b;
      s = den > kRoundoff * a * e ? std::clamp((b * f - c * e) / den, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  *s_out = s;
  *t_out = t;
  return (p1 + d1 * s - (p2 + d2 * t)).squaredNorm();
}

}  // namespace rvegen
