#include "rvegen/audit.hpp"

#include <chrono>
#include <cstdio>

namespace rvegen {

AuditReport audit(const InclusionSet& set, size_t limit) {
  const auto t0 = std::chrono::steady_clock::now();
  AuditReport r;
  r.overlaps = find_overlaps(set, limit);
  r.truncated = r.overlaps.size() >= limit;
  r.outside = find_outside(set);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

std::string describe_failure(const AuditReport& report, const InclusionSet& set) {
  const auto& inc = set.inclusions;
  std::string out;
  char buf[200];
  for (size_t k = 0; k < report.overlaps.size() && k < 3; ++k) {
    const OverlapRecord& o = report.overlaps[k];
    std::snprintf(buf, sizeof buf, "%sinclusions %d and %d overlap by %.6g (%s%s)",
                  out.empty() ? "" : "; ", inc[o.a].id, inc[o.b].id, o.contact.depth,
                  contact_type_name(o.contact.type), o.shift.isZero() ? "" : ", periodic image");
    out += buf;
  }
  if (report.overlaps.size() > 3) {
    out += "; " + std::to_string(report.overlaps.size() - 3) +
           (report.truncated ? " or more" : "") + " more overlapping pairs";
  }
  for (size_t k = 0; k < report.outside.size() && k < 3; ++k) {
    std::snprintf(buf, sizeof buf, "%sinclusion %d leaves the box", out.empty() ? "" : "; ",
                  inc[report.outside[k]].id);
    out += buf;
  }
  if (report.outside.size() > 3) {
    out += "; " + std::to_string(report.outside.size() - 3) + " more outside the box";
  }
  return out;
}

}  // namespace rvegen
