// The outer surface of an ellipsoid's interphase shell, for the tetrahedral mesher: the offset
// of an ellipsoid (every point within t of it) is no ellipsoid, and Gmsh's OpenCASCADE calls do
// not build it, so OpenCASCADE does, and Gmsh takes the solid.
#pragma once

#include "rvegen/geometry/shapes.hpp"

namespace rvegen {

/// Adds to Gmsh's OpenCASCADE model the solid of the points within `offset` (> 0) of the
/// ellipsoid {c + M x : |x| <= 1} (M invertible) and returns its volume tag. The ellipsoid is
/// the unit sphere mapped by M (a spline surface, as Gmsh's own affine transform makes it), and
/// its offset OpenCASCADE's simple offset of that surface: close to the exact offset at the
/// nodes of a fine surface mesh, for axis ratios up to 10 and t up to the longest semi-axis
/// (docs/benchmarks.md).
/// Throws MeshError when OpenCASCADE fails.
int add_ellipsoid_offset(const Mat3& M, const Vec3& c, double offset);

}  // namespace rvegen
