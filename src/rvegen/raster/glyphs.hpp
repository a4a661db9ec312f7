// Inclusions as glyph points: one vertex per inclusion (and per periodic image reaching into the
// box) with the attributes that make a unit glyph the exact inclusion. What inclusions.vtp and
// the ParaView source's Inclusions port hold (no VTK here).
#pragma once

#include <cstdint>
#include <vector>

#include "rvegen/model/inclusion_set.hpp"

namespace rvegen {

/// Structure of arrays, one entry per point (3 or 4 doubles per point for vectors).
/// A unit sphere glyph (radius 0.5) or a cylinder glyph along y (height 1, radius 0.5), scaled by
/// `scale` component-wise, then turned by the unit quaternion `orientation` (w, x, y, z) and moved
/// to the point, is the inclusion exactly (spheres and ellipsoids: sphere glyph; cylinders:
/// cylinder glyph).
struct GlyphPoints {
  std::vector<double> points;  // x, y, z
  std::vector<int32_t> inclusion_id;
  std::vector<int32_t> family;
  std::vector<int32_t> shape;       // ShapeKind as int: 0 sphere, 1 cylinder, 2 ellipsoid
  std::vector<int32_t> phase;       // phase label of the core (family + 1)
  std::vector<int32_t> image;       // 1 for a periodic image
  std::vector<int32_t> modified;    // 1 for wavy, bent, deformed or debonded (not a glyph; a
                                    // straight coated inclusion's glyph is its core)
  std::vector<double> radius;       // 0 for ellipsoids
  std::vector<double> coating;      // interphase thickness (0: none): the shell of a straight
                                    // inclusion is every point within it of the core
  std::vector<double> half_axis;    // cylinders; 0 otherwise
  std::vector<double> semi_axes;    // ellipsoids; 0 otherwise
  std::vector<double> orientation;  // quaternion w, x, y, z
  std::vector<double> direction;    // axis (z for spheres)
  std::vector<double> scale;        // glyph scale along the glyph's x, y, z
  size_t size() const { return inclusion_id.size(); }
};

GlyphPoints glyph_points(const InclusionSet& set);

/// The inclusions whose surfaces are meshed: all of them with `all`, otherwise the modified ones
/// (wavy, deformed, coated, debonded: their shape is not a glyph), or with `coated_as_glyphs`
/// only those whose shape is not exact (Modifiers::exact_shape: a straight coated inclusion is
/// its glyph and the glyph's coating).
InclusionSet meshed_inclusions(const InclusionSet& set, bool all, bool coated_as_glyphs = false);

}  // namespace rvegen
