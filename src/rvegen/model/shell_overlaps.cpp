#include "rvegen/model/shell_overlaps.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rvegen/model/neighbours.hpp"

namespace rvegen {

double ball_lens_volume(double r1, double r2, double d) {
  if (d >= r1 + r2) return 0.0;
  const double small = std::min(r1, r2);
  if (d <= std::abs(r1 - r2)) return 4.0 / 3.0 * M_PI * small * small * small;
  const double s = r1 + r2 - d;
  return M_PI * s * s * (d * d + 2.0 * d * (r1 + r2) - 3.0 * (r1 - r2) * (r1 - r2)) / (12.0 * d);
}

bool balls_meet(const Vec3& c1, double r1, const Vec3& c2, double r2, const Vec3& c3, double r3) {
  const Vec3 axis = c2 - c1;
  const double d = axis.norm();
  if (d >= r1 + r2) return false;
  auto in1 = [&](const Vec3& p) { return (p - c1).norm() <= r1; };
  auto in2 = [&](const Vec3& p) { return (p - c2).norm() <= r2; };
  if (in1(c3) && in2(c3)) return true;
  if (d <= std::abs(r1 - r2)) {  // one ball holds the other: their intersection is the smaller
    const Vec3& c = r1 <= r2 ? c1 : c2;
    return (c3 - c).norm() < (r1 <= r2 ? r1 : r2) + r3;
  }
  // The nearest point of the lens is on one of its caps (the radial projection of c3 onto the
  // sphere, where it lies in the other ball) or on the rim circle.
  double best = std::numeric_limits<double>::infinity();
  auto project = [&](const Vec3& c, double r, const auto& inside_other) {
    const Vec3 v = c3 - c;
    const double n = v.norm();
    if (n == 0.0) return;
    const Vec3 p = c + (r / n) * v;
    if (inside_other(p)) best = std::min(best, (p - c3).norm());
  };
  project(c1, r1, in2);
  project(c2, r2, in1);
  const Vec3 u = axis / d;
  const double x = (d * d + r1 * r1 - r2 * r2) / (2.0 * d);
  const double a = std::sqrt(std::max(0.0, r1 * r1 - x * x));
  const Vec3 c0 = c1 + x * u;
  const Vec3 q = c3 - c0;
  const double along = q.dot(u);
  const double across = (q - along * u).norm();
  best = std::min(best, std::hypot(along, across - a));
  return best < r3;
}

namespace {

bool may_touch(const Inclusion& inc) {
  return inc.mod.coated() && inc.mod.shells_may_touch;
}

}  // namespace

ShellOverlaps shell_overlaps(const InclusionSet& set) {
  ShellOverlaps out;
  int families = 0;
  for (const auto& inc : set.inclusions) families = std::max(families, inc.family + 1);
  out.taken.assign(families, 0.0);
  std::vector<int> shelled;
  double reach = 0.0;
  for (size_t i = 0; i < set.inclusions.size(); ++i) {
    const Inclusion& inc = set.inclusions[i];
    if (!may_touch(inc)) continue;
    shelled.push_back(static_cast<int>(i));
    reach = std::max(reach, inc.shape.bounding_radius() + inc.mod.coating);
    if (inc.shape.kind != ShapeKind::Sphere && out.exact) {
      out.exact = false;
      out.why_not = std::string("shells that may touch on ") + shape_name(inc.shape.kind) +
                    "s (only spheres' overlaps are computed)";
    }
  }
  if (shelled.empty() || !out.exact) return out;
  // Each sphere's neighbours: the images of other shells that its outer ball meets, as
  // (index, centre of that image).
  NeighbourGrid grid(set.box, 2.0 * reach, shelled.size());
  for (int i : shelled) grid.insert(i, set.inclusions[i].shape.center);
  auto outer = [&](int i) {
    return set.inclusions[i].shape.radius + set.inclusions[i].mod.coating;
  };
  std::vector<std::pair<int, Vec3>> near;
  for (int i : shelled) {
    const Shape& si = set.inclusions[i].shape;
    const double ri = outer(i);
    near.clear();
    grid.for_each_candidate(si.center, [&](int j) {
      const Shape& sj = set.inclusions[j].shape;
      for_each_image(set.box, si.center, ri, sj.center, outer(j), [&](const Vec3& shift) {
        if (j == i && shift.isZero()) return;
        near.push_back({j, sj.center + shift});
      });
    });
    for (size_t a = 0; a < near.size(); ++a) {
      const int j = near[a].first;
      const Vec3& cj = near[a].second;
      const double rj = outer(j);
      // Each pair once: from its lower index; a ball and its own image, by the image's shift.
      const Vec3 shift = cj - si.center, back = -shift;
      if (j < i || (j == i && std::lexicographical_compare(shift.data(), shift.data() + 3,
                                                           back.data(), back.data() + 3))) {
        continue;
      }
      ++out.pairs;
      const double d = shift.norm();
      const double ci = set.inclusions[i].shape.radius, cr = set.inclusions[j].shape.radius;
      const double t = std::max(set.inclusions[i].mod.coating, set.inclusions[j].mod.coating);
      if (d < (ci + cr + t) * (1.0 - 1e-9)) {  // a core within reach of the other shell
        out.exact = false;
        out.why_not = "a shell reaches into a neighbour's core (inclusions " +
                      std::to_string(set.inclusions[i].id) + " and " +
                      std::to_string(set.inclusions[j].id) + ")";
        continue;
      }
      for (size_t b = 0; b < near.size(); ++b) {
        if (b == a) continue;
        const int k = near[b].first;
        // Each triple once: counted from its lowest index, k after j.
        if (k < i || (k == j && b < a) || (k != j && k < j)) continue;
        if (balls_meet(si.center, ri, cj, rj, near[b].second, outer(k))) ++out.triples;
      }
      out.taken[set.inclusions[std::max(i, j)].family] += ball_lens_volume(ri, rj, d);
    }
  }
  if (out.triples > 0 && out.exact) {
    out.exact = false;
    out.why_not = std::to_string(out.triples) + " triples of shells have a common point";
  }
  if (!out.exact) std::fill(out.taken.begin(), out.taken.end(), 0.0);
  return out;
}

}  // namespace rvegen
