// Triangulated surfaces of the inclusions (a plain mesh, no VTK).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "rvegen/inclusion_set.hpp"

namespace rvegen {

struct SurfaceMesh {
  std::vector<Vec3> points;
  std::vector<std::array<int64_t, 3>> triangles;  // outward-facing (counter-clockwise)
  std::vector<int32_t> inclusion_id;              // per triangle
  std::vector<int32_t> family;                    // per triangle
  std::vector<int32_t> shape;                     // per triangle: ShapeKind as int
};

struct MeshOptions {
  /// Target edge length as a fraction of the smallest box size; each inclusion gets as many
  /// segments as its own size needs (clamped to [min_segments, max_segments]).
  double edge_fraction = 1.0 / 96.0;
  int min_segments = 12;
  int max_segments = 64;
  /// Periodic boxes: also mesh the images of inclusions that cross the box faces.
  bool periodic_images = true;
};

/// Tessellates every inclusion (and, for periodic boxes, its images that reach into the box).
SurfaceMesh tessellate(const InclusionSet& set, const MeshOptions& options = {});

}  // namespace rvegen
