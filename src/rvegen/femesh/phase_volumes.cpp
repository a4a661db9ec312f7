// Each phase keeps its exact volume: the facets of a curved interface are chords of it, so the
// nodes inside it move along the surface's normal by the mean gap of their facets to the true
// surface (the signed distance to each shape, grown by its shell or void, is exact or to first
// order here).
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

// The signed distance of x from the surface of shape s grown by t (negative inside), and the
// outward normal there: exact for spheres and for cylinders (flat ends; grown, their rims are
// rounded) and for grown ellipsoids outside the ellipsoid (the distance from its nearest point,
// less t), to first order for ellipsoids ((f - 1) / |grad f| with f the ellipsoidal radius;
// its error near the surface is of the order of the squared distance over the radius of
// curvature). `feature`: x lies on a flat end's plane of an ungrown cylinder (its rim and end
// disk), where the normal has no single direction.
double surface_distance(const Shape& s, double t, const Vec3& x, Vec3* normal, bool* feature) {
  const Vec3 d = x - s.center;
  *feature = false;
  switch (s.kind) {
    case ShapeKind::Sphere: {
      const double n = d.norm();
      *normal = n > 0.0 ? Vec3(d / n) : Vec3::UnitZ();
      return n - s.radius - t;
    }
    case ShapeKind::Cylinder: {
      const double h = s.half_axis.norm();
      const Vec3 u = s.half_axis / h;
      const double a = d.dot(u);
      const Vec3 radial = d - a * u;
      const double rho = radial.norm();
      const Vec3 er = rho > 0.0 ? Vec3(radial / rho) : any_orthogonal(u);
      const Vec3 eu = a >= 0.0 ? u : Vec3(-u);
      const double dr = rho - s.radius, dz = std::abs(a) - h;
      *feature = t == 0.0 && std::abs(dz) <= kOnEndPlane * std::max(h, s.radius);
      if (dr > 0.0 && dz > 0.0) {
        const double n = std::hypot(dr, dz);
        *normal = (dr * er + dz * eu) / n;
        return n - t;
      }
      *normal = dr >= dz ? er : eu;
      return std::max(dr, dz) - t;
    }
    case ShapeKind::Ellipsoid: {
      if (t > 0.0) {
        // A shell's outer surface lies t out from the ellipsoid: exact there, where the first
        // order would err by t^2 over the radius of curvature (a third of t for a shell a third
        // as thick as that radius).
        Vec3 z;
        const double out = ellipsoid_distance(s, x, &z);
        if (out > 0.0) {
          *normal = (x - z) / out;
          return out - t;
        }
      }
      const Vec3 y = s.rotation.transpose() * d;
      const Vec3 q = y.cwiseQuotient(s.semi_axes);
      const double f = q.norm();
      const Vec3 g = s.rotation * (q.cwiseQuotient(s.semi_axes) / std::max(f, kNoDirection));
      const double gn = g.norm();
      *normal = gn > 0.0 ? Vec3(g / gn) : Vec3::UnitZ();
      return (gn > 0.0 ? (f - 1.0) / gn : -s.semi_axes.minCoeff()) - t;
    }
  }
  return 0.0;
}

// An element's region: its inclusion (the matrix's -1 too) and its phase, as one number.
uint64_t region_of(const TetMesh& mesh, size_t e) {
  return (static_cast<uint64_t>(static_cast<uint32_t>(mesh.inclusion_id[e])) << 32) |
         static_cast<uint32_t>(mesh.phase[e]);
}

// The index in set.inclusions of each inclusion id.
std::unordered_map<int32_t, int> index_by_id(const InclusionSet& set) {
  std::unordered_map<int32_t, int> by_id;
  for (size_t k = 0; k < set.inclusions.size(); ++k) {
    by_id[set.inclusions[k].id] = static_cast<int>(k);
  }
  return by_id;
}

// The surface between elements of inclusions id1 and id2 (-1: the matrix) of phase kinds k1 and
// k2: 2 k for inclusion k's core (against the matrix, or its own shell or void), 2 k + 1 for its
// shell's or void's outer surface (against the matrix: a void's cone among it, on_void_cone);
// -1 for anything else (two inclusions, an unknown id).
int interface_surface(const std::unordered_map<int32_t, int>& by_id, int id1, PhaseKind k1, int id2,
                      PhaseKind k2) {
  auto inc = [&](int id) {
    const auto it = by_id.find(id);
    return it == by_id.end() ? -1 : it->second;
  };
  if (id1 == id2) return inc(id1) >= 0 ? 2 * inc(id1) : -1;
  if (k1 != PhaseKind::kMatrix && k2 != PhaseKind::kMatrix) return -1;
  const int id = k1 == PhaseKind::kMatrix ? id2 : id1;
  const PhaseKind kind = k1 == PhaseKind::kMatrix ? k2 : k1;
  if (inc(id) < 0) return -1;
  if (kind == PhaseKind::kCore) return 2 * inc(id);
  if (kind == PhaseKind::kInterphase || kind == PhaseKind::kVoid) return 2 * inc(id) + 1;
  return -1;
}

// The translation (by -1, 0 or 1 box sizes per axis) of the periodic image of the surface of
// `shape` grown by `grown` nearest x, with x's signed distance from it and whether x lies on a
// flat end there (surface_distance).
Vec3 nearest_image(const Shape& shape, double grown, const Vec3& size, const Vec3& x,
                   double* distance, bool* feature) {
  Vec3 best = Vec3::Zero();
  double least = 1e300;
  for (int dx = -1; dx <= 1; ++dx) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dz = -1; dz <= 1; ++dz) {
        const Vec3 t = Vec3(dx, dy, dz).cwiseProduct(size);
        Vec3 nrm;
        bool f;
        const double d = surface_distance(shape.translated(t), grown, x, &nrm, &f);
        if (std::abs(d) < least) {
          least = std::abs(d);
          best = t;
          *distance = d;
          *feature = f;
        }
      }
    }
  }
  return best;
}

// Whether a triangle of a debonded sphere's void against the matrix lies on the void's cone (the
// side where the cap ends) rather than on its outer sphere: the cone holds the rays from the
// centre, so its triangles' normals are across the ray through them (a sphere's, along it).
bool on_void_cone(const Inclusion& in, const Vec3& shift, const Vec3& p0, const Vec3& p1,
                  const Vec3& p2) {
  if (!in.mod.debonded()) return false;
  const Vec3 n = (p1 - p0).cross(p2 - p0), ray = (p0 + p1 + p2) / 3.0 - in.shape.center - shift;
  return std::abs(n.dot(ray)) < 0.5 * n.norm() * ray.norm();
}

// Whether x lies on a debonded sphere's void cone (its angle from the axis the cap's, to
// kOnVoidCone).
bool on_void_cone(const Inclusion& in, const Vec3& shift, const Vec3& x) {
  if (!in.mod.debonded()) return false;
  const Vec3 d = x - in.shape.center - shift;
  const double rho = d.norm();
  return rho > 0.0 &&
         std::abs(d.dot(in.mod.debond_axis) / rho - in.mod.debond_cos_cap()) < kOnVoidCone;
}

}  // namespace mesh_parts

using namespace mesh_parts;

namespace {

// A face of an element, its nodes sorted.
struct Face {
  std::array<int32_t, 3> n;
  int32_t tet;
};

// The faces of elements whose three nodes elements of two regions share (the candidates for
// interface triangles), sorted by nodes and element.
std::vector<Face> interface_faces(const TetMesh& mesh) {
  const size_t nn = mesh.nodes.size(), ne = mesh.tets.size();
  // Nodes that elements of two regions share; faces with three such nodes are the candidates.
  constexpr uint64_t kNone = std::numeric_limits<uint64_t>::max();  // no phase label is -1
  std::vector<uint64_t> first(nn, kNone);
  std::vector<uint8_t> shared(nn, 0);
  for (size_t e = 0; e < ne; ++e) {
    const uint64_t r = region_of(mesh, e);
    for (int32_t n : mesh.tets[e]) {
      if (first[n] == kNone) {
        first[n] = r;
      } else if (first[n] != r) {
        shared[n] = 1;
      }
    }
  }
  std::vector<Face> faces;
  for (size_t e = 0; e < ne; ++e) {
    const auto& t = mesh.tets[e];
    for (int skip = 0; skip < 4; ++skip) {
      Face f;
      int k = 0;
      for (int c = 0; c < 4; ++c) {
        if (c != skip) f.n[k++] = t[c];
      }
      if (!(shared[f.n[0]] && shared[f.n[1]] && shared[f.n[2]])) continue;
      std::sort(f.n.begin(), f.n.end());
      f.tet = static_cast<int32_t>(e);
      faces.push_back(f);
    }
  }
  parallel_sort(faces.begin(), faces.end(), [](const Face& a, const Face& b) {
    return a.n != b.n ? a.n < b.n : a.tet < b.tet;
  });
  return faces;
}

// An interface triangle: its face, its surface (-1: of no single surface, or straight along a
// void's cone), the image it lies on, its area and its mean gap to the surface.
struct Triangle {
  size_t face;
  int which = -1;
  Vec3 shift = Vec3::Zero();
  double area = 0.0, gap = 0.0;
};

// The interface triangles (faces that elements of two regions share), and for each, on both
// cores, its surface, image, area and mean gap.
std::vector<Triangle> interface_triangles(const TetMesh& mesh, const InclusionSet& set,
                                          const std::vector<Face>& faces) {
  const std::unordered_map<int32_t, int> by_id = index_by_id(set);
  const Box& box = mesh.box;
  std::vector<Triangle> triangles;
  for (size_t k = 0; k + 1 < faces.size(); ++k) {
    if (faces[k].n != faces[k + 1].n) continue;
    const size_t e1 = faces[k].tet, e2 = faces[k + 1].tet;
    ++k;
    if (region_of(mesh, e1) == region_of(mesh, e2)) continue;
    // Which surface: a core against the matrix or its own shell; a shell against the matrix.
    Triangle t;
    t.face = k;
    t.which = interface_surface(by_id, mesh.inclusion_id[e1], mesh.phases[mesh.phase[e1]].kind,
                                mesh.inclusion_id[e2], mesh.phases[mesh.phase[e2]].kind);
    triangles.push_back(t);
  }
  parallel_for(size_t{0}, triangles.size(), [&](size_t j) {
    Triangle& t = triangles[j];
    if (t.which < 0) return;
    const std::array<int32_t, 3>& n = faces[t.face].n;
    const Inclusion& in = set.inclusions[t.which / 2];
    const double grown = (t.which & 1) ? outer_offset(in.mod) : 0.0;
    const Vec3 &p0 = mesh.nodes[n[0]], &p1 = mesh.nodes[n[1]], &p2 = mesh.nodes[n[2]];
    // The inclusion's periodic image the triangle lies on: the one nearest its centre's surface.
    Vec3 nrm;
    bool feature;
    double centre_gap;
    t.shift = nearest_image(in.shape, grown, box.size, (p0 + p1 + p2) / 3.0, &centre_gap, &feature);
    if ((t.which & 1) && on_void_cone(in, t.shift, p0, p1, p2)) {  // straight along the rays
      t.which = -1;
      return;
    }
    const Shape s = in.shape.translated(t.shift);
    t.area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    t.gap = -(surface_distance(s, grown, 0.5 * (p0 + p1), &nrm, &feature) +
              surface_distance(s, grown, 0.5 * (p1 + p2), &nrm, &feature) +
              surface_distance(s, grown, 0.5 * (p0 + p2), &nrm, &feature)) /
            3.0;
  });
  return triangles;
}

}  // namespace

// Each interface of the mesh (a face between the matrix and an inclusion's core or shell, or
// between a core and its shell) belongs to one exact surface. Its triangles are chords of that
// surface, and cut off the gap between them and it: for a triangle, its area times the mean gap,
// which the mean of the gaps at its edge midpoints gives exactly for a surface of constant
// curvature (the gap is then quadratic over the triangle and nought at its corners). Each node
// inside a curved surface (not on a box face, on another surface or on a flat end's plane) moves
// along the surface's normal by the area-weighted mean gap of its triangles: a move d of a node
// adds d times a third of its triangles' area to the volume inside, so the moves give back what
// the chords cut off, to second order. A move is undone where it would invert an element, or
// leave one with a least dihedral angle under 5 degrees that had a larger one before.
long long keep_phase_volumes(TetMesh* mesh, const InclusionSet& set) {
  const size_t nn = mesh->nodes.size(), ne = mesh->tets.size();
  const std::vector<Face> faces = interface_faces(*mesh);
  // Per node: its surface (2 k for inclusion k's core, 2 k + 1 for its shell's outer surface;
  // -1 none yet, -2 on two surfaces or on an interface of no single surface), the image shift of
  // the inclusion, and its triangles' area and area times gap.
  std::vector<int> surface(nn, -1);
  std::vector<Vec3> shift(nn, Vec3::Zero());
  std::vector<double> area(nn, 0.0), gap(nn, 0.0);
  std::vector<double> deficit(2 * set.inclusions.size(), 0.0);  // per surface
  const std::vector<Triangle> triangles = interface_triangles(*mesh, set, faces);
  for (const Triangle& t : triangles) {
    const std::array<int32_t, 3>& n = faces[t.face].n;
    const int which = t.which;
    if (which < 0) {
      for (int32_t i : n) surface[i] = -2;
      continue;
    }
    const Vec3& best = t.shift;
    const double a = t.area, g = t.gap;
    deficit[which] += a * g;
    for (int32_t i : n) {
      if (surface[i] == -2) continue;
      if (surface[i] >= 0 && (surface[i] != which || shift[i] != best)) {
        surface[i] = -2;
        continue;
      }
      surface[i] = which;
      shift[i] = best;
      area[i] += a;
      gap[i] += a * g;
    }
  }
  // The moves. Nodes that stay (on box faces, rims) leave their triangles' share of the gap;
  // the other nodes of the surface make it up, each in proportion (at most twice their own).
  const std::vector<std::array<int8_t, 3>> ends = node_ends(*mesh);
  const std::vector<Vec3> before = mesh->nodes;
  std::vector<uint8_t> movable(nn, 0);
  std::vector<Vec3> normal(nn, Vec3::Zero());
  std::vector<double> given(deficit.size(), 0.0);
  parallel_for(size_t{0}, nn, [&](size_t i) {
    if (surface[i] < 0 || !(area[i] > 0.0) || !std::isfinite(gap[i])) return;
    if (ends[i][0] >= 0 || ends[i][1] >= 0 || ends[i][2] >= 0) return;
    const Inclusion& in = set.inclusions[surface[i] / 2];
    const double grown = (surface[i] & 1) ? outer_offset(in.mod) : 0.0;
    bool feature;
    surface_distance(in.shape.translated(shift[i]), grown, before[i], &normal[i], &feature);
    if (feature || gap[i] == 0.0) return;
    movable[i] = 1;
  });
  for (size_t i = 0; i < nn; ++i) {
    if (movable[i]) given[surface[i]] += gap[i] / 3.0;
  }
  std::vector<uint8_t> moved(nn, 0);
  long long count = 0;
  for (size_t i = 0; i < nn; ++i) {
    if (!movable[i]) continue;
    const double whole = deficit[surface[i]], part = given[surface[i]];
    const double scale = part != 0.0 && whole / part > 1.0 ? std::min(2.0, whole / part) : 1.0;
    mesh->nodes[i] = before[i] + scale * gap[i] / area[i] * normal[i];
    moved[i] = 1;
    ++count;
  }
  // Undone where an element would suffer (a few passes: undoing one move changes its other
  // elements back too, never for the worse). Each pass tells the elements apart on all cores,
  // then walks them in order, as one thread would: an element with a node undone earlier in
  // the walk is looked at again there.
  auto suffers = [&](const std::array<int32_t, 4>& t) {
    if (!(tet_volume(mesh->nodes, t) > 0.0)) return true;
    const double now = least_dihedral(*mesh, t);
    if (now >= 5.0) return false;
    const Vec3 p[4] = {before[t[0]], before[t[1]], before[t[2]], before[t[3]]};
    return now < least_dihedral(p);
  };
  auto any_moved = [&](const std::array<int32_t, 4>& t) {
    return moved[t[0]] || moved[t[1]] || moved[t[2]] || moved[t[3]];
  };
  std::vector<uint8_t> suffered(ne, 0), undone(nn, 0);
  std::vector<int32_t> undone_list;
  for (bool again = true; again;) {
    again = false;
    parallel_for(size_t{0}, ne, [&](size_t e) {
      const auto& t = mesh->tets[e];
      suffered[e] = any_moved(t) && suffers(t);
    });
    for (size_t e = 0; e < ne; ++e) {
      const auto& t = mesh->tets[e];
      if (!any_moved(t)) continue;
      const bool seen_change = undone[t[0]] || undone[t[1]] || undone[t[2]] || undone[t[3]];
      if (!(seen_change ? suffers(t) : suffered[e])) continue;
      for (int32_t n : t) {
        if (!moved[n]) continue;
        mesh->nodes[n] = before[n];
        moved[n] = 0;
        undone[n] = 1;
        undone_list.push_back(n);
        --count;
        again = true;
      }
    }
    for (int32_t n : undone_list) undone[n] = 0;
    undone_list.clear();
  }
  return count;
}

}  // namespace rvegen
