// The size field of the tetrahedral mesher and the estimate of a mesh's elements from it (the
// memory check before any mesh is made). No Gmsh here.
#include "rvegen/femesh/size_field.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <thread>
#include <vector>

#include "rvegen/femesh/mesh_tolerances.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/model/parallel.hpp"
#include "rvegen/model/resources.hpp"

namespace rvegen {

namespace mesh_parts {

namespace {

// How fast elements grow away from a surface (size per distance). Before, the chord bound held
// at full strength out to the largest size and then jumped; grown by 0.2 instead, the test
// scene took far fewer elements, of a larger least dihedral angle, and CalculiX's conductivity
// on it stayed close to the FFT's (growing faster lost more accuracy). A mixed scene (coated
// beads and rods, ellipsoids) fell under 5 degrees at times without it, and not with it
// (docs/benchmarks.md).
constexpr double kGrowth = 0.2;

// A box face that cuts a fibre's end rim less than kThinChip radii from its extreme, or passes
// that close to it, leaves a chip of the fibre or a gap of matrix thinner than the elements at
// the surface, and the elements there were slivers (many fibres at a coarse chord error: a
// face cut a rim, or passed near one). The size field puts at least two elements across such
// chips and gaps, growing by kChipGrowth away from them (growing faster left slivers where the
// sizes grew). Only where the end disk and the mantle both meet the face at kChipWedge or
// more: a fibre slightly off a face and cut just under its mantle meets the face at its small
// tilt, and refined so, its elements followed that wedge and were slivers, where the coarse
// ones cut across it left none. The figures: docs/benchmarks.md.
constexpr double kThinChip = 0.25;
constexpr double kChipGrowth = 0.5;
constexpr double kChipWedge = 20.0 * M_PI / 180.0;

}  // namespace

SizeField::SizeField(const InclusionSet& set, const TetMeshOptions& opt, double max_size,
                     double min_size)
    : set_(set), opt_(opt), max_(max_size), min_(min_size) {
  for (const Inclusion& inc : set.inclusions) {
    query_.emplace_back(inc);
    reach_.push_back(inc.shape.bounding_radius() + outer_offset(inc.mod));
    // A fibre's rims where its end disk and mantle both meet a face at kChipWedge or more.
    Vec3 limit = Vec3::Zero();
    if (inc.shape.kind == ShapeKind::Cylinder) {
      const Vec3 u = inc.shape.half_axis.normalized();
      for (int a = 0; a < 3; ++a) {
        if (std::abs(u[a]) >= std::sin(kChipWedge) && std::abs(u[a]) <= std::cos(kChipWedge))
          limit[a] = kThinChip * (inc.shape.radius + outer_offset(inc.mod));
      }
    }
    chip_limit_.push_back(limit);
  }
  images_ = images_near(set, max_);
  // Cells of a third of the largest size, each listing the images that may lie within max_
  // of it: for a cylinder, those whose capsule (its axis grown by its radius) does, tested
  // from the cell's centre; for other shapes, those whose box does. (Cells of max_ listing
  // every image whose box came within max_ held many fibres each, most of them tested in full
  // at every call.)
  const double side = set.box.size.minCoeff();
  n_ = std::clamp(static_cast<int>(3.0 * side / max_), 1, 96);
  for (int a = 0; a < 3; ++a) cell_[a] = set.box.size[a] / n_;
  const double half_diagonal = 0.5 * Vec3(cell_[0], cell_[1], cell_[2]).norm();
  lo_.resize(images_.size());
  hi_.resize(images_.size());
  bound_.resize(images_.size());
  std::vector<std::pair<int, int>> entries;  // (cell, image)
  for (size_t id = 0; id < images_.size(); ++id) {
    const Inclusion& inc = set.inclusions[images_[id].inc];
    const Shape& s = inc.shape;
    Vec3& lo = lo_[id];
    Vec3& hi = hi_[id];
    outer_aabb(inc, &lo, &hi);
    lo += images_[id].shift;
    hi += images_[id].shift;
    Bound& b = bound_[id];
    b.centre = s.center + images_[id].shift;
    b.sphere = reach_[images_[id].inc];
    const bool capsule = s.kind == ShapeKind::Cylinder;
    b.half_axis = capsule ? s.half_axis : Vec3::Zero();
    b.capsule = capsule ? s.radius + outer_offset(inc.mod) : b.sphere;
    bool chipped = false;
    for (int a = 0; a < 3; ++a) {
      const double f0 = set.box.origin[a], f1 = f0 + set.box.size[a];
      for (const double f : {f0, f1}) {
        chipped = chipped || std::min(std::abs(f - lo[a]), std::abs(hi[a] - f)) <
                                 chip_limit_[images_[id].inc][a];
      }
    }
    chipped_.push_back(chipped);
    int c0[3], c1[3];
    for (int a = 0; a < 3; ++a) {
      const double o = set.box.origin[a];
      c0[a] = std::clamp(static_cast<int>(std::floor((lo[a] - max_ - o) / cell_[a])), 0, n_ - 1);
      c1[a] = std::clamp(static_cast<int>(std::floor((hi[a] + max_ - o) / cell_[a])), 0, n_ - 1);
    }
    for (int k = c0[2]; k <= c1[2]; ++k) {
      for (int j = c0[1]; j <= c1[1]; ++j) {
        for (int i = c0[0]; i <= c1[0]; ++i) {
          if (capsule) {
            const Vec3 centre = set.box.origin + Vec3((i + 0.5) * cell_[0], (j + 0.5) * cell_[1],
                                                      (k + 0.5) * cell_[2]);
            if (b.lower(centre) > max_ + half_diagonal) continue;
          }
          entries.emplace_back(static_cast<int>(index(i, j, k)), static_cast<int>(id));
        }
      }
    }
  }
  // The lists, cell after cell, each in the images' order.
  start_.assign(static_cast<size_t>(n_) * n_ * n_ + 1, 0);
  for (const auto& e : entries) ++start_[e.first + 1];
  for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
  list_.resize(entries.size());
  std::vector<int> fill(start_.begin(), start_.end() - 1);
  for (const auto& e : entries) list_[fill[e.first]++] = e.second;
}

double SizeField::operator()(const Vec3& p) const {
  int c[3];
  for (int a = 0; a < 3; ++a) {
    c[a] = std::clamp(static_cast<int>((p[a] - set_.box.origin[a]) / cell_[a]), 0, n_ - 1);
  }
  double d1 = 1e300, d2 = 1e300, rho1 = 0.0, gap_face = 1e300, chip = 1e300;
  // Distances past `cap` leave the size at its largest.
  const double cap = max_ * opt_.gap_elements;
  const size_t cell = index(c[0], c[1], c[2]);
  auto visit = [&](int id, double lower) {
    // An image farther than d1 + d2 (or the cap) by its bounding sphere or capsule changes
    // nothing: the exact distance (a root search for ellipsoids) is skipped. An image beside
    // a thin chip or gap at a box face (chipped_) is skipped only when no chip of its can be
    // thinner than the one found.
    if (lower >= std::min(d1 + d2, cap) && !(chipped_[id] && kChipGrowth * lower < chip)) {
      return;
    }
    const Image& im = images_[id];
    const Vec3 x = p - im.shift;
    const Shape& s = set_.inclusions[im.inc].shape;
    // The core's surface and, for a coated inclusion, its shell's (the offset by the coating
    // thickness t: the shell gets gap_elements across it); for a debonded one, its void's
    // outer cap (the sphere of radius r + gap over the cap's cone: beyond the cone, the
    // distance to the cap's rim, in x's meridian plane).
    const Modifiers& m = set_.inclusions[im.inc].mod;
    const double dc = query_[im.inc].core_distance(x), t = outer_offset(m);
    auto take = [&](double d, double grown) {
      if (d < d1) {
        d2 = d1;
        d1 = d;
        rho1 = least_curvature_radius(s, x) + grown;  // only for the nearest surface
      } else if (d < d2) {
        d2 = d;
      }
    };
    take(std::abs(dc), 0.0);
    double outer = std::abs(dc - t);
    if (m.debonded()) {
      const Vec3 from_centre = x - s.center;
      const double rho = from_centre.norm(), cos_cap = m.debond_cos_cap();
      const double beyond =
          rho > 0.0 ? std::acos(std::clamp(from_centre.dot(m.debond_axis) / rho, -1.0, 1.0)) -
                          std::acos(std::clamp(cos_cap, -1.0, 1.0))
                    : 0.0;
      if (beyond > 0.0) {
        const double R = s.radius + t;
        outer = std::sqrt(std::max(0.0, rho * rho + R * R - 2.0 * rho * R * std::cos(beyond)));
      }
    }
    if (t > 0.0) take(outer, t);
    // The outer surface (a void's cap, or the core beyond it).
    const double d =
        m.debonded() ? std::min(outer, std::abs(dc)) : (t > 0.0 ? outer : std::abs(dc));
    // A thin layer of matrix between this image and a box face it does not cross.
    const Vec3 &lo = lo_[id], &hi = hi_[id];
    for (int a = 0; a < 3; ++a) {
      const double f0 = set_.box.origin[a], f1 = f0 + set_.box.size[a];
      // A fibre's thin chip on one side of a box face it crosses, or a thin gap between its
      // rim and a face. Both sides of the face are refined alike (the image inside the box
      // is the other side's image outside it), so the field stays periodic.
      for (const double f : {f0, f1}) {
        const double thin = std::min(std::abs(f - lo[a]), std::abs(hi[a] - f));
        if (thin < chip_limit_[im.inc][a]) {
          chip = std::min(chip, thin / std::max(2.0, opt_.gap_elements) +
                                    kChipGrowth * (d + std::abs(p[a] - f)));
        }
      }
      const double below = lo[a] - f0, above = f1 - hi[a];
      if (below > 0.0 && below < max_ * opt_.gap_elements && p[a] - f0 <= below + d) {
        gap_face = std::min(gap_face, d + p[a] - f0);
      }
      if (above > 0.0 && above < max_ * opt_.gap_elements && f1 - p[a] <= above + d) {
        gap_face = std::min(gap_face, d + f1 - p[a]);
      }
    }
  };
  // The two images nearest by their bounds first: their distances bound the rest, most of
  // which are then skipped (the result is the same in any order).
  thread_local std::vector<std::pair<double, int>> near;
  near.clear();
  int first = -1, second = -1;
  for (int k = start_[cell]; k < start_[cell + 1]; ++k) {
    const int id = list_[k];
    near.emplace_back(bound_[id].lower(p), id);
    const int at = static_cast<int>(near.size()) - 1;
    if (first < 0 || near[at].first < near[first].first) {
      second = first;
      first = at;
    } else if (second < 0 || near[at].first < near[second].first) {
      second = at;
    }
  }
  if (first >= 0) visit(near[first].second, near[first].first);
  if (second >= 0) visit(near[second].second, near[second].first);
  for (int k = 0; k < static_cast<int>(near.size()); ++k) {
    if (k != first && k != second) visit(near[k].second, near[k].first);
  }
  double h = std::min(std::min(d1 + d2, gap_face) / opt_.gap_elements, chip);
  // The chord bound at the nearest surface, growing by kGrowth with the distance from it.
  h = std::min(h, rho1 * std::sqrt(8.0 * opt_.chord_error) + kGrowth * d1);
  return std::clamp(h, min_, max_);
}

double least_size(const InclusionSet& set, const TetMeshSpec& spec) {
  if (spec.min_size > 0.0) return spec.min_size;
  double least = set.box.size.minCoeff();
  for (const Inclusion& inc : set.inclusions) least = std::min(least, inc.shape.min_size());
  return least / 50.0;
}

// The integral of 1 / h^3 over a cell of the box (lower corner lo, sides len), h the size field
// at the centre of each leaf of an octree refined while a leaf's longest side exceeds
// kEstimateLeaf times the size at its centre (and the least size). Each leaf's share is also
// added to `running` (in units of kEstimateUnit), and the recursion stops once that passes `stop`.
constexpr double kEstimateLeaf = 1.0;
// Elements per unit of that integral: 5.5 for two across the gaps (the default), 9 for one
// (3.5 + 4 / gap_elements, plus 1.5 (2 / gap_elements - 1) under two), from what Gmsh's HXT
// made (docs/benchmarks.md). With two, the count varies with the scene: the more near
// contacts, the more, as HXT's elements in thin gaps come smaller than the size asked there.
// With one, more, and more spread; the check guards memory, so one across takes the upper
// middle of that range. Half an element across (an element spans twice the gap) makes fewer
// than one across: 7.2 at 0.5, and between 0.5 and 1 the line to 9.
double tets_per_inverse_cube(const TetMeshSpec& spec) {
  const double g = spec.gap_elements;
  if (g < 1.0) return 9.0 - 3.6 * (1.0 - std::max(g, 0.5));
  return 3.5 + 4.0 / g + 1.5 * std::max(0.0, 2.0 / g - 1.0);
}
double inverse_cube_integral(const SizeField& size, const Vec3& lo, const Vec3& len, double least,
                             std::atomic<long long>* running, long long stop) {
  if (running->load(std::memory_order_relaxed) > stop) return 0.0;
  const double h = size(lo + 0.5 * len);
  const double side = len.maxCoeff();
  if (side <= kEstimateLeaf * h || side <= least) {
    const double share = len.prod() / (h * h * h);
    running->fetch_add(static_cast<long long>(std::min(1e15, 1e3 * share)) + 1,
                       std::memory_order_relaxed);
    return share;
  }
  double sum = 0.0;
  const Vec3 half = 0.5 * len;
  for (int k = 0; k < 8; ++k) {
    const Vec3 o =
        lo + Vec3((k & 1) ? half[0] : 0.0, (k & 2) ? half[1] : 0.0, (k & 4) ? half[2] : 0.0);
    sum += inverse_cube_integral(size, o, half, least, running, stop);
  }
  return sum;
}
}  // namespace mesh_parts

using namespace mesh_parts;

double tet_elements_estimate(const InclusionSet& set, const TetMeshSpec& spec, double cap) {
  TetMeshOptions options;
  static_cast<TetMeshSpec&>(options) = spec;
  const double largest = spec.largest_size(set.box), least = least_size(set, spec);
  const SizeField size(set, options, largest, least);
  int n[3];
  Vec3 len;
  for (int a = 0; a < 3; ++a) {
    n[a] = std::max(1, static_cast<int>(std::ceil(set.box.size[a] / largest)));
    len[a] = set.box.size[a] / n[a];
  }
  // The running total (all threads) only decides when to stop; below the cap the count is the
  // sum of the top cells' integrals in their order, the same on any number of threads.
  std::atomic<long long> running{0};
  const double per_unit = tets_per_inverse_cube(spec);
  const long long stop =
      static_cast<long long>(std::min(9e15, 1e3 * std::max(cap, 0.0) / per_unit));
  std::vector<double> part(static_cast<size_t>(n[0]) * n[1] * n[2], 0.0);
  parallel_for(size_t{0}, part.size(), [&](size_t c) {
    const size_t i = c % n[0], j = (c / n[0]) % n[1], k = c / (static_cast<size_t>(n[0]) * n[1]);
    const Vec3 lo = set.box.origin + Vec3(i * len[0], j * len[1], k * len[2]);
    part[c] = inverse_cube_integral(size, lo, len, least, &running, stop);
  });
  if (running.load() > stop) return std::max(cap, kEstimateUnit * per_unit * running.load());
  double sum = 0.0;
  for (double v : part) sum += v;
  return per_unit * sum;
}

TetMeshNeed tet_mesh_need(const InclusionSet& set, const TetMeshSpec& spec, double limit) {
  TetMeshNeed need;
  const double cap = limit > 0.0 ? limit / tet_mesh_bytes(1.0, 0.0, spec.order) : kTetEstimateCap;
  need.elements = tet_elements_estimate(set, spec, cap);
  need.capped = need.elements > cap;
  need.bytes =
      tet_mesh_bytes(need.elements, static_cast<double>(set.inclusions.size()), spec.order);
  return need;
}

bool coarser_tet_mesh_that_fits(const InclusionSet& set, const TetMeshSpec& spec, double limit,
                                const std::function<bool(const TetMeshNeed&)>& fits,
                                TetMeshSpec* fit, TetMeshNeed* need) {
  for (const TetMeshSpec& t : coarser_tet_meshes(spec)) {
    const TetMeshNeed n = tet_mesh_need(set, t, limit);
    if (n.capped || !fits(n)) continue;
    *fit = t;
    *need = n;
    return true;
  }
  return false;
}

}  // namespace rvegen
