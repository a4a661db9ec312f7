#include "rvegen/packing/md_neighbours.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "rvegen/geometry/convex.hpp"
#include "rvegen/model/neighbours.hpp"

namespace rvegen::md {

namespace {

constexpr double kSkin = 0.5;        // Verlet skin, in capsule radii of each body
constexpr double kSkinLength = 0.5;  // or in half lengths of each body if more

// A candidate pair {a, b, kx, ky, kz}: ordered lexicographically.
using Key = std::array<int, 5>;

// Canonical key of a candidate pair: a <= b, b taken at its centre + k * box (k in box sizes);
// for a == b one of k and -k.
Key make_key(int a, int b, int kx, int ky, int kz) {
  if (a > b) {
    std::swap(a, b);
    kx = -kx;
    ky = -ky;
    kz = -kz;
  }
  if (a == b && (kx < 0 || (kx == 0 && (ky < 0 || (ky == 0 && kz < 0))))) {
    kx = -kx;
    ky = -ky;
    kz = -kz;
  }
  return {a, b, kx, ky, kz};
}

}  // namespace

bool VerletList::stale(const std::vector<Body>& bodies, double s_out) const {
  if (built_scale_ < 0.0) return true;
  for (size_t i = 0; i < bodies.size(); ++i) {
    const Body& b = bodies[i];
    const double d = (b.shape.center - built_center_[i]).norm();
    const double grow = (b.radial ? b.cap_radius : b.bound) * std::max(0.0, s_out - built_scale_);
    const double r = b.cap_half_at(s_out) + b.cap_radius_at(s_out);
    if (d + turned_since_build_[i] * r + grow > half_skin_[i]) return true;
  }
  return false;
}

void VerletList::build(std::vector<Body>* all, const Box& box, double s_out,
                       const std::function<void()>& tick) {
  std::vector<Body>& bodies = *all;
  const size_t n = bodies.size();
  built_center_.resize(n);
  half_skin_.resize(n);
  turned_since_build_.assign(n, 0.0);
  built_scale_ = s_out;
  ++rebuilds_;
  pairs_.clear();
  for (Body& b : bodies) wrap(box, &b);
  // Strings of spheres covering each capsule inflated by the body's half skin (relative to its
  // size, so large bodies do not force frequent rebuilds).
  std::vector<Vec3> sub_c;
  std::vector<double> sub_r;
  std::vector<int> sub_body;
  std::vector<Vec3> seg_p(n), seg_q(n);
  std::vector<double> cap_r(n);
  for (size_t i = 0; i < n; ++i) {
    const Body& b = bodies[i];
    built_center_[i] = b.shape.center;
    // Long bodies get a skin of a fraction of their length too: their ends sweep far when
    // they grow or turn, and the capsule test in contacts() keeps the extra pairs cheap.
    // Aligned fibres (radial) neither turn nor grow in length: the skin of a half-grown fibre.
    half_skin_[i] = b.radial ? 0.5 * kSkin * b.cap_radius * std::max(s_out, 0.5)
                             : 0.5 * kSkin * std::max(b.cap_radius, kSkinLength * b.cap_half) *
                                   b.force_scale(s_out);
    const Vec3 e = principal_axis(b.shape) * b.cap_half_at(s_out);
    const double rho = b.cap_radius_at(s_out) + half_skin_[i];
    seg_p[i] = b.shape.center - e;
    seg_q[i] = b.shape.center + e;
    cap_r[i] = rho;
    const int k = b.cap_half > 0.0 ? static_cast<int>(std::ceil(2.0 * e.norm() / rho)) + 1 : 1;
    const double spacing = k > 1 ? 2.0 * e.norm() / (k - 1) : 0.0;
    const double rs = std::sqrt(rho * rho + 0.25 * spacing * spacing);
    for (int t = 0; t < k; ++t) {
      const double u = k > 1 ? -1.0 + 2.0 * t / (k - 1) : 0.0;
      sub_c.push_back(b.shape.center + u * e);
      sub_r.push_back(rs);
      sub_body.push_back(static_cast<int>(i));
    }
  }
  // Every pair of covering spheres that meet (the broad phase the audit and RSA use too).
  std::vector<Key>& keys = keys_;
  keys.clear();
  sphere_pairs(box, sub_c, sub_r, &sphere_pairs_, tick);
  for (const SpherePair& sp : sphere_pairs_) {
    const int a = sub_body[sp.i], b = sub_body[sp.j];
    if (a == b && sp.k[0] == 0 && sp.k[1] == 0 && sp.k[2] == 0) continue;
    keys.push_back(make_key(a, b, sp.k[0], sp.k[1], sp.k[2]));
  }
  if (tick) tick();
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  if (tick) tick();
  pairs_.reserve(keys.size());
  for (const Key& k : keys) {
    const int a = k[0], b = k[1];
    const Vec3 shift(k[2] * box.size[0], k[3] * box.size[1], k[4] * box.size[2]);
    const double rr = cap_r[a] + cap_r[b];
    if (segment_distance2(seg_p[a], seg_q[a], seg_p[b] + shift, seg_q[b] + shift) > rr * rr) {
      continue;
    }
    pairs_.push_back({a, b, shift});
  }
}

}  // namespace rvegen::md
