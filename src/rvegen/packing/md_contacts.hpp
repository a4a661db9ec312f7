// Molecular-dynamics packing, part 3: the contacts of one step. Every listed pair that overlaps
// at the force scale (exact pair tests, geometry/pair) gets the response of contacts.hpp; closed
// boxes add a contact with each wall. The pass also certifies the scale at which the current
// configuration is valid.
#pragma once

#include <algorithm>
#include <functional>
#include <utility>
#include <vector>

#include "rvegen/packing/md_neighbours.hpp"

namespace rvegen::md {

/// The contacts of one block of listed pairs, in pair order (md_contacts.cpp).
struct ContactBlock {
  struct Add {
    int body;
    bool turns;  // false: a move only
    Vec3 dx, dw;
  };
  std::vector<Add> adds;
  std::vector<const PairEntry*> chain_pairs;
  std::vector<std::pair<double, const PairEntry*>> limits;
  double s_in = 0.0, max_overlap = 0.0, chain_depth = 0.0;
};

/// What the contacts of one step do, summed per body.
struct ContactSums {
  std::vector<Vec3> move, turn;      // displacements and rotation vectors
  double max_overlap = 0.0;          // largest overlap depth relative to the smaller body
  std::vector<Vec3> axis;            // principal axis of every oriented body this step
  std::vector<ContactBlock> blocks;  // work space of the pass (reused)
  std::vector<std::pair<double, const PairEntry*>> limits;  // work space (reused)
};

/// Tests every listed pair (and, in a closed box, every body against the walls) at the force
/// scale s_out, sums each contact's response into *sums, and returns a scale (>= 0, at most
/// s_out) at which the current configuration is valid: pairs that do not overlap at s_out are
/// valid below it, the others below the scale at which the plane of their contact normal
/// separates them (for the pairs that limit it most, the scale bisected with the exact test).
/// `tick` is called on the calling thread every block of pairs (2048). The pairs are tested on
/// all cores (TBB), in fixed blocks whose results are applied in pair order: the sums, and so the
/// packing, do not depend on the number of threads.
///
/// Chains are not convex: a pair apart at s_out may meet when both shrink, so their scale is
/// tested, not derived. Their contacts are those of pieces grown by a relative `skin` (radius
/// r (1 + skin), half length + skin r); the pass then certifies the scale min(s_in, 1, s_out)
/// itself when the pieces as they are do not overlap there, else tests a few scales just below
/// s_out and returns 0 when none above `keep` (the best so far: a lower one is of no use)
/// passes.
double contact_pass(const std::vector<Body>& bodies, const std::vector<int>& oriented,
                    const std::vector<PairEntry>& pairs, const Box& box, double s_out, double keep,
                    double skin, ContactSums* sums, const std::function<void()>& tick);

/// A valid scale within kScaleRounding of 1 is 1: the target is reached. The certified scale is
/// a ratio of distances, and rounding leaves it at 1 - 1e-16 where bodies touch at the target
/// (a planar-fibre run reported "jammed" at what printed as the target's volume fraction). Placed
/// at scale 1, such a pair overlaps by at most that share of its size, a thousand times below
/// the exact tests' tolerance (kContactRelTolerance), so the audit still decides.
constexpr double kScaleRounding = 1e-12;
inline double round_to_target(double s) {
  return s >= 1.0 - kScaleRounding ? std::max(s, 1.0) : s;
}

}  // namespace rvegen::md
