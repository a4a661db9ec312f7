// The vector form of an RVE: box plus inclusions. Every representation (surfaces, voxels,
// reports) is a pure function of it.
#pragma once

#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "rvegen/pair.hpp"
#include "rvegen/shapes.hpp"

namespace rvegen {

/// Invalid user input (scene or inclusion file). The message names the offending key.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Box {
  Vec3 origin = Vec3::Zero();
  Vec3 size = Vec3::Ones();
  bool periodic = true;
  double volume() const { return size.prod(); }
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
  /// Cylinders: the cross-section at axial coordinate s is displaced by
  /// wave_amplitude sin(2 pi s / wave_length + wave_phase) along the direction at angle
  /// wave_angle about the axis from any_orthogonal(axis).
  double wave_amplitude = 0.0, wave_length = 0.0, wave_phase = 0.0, wave_angle = 0.0;
  /// Spheres and ellipsoids: in the normalised frame y = M^-1 (x - c) (M = rotation diag(semi
  /// axes)), the surface is |y| = deform_scale (1 + deform_amplitude g(y / |y|)), |g| <= 1;
  /// deform_scale keeps the volume of the undeformed shape.
  double deform_amplitude = 0.0, deform_scale = 1.0;
  std::vector<DeformationWave> deform_waves;
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
  bool deformed() const { return deform_amplitude > 0.0; }
  bool debonded() const { return debond_fraction > 0.0 && debond_gap > 0.0; }
  bool any() const { return coated() || wavy() || deformed() || debonded(); }
};

struct Inclusion {
  int id = 0;
  int family = 0;
  /// The straight convex core (for a deformed inclusion: the undeformed shape whose volume it
  /// keeps; for a wavy fibre: the straight fibre it is sheared from).
  Shape shape;
  Modifiers mod;
};

struct InclusionSet {
  Box box;
  std::vector<Inclusion> inclusions;
  /// Family names, indexed by Inclusion::family (may be empty).
  std::vector<std::string> family_names;
};

/// Calls f(shift) for every lattice translation `shift` of a periodic box such that the
/// bounding spheres of a (at ca, radius ra) and of b translated by shift (at cb + shift,
/// radius rb) intersect. Enumerates every image, even for inclusions longer than half the box.
/// Non-periodic boxes yield only the zero shift (when the spheres intersect).
void for_each_image(const Box& box, const Vec3& ca, double ra, const Vec3& cb, double rb,
                    const std::function<void(const Vec3&)>& f);

/// Uniform grid over inclusion centres for neighbour queries; periodic-aware.
/// `reach` must be at least the largest sum of two bounding radii that will be queried.
/// `expected_count` bounds the number of cells (about two per stored inclusion).
class NeighbourGrid {
 public:
  NeighbourGrid(const Box& box, double reach, size_t expected_count);
  void insert(int index, const Vec3& center);
  /// Calls f(index) for every stored index whose centre may lie within `reach` of c
  /// (a superset; images are the caller's business through for_each_image).
  void for_each_candidate(const Vec3& c, const std::function<void(int)>& f) const;

 private:
  int cell_of(const Vec3& c, int axis) const;
  Box box_;
  int n_[3];
  double cell_[3];
  std::vector<std::vector<int>> cells_;
};

struct OverlapRecord {
  int a = 0;  // index into inclusions
  int b = 0;
  Vec3 shift = Vec3::Zero();  // b is tested at its position + shift
  Contact contact;
};

/// Every overlapping pair (each pair and image once; an inclusion against its own periodic
/// image is reported with a == b), sorted by (a, b); the search stops after `limit` records
/// (so a result of `limit` records means "at least that many").
std::vector<OverlapRecord> find_overlaps(const InclusionSet& set,
                                         size_t limit = static_cast<size_t>(-1));

/// Indices of inclusions not wholly inside a non-periodic box (empty for periodic boxes).
std::vector<int> find_outside(const InclusionSet& set);

/// Reads and validates an inclusion list (format "rvegen.inclusions/1"). Throws InputError.
InclusionSet read_inclusions_json(const std::string& text);
/// Serialises an inclusion list; doubles are written with round-trip precision.
std::string write_inclusions_json(const InclusionSet& set);

}  // namespace rvegen
