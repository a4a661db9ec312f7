#include "rvegen/model/stats.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rvegen/model/neighbours.hpp"
#include "rvegen/model/orientation.hpp"

namespace rvegen {

Mat3 orientation_tensor(const InclusionSet& set, int family) {
  Mat3 a = Mat3::Zero();
  int n = 0;
  for (const auto& inc : set.inclusions) {
    if (inc.family != family || inc.shape.kind == ShapeKind::Sphere) continue;
    const Vec3 u = law_axis(inc.shape);
    a += u * u.transpose();
    ++n;
  }
  return n > 0 ? Mat3(a / n) : a;
}

namespace {
// Minimum-image displacement (periodic boxes) or plain difference.
Vec3 displacement(const Box& box, const Vec3& from, const Vec3& to) {
  Vec3 d = to - from;
  if (box.periodic) {
    for (int k = 0; k < 3; ++k) d[k] -= box.size[k] * std::floor(d[k] / box.size[k] + 0.5);
  }
  return d;
}
}  // namespace

Summary nearest_neighbour_distances(const InclusionSet& set) {
  Summary s;
  const auto& inc = set.inclusions;
  const size_t n = inc.size();
  if (n < 2) return s;
  // Grid with cells of twice the mean spacing (in a dense packing the nearest neighbour is about
  // one spacing away: cells of one spacing sent most inclusions to the fallback); an inclusion
  // with no candidate nearer than the cell size falls back to a scan of all centres.
  const double spacing = 2.0 * std::cbrt(set.box.volume() / static_cast<double>(n));
  NeighbourGrid grid(set.box, spacing, n);
  for (size_t i = 0; i < n; ++i) grid.insert(static_cast<int>(i), inc[i].shape.center);
  const double reach = std::max(spacing, set.box.size.minCoeff() / 1024.0);
  std::vector<double> d(n, std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < n; ++i) {
    double best = std::numeric_limits<double>::infinity();
    grid.for_each_candidate(inc[i].shape.center, [&](int j) {
      if (j == static_cast<int>(i)) return;
      best = std::min(best, displacement(set.box, inc[i].shape.center, inc[j].shape.center).norm());
    });
    if (!(best <= reach)) {
      for (size_t j = 0; j < n; ++j) {
        if (j == i) continue;
        best =
            std::min(best, displacement(set.box, inc[i].shape.center, inc[j].shape.center).norm());
      }
    }
    d[i] = best;
  }
  double sum = 0.0, sum2 = 0.0;
  s.min = std::numeric_limits<double>::infinity();
  s.max = 0.0;
  for (double x : d) {
    sum += x;
    sum2 += x * x;
    s.min = std::min(s.min, x);
    s.max = std::max(s.max, x);
  }
  s.n = static_cast<int>(n);
  s.mean = sum / n;
  s.std = std::sqrt(std::max(0.0, sum2 / n - s.mean * s.mean));
  return s;
}

RadialDistribution radial_distribution(const InclusionSet& set, int family, int bins,
                                       double r_max) {
  RadialDistribution out;
  std::vector<Vec3> c;
  for (const auto& inc : set.inclusions) {
    if (inc.family == family) c.push_back(inc.shape.center);
  }
  if (set.box.periodic) r_max = std::min(r_max, 0.5 * set.box.size.minCoeff());
  if (c.size() < 2 || bins < 1 || !(r_max > 0.0)) return out;
  const double dr = r_max / bins;
  std::vector<double> hist(bins, 0.0);
  NeighbourGrid grid(set.box, r_max, c.size());
  for (size_t i = 0; i < c.size(); ++i) grid.insert(static_cast<int>(i), c[i]);
  // Every centre is a reference up to kReferences of them; above, an evenly spread subset
  // (every k-th), each with all its neighbours: g(r) keeps its meaning at a bounded cost.
  constexpr size_t kReferences = 2000;
  const size_t step = (c.size() + kReferences - 1) / kReferences;
  size_t references = 0;
  for (size_t i = 0; i < c.size(); i += step) {
    ++references;
    grid.for_each_candidate(c[i], [&](int j) {
      if (j == static_cast<int>(i)) return;
      const double r = displacement(set.box, c[i], c[j]).norm();
      if (r < r_max) hist[static_cast<int>(r / dr)] += 1.0;
    });
  }
  // Normalise by the count an ideal gas of the same density would give in each shell.
  const double rho = c.size() / set.box.volume();
  out.r.resize(bins);
  out.g.resize(bins);
  for (int b = 0; b < bins; ++b) {
    const double r0 = b * dr, r1 = r0 + dr;
    const double shell = 4.0 / 3.0 * M_PI * (r1 * r1 * r1 - r0 * r0 * r0);
    out.r[b] = r0 + 0.5 * dr;
    out.g[b] = hist[b] / (references * rho * shell);
  }
  return out;
}

}  // namespace rvegen
