// The tetrahedral mesher's size field (not for use outside femesh/): the element size wanted
// at a point, from the gaps, the curvature and the thin chips at fibres' rims; the estimate of
// a mesh's elements integrates it. No Gmsh here.
#pragma once

#include <vector>

#include "rvegen/femesh/mesh_parts.hpp"
#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/model/body.hpp"

namespace rvegen::mesh_parts {

// The element size wanted at a point: the gap between the two nearest surfaces (two
// inclusions, or an inclusion and a box face it does not cross) over gap_elements, the chord
// bound at the nearest surface grown by kGrowth with the distance, the thin chips and gaps at
// fibres' rims (kThinChip), between min_size and max_size. A cell list of the images.
class SizeField {
 public:
  SizeField(const InclusionSet& set, const TetMeshOptions& opt, double max_size, double min_size);
  double operator()(const Vec3& p) const;

 private:
  size_t index(int i, int j, int k) const { return (static_cast<size_t>(k) * n_ + j) * n_ + i; }
  const InclusionSet& set_;
  const TetMeshOptions& opt_;
  double max_, min_;
  std::vector<BodyQuery> query_;
  std::vector<double> reach_;     // each inclusion's bounding radius
  std::vector<Vec3> chip_limit_;  // per axis, the depth under which a chip is refined
  std::vector<Image> images_;
  std::vector<Vec3> lo_, hi_;  // each image's bounding box, shifted
  // A lower bound on the distance from a point to an image's outer surface: the larger of
  // the distances to its bounding sphere and, for a cylinder, to its capsule.
  struct Bound {
    Vec3 centre, half_axis;  // half_axis zero but for cylinders
    double sphere = 0.0, capsule = 0.0;
    double lower(const Vec3& p) const {
      const Vec3 d = p - centre;
      const double along =
          std::clamp(d.dot(half_axis) / std::max(half_axis.squaredNorm(), 1e-300), -1.0, 1.0);
      return std::max(d.norm() - sphere, (d - along * half_axis).norm() - capsule);
    }
  };
  std::vector<Bound> bound_;
  std::vector<bool> chipped_;  // an image with a thin chip or gap at a face (kThinChip)
  int n_ = 1;
  double cell_[3] = {1, 1, 1};
  std::vector<int> start_, list_;  // each cell's images: list_[start_[c] .. start_[c + 1])
};

// The least element size of a mesh of the set: the options', or a fiftieth of the least
// inclusion size.
double least_size(const InclusionSet& set, const TetMeshSpec& spec);

}  // namespace rvegen::mesh_parts
