// The vector form of an RVE: box plus inclusions. Every representation (surfaces, voxels,
// reports) is a pure function of it.
#pragma once

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "rvegen/geometry/shapes.hpp"
#include "rvegen/model/errors.hpp"

namespace rvegen {

struct Box {
  Vec3 origin = Vec3::Zero();
  Vec3 size = Vec3::Ones();
  bool periodic = true;
  double volume() const { return size.prod(); }
  /// x brought into the box along each periodic axis (unchanged in a closed box).
  Vec3 wrapped(Vec3 x) const {
    if (!periodic) return x;
    for (int a = 0; a < 3; ++a) x[a] -= std::floor((x[a] - origin[a]) / size[a]) * size[a];
    return x;
  }
};

/// Refuses (InputError naming `path`) a box the arithmetic cannot serve: sizes outside
/// [1e-12, 1e12], a largest size more than 1e6 times the smallest, or an origin further than
/// 1000 box sizes from zero (coordinates would lose the precision the exact tests need).
void check_box(const Box& box, const std::string& path);

/// One random wave of a deformation: g(n) += weight cos(wavenumber (n . direction) + phase),
/// n a unit direction in the inclusion's own frame.
struct DeformationWave {
  Vec3 direction = Vec3::UnitZ();
  double weight = 0.0;
  double wavenumber = 0.0;
  double phase = 0.0;
};

/// What makes an inclusion more than its straight convex shape (see body.hpp for the geometry).
/// Lengths are absolute, in the units of the box. All zero: a plain inclusion.
struct Modifiers {
  /// Interphase shell: every point within `coating` of the core.
  double coating = 0.0;
  /// Shells of neighbours may merge (cores are then packed coating apart, not 2 x coating).
  bool shells_may_touch = false;
  /// Cylinders: a continuous fibre ("length": "through"), exactly as long as the periodic box
  /// along its axis, which is a box axis: it meets its own images end to end, so it has no
  /// ends, and its shell is a tube without caps. Not a modifier of the shape (any() ignores it):
  /// a plain continuous fibre is its straight cylinder and the cylinder's periodic images.
  bool through = false;
  /// Cylinders: the cross-section at axial coordinate s is displaced by
  /// wave_amplitude sin(2 pi s / wave_length + wave_phase) along the direction at angle
  /// wave_angle about the axis from any_orthogonal(axis).
  double wave_amplitude = 0.0, wave_length = 0.0, wave_phase = 0.0, wave_angle = 0.0;
  /// Cylinders: a bend of the centre line into a circular arc of radius bend_radius (the
  /// radius of curvature), in the plane of the axis and the direction at angle bend_angle
  /// about the axis from any_orthogonal(axis); see body.hpp (centre_offset). 0: straight.
  double bend_radius = 0.0, bend_angle = 0.0;
  /// Spheres and ellipsoids: in the normalised frame y = M^-1 (x - c) (M = rotation diag(semi
  /// axes)), the surface is |y| = deform_scale (1 + deform_amplitude g(y / |y|)), |g| <= 1;
  /// deform_scale keeps the volume of the undeformed shape.
  double deform_amplitude = 0.0, deform_scale = 1.0;
  std::vector<DeformationWave> deform_waves;
  /// A certified upper bound of g's maximum (deformation_peak), set where the waves are drawn
  /// or read; 1 (the bound |g| <= 1) otherwise. Derived: not written.
  double deform_peak = 1.0;
  /// Spheres: a void of thickness debond_gap over the cap of the surface around debond_axis
  /// that covers debond_fraction of the surface.
  double debond_fraction = 0.0, debond_gap = 0.0;
  Vec3 debond_axis = Vec3::UnitZ();

  /// Clearance added to the packing envelope of every inclusion of a scene in which shells may
  /// touch: half the largest such coating, so a shell that reaches beyond its own envelope
  /// never meets another inclusion's body (only another touching shell).
  double packing_pad = 0.0;

  bool coated() const { return coating > 0.0; }
  bool wavy() const { return wave_amplitude > 0.0; }
  bool bent() const { return bend_radius > 0.0; }
  /// The fibre's centre line is not straight (wavy or bent).
  bool curved() const { return wavy() || bent(); }
  bool deformed() const { return deform_amplitude > 0.0; }
  bool debonded() const { return debond_fraction > 0.0 && debond_gap > 0.0; }
  /// The cosine of the debonded cap's half-angle about debond_axis (the cap covers
  /// debond_fraction of the sphere: 1 - 2 f).
  double debond_cos_cap() const { return 1.0 - 2.0 * debond_fraction; }
  bool any() const { return coated() || curved() || deformed() || debonded(); }
  /// The core is its straight convex shape and a shell, if any, the exact offset of it: the
  /// shape and the coating's thickness say everything (no level set or surface mesh needed).
  bool exact_shape() const { return !curved() && !deformed() && !debonded(); }
};

struct Inclusion {
  int id = 0;
  int family = 0;
  /// The straight convex core (for a deformed inclusion: the undeformed shape whose volume it
  /// keeps; for a wavy or bent fibre: the straight fibre it is sheared from).
  Shape shape;
  Modifiers mod;
};

struct InclusionSet {
  Box box;
  std::vector<Inclusion> inclusions;
  /// Family names, indexed by Inclusion::family (may be empty).
  std::vector<std::string> family_names;
};

}  // namespace rvegen
