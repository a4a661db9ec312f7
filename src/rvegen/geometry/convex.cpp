#include "rvegen/geometry/convex.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace rvegen {
namespace {

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
      h_ = s.half_axis.norm();
      u_ = s.half_axis / h_;
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
        Vec3 x = du >= 0.0 ? Vec3(s_.center + s_.half_axis) : Vec3(s_.center - s_.half_axis);
        Vec3 radial = d - du * u_;
        radial -= radial.dot(u_) * u_;  // second Gram-Schmidt pass, as in Shape::support
        const double rn = radial.norm();
        if (rn > 1e-14 * d.norm()) x += (s_.radius / rn) * radial;
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
  double h_ = 0.0;
};

// The pair's supports: a's in direction d, b's in -d.
struct PairSupport {
  SupportMap a, b;
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
    const bool flat = std::abs(sd) <= 1e-14 * scale;
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
bool grow_to_tetrahedron(const PairSupport& support, Simplex& s, double eps) {
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
// triangulated, at most 2 V - 4 faces. Only live faces are stored (a dead face is overwritten by
// the last one), so the nearest-face scan and the visibility pass see live faces only.
constexpr int kEpaIterations = 124;
constexpr int kEpaVertices = kEpaIterations + 4;
constexpr int kEpaFaces = 2 * kEpaVertices;
constexpr int kEpaEdges = 3 * kEpaFaces;

struct Face {
  int i[3];
  Vec3 n;
  double d;
};

struct Polytope {
  std::array<Vertex, kEpaVertices> v;
  std::array<Face, kEpaFaces> f;
  struct Edge {
    int from, to;
  };
  std::array<Edge, kEpaEdges> edge;
  int nv = 0, nf = 0, ne = 0;

  // Face (i0, i1, i2) with its outward unit normal and its plane's distance to the origin.
  // A degenerate (zero-area) face gets an infinite distance and is never the nearest.
  Face make(int i0, int i1, int i2) const {
    Face fc{{i0, i1, i2}, Vec3::Zero(), std::numeric_limits<double>::infinity()};
    const Vec3 n = (v[i1].w - v[i0].w).cross(v[i2].w - v[i0].w);
    const double len = n.norm();
    if (len > 0.0) {
      fc.n = n / len;
      fc.d = fc.n.dot(v[i0].w);
    }
    return fc;
  }
  // Horizon bookkeeping: an edge seen twice (once each way) is interior and cancels.
  void toggle_edge(int e0, int e1) {
    for (int k = 0; k < ne; ++k) {
      if (edge[k].from == e1 && edge[k].to == e0) {
        edge[k] = edge[--ne];
        return;
      }
    }
    edge[ne++] = {e0, e1};
  }
};

// Expanding polytope algorithm from a tetrahedron that contains the origin (possibly on its
// boundary). Fills depth, normal and witness points of q. The depth is the least directional
// depth h_D(n) met, so translating b by it along its n separates the pair whatever the
// convergence. The polytope's nearest face is a lower bound: the search stops when the
// decision is certain and the depth within rel of it, or the bounds are within tol / 100.
void epa(const PairSupport& support, const Simplex& s, double tol, double rel, ConvexQuery* q) {
  Polytope P;
  for (int k = 0; k < 4; ++k) P.v[k] = s.v[k];
  P.nv = 4;
  const Vec3 centre = 0.25 * (P.v[0].w + P.v[1].w + P.v[2].w + P.v[3].w);
  // Outward winding for the initial tetrahedron.
  static const int tet[4][4] = {{0, 1, 2, 3}, {0, 3, 1, 2}, {0, 2, 3, 1}, {1, 3, 2, 0}};
  for (const auto& t : tet) {
    const Vec3 n = (P.v[t[1]].w - P.v[t[0]].w).cross(P.v[t[2]].w - P.v[t[0]].w);
    P.f[P.nf++] = n.dot(P.v[t[3]].w - P.v[t[0]].w) > 0.0 ? P.make(t[0], t[2], t[1])
                                                         : P.make(t[0], t[1], t[2]);
  }
  double upper = std::numeric_limits<double>::infinity();
  Vec3 best_n = Vec3::UnitX();
  Face best_face{{-1, -1, -1}, Vec3::Zero(), 0.0};
  for (int iter = 0; iter < kEpaIterations; ++iter) {
    int fi = -1;
    double dmin = std::numeric_limits<double>::infinity();
    for (int k = 0; k < P.nf; ++k) {
      if (P.f[k].d < dmin) {
        dmin = P.f[k].d;
        fi = k;
      }
    }
    if (fi < 0) break;
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
    // Expand: remove the faces that see w, stitch the horizon to w.
    const int wi = P.nv;
    P.v[P.nv++] = w;
    P.ne = 0;
    for (int k = 0; k < P.nf;) {
      const Face& f = P.f[k];
      if (f.n.dot(w.w) - f.d > 1e-14 * (1.0 + std::abs(f.d))) {
        for (int e = 0; e < 3; ++e) P.toggle_edge(f.i[e], f.i[(e + 1) % 3]);
        P.f[k] = P.f[--P.nf];
      } else {
        ++k;
      }
    }
    if (P.ne == 0 || P.nf + P.ne > kEpaFaces) break;  // w sees no face: numerically converged
    for (int k = 0; k < P.ne; ++k) {
      const auto [e0, e1] = P.edge[k];
      Face f = P.make(e0, e1, wi);
      // Keep the outward orientation even for slivers.
      if (f.d < std::numeric_limits<double>::infinity() && f.n.dot(P.v[e0].w - centre) < 0.0) {
        f.n = -f.n;
        f.d = -f.d;
      }
      P.f[P.nf++] = f;
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

}  // namespace

ConvexQuery convex_query(const Shape& a, const Shape& b, double tolerance, bool need_distance,
                         double depth_rel) {
  ConvexQuery q;
  const double scale = a.bounding_radius() + b.bounding_radius();
  const double tiny = 1e-13 * scale;
  const PairSupport support{SupportMap(a), SupportMap(b)};
  Simplex s;
  Vec3 v = a.center - b.center;  // a point of D = a - b
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
    if (vn * vn - vw <= 1e-12 * vn * vn || vn - lower <= 0.25 * tolerance) break;
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
  if (a <= 1e-300 && e <= 1e-300) {
    *s_out = *t_out = 0.0;
    return r.squaredNorm();
  }
  if (a <= 1e-300) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 1e-300) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), den = a * e - b * b;
      s = den > 1e-14 * a * e ? std::clamp((b * f - c * e) / den, 0.0, 1.0) : 0.0;
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
