#include "rvegen/mesh.hpp"

#include <algorithm>
#include <cmath>

namespace rvegen {
namespace {

int segments_for(double length, const MeshOptions& o, double box_min) {
  const int n = static_cast<int>(std::ceil(length / (o.edge_fraction * box_min)));
  return std::clamp(n, o.min_segments, o.max_segments);
}

void add_tri(SurfaceMesh& m, int64_t a, int64_t b, int64_t c, const Inclusion& inc) {
  m.triangles.push_back({a, b, c});
  m.inclusion_id.push_back(inc.id);
  m.family.push_back(inc.family);
  m.shape.push_back(static_cast<int32_t>(inc.shape.kind));
}

// Unit sphere (latitude-longitude) mapped through x -> center + M x.
void mesh_ellipsoid(SurfaceMesh& m, const Inclusion& inc, const Vec3& center, const Mat3& M,
                    int nseg) {
  const int nlat = std::max(6, nseg / 2);
  const int64_t base = static_cast<int64_t>(m.points.size());
  m.points.push_back(center + M * Vec3(0, 0, 1));
  for (int i = 1; i < nlat; ++i) {
    const double th = M_PI * i / nlat;
    for (int j = 0; j < nseg; ++j) {
      const double ph = 2.0 * M_PI * j / nseg;
      m.points.push_back(center + M * Vec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph),
                                           std::cos(th)));
    }
  }
  m.points.push_back(center + M * Vec3(0, 0, -1));
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

void mesh_cylinder(SurfaceMesh& m, const Inclusion& inc, const Vec3& center, int nseg) {
  const Shape& s = inc.shape;
  const Vec3 u = s.half_axis.normalized();
  const Vec3 e1 = any_orthogonal(u), e2 = u.cross(e1);
  const int64_t base = static_cast<int64_t>(m.points.size());
  for (int side = 0; side < 2; ++side) {
    const Vec3 c = center + (side == 0 ? -1.0 : 1.0) * s.half_axis;
    for (int j = 0; j < nseg; ++j) {
      const double ph = 2.0 * M_PI * j / nseg;
      m.points.push_back(c + s.radius * (std::cos(ph) * e1 + std::sin(ph) * e2));
    }
  }
  m.points.push_back(center - s.half_axis);
  m.points.push_back(center + s.half_axis);
  const int64_t cb = base + 2 * nseg, ct = cb + 1;
  for (int j = 0; j < nseg; ++j) {
    const int64_t b0 = base + j, b1 = base + (j + 1) % nseg;
    const int64_t t0 = b0 + nseg, t1 = b1 + nseg;
    add_tri(m, b0, b1, t1, inc);
    add_tri(m, b0, t1, t0, inc);
    add_tri(m, cb, b1, b0, inc);
    add_tri(m, ct, t0, t1, inc);
  }
}

void mesh_one(SurfaceMesh& m, const Inclusion& inc, const Vec3& center, const MeshOptions& o,
              double box_min) {
  const Shape& s = inc.shape;
  switch (s.kind) {
    case ShapeKind::Sphere:
      mesh_ellipsoid(m, inc, center, Mat3::Identity() * s.radius,
                     segments_for(2.0 * M_PI * s.radius, o, box_min));
      break;
    case ShapeKind::Ellipsoid:
      mesh_ellipsoid(m, inc, center, s.rotation * s.semi_axes.asDiagonal(),
                     segments_for(2.0 * M_PI * s.semi_axes.maxCoeff(), o, box_min));
      break;
    case ShapeKind::Cylinder:
      mesh_cylinder(m, inc, center, segments_for(2.0 * M_PI * s.radius, o, box_min));
      break;
  }
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
    inc.shape.aabb(&lo, &hi);
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
  return m;
}

}  // namespace rvegen
