// Fixtures the femesh tests share: a cube of six tetrahedra, one inclusion in a unit box,
// tilted fibres.
#pragma once

#include <array>
#include <cmath>
#include <utility>
#include <vector>

#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/model/inclusion_set.hpp"

namespace rvegen::femesh_test {

// The unit cube cut into six tetrahedra about its diagonal (0,0,0)-(1,1,1).
inline TetMesh kuhn_cube() {
  TetMesh m;
  m.box.origin = Vec3(0, 0, 0);
  m.box.size = Vec3(1, 1, 1);
  for (int k = 0; k < 8; ++k) m.nodes.push_back(Vec3(k & 1, (k >> 1) & 1, (k >> 2) & 1));
  // Paths from corner 0 to corner 7 adding one axis bit at a time.
  const int axes[6][3] = {{1, 2, 4}, {1, 4, 2}, {2, 1, 4}, {2, 4, 1}, {4, 1, 2}, {4, 2, 1}};
  for (const auto& p : axes) {
    std::array<int32_t, 4> t = {0, p[0], p[0] | p[1], 7};
    if (tet_volume(m.nodes, t) < 0.0) std::swap(t[2], t[3]);  // positive, as tet_mesh's
    m.tets.push_back(t);
    m.phase.push_back(0);
    m.inclusion_id.push_back(-1);
  }
  return m;
}

inline InclusionSet one_of(const Shape& shape) {
  InclusionSet set;
  set.box.size = Vec3(1, 1, 1);
  Inclusion inc;
  inc.shape = shape;
  set.inclusions.push_back(inc);
  set.family_names = {"one"};
  return set;
}

// A fibre of radius r and half length h about (0.5, 0.5, z), its axis `degrees` off the z
// faces in the xz plane.
inline Inclusion tilted_fibre(double degrees, double r, double h, double z) {
  const double t = degrees * M_PI / 180.0;
  Inclusion inc;
  inc.shape = Shape::cylinder(Vec3(0.5, 0.5, z), r, h * Vec3(std::cos(t), 0.0, std::sin(t)));
  return inc;
}

// Twelve fibres of radius r and half length 0.2, 7 degrees off the z faces, at heights k / 12.
inline InclusionSet shallow_fibres(double r) {
  InclusionSet set = one_of(Shape::sphere(Vec3(0.5, 0.5, 0.5), 0.01));
  set.inclusions.clear();
  for (int k = 0; k < 12; ++k) set.inclusions.push_back(tilted_fibre(7.0, r, 0.2, k / 12.0));
  return set;
}

}  // namespace rvegen::femesh_test
