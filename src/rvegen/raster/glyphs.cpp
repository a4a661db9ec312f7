#include "rvegen/raster/glyphs.hpp"

#include <Eigen/Geometry>

#include "rvegen/geometry/shapes.hpp"
#include "rvegen/model/body.hpp"

namespace rvegen {

GlyphPoints glyph_points(const InclusionSet& set) {
  GlyphPoints g;
  const Box& box = set.box;
  for (const Inclusion& inc : set.inclusions) {
    const Shape& sh = inc.shape;
    // Glyph frame -> world: a unit sphere glyph (radius 0.5) or a cylinder glyph along y
    // (height 1, radius 0.5) scaled by `scale`, then turned by `orientation`.
    Mat3 R = Mat3::Identity();
    Vec3 sc = Vec3::Zero(), dir = Vec3::UnitZ();
    switch (sh.kind) {
      case ShapeKind::Sphere:
        sc = Vec3::Constant(2.0 * sh.radius);
        break;
      case ShapeKind::Cylinder: {
        const double h = sh.half_axis.norm();
        dir = sh.half_axis / h;
        R.col(1) = dir;
        R.col(0) = any_orthogonal(dir);
        R.col(2) = R.col(0).cross(R.col(1));
        sc = Vec3(2.0 * sh.radius, 2.0 * h, 2.0 * sh.radius);
        break;
      }
      case ShapeKind::Ellipsoid:
        R = sh.rotation;
        if (R.determinant() < 0.0) R.col(2) = -R.col(2);
        dir = R.col(0);
        sc = 2.0 * sh.semi_axes;
        break;
    }
    const Eigen::Quaterniond q(R);
    const Vec3 ha = sh.kind == ShapeKind::Cylinder ? sh.half_axis : Vec3::Zero();
    const Vec3 sa = sh.kind == ShapeKind::Ellipsoid ? sh.semi_axes : Vec3::Zero();
    // The inclusion, and its periodic images whose bounding box reaches into the box. A
    // continuous fibre is one glyph spanning the box along its axis (moved along its axis it is
    // the same fibre; its images along it would overhang the box).
    const int along = through_axis(inc);
    Vec3 centre = sh.center;
    if (along >= 0) centre[along] = box.origin[along] + 0.5 * box.size[along];
    Vec3 lo, hi;
    sh.translated(centre - sh.center).aabb(&lo, &hi);
    const int m = box.periodic ? 1 : 0;
    for (int kz = -m; kz <= m; ++kz) {
      for (int ky = -m; ky <= m; ++ky) {
        for (int kx = -m; kx <= m; ++kx) {
          const Vec3 shift(kx * box.size[0], ky * box.size[1], kz * box.size[2]);
          const bool self = kx == 0 && ky == 0 && kz == 0;
          if (along >= 0 && (along == 0 ? kx : along == 1 ? ky : kz) != 0) continue;
          if (!self && ((hi + shift).array() <= box.origin.array()).any()) continue;
          if (!self && ((lo + shift).array() >= (box.origin + box.size).array()).any()) continue;
          const Vec3 c = centre + shift;
          g.points.insert(g.points.end(), {c[0], c[1], c[2]});
          g.inclusion_id.push_back(inc.id);
          g.family.push_back(inc.family);
          g.shape.push_back(static_cast<int32_t>(sh.kind));
          g.phase.push_back(inc.family + 1);
          g.image.push_back(self ? 0 : 1);
          g.modified.push_back(inc.mod.exact_shape() ? 0 : 1);
          g.radius.push_back(sh.kind == ShapeKind::Ellipsoid ? 0.0 : sh.radius);
          g.coating.push_back(inc.mod.coating);
          g.half_axis.insert(g.half_axis.end(), {ha[0], ha[1], ha[2]});
          g.semi_axes.insert(g.semi_axes.end(), {sa[0], sa[1], sa[2]});
          g.orientation.insert(g.orientation.end(), {q.w(), q.x(), q.y(), q.z()});
          g.direction.insert(g.direction.end(), {dir[0], dir[1], dir[2]});
          g.scale.insert(g.scale.end(), {sc[0], sc[1], sc[2]});
        }
      }
    }
  }
  return g;
}

InclusionSet meshed_inclusions(const InclusionSet& set, bool all, bool coated_as_glyphs) {
  InclusionSet meshed;
  meshed.box = set.box;
  meshed.family_names = set.family_names;
  for (const Inclusion& inc : set.inclusions) {
    if (all || (coated_as_glyphs ? !inc.mod.exact_shape() : inc.mod.any()))
      meshed.inclusions.push_back(inc);
  }
  return meshed;
}

}  // namespace rvegen
