#include "rvegen/packing.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <numeric>

namespace rvegen {

Shape draw_inclusion(const Family& f, const Vec3& center, Random& rng) {
  const bool aligned = f.orientation.kind == OrientationLaw::Kind::kAligned;
  switch (f.shape) {
    case ShapeKind::Sphere:
      return Shape::sphere(center, f.radius);
    case ShapeKind::Cylinder: {
      const Vec3 u = aligned ? f.orientation.axis : rng.unit_vector();
      return Shape::cylinder(center, f.radius, u * (f.aspect_ratio * f.radius));
    }
    case ShapeKind::Ellipsoid: {
      Mat3 R = rng.rotation();
      if (aligned) {
        // First principal axis along the law's axis, random spin about it.
        const Vec3 a = f.orientation.axis;
        const Vec3 b0 = any_orthogonal(a);
        const double th = 2.0 * M_PI * rng.uniform();
        const Vec3 b = std::cos(th) * b0 + std::sin(th) * a.cross(b0);
        R.col(0) = a;
        R.col(1) = b;
        R.col(2) = a.cross(b);
      }
      return Shape::ellipsoid(center, f.semi_axes, R);
    }
  }
  return Shape::sphere(center, f.radius);
}

PackingResult pack_rsa(const Scene& scene, const ProgressFn& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  PackingResult res;
  res.set.box = scene.box;
  const int nf = static_cast<int>(scene.families.size());
  res.target_count.resize(nf);
  res.placed_count.assign(nf, 0);
  double rmax = 0.0;
  for (int f = 0; f < nf; ++f) {
    res.target_count[f] = scene.target_count(f);
    rmax = std::max(rmax, scene.families[f].bounding_radius());
  }
  // Bulkiest inclusions first (largest smallest width): they are the hardest to place late.
  std::vector<int> order(nf);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return scene.families[a].min_width() > scene.families[b].min_width();
  });
  const long long total = std::accumulate(res.target_count.begin(), res.target_count.end(), 0LL);
  Random rng(scene.seed);
  const Box& box = scene.box;
  NeighbourGrid grid(box, 2.0 * rmax + scene.min_gap, static_cast<size_t>(total));
  auto& out = res.set.inclusions;
  out.reserve(total);
  long long done = 0;
  for (int f : order) {
    const Family& fam = scene.families[f];
    for (int k = 0; k < res.target_count[f]; ++k) {
      bool placed = false;
      for (int attempt = 0; attempt < scene.rsa_max_attempts && !placed; ++attempt) {
        ++res.attempts;
        Shape s = draw_inclusion(fam, Vec3::Zero(), rng);
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
            const Shape& o = out[j].shape;
            for_each_image(box, c, rs + scene.min_gap, o.center, o.bounding_radius(),
                           [&](const Vec3& sh) {
                             if (clear) clear = clear_of(s, o.translated(sh), scene.min_gap);
                           });
          });
        }
        if (!clear) continue;
        Inclusion inc;
        inc.id = static_cast<int>(out.size());
        inc.family = f;
        inc.shape = s;
        grid.insert(inc.id, c);
        out.push_back(inc);
        placed = true;
      }
      if (!placed) {
        res.status = "target_not_reached";
        if (progress) {
          progress("rsa: family \"" + fam.name + "\": no room for inclusion " +
                   std::to_string(k + 1) + " of " + std::to_string(res.target_count[f]) +
                   " after " + std::to_string(scene.rsa_max_attempts) + " attempts");
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
    if (res.status != "ok") break;
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

PackingResult generate(const Scene& scene, const ProgressFn& progress) {
  return pack_rsa(scene, progress);
}

}  // namespace rvegen
