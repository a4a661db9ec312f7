#include "rvegen/raster/mesh.hpp"

#include <algorithm>
#include <cmath>

#include "rvegen/model/body.hpp"

namespace rvegen {
namespace {

// Segments around a circumference of radius r.
int segments_for(double r, const MeshOptions& o, double box_min) {
  double n = 2.0 * M_PI * r / (o.edge_fraction * box_min);
  if (o.chord_error > 0.0) {
    // A chord of angle 2 pi / n stays within r (1 - cos(pi / n)) of the circle.
    n = o.chord_error >= r ? 0.0 : M_PI / std::acos(1.0 - o.chord_error / r);
  }
  return std::clamp(static_cast<int>(std::ceil(std::min(n, 1e6))), o.min_segments, o.max_segments);
}

Vec3 axis_of(const Shape& s) {
  switch (s.kind) {
    case ShapeKind::Cylinder:
      return s.half_axis.normalized();
    case ShapeKind::Ellipsoid: {
      int k;
      s.semi_axes.maxCoeff(&k);
      return s.rotation.col(k);
    }
    default:
      return Vec3::Zero();
  }
}

void add_tri(SurfaceMesh& m, int64_t a, int64_t b, int64_t c, const Inclusion& inc) {
  m.triangles.push_back({a, b, c});
  m.inclusion_id.push_back(inc.id);
  m.family.push_back(inc.family);
  m.shape.push_back(static_cast<int32_t>(inc.shape.kind));
  m.phase.push_back(inc.family + 1);
  const Vec3 u = axis_of(inc.shape);
  m.axis.push_back({static_cast<float>(u[0]), static_cast<float>(u[1]), static_cast<float>(u[2])});
}

// Unit sphere (latitude-longitude) mapped through n -> center + M (rho(n) n).
template <class Radial>
void mesh_ellipsoid(SurfaceMesh& m, const Inclusion& inc, const Vec3& center, const Mat3& M,
                    int nseg, Radial rho) {
  const int nlat = std::max(6, nseg / 2);
  const int64_t base = static_cast<int64_t>(m.points.size());
  auto map = [&](const Vec3& n) { return Vec3(center + M * (rho(n) * n)); };
  m.points.push_back(map(Vec3(0, 0, 1)));
  for (int i = 1; i < nlat; ++i) {
    const double th = M_PI * i / nlat;
    for (int j = 0; j < nseg; ++j) {
      const double ph = 2.0 * M_PI * j / nseg;
      m.points.push_back(
          map(Vec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th))));
    }
  }
  m.points.push_back(map(Vec3(0, 0, -1)));
  const int64_t south = static_cast<int64_t>(m.points.size()) - 1;
  auto ring = [&](int i, int j) {
    return base + 1 + static_cast<int64_t>(i - 1) * nseg + (j % nseg);
  };
  for (int j = 0; j < nseg; ++j) add_tri(m, base, ring(1, j), ring(1, j + 1), inc);
  for (int i = 1; i < nlat - 1; ++i) {
    for (int j = 0; j < nseg; ++j) {
      add_tri(m, ring(i, j), ring(i + 1, j), ring(i + 1, j + 1), inc);
      add_tri(m, ring(i, j), ring(i + 1, j + 1), ring(i, j + 1), inc);
    }
  }
  for (int j = 0; j < nseg; ++j) add_tri(m, ring(nlat - 1, j), south, ring(nlat - 1, j + 1), inc);
}

// Cylinder with `rings` + 1 rings along the axis, each displaced by the fibre's wave and bend.
void mesh_cylinder(SurfaceMesh& m, const Inclusion& inc, const Vec3& center, int nseg, int rings) {
  const Shape& s = inc.shape;
  const double h = s.half_axis.norm();
  const Vec3 u = s.half_axis / h;
  const Vec3 e1 = any_orthogonal(u), e2 = u.cross(e1);
  const CentreLine line(inc);
  const int64_t base = static_cast<int64_t>(m.points.size());
  for (int r = 0; r <= rings; ++r) {
    const double a = -h + 2.0 * h * r / rings;
    const Vec3 c = center + a * u + line.offset(a);
    for (int j = 0; j < nseg; ++j) {
      const double ph = 2.0 * M_PI * j / nseg;
      m.points.push_back(c + s.radius * (std::cos(ph) * e1 + std::sin(ph) * e2));
    }
  }
  m.points.push_back(center - s.half_axis + line.offset(-h));
  m.points.push_back(center + s.half_axis + line.offset(h));
  const int64_t cb = base + static_cast<int64_t>(rings + 1) * nseg, ct = cb + 1;
  for (int r = 0; r < rings; ++r) {
    for (int j = 0; j < nseg; ++j) {
      const int64_t b0 = base + r * nseg + j, b1 = base + r * nseg + (j + 1) % nseg;
      const int64_t t0 = b0 + nseg, t1 = b1 + nseg;
      add_tri(m, b0, b1, t1, inc);
      add_tri(m, b0, t1, t0, inc);
    }
  }
  const int64_t top = base + static_cast<int64_t>(rings) * nseg;
  for (int j = 0; j < nseg; ++j) {
    add_tri(m, cb, base + (j + 1) % nseg, base + j, inc);
    add_tri(m, ct, top + j, top + (j + 1) % nseg, inc);
  }
}

void mesh_one(SurfaceMesh& m, const Inclusion& inc, const Vec3& center, const MeshOptions& o,
              double box_min) {
  const Shape& s = inc.shape;
  const Modifiers& mod = inc.mod;
  auto radial = [&](const Vec3& n) { return mod.deformed() ? deformed_radius(mod, n) : 1.0; };
  switch (s.kind) {
    case ShapeKind::Sphere:
      mesh_ellipsoid(m, inc, center, Mat3::Identity() * s.radius,
                     segments_for(s.radius, o, box_min), radial);
      break;
    case ShapeKind::Ellipsoid:
      mesh_ellipsoid(m, inc, center, s.rotation * s.semi_axes.asDiagonal(),
                     segments_for(s.semi_axes.maxCoeff(), o, box_min), radial);
      break;
    case ShapeKind::Cylinder: {
      const int rings = static_cast<int>(fibre_rings(
          2.0 * s.half_axis.norm(), s.radius, mod.wavy() ? mod.wave_length : 0.0, mod.bend_radius));
      mesh_cylinder(m, inc, center, segments_for(s.radius, o, box_min), rings);
      break;
    }
  }
}

// Appends triangle `t` of `src` (with its cell data) to dst, vertices given explicitly.
void add_clipped(SurfaceMesh& dst, const SurfaceMesh& src, size_t t, const Vec3& a, const Vec3& b,
                 const Vec3& c) {
  const int64_t base = static_cast<int64_t>(dst.points.size());
  dst.points.push_back(a);
  dst.points.push_back(b);
  dst.points.push_back(c);
  dst.triangles.push_back({base, base + 1, base + 2});
  dst.inclusion_id.push_back(src.inclusion_id[t]);
  dst.family.push_back(src.family[t]);
  dst.shape.push_back(src.shape[t]);
  dst.phase.push_back(src.phase[t]);
  dst.axis.push_back(src.axis[t]);
}

}  // namespace

SurfaceMesh tessellate(const InclusionSet& set, const MeshOptions& o) {
  SurfaceMesh m;
  const Box& box = set.box;
  const double box_min = box.size.minCoeff();
  for (const auto& inc : set.inclusions) {
    if (!box.periodic || !o.periodic_images) {
      mesh_one(m, inc, inc.shape.center, o, box_min);
      continue;
    }
    Vec3 lo, hi;
    outer_bound(inc).aabb(&lo, &hi);
    int k0[3], k1[3];
    for (int a = 0; a < 3; ++a) {
      // Images whose bounding box meets [origin, origin + size].
      k0[a] = static_cast<int>(std::ceil((box.origin[a] - hi[a]) / box.size[a]));
      k1[a] = static_cast<int>(std::floor((box.origin[a] + box.size[a] - lo[a]) / box.size[a]));
    }
    for (int i = k0[0]; i <= k1[0]; ++i) {
      for (int j = k0[1]; j <= k1[1]; ++j) {
        for (int k = k0[2]; k <= k1[2]; ++k) {
          const Vec3 shift(i * box.size[0], j * box.size[1], k * box.size[2]);
          mesh_one(m, inc, inc.shape.center + shift, o, box_min);
        }
      }
    }
  }
  return o.clip_to_box ? clip_to_box(m, box) : m;
}

SurfaceMesh clip_to_box(const SurfaceMesh& m, const Box& box) {
  SurfaceMesh out;
  const Vec3 lo = box.origin, hi = box.origin + box.size;
  for (size_t t = 0; t < m.triangles.size(); ++t) {
    std::vector<Vec3> poly = {m.points[m.triangles[t][0]], m.points[m.triangles[t][1]],
                              m.points[m.triangles[t][2]]};
    // Sutherland-Hodgman against the six half-spaces of the box.
    for (int plane = 0; plane < 6 && !poly.empty(); ++plane) {
      const int a = plane / 2;
      const bool upper = plane % 2 == 1;
      auto inside = [&](const Vec3& p) { return upper ? p[a] <= hi[a] : p[a] >= lo[a]; };
      const double level = upper ? hi[a] : lo[a];
      std::vector<Vec3> next;
      for (size_t i = 0; i < poly.size(); ++i) {
        const Vec3& p = poly[i];
        const Vec3& q = poly[(i + 1) % poly.size()];
        const bool ip = inside(p), iq = inside(q);
        if (ip) next.push_back(p);
        if (ip != iq) next.push_back(p + (q - p) * ((level - p[a]) / (q[a] - p[a])));
      }
      poly.swap(next);
    }
    for (size_t i = 1; i + 1 < poly.size(); ++i)
      add_clipped(out, m, t, poly[0], poly[i], poly[i + 1]);
  }
  return out;
}

void append(SurfaceMesh* a, const SurfaceMesh& b) {
  const int64_t base = static_cast<int64_t>(a->points.size());
  a->points.insert(a->points.end(), b.points.begin(), b.points.end());
  for (const auto& t : b.triangles) a->triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  a->inclusion_id.insert(a->inclusion_id.end(), b.inclusion_id.begin(), b.inclusion_id.end());
  a->family.insert(a->family.end(), b.family.begin(), b.family.end());
  a->shape.insert(a->shape.end(), b.shape.begin(), b.shape.end());
  a->phase.insert(a->phase.end(), b.phase.begin(), b.phase.end());
  a->axis.insert(a->axis.end(), b.axis.begin(), b.axis.end());
}

MeshOptions mesh_options(const OutputSpec& spec, const Box& box) {
  MeshOptions o;
  o.clip_to_box = spec.clip_surfaces;
  double voxel = box.size[0] / spec.resolution[0];
  for (int a = 1; a < 3; ++a) voxel = std::min(voxel, box.size[a] / spec.resolution[a]);
  o.chord_error = spec.surface_chord_error * voxel;
  return o;
}

}  // namespace rvegen
