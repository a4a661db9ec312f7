#include <cstdio>

#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {

PackingResult generate(const Scene& scene, const ProgressFn& progress,
                       const std::function<void(InclusionSet&)>& before_audit) {
  PackingResult r = scene.method == "rsa" ? pack_rsa(scene, progress) : pack_md(scene, progress);
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
  if (progress) {
    char buf[120];
    std::snprintf(buf, sizeof buf, "audit: %zu inclusions, no overlap (%.2f s)",
                  r.set.inclusions.size(), a.seconds);
    progress(buf);
  }
  return r;
}

}  // namespace rvegen
