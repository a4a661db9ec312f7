// Triangulated surfaces of the inclusions (a plain mesh, no VTK).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/scene.hpp"

namespace rvegen {

struct SurfaceMesh {
  std::vector<Vec3> points;
  std::vector<std::array<int64_t, 3>> triangles;  // outward-facing (counter-clockwise)
  std::vector<int32_t> inclusion_id;              // per triangle
  std::vector<int32_t> family;                    // per triangle
  std::vector<int32_t> shape;                     // per triangle: ShapeKind as int (-1: none)
  std::vector<int32_t> phase;                     // per triangle: phase label (phase_table)
  std::vector<std::array<float, 3>> axis;         // per triangle: inclusion axis (0 for spheres)
};

struct MeshOptions {
  /// Target edge length as a fraction of the smallest box size; each inclusion gets as many
  /// segments as its own size needs (clamped to [min_segments, max_segments]).
  double edge_fraction = 1.0 / 96.0;
  int min_segments = 12;
  int max_segments = 64;
  /// Periodic boxes: also mesh the images of inclusions that cross the box faces.
  bool periodic_images = true;
  /// Cut every triangle at the box faces and keep what lies inside (open surfaces at the faces).
  bool clip_to_box = false;
  /// When positive: each inclusion gets the segments around its circumference that keep the
  /// chords within this distance of the true surface (a radius r needs
  /// ceil(pi / acos(1 - chord_error / r)) segments, clamped as above), instead of edge_fraction.
  double chord_error = 0.0;
};

/// The mesh options of a scene: clipping, and the chord error in voxels (surface_chord_error)
/// turned into a length (the smallest voxel size of the image).
MeshOptions mesh_options(const OutputSpec& spec, const Box& box);

/// Tessellates every inclusion core (and, for periodic boxes, its images that reach into the
/// box): straight shapes analytically, wavy fibres with rings along the wave, deformed shapes
/// by their radial map. Each inclusion gets segments for its own size (edge length
/// edge_fraction x smallest box size, clamped to [min_segments, max_segments]).
SurfaceMesh tessellate(const InclusionSet& set, const MeshOptions& options = {});

/// Cuts the mesh at the faces of the box (triangles split, outside parts dropped).
SurfaceMesh clip_to_box(const SurfaceMesh& mesh, const Box& box);

/// Appends b to a (points and cell data).
void append(SurfaceMesh* a, const SurfaceMesh& b);

}  // namespace rvegen
