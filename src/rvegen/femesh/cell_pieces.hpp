// The inclusions as solids in the box, through Gmsh's OpenCASCADE kernel (not for use outside
// femesh/): each inclusion's solids (its core, its shell's outer surface, its void) cut by the
// faces of the periodic cells it crosses, and each piece brought into the box by its cell's
// shift, so that a face cut by a box face lies on both opposite faces as one face and its exact
// translate.
#pragma once

#include <gmsh.h>

#include <cstdint>
#include <vector>

#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/phases.hpp"

namespace rvegen::mesh_parts {

/// The solids inside the box, each with its inclusion (index in the set) and phase label.
struct CellPieces {
  gmsh::vectorpair solids;
  std::vector<int> inclusion;
  std::vector<int32_t> label;
};

/// Every inclusion of `set` as pieces inside the box: those with one image, inside the box and
/// without a shell or void, as that image; the others cut by the planes of the cells' faces in
/// as few boolean operations as can be (one per axis for the solids that cross planes of two
/// or three axes, then one for the rest). `frame_rank[i]`: the frame inclusion i is built in
/// (add_solid). Synchronizes the model.
CellPieces cut_into_box(const InclusionSet& set, const std::vector<Phase>& phases,
                        const std::vector<int>& frame_rank);

}  // namespace rvegen::mesh_parts
