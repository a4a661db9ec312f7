// The periodic faces of the tetrahedral mesh, through Gmsh (not for use outside femesh/):
// each patch of an upper box face meshed as the copy of its translate on the lower face, its
// curves tied to their images first, and curved triangles lying flat in a box face raised off
// it.
#pragma once

#include <vector>

#include "rvegen/model/inclusion_set.hpp"

namespace rvegen::mesh_parts {

/// A patch of a box face at the upper end of an axis, and the patch at the lower end whose
/// translate it is.
struct FacePair {
  int upper, lower, axis;
};

/// The patches of the box's faces, paired: each upper patch with the lower one whose translate
/// it is, matched by bounding box and area. A box face's patches are the planes whose normal is
/// the axis and whose centre of mass lies within `tol` of the face (OpenCASCADE's bounding boxes
/// of patches bounded by spline curves stand out of the plane by the curves' tolerance). Throws
/// MeshError when a face's patches have no images.
std::vector<FacePair> pair_box_patches(const Box& box, double tol);
/// Ties every curve of the upper patches to its image on the lower one (Gmsh then meshes it as
/// a copy): each curve is paired with the image whose end points match and whose curve passes
/// nearest its middle.
void tie_face_curves(const std::vector<FacePair>& pairs, const Vec3& len, double tol);
/// Meshes each upper patch as the copy of its lower one's mesh, node for node.
void copy_face_meshes(const std::vector<FacePair>& pairs, const Vec3& len, double tol);
/// Splits each curved surface's triangle flat in a box face about a node on the surface, and
/// flips the chords left in the face (counted in `flipped`); returns the triangles split.
long long raise_flat_triangles(const Box& box, double tol, long long* flipped);

}  // namespace rvegen::mesh_parts
