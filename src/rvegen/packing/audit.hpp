// The exact audit of an RVE: what `rvegen check` runs, and what every packed RVE passes before
// it is returned, shown or written.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "rvegen/geometry/pair.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/model/scene.hpp"

namespace rvegen {

struct OverlapRecord {
  int a = 0;  // index into inclusions
  int b = 0;
  Vec3 shift = Vec3::Zero();  // b is tested at its position + shift
  Contact contact;
};

/// Every overlapping pair (each pair and image once; an inclusion against its own periodic
/// image is reported with a == b), sorted by (a, b); the search stops after `limit` records
/// (so a result of `limit` records means "at least that many"). `candidates` (optional) receives
/// the number of (pair, image) candidates the exact tests were run on.
std::vector<OverlapRecord> find_overlaps(const InclusionSet& set,
                                         size_t limit = static_cast<size_t>(-1),
                                         size_t* candidates = nullptr);

/// Indices of inclusions not wholly inside a non-periodic box (empty for periodic boxes).
std::vector<int> find_outside(const InclusionSet& set);

struct AuditReport {
  /// Overlapping pairs found (at most the limit given to audit(), sorted by (a, b)).
  std::vector<OverlapRecord> overlaps;
  /// True when the search stopped at the limit (there may be more).
  bool truncated = false;
  /// Non-periodic boxes: indices of inclusions not wholly inside.
  std::vector<int> outside;
  /// (pair, image) candidates given to the exact tests: near-linear in the inclusions for any
  /// size ratio (their bounding spheres meet).
  size_t candidates = 0;
  double seconds = 0.0;
  bool clean() const { return overlaps.empty() && outside.empty(); }
};

/// Every pair (and every periodic image that can reach) by the exact pair tests, on the
/// envelopes of modified inclusions, the candidates from for_each_sphere_pair (a two-level grid
/// tested against brute force: one large inclusion does not coarsen the grid for all); and, in a
/// non-periodic box, every inclusion against the walls. Stops collecting overlaps at `limit`.
AuditReport audit(const InclusionSet& set, size_t limit = 10000);

/// One line naming the first overlaps or inclusions outside the box of a failed audit.
std::string describe_failure(const AuditReport& report, const InclusionSet& set);

/// Checks an RVE handed in (an inclusion list read from a file) before any work is done with
/// the scene `scene`: the box is the scene's; every inclusion's family is one of the scene's,
/// with the family's shape, its coating (thickness and whether shells may touch) and, for
/// continuous fibres, marked so; and the exact audit finds no overlapping pair and, in a
/// non-periodic box, no inclusion leaving it. Throws InputError naming `where` and the first
/// inclusion (its id) that is wrong, and what is wrong with it.
void check_rve_for_scene(const InclusionSet& set, const PackingSpec& scene,
                         const std::string& where);

/// A packed RVE failed the exact audit: a defect of the packer, never of the input. Nothing
/// may be written or shown as a result.
class AuditFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace rvegen
