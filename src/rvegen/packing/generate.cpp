#include <cstdio>
#include <string>

#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {

const char* status_name(PackingStatus status) {
  return status == PackingStatus::kOk ? "ok" : "target_not_reached";
}

const char* stop_reason_name(StopReason reason) {
  switch (reason) {
    case StopReason::kTargetReached:
      return "target reached";
    case StopReason::kJammed:
      return "jammed";
    case StopReason::kStepBudget:
      return "step budget";
    case StopReason::kTimeBudget:
      return "time budget";
    case StopReason::kNoRoom:
      return "no room after max_attempts";
  }
  return "target reached";
}

PackingResult generate(const PackingSpec& scene, const Monitor& monitor,
                       const std::function<void(InclusionSet&)>& before_audit) {
  PackingResult r =
      scene.method == Method::kRsa ? pack_rsa(scene, monitor) : pack_md(scene, monitor);
  if (monitor.cancelled && monitor.cancelled()) throw Cancelled();
  if (r.set.inclusions.empty()) {
    throw NothingPlaced(
        std::string("not one inclusion could be placed before the packing stopped (") +
        stop_reason_name(r.stop_reason) +
        "): lower the volume fraction or the modifiers (waviness, curvature), "
        "or give more time (md.max_seconds)");
  }
  for (const Family& f : scene.families) r.set.family_names.push_back(f.name);
  if (before_audit) before_audit(r.set);
  const AuditReport a = audit(r.set, 16);
  r.audit_seconds = a.seconds;
  if (!a.clean()) {
    throw AuditFailure("internal error: the packed RVE failed the exact audit (" +
                       describe_failure(a, r.set) +
                       "). This is a defect of rvegen, not of the scene; please report it "
                       "with the scene file");
  }
  if (const ProgressFn& progress = monitor.line) {
    char buf[120];
    std::snprintf(buf, sizeof buf, "audit: %zu inclusions, no overlap (%.2f s)",
                  r.set.inclusions.size(), a.seconds);
    progress(buf);
  }
  return r;
}

}  // namespace rvegen
