// Packing engines: turn a validated Scene into an InclusionSet with no overlapping pair.
#pragma once

#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "rvegen/model/errors.hpp"
#include "rvegen/model/scene.hpp"

namespace rvegen {

/// kOk, or kTargetNotReached (the best non-overlapping configuration is still in the result).
enum class PackingStatus { kOk, kTargetNotReached };
/// Why a packing run ended.
enum class StopReason { kTargetReached, kJammed, kStepBudget, kTimeBudget, kNoRoom };
/// JSON names: "ok", "target_not_reached".
const char* status_name(PackingStatus status);
/// JSON names: "target reached", "jammed", "step budget", "time budget",
/// "no room after max_attempts".
const char* stop_reason_name(StopReason reason);

struct PackingResult {
  InclusionSet set;
  PackingStatus status = PackingStatus::kOk;
  Method method = Method::kMd;
  StopReason stop_reason = StopReason::kTargetReached;
  std::vector<int> target_count;               // per family
  std::vector<int> placed_count;               // per family
  std::vector<double> target_volume_fraction;  // per family, of the drawn population
  double seconds = 0.0;
  /// Seconds of the exact audit that generate() runs on the result.
  double audit_seconds = 0.0;
  long long attempts = 0;  // rsa: placement attempts
  long long steps = 0;     // md: integration steps
  /// md: size scale of the returned inclusions relative to the drawn ones (1 when reached;
  /// below 1 the best valid configuration is returned shrunk about the centres).
  double scale = 1.0;
};

/// Progress callback: receives one human-readable line at a time.
using ProgressFn = std::function<void(const std::string&)>;

/// What a caller sees of a packing run, and how it stops one. Every member is optional.
struct Monitor {
  /// One human-readable line at a time (about once a second).
  ProgressFn line;
  /// The share of the packing done, from 0 rising to 1: the volume of the inclusions at the
  /// best valid scale over their drawn volume (md), the inclusions placed over those drawn
  /// (rsa). Called at most every 16 md steps or 64 rsa attempts, and at the end.
  std::function<void(double)> fraction;
  /// Polled between steps and inside the long loops of a step (as often as the time budget
  /// is checked); true stops the run and generate() throws Cancelled. Must be cheap.
  std::function<bool()> cancelled;
};

/// Thrown by generate() when the packing stopped (time or step budget, jam) before a single
/// inclusion had a valid place: an empty box is no RVE, so nothing is returned.
class NothingPlaced : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Random sequential adsorption: the population is drawn (draw_population), then inclusions are
/// placed one at a time (largest first) at uniform random positions and kept when clear of every
/// placed one (and their periodic images) by scene.min_gap. Each inclusion gets at most
/// scene.rsa_max_attempts draws; when one fails the run stops with status "target_not_reached".
PackingResult pack_rsa(const PackingSpec& scene, const Monitor& monitor);
inline PackingResult pack_rsa(const PackingSpec& scene, const ProgressFn& progress = nullptr) {
  return pack_rsa(scene, Monitor{progress, nullptr, nullptr});
}

/// Molecular-dynamics packing with growth (see md.cpp for the scheme). Never overlapping by
/// the exact tests; bounded by scene.md (steps, seconds); status "target_not_reached" with the
/// best valid configuration (shrunk by `scale`) when jammed or out of budget.
PackingResult pack_md(const PackingSpec& scene, const Monitor& monitor);
inline PackingResult pack_md(const PackingSpec& scene, const ProgressFn& progress = nullptr) {
  return pack_md(scene, Monitor{progress, nullptr, nullptr});
}

/// Runs the scene's method, then the exact audit (audit.hpp) of the result. Throws AuditFailure
/// when the audit finds an overlap (or, in a non-periodic box, an inclusion leaving it): no
/// overlapping RVE is ever returned, whatever the status; NothingPlaced when not one inclusion
/// was placed. `before_audit` is a test hook that may
/// alter the packed set before the audit (fault injection).
PackingResult generate(const PackingSpec& scene, const Monitor& monitor,
                       const std::function<void(InclusionSet&)>& before_audit = nullptr);
inline PackingResult generate(const PackingSpec& scene, const ProgressFn& progress = nullptr,
                              const std::function<void(InclusionSet&)>& before_audit = nullptr) {
  return generate(scene, Monitor{progress, nullptr, nullptr}, before_audit);
}

}  // namespace rvegen
