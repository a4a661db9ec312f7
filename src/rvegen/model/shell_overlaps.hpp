// Where interphase shells that may touch (shells_may_touch) overlap: the volume that the sum of
// the shells counts twice, so that the phases' exact volumes count a merged shell once.
#pragma once

#include <string>
#include <vector>

#include "rvegen/model/inclusion_set.hpp"

namespace rvegen {

struct ShellOverlaps {
  /// Per family: the volume of the lenses where its shells overlap a shell of an earlier
  /// inclusion (lower index). The voxel image and the tetrahedral mesh give such a lens to the
  /// earlier inclusion, so this is what the later one's family loses.
  std::vector<double> taken;
  long long pairs = 0;    // pairs of shells (periodic images counted apart) that overlap
  long long triples = 0;  // triples of shells with a common point
  /// True when `taken` is the exact double count: every overlapping pair is two coated spheres
  /// whose lens is clear of both cores, and no point lies in three shells. Otherwise `taken`
  /// is zero everywhere and `why_not` says what stood in the way.
  bool exact = true;
  std::string why_not;
};

/// The overlaps of the shells of the set's coated inclusions with shells_may_touch (none when
/// no inclusion has such a shell). Spheres: lenses of their outer balls in closed form; a
/// common point of three balls is found exactly (the point of a lens nearest the third centre).
ShellOverlaps shell_overlaps(const InclusionSet& set);

/// The volume common to two balls of radii r1, r2 whose centres are d apart.
double ball_lens_volume(double r1, double r2, double d);

/// Whether three balls (centre, radius) have a common point of positive measure's closure:
/// the nearest point to c3 of the first two balls' intersection lies within r3.
bool balls_meet(const Vec3& c1, double r1, const Vec3& c2, double r2, const Vec3& c3, double r3);

}  // namespace rvegen
