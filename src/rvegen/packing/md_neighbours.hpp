// Molecular-dynamics packing, part 2: the neighbour (Verlet) list. The pairs of bodies (with the
// periodic image) whose bounding capsules, inflated by a skin, intersect; rebuilt when some body
// could have moved by more than half its skin.
#pragma once

#include <array>
#include <functional>
#include <vector>

#include "rvegen/model/neighbours.hpp"
#include "rvegen/packing/md_bodies.hpp"

namespace rvegen::md {

/// A listed pair: body b is taken at its centre + shift.
struct PairEntry {
  int a, b;
  Vec3 shift;
};

class VerletList {
 public:
  /// True when the list was never built, or when some body could have moved since the build
  /// (translation, turn times its capsule size, growth to s_out) by more than half its skin.
  bool stale(const std::vector<Body>& bodies, double s_out) const;
  /// Wraps the centres into a periodic box, then lists every pair whose capsules at s_out,
  /// inflated by their half skins, intersect. Bodies are covered by strings of spheres for the
  /// broad phase (model/neighbours), so long fibres do not force huge cells. `tick` is called
  /// in long loops (a time budget may throw from it).
  void build(std::vector<Body>* bodies, const Box& box, double s_out,
             const std::function<void()>& tick);
  const std::vector<PairEntry>& pairs() const { return pairs_; }
  /// Records that body i turned by `angle` radians since the last build.
  void turned(int i, double angle) { turned_since_build_[i] += angle; }
  long long rebuilds() const { return rebuilds_; }

 private:
  std::vector<PairEntry> pairs_;
  // The state the list was built for. Centres are wrapped into a periodic box only when the
  // list is rebuilt, so the stored shifts stay right between rebuilds.
  std::vector<Vec3> built_center_;
  std::vector<double> half_skin_;
  std::vector<double> turned_since_build_;
  double built_scale_ = -1.0;
  long long rebuilds_ = 0;
  // Work space of build(), kept for its capacity.
  std::vector<SpherePair> sphere_pairs_;
  std::vector<std::array<int, 5>> keys_;
};

}  // namespace rvegen::md
