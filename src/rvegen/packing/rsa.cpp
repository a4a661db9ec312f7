#include <algorithm>
#include <chrono>
#include <cstdio>
#include <numeric>

#include "rvegen/model/body.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {

PackingResult pack_rsa(const PackingSpec& scene, const Monitor& monitor) {
  const ProgressFn& progress = monitor.line;
  const auto t0 = std::chrono::steady_clock::now();
  PackingResult res;
  res.set.box = scene.box;
  res.method = Method::kRsa;
  const int nf = static_cast<int>(scene.families.size());
  Random rng(scene.seed);
  std::vector<Inclusion> pop = draw_population(scene, rng);
  res.target_count.assign(nf, 0);
  res.placed_count.assign(nf, 0);
  res.target_volume_fraction.assign(nf, 0.0);
  double rmax = 0.0;
  for (const auto& inc : pop) {
    ++res.target_count[inc.family];
    res.target_volume_fraction[inc.family] += inc.shape.volume() / scene.box.volume();
    rmax = std::max(rmax, envelope(inc).bounding_radius());
  }
  // Bulkiest inclusions first (largest smallest width): they are the hardest to place late.
  std::stable_sort(pop.begin(), pop.end(), [](const Inclusion& a, const Inclusion& b) {
    return envelope(a).min_size() > envelope(b).min_size();
  });
  const long long total = static_cast<long long>(pop.size());
  const Box& box = scene.box;
  NeighbourGrid grid(box, 2.0 * rmax + scene.min_gap, static_cast<size_t>(total));
  auto& out = res.set.inclusions;
  out.reserve(total);
  long long done = 0;
  bool out_of_time = false;
  for (const Inclusion& drawn : pop) {
    const int f = drawn.family;
    {
      bool placed = false;
      for (int attempt = 0; attempt < scene.rsa_max_attempts && !placed; ++attempt) {
        if ((++res.attempts & 63) == 0) {
          if (monitor.cancelled && monitor.cancelled()) throw Cancelled();
          if (monitor.fraction) monitor.fraction(static_cast<double>(done) / total);
          if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() >
              scene.rsa_max_seconds) {
            out_of_time = true;
            break;
          }
        }
        Shape s = envelope(drawn);  // modified inclusions are placed by their envelopes
        Vec3 lo, hi;
        s.aabb(&lo, &hi);  // around the origin: half extents are hi
        Vec3 c;
        bool fits = true;
        for (int a = 0; a < 3; ++a) {
          if (box.periodic) {
            c[a] = box.origin[a] + box.size[a] * rng.uniform();
          } else {
            const double room = box.size[a] - 2.0 * hi[a];
            fits &= room > 0.0;
            c[a] = box.origin[a] + hi[a] + std::max(room, 0.0) * rng.uniform();
          }
        }
        if (!fits) continue;
        s.center = c;
        const double rs = s.bounding_radius();
        bool clear = true;
        // Against its own periodic images (inclusions longer than the box).
        if (box.periodic && 2.0 * rs + scene.min_gap > box.size.minCoeff()) {
          for_each_image(box, c, rs + 0.5 * scene.min_gap, c, rs + 0.5 * scene.min_gap,
                         [&](const Vec3& sh) {
                           if (clear && !sh.isZero())
                             clear = clear_of(s, s.translated(sh), scene.min_gap);
                         });
        }
        if (clear) {
          grid.for_each_candidate(c, [&](int j) {
            if (!clear) return;
            const Shape o = envelope(out[j]);
            for_each_image(box, c, rs + scene.min_gap, o.center, o.bounding_radius(),
                           [&](const Vec3& sh) {
                             if (clear) clear = clear_of(s, o.translated(sh), scene.min_gap);
                           });
          });
        }
        if (!clear) continue;
        Inclusion inc = place_like(drawn, s, 1.0);
        inc.id = static_cast<int>(out.size());
        grid.insert(inc.id, c);
        out.push_back(inc);
        placed = true;
      }
      if (!placed) {
        res.status = PackingStatus::kTargetNotReached;
        if (out_of_time) {
          if (progress) progress("rsa: time budget (rsa.max_seconds) spent");
          break;
        }
        if (progress) {
          progress("rsa: family \"" + scene.families[f].name + "\": no room for inclusion " +
                   std::to_string(done + 1) + " of " + std::to_string(total) + " after " +
                   std::to_string(scene.rsa_max_attempts) + " attempts");
        }
        break;
      }
      ++res.placed_count[f];
      ++done;
      if (progress && (done % 500 == 0 || done == total)) {
        char buf[128];
        std::snprintf(buf, sizeof buf, "rsa: placed %lld / %lld inclusions (%lld attempts)", done,
                      total, res.attempts);
        progress(buf);
      }
    }
  }
  res.stop_reason = res.status == PackingStatus::kOk ? StopReason::kTargetReached
                    : out_of_time                    ? StopReason::kTimeBudget
                                                     : StopReason::kNoRoom;
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (monitor.fraction) monitor.fraction(total > 0 ? static_cast<double>(done) / total : 1.0);
  return res;
}

}  // namespace rvegen
