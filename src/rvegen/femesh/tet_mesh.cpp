#include "rvegen/femesh/tet_mesh.hpp"

#include <gmsh.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <unordered_map>

#include "rvegen/femesh/offset_solid.hpp"
#include "rvegen/geometry/pair.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/errors.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/model/parallel.hpp"
#include "rvegen/model/resources.hpp"

namespace rvegen {

namespace {

// Gmsh holds one model per process: one mesh at a time.
std::mutex gmsh_mutex;

// Initialises Gmsh for one mesh and finalises it on every way out.
struct GmshSession {
  GmshSession() {
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::model::add("rve");
  }
  ~GmshSession() { gmsh::finalize(); }
};

std::string last_gmsh_error() {
  std::string e;
  gmsh::logger::getLastError(e);
  return e.empty() ? "no message" : e;
}

// An inclusion's periodic image: the inclusion and its shift.
struct Image {
  int inc;
  Vec3 shift;
};

// How far an inclusion's outer surface lies out from its core: its interphase shell's thickness,
// or its debonding void's gap (over the cap; a sphere can have one or the other).
double outer_offset(const Modifiers& m) {
  return m.coated() ? m.coating : (m.debonded() ? m.debond_gap : 0.0);
}

// An inclusion's bounding box, its interphase shell or debonding void included.
void outer_aabb(const Inclusion& inc, Vec3* lo, Vec3* hi) {
  inc.shape.aabb(lo, hi);
  *lo -= Vec3::Constant(outer_offset(inc.mod));
  *hi += Vec3::Constant(outer_offset(inc.mod));
}

// The images of the set's inclusions whose box, grown by `margin`, meets the box.
std::vector<Image> images_near(const InclusionSet& set, double margin) {
  const Vec3 o = set.box.origin, len = set.box.size;
  std::vector<Image> out;
  for (size_t m = 0; m < set.inclusions.size(); ++m) {
    Vec3 lo, hi;
    outer_aabb(set.inclusions[m], &lo, &hi);
    for (int ox = -1; ox <= 1; ++ox) {
      for (int oy = -1; oy <= 1; ++oy) {
        for (int oz = -1; oz <= 1; ++oz) {
          const Vec3 t(ox * len[0], oy * len[1], oz * len[2]);
          bool meets = true;
          for (int a = 0; a < 3; ++a) {
            meets = meets && hi[a] + t[a] + margin > o[a] && lo[a] + t[a] - margin < o[a] + len[a];
          }
          if (meets) out.push_back({static_cast<int>(m), t});
        }
      }
    }
  }
  return out;
}

// How fast elements grow away from a surface (size per distance). Before, the chord bound held
// at full strength out to the largest size and then jumped; grown by 0.2 instead, the test
// scene took 0.22 M elements instead of 0.54 M, its least dihedral angle rose from 8.5 to 12
// degrees, and CalculiX's conductivity on it moved from 0.2 % to 0.55 % above the FFT's at 32^3
// (0.5: 0.12 M, 1.5 %). A mixed scene (coated beads and rods, ellipsoids) fell under 5 degrees
// in 3 runs of 9 without it, in none of 5 with it.
constexpr double kGrowth = 0.2;

// A box face that cuts a fibre's end rim less than kThinChip radii from its extreme, or passes
// that close to it, leaves a chip of the fibre or a gap of matrix thinner than the elements at
// the surface: 2,484 fibres at chord error 0.1 kept two matrix elements of 4.1-4.7 degrees
// where a face cut a rim 0.075 radius deep (surface elements 5e-3 long over a chip 9e-4
// deep), and then one of 4.8-4.9 where a face passed 0.066 radius from a rim. The size field
// puts at least two elements across such chips and gaps, growing by kChipGrowth away from
// them (growing by 1, the 87 fibres about that chip, meshed alone, left an element of 4.3-4.6
// degrees where the sizes grew, in 1 run of 6; by 0.5, in none of 16). Only where the end
// disk and the mantle both meet the face at kChipWedge or more: a fibre 3.6 degrees off a
// face and cut 0.04 radius under its mantle meets the face at 3.6 degrees, and refined so,
// its elements followed that wedge (39-46 under 5 degrees, where the coarse ones cut across
// it left none).
constexpr double kThinChip = 0.25;
constexpr double kChipGrowth = 0.5;
constexpr double kChipWedge = 20.0 * M_PI / 180.0;

// The element size wanted at a point: the gap between the two nearest surfaces (two
// inclusions, or an inclusion and a box face it does not cross) over gap_elements, the chord
// bound at the nearest surface grown by kGrowth with the distance, the thin chips and gaps at
// fibres' rims (kThinChip), between min_size and max_size. A cell list of the images.
class SizeField {
 public:
  SizeField(const InclusionSet& set, const TetMeshOptions& opt, double max_size, double min_size)
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
    // every image whose box came within max_ held about 140 fibres of L/D 10 each, most of
    // them tested in full at every call.)
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

  double operator()(const Vec3& p) const {
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

 private:
  size_t index(int i, int j, int k) const { return (static_cast<size_t>(k) * n_ + j) * n_ + i; }
  const InclusionSet& set_;
  const TetMeshOptions& opt_;
  double max_, min_;
  std::vector<BodyQuery> query_;
  std::vector<double> reach_;     // each inclusion's bounding radius
  std::vector<Vec3> chip_limit_;  // per axis, the depth under which a chip is refined
  std::vector<Image> images_;
  std::vector<Vec3> lo_, hi_;  // each image's bounding box, shifted
  // A lower bound on the distance from a point to an image's outer surface: the larger of
  // the distances to its bounding sphere and, for a cylinder, to its capsule.
  struct Bound {
    Vec3 centre, half_axis;  // half_axis zero but for cylinders
    double sphere = 0.0, capsule = 0.0;
    double lower(const Vec3& p) const {
      const Vec3 d = p - centre;
      const double along =
          std::clamp(d.dot(half_axis) / std::max(half_axis.squaredNorm(), 1e-300), -1.0, 1.0);
      return std::max(d.norm() - sphere, (d - along * half_axis).norm() - capsule);
    }
  };
  std::vector<Bound> bound_;
  std::vector<bool> chipped_;  // an image with a thin chip or gap at a face (kThinChip)
  int n_ = 1;
  double cell_[3] = {1, 1, 1};
  std::vector<int> start_, list_;  // each cell's images: list_[start_[c] .. start_[c + 1])
};

// The least element size of a mesh of the set: the options', or a fiftieth of the least
// inclusion size.
double least_size(const InclusionSet& set, const TetMeshSpec& spec) {
  if (spec.min_size > 0.0) return spec.min_size;
  double least = set.box.size.minCoeff();
  for (const Inclusion& inc : set.inclusions) least = std::min(least, inc.shape.min_size());
  return least / 50.0;
}

// The integral of 1 / h^3 over a cell of the box (lower corner lo, sides len), h the size field
// at the centre of each leaf of an octree refined while a leaf's longest side exceeds
// kEstimateLeaf times the size at its centre (and the least size). Each leaf's share is also
// added to `running` (in units of 1e-3), and the recursion stops once that passes `stop`.
constexpr double kEstimateLeaf = 1.0;
// Elements per unit of that integral: 5.5 for two across the gaps (the default), 9 for one
// (3.5 + 4 / gap_elements, plus 1.5 (2 / gap_elements - 1) under two). With two, Gmsh's HXT made
// 4.5-6.3: 40 fibres of L/D 10, 4.5; spheres of radius 0.1 in a box of 0.6 from 0.15 to 0.64
// with min_gap 0 to 0.03, 4.9-6.3 (24 meshes: the more near contacts, the more, as HXT's
// elements in thin gaps come smaller than the size asked there). With one, more, and more
// spread: 6.4 for the default scene (10-node), 7.6 for 2,484 fibres of L/D 10 at chord error
// 0.1, 9.1 for spheres a twelfth of their radius apart (10-node), 12.2 for touching spheres
// (min_gap 0, radius 0.1 at 0.5 in a box of 0.6, 10-node); the check guards memory, so one
// across takes the upper middle of that range. Half an element across (an element spans twice
// the gap): 6.9 for 2,484 fibres and 7.1 for 311 (chord error 0.1, 10-node), where one across
// made 8.0 and 8.3 (2026-12-03); 7.2 at 0.5, and between 0.5 and 1 the line to 9.
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

// OpenCASCADE's spheres (and the ellipsoids made of them) have two poles and a seam, the
// meridian through +x of their frame (poles at +-z); its cylinders a seam along the mantle at
// +x, between two vertices on the rims. They are edges of the surfaces: a box face that passes near
// a pole, or runs along a seam, cuts a sliver between the two, and the elements there are slivers
// too (seen: a face 3e-5 of the size from an ellipsoid's pole; a face nearly along a fibre's seam).
// Each solid that crosses a box face is built in the frame, of a fixed set, that keeps them
// farthest from the faces: its score is the least, over the seam's points near each face, of the
// larger of the point's distance to the face (over the shape's extent across it) and the sine of
// the seam's angle to the face (0 at the poles and at a cylinder seam's ends).
//
// The seam of a shape in frame P: points x(t) of the unit shape's seam and their unit tangents,
// mapped by x -> c + M P x (M: the shape's own map; a cylinder's P turns about its axis).
struct Seam {
  std::vector<Vec3> at, tangent;
};
constexpr int kSeamPoints = 65;
Seam seam_of(const Shape& s, const Mat3& P) {
  Seam seam;
  if (s.kind == ShapeKind::Cylinder) {
    const Vec3 side = P.col(0), along = s.half_axis;  // P's first column: the seam's direction
    for (int k = 0; k < kSeamPoints; ++k) {
      const double t = -1.0 + 2.0 * k / (kSeamPoints - 1);
      seam.at.push_back(s.center + s.radius * side + t * along);
      // Its ends are vertices on the rims, scored by their distance alone (as poles are): a
      // seam that crosses a face steeply scores well wherever it lies, and one fibre's seam
      // ended 1.1e-5 from the face that cut its end disk (10 elements of 2.1-4.3 degrees
      // between that vertex and the face's cut, whatever the sizes).
      const bool end = k == 0 || k == kSeamPoints - 1;
      seam.tangent.push_back(end ? Vec3::Zero() : Vec3(along.normalized()));
    }
    return seam;
  }
  const Mat3 M = s.kind == ShapeKind::Sphere ? Mat3(s.radius * P)
                                             : Mat3(s.rotation * s.semi_axes.asDiagonal() * P);
  for (int k = 0; k < kSeamPoints; ++k) {
    const double phi = M_PI * k / (kSeamPoints - 1);
    seam.at.push_back(s.center + M * Vec3(std::sin(phi), 0.0, std::cos(phi)));
    const bool pole = k == 0 || k == kSeamPoints - 1;
    seam.tangent.push_back(pole ? Vec3::Zero()
                                : Vec3(M * Vec3(std::cos(phi), 0.0, -std::sin(phi))).normalized());
  }
  return seam;
}

// The frames tried: the identity, then rotations about axes spread over the sphere (a Fibonacci
// lattice) by angles spread by the golden ratio; for cylinders, turns about the axis.
constexpr int kFrames = 32;
Mat3 frame(const Shape& s, int k) {
  if (s.kind == ShapeKind::Cylinder) {
    const Vec3 u = s.half_axis.normalized(), w = any_orthogonal(u), v = u.cross(w);
    const double psi = 2.0 * M_PI * k / kFrames;
    Mat3 P;
    P.col(0) = std::cos(psi) * w + std::sin(psi) * v;
    P.col(1) = u.cross(P.col(0));
    P.col(2) = u;
    return P;
  }
  if (k == 0) return Mat3::Identity();
  const double golden = 0.5 * (std::sqrt(5.0) - 1.0);
  const double z = 1.0 - (2.0 * k + 1.0) / kFrames, r = std::sqrt(std::max(0.0, 1.0 - z * z));
  const double az = 2.0 * M_PI * golden * k;
  const Vec3 axis(r * std::cos(az), r * std::sin(az), z);
  return Eigen::AngleAxisd(2.0 * M_PI * std::fmod(golden * k * 7.0, 1.0), axis).toRotationMatrix();
}

// Per box face the shape crosses, the least over the seam's points of the larger of the two
// terms above; ascending. Frames compare by these in order (lexicographically): a face whose
// term is the same for every frame (one the seam crosses at a fixed angle, its tangent's term)
// then leaves the choice to the next face, not to the first frame.
std::vector<double> frame_score(const Shape& s, const Seam& seam, const Box& box) {
  Vec3 lo, hi;
  s.aabb(&lo, &hi);
  std::vector<double> score;
  for (int a = 0; a < 3; ++a) {
    const double L = box.size[a], half = 0.5 * (hi[a] - lo[a]);
    for (double f = box.origin[a] + L * std::ceil((lo[a] - box.origin[a]) / L); f < hi[a]; f += L) {
      double least = 1e300;
      for (size_t k = 0; k < seam.at.size(); ++k) {
        least = std::min(
            least, std::max(std::abs(seam.at[k][a] - f) / half, std::abs(seam.tangent[k][a])));
      }
      score.push_back(least);
    }
  }
  std::sort(score.begin(), score.end());
  return score;
}

// The solid swept by a profile (a plane surface in the half plane x >= 0 of y = 0) turned about
// z, its seam at +x; the profile and the points that only served its arcs as centres go.
int revolved_solid(int profile, std::initializer_list<int> centres) {
  namespace occ = gmsh::model::occ;
  gmsh::vectorpair out;
  occ::revolve({{2, profile}}, 0, 0, 0, 0, 0, 1, 2.0 * M_PI, out);
  int solid = -1;
  for (const auto& dt : out) {
    if (dt.first == 3) solid = dt.second;
  }
  occ::remove({{2, profile}}, true);
  gmsh::vectorpair points;
  for (const int c : centres) points.push_back({0, c});
  occ::remove(points);
  return solid;
}

// The frame of rank `rank` among kFrames by frame_score, best first (equal scores in the order
// of the frames; a shape that crosses no face scores alike in every frame).
int ranked_frame(const Shape& s, const Box& box, int rank) {
  std::vector<std::pair<std::vector<double>, int>> scored;
  const std::vector<double> first = frame_score(s, seam_of(s, frame(s, 0)), box);
  scored.emplace_back(first, 0);
  for (int k = 1; k < kFrames && (!first.empty() || rank > 0); ++k) {
    scored.emplace_back(frame_score(s, seam_of(s, frame(s, k)), box), k);
  }
  std::stable_sort(scored.begin(), scored.end(),
                   [](const auto& a, const auto& b) { return b.first < a.first; });
  return scored[static_cast<size_t>(rank) % scored.size()].second;
}

// The OCC solid of a shape grown by `offset` (every point within it of the shape: an
// interphase shell's outer surface), built in the frame that keeps its
// seam and poles off the faces of `box` it crosses (the shape's own, whatever the offset), or
// in the frame of rank `rank` by that measure; its tag.
int add_solid(const Shape& s, const Box& box, double offset = 0.0, const Mat3* given = nullptr,
              int rank = 0) {
  const Mat3 P = given ? *given : frame(s, ranked_frame(s, box, rank));
  const Vec3 c = s.center;
  auto turn = [&](int tag, const Mat3& R) {
    const Eigen::AngleAxisd aa(R);
    if (aa.angle() > 0.0) {
      gmsh::model::occ::rotate({{3, tag}}, 0, 0, 0, aa.axis()[0], aa.axis()[1], aa.axis()[2],
                               aa.angle());
    }
    gmsh::model::occ::translate({{3, tag}}, c[0], c[1], c[2]);
    return tag;
  };
  switch (s.kind) {
    case ShapeKind::Sphere:
      return turn(gmsh::model::occ::addSphere(0, 0, 0, s.radius + offset), P);
    case ShapeKind::Cylinder: {
      // Built along +z with its seam at +x, then turned so that z is the axis and x the seam's
      // side (P's columns).
      const double h = s.half_axis.norm(), r = s.radius;
      if (offset <= 0.0) return turn(gmsh::model::occ::addCylinder(0, 0, -h, 0, 0, 2.0 * h, r), P);
      // Grown: its profile in the half plane x >= 0 of y = 0 (end disks of radius r moved out
      // by the offset t, the mantle at r + t, quarter circles of radius t about the rims),
      // turned about z: its seam at +x too.
      const double t = offset;
      namespace occ = gmsh::model::occ;
      const int a0 = occ::addPoint(0, 0, -h - t), a1 = occ::addPoint(r, 0, -h - t),
                rim0 = occ::addPoint(r, 0, -h), a2 = occ::addPoint(r + t, 0, -h),
                a3 = occ::addPoint(r + t, 0, h), rim1 = occ::addPoint(r, 0, h),
                a4 = occ::addPoint(r, 0, h + t), a5 = occ::addPoint(0, 0, h + t);
      const int loop = occ::addCurveLoop({occ::addLine(a0, a1), occ::addCircleArc(a1, rim0, a2),
                                          occ::addLine(a2, a3), occ::addCircleArc(a3, rim1, a4),
                                          occ::addLine(a4, a5), occ::addLine(a5, a0)});
      return turn(revolved_solid(occ::addPlaneSurface({loop}), {rim0, rim1}), P);
    }
    case ShapeKind::Ellipsoid: {
      // A unit sphere mapped by x -> c + R diag(semi-axes) P x (a spline surface in
      // OpenCASCADE); grown, that surface's offset.
      const Mat3 M = s.rotation * s.semi_axes.asDiagonal() * P;
      if (offset > 0.0) return add_ellipsoid_offset(M, c, offset);
      const int tag = gmsh::model::occ::addSphere(0, 0, 0, 1);
      std::vector<double> a(12);
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) a[4 * i + j] = M(i, j);
        a[4 * i + 3] = c[i];
      }
      gmsh::model::occ::affineTransform({{3, tag}}, a);
      return tag;
    }
  }
  return -1;
}

// The OCC solid of a shape inside the box, made where it lies (its seam and poles meet no box
// face, whatever their frame; Gmsh's moves of a solid cost in proportion to the shapes it
// holds: 1,699 fibres turned and moved took 12 s after the cut); its tag. With `rank` above 0,
// built as add_solid builds it in that frame.
int add_inside_solid(const Shape& s, const Box& box, int rank) {
  if (rank > 0) return add_solid(s, box, 0.0, nullptr, rank);
  const Vec3& c = s.center;
  switch (s.kind) {
    case ShapeKind::Sphere:
      return gmsh::model::occ::addSphere(c[0], c[1], c[2], s.radius);
    case ShapeKind::Cylinder: {
      const Vec3 a = c - s.half_axis, d = 2.0 * s.half_axis;
      return gmsh::model::occ::addCylinder(a[0], a[1], a[2], d[0], d[1], d[2], s.radius);
    }
    case ShapeKind::Ellipsoid:
      break;
  }
  return add_solid(s, box);
}

// The frame of a debonded sphere's void and core: z along the debonding axis (the core's poles
// on it, so that its meridians, its seam among them, cross the cap's rim square: a seam
// grazing the rim left a sliver of surface along it, and elements under 2 degrees), and the
// seam turned about the axis off the faces of `box` it crosses.
Mat3 void_frame(const Inclusion& in, const Box& box) {
  const Shape& s = in.shape;
  const Modifiers& m = in.mod;
  const double r = s.radius, g = m.debond_gap, cos_cap = m.debond_cos_cap();
  const double theta = std::acos(std::clamp(cos_cap, -1.0, 1.0));
  const Vec3 u = m.debond_axis.normalized(), w = any_orthogonal(u), v = u.cross(w);
  Shape outer = s;
  outer.radius = r + g;
  Mat3 P = Mat3::Identity();
  double best = -1.0;
  for (int k = 0; k < kFrames && best < 1e300; ++k) {
    const double psi = 2.0 * M_PI * k / kFrames;
    Mat3 F;
    F.col(0) = std::cos(psi) * w + std::sin(psi) * v;
    F.col(1) = u.cross(F.col(0));
    F.col(2) = u;
    Seam seam;  // the core's meridian from pole to pole, and the void's to the cap's rim
    for (const double rho : {r, r + g}) {
      const double end = rho == r ? M_PI : theta;
      for (int j = 0; j < kSeamPoints; ++j) {
        const double phi = end * j / (kSeamPoints - 1);
        seam.at.push_back(s.center + rho * (std::sin(phi) * F.col(0) + std::cos(phi) * u));
        const bool pole = j == 0 || (rho == r && j == kSeamPoints - 1);
        seam.tangent.push_back(pole ? Vec3::Zero()
                                    : Vec3(std::cos(phi) * F.col(0) - std::sin(phi) * u));
      }
    }
    const std::vector<double> faces = frame_score(outer, seam, box);
    const double score = faces.empty() ? 1e300 : faces.front();
    if (score > best) {
      best = score;
      P = F;
    }
  }
  return P;
}

// The OCC solid of a debonded sphere's void: the points between the sphere (radius r) and the
// sphere of radius r + g over the cap of half-angle theta about the debonding axis (cos theta =
// 1 - 2 f), the profile in the half plane of its seam turned about the axis; when the cap is the
// whole sphere, the sphere of radius r + g (the fragment against the core leaves the shell).
// Built in void_frame.
int add_void_solid(const Inclusion& in, const Box& box) {
  const Shape& s = in.shape;
  const Modifiers& m = in.mod;
  const double r = s.radius, g = m.debond_gap, cos_cap = m.debond_cos_cap();
  if (cos_cap <= -1.0 + 1e-9) return add_solid(s, box, g);
  const double sin_cap = std::sqrt(std::max(0.0, 1.0 - cos_cap * cos_cap));
  const Mat3 P = void_frame(in, box);
  namespace occ = gmsh::model::occ;
  const int centre = occ::addPoint(0, 0, 0), pole_in = occ::addPoint(0, 0, r),
            pole_out = occ::addPoint(0, 0, r + g),
            rim_in = occ::addPoint(r * sin_cap, 0, r * cos_cap),
            rim_out = occ::addPoint((r + g) * sin_cap, 0, (r + g) * cos_cap);
  const int loop = occ::addCurveLoop(
      {occ::addCircleArc(pole_in, centre, rim_in), occ::addLine(rim_in, rim_out),
       occ::addCircleArc(rim_out, centre, pole_out), occ::addLine(pole_out, pole_in)});
  const int solid = revolved_solid(occ::addPlaneSurface({loop}), {centre});
  const Eigen::AngleAxisd aa(P);
  if (aa.angle() > 0.0) {
    occ::rotate({{3, solid}}, 0, 0, 0, aa.axis()[0], aa.axis()[1], aa.axis()[2], aa.angle());
  }
  occ::translate({{3, solid}}, s.center[0], s.center[1], s.center[2]);
  return solid;
}

// A face's key: its three node numbers in any order, mixed into 64 bits.
uint64_t face_key(int32_t a, int32_t b, int32_t c) {
  if (a > b) std::swap(a, b);
  if (b > c) std::swap(b, c);
  if (a > b) std::swap(a, b);
  auto mix = [](uint64_t x) {  // splitmix64's finaliser
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
  };
  return mix(mix(mix(static_cast<uint64_t>(a)) + static_cast<uint32_t>(b)) +
             static_cast<uint32_t>(c));
}

// Drops the nodes in no element; the others keep their order.
void drop_unused_nodes(TetMesh* mesh) {
  std::vector<int32_t> number(mesh->nodes.size(), -1);
  for (const auto& t : mesh->tets) {
    for (int32_t n : t) number[n] = 0;
  }
  int32_t kept = 0;
  for (size_t i = 0; i < number.size(); ++i) {
    if (number[i] < 0) continue;
    number[i] = kept;
    mesh->nodes[kept++] = mesh->nodes[i];
  }
  if (static_cast<size_t>(kept) == mesh->nodes.size()) return;
  mesh->nodes.resize(kept);
  for (auto& t : mesh->tets) {
    for (int32_t& n : t) n = number[n];
  }
}

// Each node on an upper box face (within `on` of it) and the node on the lower faces nearest
// its translate there, within `reach` (-1 when none), in the order of the nodes. The candidates
// are the nodes within `reach` of a lower face and on no upper one, on a grid of cells of
// `reach`.
std::vector<std::pair<int32_t, int32_t>> lower_images(const TetMesh& mesh, double on,
                                                      double reach) {
  const Box& box = mesh.box;
  struct KeyHash {
    size_t operator()(const std::array<long long, 3>& k) const {
      return std::hash<long long>()(k[0] * 73856093LL ^ k[1] * 19349663LL ^ k[2] * 83492791LL);
    }
  };
  // The cell of x, or its neighbour d (0 to 26, 13 itself).
  auto cell = [&](const Vec3& x, int d) {
    const int step[3] = {d % 3 - 1, d / 3 % 3 - 1, d / 9 - 1};
    std::array<long long, 3> k;
    for (int a = 0; a < 3; ++a) {
      k[a] = static_cast<long long>(std::floor((x[a] - box.origin[a]) / reach)) + step[a];
    }
    return k;
  };
  auto upper = [&](const Vec3& x, int a) {
    return std::abs(x[a] - box.origin[a] - box.size[a]) <= on;
  };
  std::unordered_map<std::array<long long, 3>, std::vector<int32_t>, KeyHash> grid;
  std::vector<std::pair<int32_t, int32_t>> out;
  for (size_t i = 0; i < mesh.nodes.size(); ++i) {
    const Vec3& x = mesh.nodes[i];
    bool up = false, low = false;
    for (int a = 0; a < 3; ++a) {
      up = up || upper(x, a);
      low = low || std::abs(x[a] - box.origin[a]) <= reach;
    }
    if (up) {
      out.push_back({static_cast<int32_t>(i), -1});
    } else if (low) {
      grid[cell(x, 13)].push_back(static_cast<int32_t>(i));
    }
  }
  for (auto& [i, master] : out) {
    Vec3 x = mesh.nodes[i];
    for (int a = 0; a < 3; ++a) {
      if (upper(mesh.nodes[i], a)) x[a] -= box.size[a];
    }
    double best = reach;
    for (int d = 0; d < 27; ++d) {
      const auto it = grid.find(cell(x, d));
      if (it == grid.end()) continue;
      for (const int32_t m : it->second) {
        const double dist = (mesh.nodes[m] - x).norm();
        if (dist <= best) {
          best = dist;
          master = m;
        }
      }
    }
  }
  return out;
}

}  // namespace

long long snap_periodic_nodes(TetMesh* mesh) {
  const double side = mesh->box.size.minCoeff(), on = 1e-9 * side;
  long long moved = 0;
  for (const auto& [i, master] : lower_images(*mesh, on, 1e-6 * side)) {
    if (master < 0) continue;
    // The master's position, moved along the axes whose upper face i lies on.
    Vec3 exact = mesh->nodes[master];
    for (int a = 0; a < 3; ++a) {
      if (std::abs(mesh->nodes[i][a] - mesh->box.origin[a] - mesh->box.size[a]) <= on)
        exact[a] += mesh->box.size[a];
    }
    if ((exact - mesh->nodes[i]).norm() > on) ++moved;
    mesh->nodes[i] = exact;
  }
  return moved;
}

// The volume mesher rarely leaves two nodes at one position, each used by elements on its own
// side (a crack in the mesh: seen in 3 runs in 10 of the test scene). Such nodes are merged
// (the lowest number kept); nodes no element uses are dropped and the rest renumbered in order.
long long merge_coincident_nodes(TetMesh* mesh) {
  std::vector<int32_t> order(mesh->nodes.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int32_t>(i);
  auto less = [&](int32_t a, int32_t b) {
    const Vec3 &p = mesh->nodes[a], &q = mesh->nodes[b];
    if (p[0] != q[0]) return p[0] < q[0];
    if (p[1] != q[1]) return p[1] < q[1];
    if (p[2] != q[2]) return p[2] < q[2];
    return a < b;
  };
  std::sort(order.begin(), order.end(), less);
  std::vector<int32_t> same(mesh->nodes.size());
  long long merged = 0;
  for (size_t k = 0; k < order.size(); ++k) {
    const bool repeat = k > 0 && mesh->nodes[order[k]] == mesh->nodes[order[k - 1]];
    same[order[k]] = repeat ? same[order[k - 1]] : order[k];
    merged += repeat;
  }
  for (auto& t : mesh->tets) {
    for (int32_t& n : t) n = same[n];
  }
  drop_unused_nodes(mesh);
  for (const auto& t : mesh->tets) {
    for (int c = 0; c < 4; ++c) {
      for (int d = c + 1; d < 4; ++d) {
        if (t[c] == t[d]) throw MeshError("mesh_tet: an element with two nodes at one position");
      }
    }
  }
  return merged;
}

// A conforming mesh of the box: every face of an element is the face of one other element, or
// lies in a box face. Checked without storing the faces: interior faces come in pairs, so the
// XOR of the keys of all elements' faces equals the XOR of those of the faces in box faces;
// a face left alone (a crack, a hole) breaks the equality (but for a 2^-64 chance).
void check_conforming(const TetMesh& mesh) {
  // Per node, bits of the box faces it lies on.
  const std::vector<std::array<int8_t, 3>> ends = node_ends(mesh);
  std::vector<uint8_t> plane(ends.size(), 0);
  for (size_t n = 0; n < ends.size(); ++n) {
    for (int a = 0; a < 3; ++a) {
      if (ends[n][a] >= 0) plane[n] |= static_cast<uint8_t>(1 << (2 * a + ends[n][a]));
    }
  }
  uint64_t all = 0, outer = 0;
  for (const auto& t : mesh.tets) {
    for (int skip = 0; skip < 4; ++skip) {
      int32_t f[3], n = 0;
      for (int c = 0; c < 4; ++c) {
        if (c != skip) f[n++] = t[c];
      }
      const uint64_t k = face_key(f[0], f[1], f[2]);
      all ^= k;
      if (plane[f[0]] & plane[f[1]] & plane[f[2]]) outer ^= k;
    }
  }
  if (all != outer) {
    throw MeshError(
        "mesh_tet: the mesh is not conforming (an element face is shared by no other "
        "element and lies in no box face)");
  }
  // And the elements fill the box: their volumes (each positive) add up to it.
  double total = 0.0, least = 1e300;
  for (const auto& t : mesh.tets) {
    const double v = tet_volume(mesh.nodes, t);
    total += v;
    least = std::min(least, v);
  }
  if (!(least > 0.0) || std::abs(total / mesh.box.volume() - 1.0) > 1e-9) {
    throw MeshError("mesh_tet: the elements do not fill the box (their volume " +
                    std::to_string(total) + ", the box " + std::to_string(mesh.box.volume()) +
                    ", least element " + std::to_string(mesh.tets.empty() ? 0.0 : least) + ")");
  }
}

// The edges as sorted keys (lower node in the high half), sorted and made unique: an edge's
// midside node is the corners' count plus its rank among them. No hash table: 8 bytes an edge
// for the elements' six, then the edges alone.
void add_midside_nodes(TetMesh* mesh) {
  if (!mesh->mid.empty()) return;
  // Each edge (a, b), a < b, listed under a: its rank among the edges in (a, b) order is the
  // number of edges listed under the nodes before a, plus its place in a's sorted list. (A
  // sort of all six edges of every element and a binary search of each took twice as long.)
  const size_t nn = mesh->nodes.size(), ne = mesh->tets.size();
  std::vector<int64_t> start(nn + 1, 0);
  for (const auto& t : mesh->tets) {
    for (const auto& e : kTetEdges) ++start[std::min(t[e[0]], t[e[1]]) + 1];
  }
  for (size_t a = 0; a < nn; ++a) start[a + 1] += start[a];
  std::vector<int32_t> list(static_cast<size_t>(start[nn]));
  {
    std::vector<int64_t> fill(start.begin(), start.end() - 1);
    for (const auto& t : mesh->tets) {
      for (const auto& e : kTetEdges) {
        const int32_t a = std::min(t[e[0]], t[e[1]]), b = std::max(t[e[0]], t[e[1]]);
        list[fill[a]++] = b;
      }
    }
  }
  std::vector<int32_t> count(nn);
  parallel_for(size_t{0}, nn, [&](size_t a) {
    const auto first = list.begin() + start[a], last = list.begin() + start[a + 1];
    std::sort(first, last);
    count[a] = static_cast<int32_t>(std::unique(first, last) - first);
  });
  std::vector<int64_t> rank(nn + 1, 0);  // the edges listed under the nodes before a
  for (size_t a = 0; a < nn; ++a) rank[a + 1] = rank[a] + count[a];
  const size_t corners = nn, edges = static_cast<size_t>(rank[nn]);
  if (corners + edges > static_cast<size_t>(std::numeric_limits<int32_t>::max())) {
    throw MeshError("mesh_tet: too many nodes for second order (" +
                    std::to_string(corners + edges) + ")");
  }
  mesh->nodes.resize(corners + edges);
  parallel_for(size_t{0}, nn, [&](size_t a) {
    for (int32_t k = 0; k < count[a]; ++k) {
      const int32_t b = list[start[a] + k];
      mesh->nodes[corners + rank[a] + k] = 0.5 * (mesh->nodes[a] + mesh->nodes[b]);
    }
  });
  mesh->mid.resize(ne);
  parallel_for(size_t{0}, ne, [&](size_t e) {
    const auto& t = mesh->tets[e];
    for (int k = 0; k < 6; ++k) {
      const int32_t a = std::min(t[kTetEdges[k][0]], t[kTetEdges[k][1]]);
      const int32_t b = std::max(t[kTetEdges[k][0]], t[kTetEdges[k][1]]);
      const auto first = list.begin() + start[a], last = first + count[a];
      mesh->mid[e][k] =
          static_cast<int32_t>(corners + rank[a] + (std::lower_bound(first, last, b) - first));
    }
  });
}

namespace {

// The least dihedral angle of a tetrahedron, in degrees: at each edge, the angle between the
// other two vertices seen across it.
double least_dihedral(const Vec3 (&p)[4]) {
  // The least angle has the largest cosine: one arc cosine, of that (acos is monotonic, so the
  // angle is the same to the last bit as the least of the six).
  double m = -1.0;
  for (int i = 0; i < 4; ++i) {
    for (int j = i + 1; j < 4; ++j) {
      int other[2], n = 0;
      for (int k = 0; k < 4; ++k) {
        if (k != i && k != j) other[n++] = k;
      }
      const Vec3 axis = (p[j] - p[i]).normalized();
      Vec3 u = p[other[0]] - p[i], w = p[other[1]] - p[i];
      u -= u.dot(axis) * axis;
      w -= w.dot(axis) * axis;
      m = std::max(m, std::clamp(u.normalized().dot(w.normalized()), -1.0, 1.0));
    }
  }
  return std::acos(m) * 180.0 / M_PI;
}

double least_dihedral(const TetMesh& mesh, const std::array<int32_t, 4>& t) {
  const Vec3 p[4] = {mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]], mesh.nodes[t[3]]};
  return least_dihedral(p);
}

// The signed distance of x from the surface of shape s grown by t (negative inside), and the
// outward normal there: exact for spheres and for cylinders (flat ends; grown, their rims are
// rounded) and for grown ellipsoids outside the ellipsoid (the distance from its nearest point,
// less t), to first order for ellipsoids ((f - 1) / |grad f| with f the ellipsoidal radius;
// its error near the surface is of the order of the squared distance over the radius of
// curvature). `feature`: x lies on a flat end's plane of an ungrown cylinder (its rim and end
// disk), where the normal has no single direction.
double surface_distance(const Shape& s, double t, const Vec3& x, Vec3* normal, bool* feature) {
  const Vec3 d = x - s.center;
  *feature = false;
  switch (s.kind) {
    case ShapeKind::Sphere: {
      const double n = d.norm();
      *normal = n > 0.0 ? Vec3(d / n) : Vec3::UnitZ();
      return n - s.radius - t;
    }
    case ShapeKind::Cylinder: {
      const double h = s.half_axis.norm();
      const Vec3 u = s.half_axis / h;
      const double a = d.dot(u);
      const Vec3 radial = d - a * u;
      const double rho = radial.norm();
      const Vec3 er = rho > 0.0 ? Vec3(radial / rho) : any_orthogonal(u);
      const Vec3 eu = a >= 0.0 ? u : Vec3(-u);
      const double dr = rho - s.radius, dz = std::abs(a) - h;
      *feature = t == 0.0 && std::abs(dz) <= 1e-6 * std::max(h, s.radius);
      if (dr > 0.0 && dz > 0.0) {
        const double n = std::hypot(dr, dz);
        *normal = (dr * er + dz * eu) / n;
        return n - t;
      }
      *normal = dr >= dz ? er : eu;
      return std::max(dr, dz) - t;
    }
    case ShapeKind::Ellipsoid: {
      if (t > 0.0) {
        // A shell's outer surface lies t out from the ellipsoid: exact there, where the first
        // order would err by t^2 over the radius of curvature (a third of t for a shell a third
        // as thick as that radius).
        Vec3 z;
        const double out = ellipsoid_distance(s, x, &z);
        if (out > 0.0) {
          *normal = (x - z) / out;
          return out - t;
        }
      }
      const Vec3 y = s.rotation.transpose() * d;
      const Vec3 q = y.cwiseQuotient(s.semi_axes);
      const double f = q.norm();
      const Vec3 g = s.rotation * (q.cwiseQuotient(s.semi_axes) / std::max(f, 1e-300));
      const double gn = g.norm();
      *normal = gn > 0.0 ? Vec3(g / gn) : Vec3::UnitZ();
      return (gn > 0.0 ? (f - 1.0) / gn : -s.semi_axes.minCoeff()) - t;
    }
  }
  return 0.0;
}

}  // namespace

namespace {

// An element's region: its inclusion (the matrix's -1 too) and its phase, as one number.
uint64_t region_of(const TetMesh& mesh, size_t e) {
  return (static_cast<uint64_t>(static_cast<uint32_t>(mesh.inclusion_id[e])) << 32) |
         static_cast<uint32_t>(mesh.phase[e]);
}

// The index in set.inclusions of each inclusion id.
std::unordered_map<int32_t, int> index_by_id(const InclusionSet& set) {
  std::unordered_map<int32_t, int> by_id;
  for (size_t k = 0; k < set.inclusions.size(); ++k) {
    by_id[set.inclusions[k].id] = static_cast<int>(k);
  }
  return by_id;
}

// The surface between elements of inclusions id1 and id2 (-1: the matrix) of phase kinds k1 and
// k2: 2 k for inclusion k's core (against the matrix, or its own shell or void), 2 k + 1 for its
// shell's or void's outer surface (against the matrix: a void's cone among it, on_void_cone);
// -1 for anything else (two inclusions, an unknown id).
int interface_surface(const std::unordered_map<int32_t, int>& by_id, int id1, PhaseKind k1, int id2,
                      PhaseKind k2) {
  auto inc = [&](int id) {
    const auto it = by_id.find(id);
    return it == by_id.end() ? -1 : it->second;
  };
  if (id1 == id2) return inc(id1) >= 0 ? 2 * inc(id1) : -1;
  if (k1 != PhaseKind::kMatrix && k2 != PhaseKind::kMatrix) return -1;
  const int id = k1 == PhaseKind::kMatrix ? id2 : id1;
  const PhaseKind kind = k1 == PhaseKind::kMatrix ? k2 : k1;
  if (inc(id) < 0) return -1;
  if (kind == PhaseKind::kCore) return 2 * inc(id);
  if (kind == PhaseKind::kInterphase || kind == PhaseKind::kVoid) return 2 * inc(id) + 1;
  return -1;
}

// The translation (by -1, 0 or 1 box sizes per axis) of the periodic image of the surface of
// `shape` grown by `grown` nearest x, with x's signed distance from it and whether x lies on a
// flat end there (surface_distance).
Vec3 nearest_image(const Shape& shape, double grown, const Vec3& size, const Vec3& x,
                   double* distance, bool* feature) {
  Vec3 best = Vec3::Zero();
  double least = 1e300;
  for (int dx = -1; dx <= 1; ++dx) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dz = -1; dz <= 1; ++dz) {
        const Vec3 t = Vec3(dx, dy, dz).cwiseProduct(size);
        Vec3 nrm;
        bool f;
        const double d = surface_distance(shape.translated(t), grown, x, &nrm, &f);
        if (std::abs(d) < least) {
          least = std::abs(d);
          best = t;
          *distance = d;
          *feature = f;
        }
      }
    }
  }
  return best;
}

// Whether a triangle of a debonded sphere's void against the matrix lies on the void's cone (the
// side where the cap ends) rather than on its outer sphere: the cone holds the rays from the
// centre, so its triangles' normals are across the ray through them (a sphere's, along it).
bool on_void_cone(const Inclusion& in, const Vec3& shift, const Vec3& p0, const Vec3& p1,
                  const Vec3& p2) {
  if (!in.mod.debonded()) return false;
  const Vec3 n = (p1 - p0).cross(p2 - p0), ray = (p0 + p1 + p2) / 3.0 - in.shape.center - shift;
  return std::abs(n.dot(ray)) < 0.5 * n.norm() * ray.norm();
}

// Whether x lies on a debonded sphere's void cone (its angle from the axis the cap's, to 1e-7).
bool on_void_cone(const Inclusion& in, const Vec3& shift, const Vec3& x) {
  if (!in.mod.debonded()) return false;
  const Vec3 d = x - in.shape.center - shift;
  const double rho = d.norm();
  return rho > 0.0 && std::abs(d.dot(in.mod.debond_axis) / rho - in.mod.debond_cos_cap()) < 1e-7;
}

}  // namespace

// Each interface of the mesh (a face between the matrix and an inclusion's core or shell, or
// between a core and its shell) belongs to one exact surface. Its triangles are chords of that
// surface, and cut off the gap between them and it: for a triangle, its area times the mean gap,
// which the mean of the gaps at its edge midpoints gives exactly for a surface of constant
// curvature (the gap is then quadratic over the triangle and nought at its corners). Each node
// inside a curved surface (not on a box face, on another surface or on a flat end's plane) moves
// along the surface's normal by the area-weighted mean gap of its triangles: a move d of a node
// adds d times a third of its triangles' area to the volume inside, so the moves give back what
// the chords cut off, to second order. A move is undone where it would invert an element, or
// leave one with a least dihedral angle under 5 degrees that had a larger one before.
long long keep_phase_volumes(TetMesh* mesh, const InclusionSet& set) {
  const size_t nn = mesh->nodes.size(), ne = mesh->tets.size();
  const std::unordered_map<int32_t, int> by_id = index_by_id(set);
  auto region = [&](size_t e) { return region_of(*mesh, e); };
  // Nodes that elements of two regions share; faces with three such nodes are the candidates.
  constexpr uint64_t kNone = std::numeric_limits<uint64_t>::max();  // no phase label is -1
  std::vector<uint64_t> first(nn, kNone);
  std::vector<uint8_t> shared(nn, 0);
  for (size_t e = 0; e < ne; ++e) {
    const uint64_t r = region(e);
    for (int32_t n : mesh->tets[e]) {
      if (first[n] == kNone) {
        first[n] = r;
      } else if (first[n] != r) {
        shared[n] = 1;
      }
    }
  }
  struct Face {
    std::array<int32_t, 3> n;
    int32_t tet;
  };
  std::vector<Face> faces;
  for (size_t e = 0; e < ne; ++e) {
    const auto& t = mesh->tets[e];
    for (int skip = 0; skip < 4; ++skip) {
      Face f;
      int k = 0;
      for (int c = 0; c < 4; ++c) {
        if (c != skip) f.n[k++] = t[c];
      }
      if (!(shared[f.n[0]] && shared[f.n[1]] && shared[f.n[2]])) continue;
      std::sort(f.n.begin(), f.n.end());
      f.tet = static_cast<int32_t>(e);
      faces.push_back(f);
    }
  }
  parallel_sort(faces.begin(), faces.end(), [](const Face& a, const Face& b) {
    return a.n != b.n ? a.n < b.n : a.tet < b.tet;
  });
  // Per node: its surface (2 k for inclusion k's core, 2 k + 1 for its shell's outer surface;
  // -1 none yet, -2 on two surfaces or on an interface of no single surface), the image shift of
  // the inclusion, and its triangles' area and area times gap.
  std::vector<int> surface(nn, -1);
  std::vector<Vec3> shift(nn, Vec3::Zero());
  std::vector<double> area(nn, 0.0), gap(nn, 0.0);
  std::vector<double> deficit(2 * set.inclusions.size(), 0.0);  // per surface
  const Box& box = mesh->box;
  // The interface triangles (faces that elements of two regions share), and for each, on both
  // cores, its surface (-1: of no single surface, or straight along a void's cone), the image it
  // lies on, its area and its mean gap; then their sums per node and surface, in order.
  struct Triangle {
    size_t face;
    int which = -1;
    Vec3 shift = Vec3::Zero();
    double area = 0.0, gap = 0.0;
  };
  std::vector<Triangle> triangles;
  for (size_t k = 0; k + 1 < faces.size(); ++k) {
    if (faces[k].n != faces[k + 1].n) continue;
    const size_t e1 = faces[k].tet, e2 = faces[k + 1].tet;
    ++k;
    if (region(e1) == region(e2)) continue;
    // Which surface: a core against the matrix or its own shell; a shell against the matrix.
    Triangle t;
    t.face = k;
    t.which = interface_surface(by_id, mesh->inclusion_id[e1], mesh->phases[mesh->phase[e1]].kind,
                                mesh->inclusion_id[e2], mesh->phases[mesh->phase[e2]].kind);
    triangles.push_back(t);
  }
  parallel_for(size_t{0}, triangles.size(), [&](size_t j) {
    Triangle& t = triangles[j];
    if (t.which < 0) return;
    const std::array<int32_t, 3>& n = faces[t.face].n;
    const Inclusion& in = set.inclusions[t.which / 2];
    const double grown = (t.which & 1) ? outer_offset(in.mod) : 0.0;
    const Vec3 &p0 = mesh->nodes[n[0]], &p1 = mesh->nodes[n[1]], &p2 = mesh->nodes[n[2]];
    // The inclusion's periodic image the triangle lies on: the one nearest its centre's surface.
    Vec3 nrm;
    bool feature;
    double centre_gap;
    t.shift = nearest_image(in.shape, grown, box.size, (p0 + p1 + p2) / 3.0, &centre_gap, &feature);
    if ((t.which & 1) && on_void_cone(in, t.shift, p0, p1, p2)) {  // straight along the rays
      t.which = -1;
      return;
    }
    const Shape s = in.shape.translated(t.shift);
    t.area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    t.gap = -(surface_distance(s, grown, 0.5 * (p0 + p1), &nrm, &feature) +
              surface_distance(s, grown, 0.5 * (p1 + p2), &nrm, &feature) +
              surface_distance(s, grown, 0.5 * (p0 + p2), &nrm, &feature)) /
            3.0;
  });
  for (const Triangle& t : triangles) {
    const std::array<int32_t, 3>& n = faces[t.face].n;
    const int which = t.which;
    if (which < 0) {
      for (int32_t i : n) surface[i] = -2;
      continue;
    }
    const Vec3& best = t.shift;
    const double a = t.area, g = t.gap;
    deficit[which] += a * g;
    for (int32_t i : n) {
      if (surface[i] == -2) continue;
      if (surface[i] >= 0 && (surface[i] != which || shift[i] != best)) {
        surface[i] = -2;
        continue;
      }
      surface[i] = which;
      shift[i] = best;
      area[i] += a;
      gap[i] += a * g;
    }
  }
  // The moves. Nodes that stay (on box faces, rims) leave their triangles' share of the gap;
  // the other nodes of the surface make it up, each in proportion (at most twice their own).
  const std::vector<std::array<int8_t, 3>> ends = node_ends(*mesh);
  const std::vector<Vec3> before = mesh->nodes;
  std::vector<uint8_t> movable(nn, 0);
  std::vector<Vec3> normal(nn, Vec3::Zero());
  std::vector<double> given(deficit.size(), 0.0);
  parallel_for(size_t{0}, nn, [&](size_t i) {
    if (surface[i] < 0 || !(area[i] > 0.0) || !std::isfinite(gap[i])) return;
    if (ends[i][0] >= 0 || ends[i][1] >= 0 || ends[i][2] >= 0) return;
    const Inclusion& in = set.inclusions[surface[i] / 2];
    const double grown = (surface[i] & 1) ? outer_offset(in.mod) : 0.0;
    bool feature;
    surface_distance(in.shape.translated(shift[i]), grown, before[i], &normal[i], &feature);
    if (feature || gap[i] == 0.0) return;
    movable[i] = 1;
  });
  for (size_t i = 0; i < nn; ++i) {
    if (movable[i]) given[surface[i]] += gap[i] / 3.0;
  }
  std::vector<uint8_t> moved(nn, 0);
  long long count = 0;
  for (size_t i = 0; i < nn; ++i) {
    if (!movable[i]) continue;
    const double whole = deficit[surface[i]], part = given[surface[i]];
    const double scale = part != 0.0 && whole / part > 1.0 ? std::min(2.0, whole / part) : 1.0;
    mesh->nodes[i] = before[i] + scale * gap[i] / area[i] * normal[i];
    moved[i] = 1;
    ++count;
  }
  // Undone where an element would suffer (a few passes: undoing one move changes its other
  // elements back too, never for the worse). Each pass tells the elements apart on all cores,
  // then walks them in order, as one thread would: an element with a node undone earlier in
  // the walk is looked at again there.
  auto suffers = [&](const std::array<int32_t, 4>& t) {
    if (!(tet_volume(mesh->nodes, t) > 0.0)) return true;
    const double now = least_dihedral(*mesh, t);
    if (now >= 5.0) return false;
    const Vec3 p[4] = {before[t[0]], before[t[1]], before[t[2]], before[t[3]]};
    return now < least_dihedral(p);
  };
  auto any_moved = [&](const std::array<int32_t, 4>& t) {
    return moved[t[0]] || moved[t[1]] || moved[t[2]] || moved[t[3]];
  };
  std::vector<uint8_t> suffered(ne, 0), undone(nn, 0);
  std::vector<int32_t> undone_list;
  for (bool again = true; again;) {
    again = false;
    parallel_for(size_t{0}, ne, [&](size_t e) {
      const auto& t = mesh->tets[e];
      suffered[e] = any_moved(t) && suffers(t);
    });
    for (size_t e = 0; e < ne; ++e) {
      const auto& t = mesh->tets[e];
      if (!any_moved(t)) continue;
      const bool seen_change = undone[t[0]] || undone[t[1]] || undone[t[2]] || undone[t[3]];
      if (!(seen_change ? suffers(t) : suffered[e])) continue;
      for (int32_t n : t) {
        if (!moved[n]) continue;
        mesh->nodes[n] = before[n];
        moved[n] = 0;
        undone[n] = 1;
        undone_list.push_back(n);
        --count;
        again = true;
      }
    }
    for (int32_t n : undone_list) undone[n] = 0;
    undone_list.clear();
  }
  return count;
}

namespace {

// Drops the elements marked in `gone` (the first gone.size() elements; those after it stay),
// keeping the order of the rest.
void drop_elements(TetMesh* mesh, const std::vector<uint8_t>& gone) {
  size_t w = 0;
  for (size_t e = 0; e < mesh->tets.size(); ++e) {
    if (e < gone.size() && gone[e]) continue;
    mesh->tets[w] = mesh->tets[e];
    mesh->phase[w] = mesh->phase[e];
    mesh->inclusion_id[w] = mesh->inclusion_id[e];
    ++w;
  }
  mesh->tets.resize(w);
  mesh->phase.resize(w);
  mesh->inclusion_id.resize(w);
}

// For each node on a box face of axis a (ends: node_ends), the node on the opposite face of that
// axis with the same other coordinates (within 1e-9 of the box's smallest side, the rounding of
// the key taken into account); -1 for the others.
std::vector<int32_t> images_across(const TetMesh& mesh,
                                   const std::vector<std::array<int8_t, 3>>& ends, int a) {
  const double tol = 1e-9 * mesh.box.size.minCoeff();
  auto key = [&](size_t n, int end) {
    const Vec3& x = mesh.nodes[n];
    return std::array<long long, 3>{end, std::llround(x[(a + 1) % 3] / tol),
                                    std::llround(x[(a + 2) % 3] / tol)};
  };
  std::map<std::array<long long, 3>, int32_t> at;
  for (size_t n = 0; n < mesh.nodes.size(); ++n) {
    if (ends[n][a] >= 0) at[key(n, ends[n][a])] = static_cast<int32_t>(n);
  }
  std::vector<int32_t> image(mesh.nodes.size(), -1);
  for (size_t n = 0; n < mesh.nodes.size(); ++n) {
    if (ends[n][a] < 0) continue;
    const std::array<long long, 3> k = key(n, 1 - ends[n][a]);
    for (int d1 = -1; d1 <= 1 && image[n] < 0; ++d1) {
      for (int d2 = -1; d2 <= 1 && image[n] < 0; ++d2) {
        const auto it = at.find({k[0], k[1] + d1, k[2] + d2});
        if (it != at.end()) image[n] = it->second;
      }
    }
  }
  return image;
}

}  // namespace

long long remove_flat_face_elements(TetMesh* mesh) {
  const size_t nn = mesh->nodes.size(), ne = mesh->tets.size();
  const std::vector<std::array<int8_t, 3>> ends = node_ends(*mesh);
  // The box face (axis, end) all four nodes of e lie on, or -1.
  auto flat_face = [&](size_t e) {
    const auto& t = mesh->tets[e];
    for (int a = 0; a < 3; ++a) {
      const int8_t end = ends[t[0]][a];
      if (end < 0) continue;
      if (ends[t[1]][a] == end && ends[t[2]][a] == end && ends[t[3]][a] == end) return 2 * a + end;
    }
    return -1;
  };
  std::vector<size_t> flat;
  for (size_t e = 0; e < ne; ++e) {
    if (flat_face(e) >= 0) flat.push_back(e);
  }
  if (flat.empty()) return 0;
  // The elements around each node.
  std::vector<std::vector<int32_t>> around(nn);
  for (size_t e = 0; e < ne; ++e) {
    for (int32_t n : mesh->tets[e]) around[n].push_back(static_cast<int32_t>(e));
  }
  auto has = [](const std::array<int32_t, 4>& t, int32_t n) {
    return std::find(t.begin(), t.end(), n) != t.end();
  };
  // The elements other than `skip` with nodes a, b and c.
  auto with_face = [&](int32_t a, int32_t b, int32_t c, int32_t skip) {
    std::vector<int32_t> out;
    for (int32_t f : around[a]) {
      if (f != skip && has(mesh->tets[f], b) && has(mesh->tets[f], c)) out.push_back(f);
    }
    return out;
  };
  // Each face node's image on the opposite face, per axis.
  std::array<std::vector<int32_t>, 3> images;
  for (int a = 0; a < 3; ++a) images[a] = images_across(*mesh, ends, a);
  auto image_of = [&](int32_t n, int a) { return images[a][n]; };
  std::vector<uint8_t> gone(ne, 0);
  long long removed = 0;
  for (size_t e : flat) {
    if (gone[e]) continue;
    const auto t = mesh->tets[e];
    const int a = flat_face(e) / 2;
    // Its faces on the box face: those no other element shares.
    std::vector<std::array<int32_t, 3>> outer, inner;
    for (int k = 0; k < 4; ++k) {
      const std::array<int32_t, 3> f = {t[(k + 1) % 4], t[(k + 2) % 4], t[(k + 3) % 4]};
      (with_face(f[0], f[1], f[2], static_cast<int32_t>(e)).empty() ? outer : inner).push_back(f);
    }
    if (outer.size() != 2 || inner.size() != 2) continue;
    // The outer diagonal (p, q) and the two other corners (u, v).
    int32_t p = -1, q = -1, u = -1, v = -1;
    for (int32_t n : t) {
      const bool in0 = std::count(outer[0].begin(), outer[0].end(), n) > 0;
      const bool in1 = std::count(outer[1].begin(), outer[1].end(), n) > 0;
      if (in0 && in1) {
        (p < 0 ? p : q) = n;
      } else {
        (u < 0 ? u : v) = n;
      }
    }
    if (q < 0 || v < 0) continue;
    // The images, and the two elements on the image triangles (p' q' u') and (p' q' v').
    const int32_t pi = image_of(p, a), qi = image_of(q, a), ui = image_of(u, a),
                  vi = image_of(v, a);
    if (pi < 0 || qi < 0 || ui < 0 || vi < 0) continue;
    const std::vector<int32_t> f1 = with_face(pi, qi, ui, -1), f2 = with_face(pi, qi, vi, -1);
    if (f1.size() != 1 || f2.size() != 1 || gone[f1[0]] || gone[f2[0]]) continue;
    if (region_of(*mesh, f1[0]) != region_of(*mesh, f2[0])) continue;
    auto apex = [&](int32_t f, int32_t x) {
      for (int32_t n : mesh->tets[f]) {
        if (n != pi && n != qi && n != x) return n;
      }
      return int32_t(-1);
    };
    const int32_t r = apex(f1[0], ui);
    if (r < 0 || r != apex(f2[0], vi)) continue;
    // The flip: (p' q' u' r), (p' q' v' r) become (u' v' p' r), (u' v' q' r).
    std::array<int32_t, 4> n1 = {ui, vi, pi, r}, n2 = {ui, vi, qi, r};
    if (tet_volume(mesh->nodes, n1) < 0.0) std::swap(n1[0], n1[1]);
    if (tet_volume(mesh->nodes, n2) < 0.0) std::swap(n2[0], n2[1]);
    const double before =
        tet_volume(mesh->nodes, mesh->tets[f1[0]]) + tet_volume(mesh->nodes, mesh->tets[f2[0]]);
    const double v1 = tet_volume(mesh->nodes, n1), v2 = tet_volume(mesh->nodes, n2);
    if (!(v1 > 0.0 && v2 > 0.0) || std::abs(v1 + v2 - before) > 1e-9 * before) continue;
    mesh->tets[f1[0]] = n1;
    mesh->tets[f2[0]] = n2;
    // (A node's list may keep an element that no longer has it: each search checks the nodes.)
    for (int32_t f : {f1[0], f2[0]}) {
      for (int32_t n : mesh->tets[f]) {
        if (std::find(around[n].begin(), around[n].end(), f) == around[n].end()) {
          around[n].push_back(f);
        }
      }
    }
    gone[e] = 1;
    ++removed;
  }
  if (removed > 0) drop_elements(mesh, gone);
  return removed;
}

namespace {
void elements_around(const TetMesh& mesh, std::vector<int32_t>* start,
                     std::vector<int32_t>* around);  // below
}  // namespace

// The nodes a relocation may move, and how. A node inside one region (every element around in
// one inclusion and phase) moves freely: no phase's volume or interface changes. A node on one
// curved interface (a core against the matrix or its shell, a shell against the matrix) slides
// along it, at its signed distance from the exact surface (keep_phase_volumes set it): the
// phases' volumes change only by the surface's curvature over a step. A node on one box face
// moves with its image on the opposite face (the faces' triangulations stay translates of each
// other): in the face, or along the face's cut of one curved interface (a cut's own vertex,
// where the geometry kernel starts a closed curve, can lie a hair from a rim's crossing, and
// its elements are slivers: seen in a debonded sphere cut by a face). Nodes on box edges, on
// flat ends, on two interfaces or between two inclusions stay. Elements under `angle` have each
// such node moved where the least angle of its ball (the elements around it) is largest: a pattern
// search from where it is, along the axes and towards the centroid of its neighbours (in the
// surface's tangent plane for a sliding node), in steps from a quarter of its shortest edge down to
// a thousandth of it; a step is taken only when it raises the ball's least angle, every element
// positive. Rounds until none is left under `angle` or a round moves nothing (at most 4): a move
// can help an element next to it.
long long lift_slivers(TetMesh* mesh, const InclusionSet& set, double angle) {
  const size_t nn = mesh->nodes.size(), ne = mesh->tets.size();
  // Per node, the first two regions met; `many` a third (or a box face).
  constexpr uint64_t kNone = std::numeric_limits<uint64_t>::max();
  std::vector<std::array<uint64_t, 2>> met(nn, {kNone, kNone});
  std::vector<uint8_t> many(nn, 0);
  for (size_t e = 0; e < ne; ++e) {
    const uint64_t r = region_of(*mesh, e);
    for (int32_t n : mesh->tets[e]) {
      auto& m = met[n];
      if (m[0] == kNone || m[0] == r) {
        m[0] = r;
      } else if (m[1] == kNone || m[1] == r) {
        m[1] = r;
      } else {
        many[n] = 1;
      }
    }
  }
  // A node on one box face (not an edge) moves with its image on the opposite face: in the
  // face, or along the face's cut of one curved interface. The lower one leads (`image`: each
  // node's image, -1 if none; `face`: the face's axis). Nodes on edges stay.
  const std::vector<std::array<int8_t, 3>> ends = node_ends(*mesh);
  std::vector<int32_t> image(nn, -1);
  std::vector<int8_t> face(nn, -1);
  for (int a = 0; a < 3; ++a) {
    const std::vector<int32_t> across = images_across(*mesh, ends, a);
    for (size_t i = 0; i < nn; ++i) {
      const int32_t j = across[i];
      if (j < 0 || ends[i][(a + 1) % 3] >= 0 || ends[i][(a + 2) % 3] >= 0) continue;  // edges
      // The same regions on both sides (an inclusion's image keeps its id).
      if (met[i] != met[j] && !(met[i][0] == met[j][1] && met[i][1] == met[j][0])) continue;
      image[i] = j;
      face[i] = static_cast<int8_t>(a);
    }
  }
  for (size_t i = 0; i < nn; ++i) {
    if (ends[i][0] >= 0 || ends[i][1] >= 0 || ends[i][2] >= 0) {
      if (image[i] < 0) many[i] = 1;
    }
  }
  for (size_t i = 0; i < nn; ++i) {
    if (image[i] >= 0 && (many[i] || many[image[i]])) many[i] = many[image[i]] = 1;
  }
  const std::unordered_map<int32_t, int> by_id = index_by_id(set);
  // The surface a node on two regions slides on (interface_surface); -1 where it may not move.
  auto surface_of = [&](int32_t n) {
    const uint32_t label[2] = {static_cast<uint32_t>(met[n][0]), static_cast<uint32_t>(met[n][1])};
    if (label[0] >= mesh->phases.size() || label[1] >= mesh->phases.size()) return -1;
    return interface_surface(by_id, static_cast<int32_t>(met[n][0] >> 32),
                             mesh->phases[label[0]].kind, static_cast<int32_t>(met[n][1] >> 32),
                             mesh->phases[label[1]].kind);
  };
  std::vector<double> least(ne);
  parallel_for(size_t{0}, ne, [&](size_t e) { least[e] = least_dihedral(*mesh, mesh->tets[e]); });
  long long moved = 0;
  std::vector<int32_t> start, around_all;  // elements_around, made once needed
  for (int round = 0; round < 4; ++round) {
    // The nodes of the elements under the angle that may move, and their balls.
    // (A node on a box face is moved by the lower of it and its image; its ball holds both's.)
    auto leader = [&](int32_t n) { return image[n] >= 0 && ends[n][face[n]] == 1 ? image[n] : n; };
    std::unordered_map<int32_t, std::vector<int32_t>> ball;
    for (size_t e = 0; e < ne; ++e) {
      if (least[e] >= angle) continue;
      for (int32_t n : mesh->tets[e]) {
        if (!many[n]) ball[leader(n)];
      }
    }
    if (ball.empty()) break;
    // A leader's ball: the elements around it and around the image it leads, in the elements'
    // order (an element once for each of its nodes led).
    if (start.empty()) elements_around(*mesh, &start, &around_all);
    for (auto& [n, elements] : ball) {
      const int32_t led = image[n] >= 0 && leader(image[n]) == n ? image[n] : -1;
      const auto a0 = around_all.begin() + start[n], a1 = around_all.begin() + start[n + 1];
      if (led < 0) {
        elements.assign(a0, a1);
      } else {
        std::merge(a0, a1, around_all.begin() + start[led], around_all.begin() + start[led + 1],
                   std::back_inserter(elements));
      }
    }
    std::vector<int32_t> order;
    for (const auto& kv : ball) order.push_back(kv.first);
    std::sort(order.begin(), order.end());  // the same moves on every run
    long long this_round = 0;
    for (int32_t n : order) {
      const std::vector<int32_t>& around = ball[n];
      Vec3& x = mesh->nodes[n];
      // On a box face: the axis, and the image, which follows x on the other coordinates.
      const int a = face[n];
      Vec3* follower = image[n] >= 0 ? &mesh->nodes[image[n]] : nullptr;
      auto place = [&](const Vec3& y) {
        x = y;
        if (follower) {
          const double keep = (*follower)[a];
          *follower = y;
          (*follower)[a] = keep;
        }
      };
      // A sliding node: its surface (the periodic image nearest it) and its distance from it.
      const bool slides = met[n][1] != kNone;
      Shape surface;
      double grown = 0.0, offset = 0.0;
      if (slides) {
        const int which = surface_of(n);
        if (which < 0) continue;
        const Inclusion& in = set.inclusions[which / 2];
        grown = (which & 1) ? outer_offset(in.mod) : 0.0;
        bool feature;
        const Vec3 shift = nearest_image(in.shape, grown, set.box.size, x, &offset, &feature);
        surface = in.shape.translated(shift);
        if (feature) continue;                                    // on a flat end: stays
        if ((which & 1) && on_void_cone(in, shift, x)) continue;  // on a void's cone: stays
      }
      // The ball's least angle with the node at y (-1 if an element is not positive).
      auto worst = [&](const Vec3& y) {
        const Vec3 keep = x, keep_image = follower ? *follower : x;
        place(y);
        double w = 180.0;
        for (int32_t e : around) {
          const auto& t = mesh->tets[e];
          w = tet_volume(mesh->nodes, t) > 0.0 ? std::min(w, least_dihedral(*mesh, t)) : -1.0;
          if (w < 0.0) break;
        }
        x = keep;
        if (follower) *follower = keep_image;
        return w;
      };
      // A step of h along d from p: in the tangent plane, then back to the offset, for a
      // sliding node.
      auto step = [&](const Vec3& p, const Vec3& d, double h, Vec3* y) {
        if (a >= 0) {
          // In the face: the direction's part in it; along the face's cut of the surface when
          // sliding, brought back to both (the surface, then the face) until they agree.
          Vec3 t = d;
          t[a] = 0.0;
          Vec3 nrm;
          bool feature = false;
          if (slides) {
            surface_distance(surface, grown, p, &nrm, &feature);
            const Vec3 along = Vec3::Unit(a).cross(nrm);
            if (!(along.norm() > 1e-3)) return false;  // the face nearly tangent to it
            t = along.normalized() * (along.normalized().dot(t) >= 0.0 ? 1.0 : -1.0);
          }
          if (!(t.norm() > 1e-6)) return false;
          Vec3 q = p + h * t.normalized();
          if (slides) {
            // Newton's steps in the face, along the normal's part in it.
            double off = 1.0;
            for (int k = 0; k < 8 && std::abs(off) > 1e-12 * h; ++k) {
              off = surface_distance(surface, grown, q, &nrm, &feature) - offset;
              if (feature) return false;
              Vec3 m = nrm;
              m[a] = 0.0;
              if (!(m.squaredNorm() > 1e-6)) return false;
              q -= (off / m.squaredNorm()) * m;
              q[a] = p[a];
            }
            if (!(std::abs(off) <= 1e-9 * h)) return false;
          }
          q[a] = p[a];
          *y = q;
          return true;
        }
        if (!slides) {
          *y = p + h * d;
          return true;
        }
        Vec3 nrm;
        bool feature;
        surface_distance(surface, grown, p, &nrm, &feature);
        const Vec3 t = d - d.dot(nrm) * nrm;
        if (!(t.norm() > 1e-6)) return false;
        Vec3 q = p + h * t.normalized();
        const double off = surface_distance(surface, grown, q, &nrm, &feature) - offset;
        if (feature) return false;
        *y = q - off * nrm;
        return true;
      };
      double shortest = 1e300;
      Vec3 centroid = Vec3::Zero();
      int neighbours = 0;
      for (int32_t e : around) {
        const auto& t = mesh->tets[e];
        if (std::find(t.begin(), t.end(), n) == t.end()) continue;  // the image's
        for (int32_t m : t) {
          if (m == n) continue;
          shortest = std::min(shortest, (mesh->nodes[m] - x).norm());
          centroid += mesh->nodes[m];
          ++neighbours;
        }
      }
      centroid /= std::max(1, neighbours);
      const double start = worst(x);
      double best = start;
      Vec3 at = x;
      const Vec3 to_centroid =
          (centroid - x).norm() > 0.0 ? Vec3((centroid - x).normalized()) : Vec3::UnitX();
      const Vec3 dirs[8] = {to_centroid,   -to_centroid,   Vec3::UnitX(), -Vec3::UnitX(),
                            Vec3::UnitY(), -Vec3::UnitY(), Vec3::UnitZ(), -Vec3::UnitZ()};
      int tries = 0;
      for (double h = 0.25 * shortest; h > 1e-3 * shortest && tries < 400;) {
        bool better = false;
        for (const Vec3& d : dirs) {
          Vec3 y;
          if (!step(at, d, h, &y)) continue;
          const double w = worst(y);
          ++tries;
          if (w > best) {
            best = w;
            at = y;
            better = true;
            break;
          }
        }
        if (!better) h *= 0.5;
      }
      if (best > start) {
        place(at);
        ++this_round;
        for (int32_t e : around) least[e] = least_dihedral(*mesh, mesh->tets[e]);
      }
    }
    moved += this_round;
    if (this_round == 0) break;
  }
  return moved;
}

namespace {

// The elements whose least dihedral angle is under `angle` degrees, in order; *least: every
// element's least angle.
std::vector<int32_t> elements_under(const TetMesh& mesh, double angle, std::vector<double>* least) {
  least->resize(mesh.tets.size());
  parallel_for(size_t{0}, mesh.tets.size(),
               [&](size_t e) { (*least)[e] = least_dihedral(mesh, mesh.tets[e]); });
  std::vector<int32_t> bad;
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    if ((*least)[e] < angle) bad.push_back(static_cast<int32_t>(e));
  }
  return bad;
}

// The elements around each node n of the mesh: (*around)[(*start)[n]] to
// (*around)[(*start)[n + 1] - 1], in element order.
void elements_around(const TetMesh& mesh, std::vector<int32_t>* start,
                     std::vector<int32_t>* around) {
  start->assign(mesh.nodes.size() + 1, 0);
  around->resize(4 * mesh.tets.size());
  for (const auto& t : mesh.tets) {
    for (int32_t n : t) ++(*start)[n + 1];
  }
  for (size_t i = 1; i < start->size(); ++i) (*start)[i] += (*start)[i - 1];
  std::vector<int32_t> fill(start->begin(), start->end() - 1);
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    for (int32_t n : mesh.tets[e]) (*around)[fill[n]++] = static_cast<int32_t>(e);
  }
}

// The element other than `except` that has face (a, b, c), -1 if none (start and around:
// elements_around).
int32_t element_on(const TetMesh& mesh, const std::vector<int32_t>& start,
                   const std::vector<int32_t>& around, int32_t a, int32_t b, int32_t c,
                   int32_t except) {
  for (int32_t i = start[a]; i < start[a + 1]; ++i) {
    const int32_t f = around[i];
    if (f == except) continue;
    const auto& u = mesh.tets[f];
    if (std::count(u.begin(), u.end(), b) > 0 && std::count(u.begin(), u.end(), c) > 0) return f;
  }
  return -1;
}

// The centre of a tetrahedron's circumscribed sphere (its centroid when the tetrahedron is flat
// to rounding).
Vec3 circumcentre(const Vec3 (&p)[4]) {
  const Vec3 a = p[1] - p[0], b = p[2] - p[0], c = p[3] - p[0];
  const double det = 2.0 * a.dot(b.cross(c));
  const double scale = a.norm() * b.norm() * c.norm();
  if (!(std::abs(det) > 1e-12 * scale)) return 0.25 * (p[0] + p[1] + p[2] + p[3]);
  return p[0] + (a.squaredNorm() * b.cross(c) + b.squaredNorm() * c.cross(a) +
                 c.squaredNorm() * a.cross(b)) /
                    det;
}

}  // namespace

long long insert_nodes_in_slivers(TetMesh* mesh, double angle) {
  long long inserted = 0;
  for (int round = 0; round < 3; ++round) {
    const size_t ne = mesh->tets.size();
    std::vector<double> least;
    std::vector<int32_t> bad = elements_under(*mesh, angle, &least);
    if (bad.empty()) break;
    // The elements around each node: around[start[n]] to around[start[n + 1] - 1].
    std::vector<int32_t> start, around;
    elements_around(*mesh, &start, &around);
    // Elements replaced in this round. A face of a kept element whose other side was replaced
    // finds the replaced element (the new ones are not in `around`), which counts as outside.
    std::vector<uint8_t> gone(ne, 0);
    // The element across face k of e (the face without corner k), -1 if none.
    auto across = [&](int32_t e, int k) {
      const auto& t = mesh->tets[e];
      return element_on(*mesh, start, around, t[(k + 1) % 4], t[(k + 2) % 4], t[(k + 3) % 4], e);
    };
    auto tet_points = [&](const std::array<int32_t, 4>& t, Vec3(&p)[4]) {
      for (int k = 0; k < 4; ++k) p[k] = mesh->nodes[t[k]];
    };
    long long this_round = 0;
    for (int32_t e : bad) {
      if (gone[e]) continue;
      const uint64_t region = region_of(*mesh, e);
      Vec3 pe[4];
      tet_points(mesh->tets[e], pe);
      // Candidates: the circumcentre and the centroid of the element, and the centroid of its
      // neighbours in its region.
      std::vector<Vec3> candidates = {circumcentre(pe), 0.25 * (pe[0] + pe[1] + pe[2] + pe[3])};
      {
        Vec3 sum = Vec3::Zero();
        int n = 0;
        for (int k = 0; k < 4; ++k) {
          const int32_t f = across(e, k);
          if (f < 0 || gone[f] || region_of(*mesh, f) != region) continue;
          for (int32_t m : mesh->tets[f]) sum += mesh->nodes[m];
          n += 4;
        }
        if (n > 0) candidates.push_back(sum / n);
      }
      struct Best {
        double worst = -1.0;
        int below = 0;
        std::vector<int32_t> cavity;
        std::vector<std::array<int32_t, 4>> tets;
        Vec3 p;
      } best;
      double old_worst = 0.0;
      int old_below = 0;
      for (const Vec3& p : candidates) {
        // The cavity: the elements of the region connected to e whose circumscribed sphere
        // holds p (e always).
        std::vector<int32_t> cavity = {e};
        std::set<int32_t> in(cavity.begin(), cavity.end());
        for (size_t q = 0; q < cavity.size() && cavity.size() < 200; ++q) {
          for (int k = 0; k < 4; ++k) {
            const int32_t f = across(cavity[q], k);
            if (f < 0 || gone[f] || in.count(f) || region_of(*mesh, f) != region) continue;
            Vec3 pf[4];
            tet_points(mesh->tets[f], pf);
            const Vec3 cc = circumcentre(pf);
            if ((p - cc).squaredNorm() < (pf[0] - cc).squaredNorm() * (1.0 - 1e-12)) {
              cavity.push_back(f);
              in.insert(f);
            }
          }
        }
        // Each face of the cavity's boundary with p: its element with the opposite corner
        // replaced by p (positive when p sees the face from inside). An element with a face
        // that p does not see leaves the cavity (unless it is e), until p sees every face.
        const int32_t pn = static_cast<int32_t>(mesh->nodes.size());
        mesh->nodes.push_back(p);
        std::vector<std::array<int32_t, 4>> made;
        double volume_old = 0.0, volume_new = 0.0, worst = 180.0, was = 180.0;
        int below = 0, was_below = 0;
        bool ok = false;
        for (int pass = 0; pass < 64 && !ok; ++pass) {
          made.clear();
          volume_old = volume_new = 0.0;
          worst = was = 180.0;
          below = was_below = 0;
          std::vector<int32_t> blind;
          for (int32_t c : cavity) {
            volume_old += tet_volume(mesh->nodes, mesh->tets[c]);
            was = std::min(was, least[c]);
            was_below += least[c] < angle;
            for (int k = 0; k < 4; ++k) {
              const int32_t f = across(c, k);
              if (f >= 0 && in.count(f)) continue;
              std::array<int32_t, 4> t = mesh->tets[c];
              t[k] = pn;
              const double v = tet_volume(mesh->nodes, t);
              if (!(v > 0.0)) {
                blind.push_back(c);
                break;
              }
              volume_new += v;
              const double a = least_dihedral(*mesh, t);
              worst = std::min(worst, a);
              below += a < angle;
              made.push_back(t);
            }
          }
          if (blind.empty()) {
            ok = true;
            break;
          }
          if (std::count(blind.begin(), blind.end(), e)) break;
          for (int32_t c : blind) in.erase(c);
          cavity.erase(
              std::remove_if(cavity.begin(), cavity.end(), [&](int32_t c) { return !in.count(c); }),
              cavity.end());
        }
        mesh->nodes.pop_back();
        ok = ok && std::abs(volume_new - volume_old) <= 1e-9 * volume_old;
        if (!ok) continue;
        if (best.worst < 0.0 || worst > best.worst) {
          best = {worst, below, cavity, made, p};
          old_worst = was;
          old_below = was_below;
        }
      }
      if (best.worst < 0.0) continue;
      // Taken when it lifts every element over the angle, or raises the least angle with
      // fewer elements under it.
      if (!(best.worst >= angle || (best.worst > old_worst && best.below < old_below))) continue;
      mesh->nodes.push_back(best.p);
      for (int32_t c : best.cavity) gone[c] = 1;
      const int32_t phase = mesh->phase[e], id = mesh->inclusion_id[e];
      for (const auto& t : best.tets) {  // made with the node at its index now
        mesh->tets.push_back(t);
        mesh->phase.push_back(phase);
        mesh->inclusion_id.push_back(id);
      }
      ++this_round;
    }
    drop_elements(mesh, gone);  // the elements replaced
    inserted += this_round;
    if (this_round == 0) break;
  }
  return inserted;
}

namespace {

// A retriangulation of some elements: the elements it replaces, the new ones (positive) and
// the region (index of an old element whose phase and inclusion it takes) of each.
struct Remake {
  double worst = -1.0;  // least angle of the new elements (-1: none valid)
  int below = 0;        // new elements under the angle
  std::vector<int32_t> old;
  std::vector<std::array<int32_t, 4>> tets;
  std::vector<int32_t> like;
  bool moves_interface = false;
};

// The distance between the lines through p0-p1 and q0-q1 (the larger of the two endpoints'
// distances when they are parallel).
double line_distance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
  const Vec3 n = (p1 - p0).cross(q1 - q0);
  if (n.norm() > 1e-12 * (p1 - p0).norm() * (q1 - q0).norm()) {
    return std::abs((q0 - p0).dot(n.normalized()));
  }
  const Vec3 d = (p1 - p0).normalized();
  const Vec3 r = q0 - p0;
  return (r - r.dot(d) * d).norm();
}

}  // namespace

long long remake_slivers(TetMesh* mesh, double angle) {
  const std::vector<std::array<int8_t, 3>> ends = node_ends(*mesh);
  auto same_face = [&](int32_t a, int32_t b) {
    for (int x = 0; x < 3; ++x) {
      if (ends[a][x] >= 0 && ends[a][x] == ends[b][x]) return true;
    }
    return false;
  };
  long long remakes = 0;
  for (int round = 0; round < 4; ++round) {
    const size_t ne = mesh->tets.size();
    std::vector<double> least;
    std::vector<int32_t> bad = elements_under(*mesh, angle, &least);
    if (bad.empty()) break;
    // The worst first; the same order on every run.
    std::sort(bad.begin(), bad.end(), [&](int32_t a, int32_t b) {
      return least[a] < least[b] || (least[a] == least[b] && a < b);
    });
    // The elements around each node: around[start[n]] to around[start[n + 1] - 1].
    std::vector<int32_t> start, around;
    elements_around(*mesh, &start, &around);
    std::vector<uint8_t> gone(ne, 0);
    auto has = [](const std::array<int32_t, 4>& t, int32_t n) {
      return t[0] == n || t[1] == n || t[2] == n || t[3] == n;
    };
    auto quality = [&](std::array<int32_t, 4>* t) {
      const double v = tet_volume(mesh->nodes, *t);
      if (!(v != 0.0)) return -1.0;
      if (v < 0.0) std::swap((*t)[0], (*t)[1]);
      return least_dihedral(*mesh, *t);
    };
    auto score = [&](Remake* r) {
      r->worst = 180.0;
      r->below = 0;
      for (auto& t : r->tets) {
        const double q = quality(&t);
        r->worst = std::min(r->worst, q);
        r->below += q < angle;
      }
    };

    // Edge removal: the elements around edge (u, v), a closed ring in one region or in two
    // (each a run of the ring), replaced by a triangulation of the ring's polygon joined to u
    // and to v, the one whose least angle is largest (Klincsek's dynamic programme). In two
    // regions the triangulation keeps the diagonal between the two runs' ends, which becomes
    // the interface: the interface's edge (u, v) is flipped, allowed only where its two
    // triangles nearly lie in one plane (the lines u-v and a-b within a tenth of the shorter
    // apart), so the interface moves by no more than the flat element between them.
    auto remove_edge = [&](int32_t u, int32_t v, Remake* out) {
      std::vector<int32_t> ring;
      for (int32_t i = start[u]; i < start[u + 1]; ++i) {
        const int32_t f = around[i];
        if (has(mesh->tets[f], v)) {
          if (gone[f]) return false;
          ring.push_back(f);
        }
      }
      const int n = static_cast<int>(ring.size());
      if (n < 3 || n > 12) return false;
      // The link: each element's two other nodes; a closed cycle.
      std::vector<std::array<int32_t, 2>> link(n);
      for (int k = 0; k < n; ++k) {
        int c = 0;
        for (int32_t m : mesh->tets[ring[k]]) {
          if (m != u && m != v) link[k][c++] = m;
        }
      }
      std::vector<int32_t> w = {link[0][0], link[0][1]};
      std::vector<int32_t> tet_of = {ring[0]};  // element between w[i] and w[i + 1]
      std::vector<uint8_t> used(n, 0);
      used[0] = 1;
      while (static_cast<int>(w.size()) <= n) {
        int next = -1;
        for (int k = 0; k < n && next < 0; ++k) {
          if (!used[k] && (link[k][0] == w.back() || link[k][1] == w.back())) next = k;
        }
        if (next < 0) return false;  // open: the edge lies in a box face
        used[next] = 1;
        tet_of.push_back(ring[next]);
        w.push_back(link[next][0] == w.back() ? link[next][1] : link[next][0]);
      }
      if (w.back() != w.front()) return false;
      w.pop_back();
      {
        std::vector<int32_t> sorted = w;
        std::sort(sorted.begin(), sorted.end());
        if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) return false;
      }
      // The runs of regions around the ring.
      std::vector<int> cuts;
      for (int k = 0; k < n; ++k) {
        if (region_of(*mesh, tet_of[k]) != region_of(*mesh, tet_of[(k + n - 1) % n])) {
          cuts.push_back(k);
        }
      }
      if (cuts.size() != 0 && cuts.size() != 2) return false;
      int split = n;  // the polygon 0..split and split..n (w[n] = w[0])
      if (cuts.size() == 2) {
        std::rotate(w.begin(), w.begin() + cuts[0], w.end());
        std::rotate(tet_of.begin(), tet_of.begin() + cuts[0], tet_of.end());
        split = cuts[1] - cuts[0];
        const int32_t a = w[0], b = w[split];
        if (same_face(a, b)) return false;
        const Vec3 &pu = mesh->nodes[u], &pv = mesh->nodes[v];
        const Vec3 &pa = mesh->nodes[a], &pb = mesh->nodes[b];
        const double shorter = std::min((pv - pu).norm(), (pb - pa).norm());
        if (!(line_distance(pu, pv, pa, pb) <= 0.1 * shorter)) return false;
      }
      w.push_back(w[0]);
      // The side of u: the sign that the fan's volumes (triangle with u, less triangle with
      // v) add up to; every new element with u must have it.
      auto vol = [&](int32_t p, int32_t q, int32_t r, int32_t s) {
        return tet_volume(mesh->nodes, {p, q, r, s});
      };
      double sum = 0.0;
      for (int k = 1; k + 1 < n; ++k)
        sum += vol(w[0], w[k], w[k + 1], u) - vol(w[0], w[k], w[k + 1], v);
      if (!(sum != 0.0)) return false;
      const double sign = sum > 0.0 ? 1.0 : -1.0;
      auto triangle = [&](int i, int k, int j) {
        const int32_t p = w[i], q = w[k], r = w[j];
        if (!(sign * vol(p, q, r, u) > 0.0 && sign * vol(p, q, r, v) < 0.0)) return -1.0;
        std::array<int32_t, 4> tu = {p, q, r, u}, tv = {p, q, r, v};
        return std::min(quality(&tu), quality(&tv));
      };
      // best[i][j]: the largest least angle over triangulations of w[i..j]; pick[i][j] its apex.
      const int m = n + 1;
      std::vector<double> best(m * m, 180.0);
      std::vector<int> pick(m * m, -1);
      auto solve = [&](int lo, int hi) {
        for (int len = 2; len <= hi - lo; ++len) {
          for (int i = lo; i + len <= hi; ++i) {
            const int j = i + len;
            double b = -1.0;
            for (int k = i + 1; k < j; ++k) {
              const double q = std::min({triangle(i, k, j), best[i * m + k], best[k * m + j]});
              if (q > b) {
                b = q;
                pick[i * m + j] = k;
              }
            }
            best[i * m + j] = b;
          }
        }
      };
      std::vector<std::array<int, 3>> parts;  // (lo, hi, the ring element whose region)
      if (split == n) {
        solve(0, n - 1);  // w[0..n-1]: its side w[n-1]-w[0] closes it
        parts.push_back({0, n - 1, 0});
      } else {
        solve(0, split);
        solve(split, n);
        parts.push_back({0, split, 0});
        parts.push_back({split, n, split});
      }
      Remake r;
      r.old = ring;
      r.moves_interface = split != n;
      for (const auto& part : parts) {
        if (part[1] - part[0] < 2) {
          // A run of one element goes, and its faces away from the edge become the interface:
          // both must face elements of its own region (not a box face, not a third region).
          const int32_t one = tet_of[part[2]], a = w[part[0]], b = w[part[1]];
          for (int32_t c : {u, v}) {
            const int32_t f = element_on(*mesh, start, around, a, b, c, one);
            if (f < 0 || gone[f] || region_of(*mesh, f) != region_of(*mesh, one)) return false;
          }
          continue;
        }
        if (!(best[part[0] * m + part[1]] > 0.0)) return false;
        std::vector<std::array<int, 2>> stack = {{part[0], part[1]}};
        while (!stack.empty()) {
          const auto [i, j] = stack.back();
          stack.pop_back();
          if (j - i < 2) continue;
          const int k = pick[i * m + j];
          r.tets.push_back({w[i], w[k], w[j], u});
          r.tets.push_back({w[i], w[k], w[j], v});
          r.like.push_back(tet_of[part[2]]);
          r.like.push_back(tet_of[part[2]]);
          stack.push_back({i, k});
          stack.push_back({k, j});
        }
      }
      score(&r);
      *out = std::move(r);
      return true;
    };

    // Two elements of one region on either side of a face, made three about the line between
    // their other nodes (where it crosses the face).
    auto split_face = [&](int32_t e, int k, Remake* out) {
      const auto& t = mesh->tets[e];
      const int32_t p = t[(k + 1) % 4], q = t[(k + 2) % 4], r = t[(k + 3) % 4], d = t[k];
      const int32_t f = element_on(*mesh, start, around, p, q, r, e);
      if (f < 0 || gone[f] || region_of(*mesh, f) != region_of(*mesh, e)) return false;
      int32_t x = -1;
      for (int32_t c : mesh->tets[f]) {
        if (c != p && c != q && c != r) x = c;
      }
      const double s1 = tet_volume(mesh->nodes, {p, q, d, x});
      const double s2 = tet_volume(mesh->nodes, {q, r, d, x});
      const double s3 = tet_volume(mesh->nodes, {r, p, d, x});
      if (!((s1 > 0.0 && s2 > 0.0 && s3 > 0.0) || (s1 < 0.0 && s2 < 0.0 && s3 < 0.0))) {
        return false;
      }
      Remake m;
      m.old = {e, f};
      m.tets = {{p, q, d, x}, {q, r, d, x}, {r, p, d, x}};
      m.like = {e, e, e};
      score(&m);
      *out = std::move(m);
      return true;
    };

    // An edge collapsed into one of its nodes u: its other node v (inside the box) goes, the
    // elements around the edge go, v's other elements take u instead. v must lie in one region
    // (nothing but the elements changes), or on one interface whose two regions both meet the
    // edge, where u lies within a tenth of the mean length of v's other edges of the plane of
    // each of v's interface triangles (the interface then moves by no more than that: a short
    // edge, or one along a flat interface).
    auto collapse = [&](int32_t v, int32_t u, Remake* out) {
      if (ends[v][0] >= 0 || ends[v][1] >= 0 || ends[v][2] >= 0) return false;
      std::vector<int32_t> star;
      std::vector<uint64_t> regions, on_edge;
      double others = 0.0;
      int count = 0;
      for (int32_t i = start[v]; i < start[v + 1]; ++i) {
        const int32_t f = around[i];
        if (gone[f]) return false;
        star.push_back(f);
        const uint64_t r = region_of(*mesh, f);
        if (std::find(regions.begin(), regions.end(), r) == regions.end()) regions.push_back(r);
        if (has(mesh->tets[f], u)) {
          if (std::find(on_edge.begin(), on_edge.end(), r) == on_edge.end()) on_edge.push_back(r);
          continue;
        }
        for (int32_t m : mesh->tets[f]) {
          if (m == v) continue;
          others += (mesh->nodes[m] - mesh->nodes[v]).norm();
          ++count;
        }
      }
      if (regions.size() > 2 || on_edge.size() != regions.size() || count == 0) return false;
      // v's triangles (v, p, q) and the regions of the elements on them: two each (v lies
      // inside the mesh), of two regions where v's interface passes.
      std::map<std::pair<int32_t, int32_t>, std::vector<uint64_t>> sides;
      for (int32_t f : star) {
        const auto& t = mesh->tets[f];
        for (int i = 0; i < 4; ++i) {
          for (int j = i + 1; j < 4; ++j) {
            if (t[i] == v || t[j] == v) continue;
            sides[{std::min(t[i], t[j]), std::max(t[i], t[j])}].push_back(region_of(*mesh, f));
          }
        }
      }
      const double reach = 0.1 * others / count;
      const Vec3& x = mesh->nodes[v];
      for (const auto& [pq, by] : sides) {
        if (by.size() != 2) return false;
        if (by[0] == by[1] || pq.first == u || pq.second == u) continue;
        const Vec3 n = (mesh->nodes[pq.first] - x).cross(mesh->nodes[pq.second] - x);
        if (!(std::abs((mesh->nodes[u] - x).dot(n)) <= reach * n.norm())) return false;
      }
      Remake r;
      r.old = star;
      r.moves_interface = regions.size() == 2;
      for (int32_t f : star) {
        auto t = mesh->tets[f];
        if (has(t, u)) continue;
        std::replace(t.begin(), t.end(), v, u);
        if (!(tet_volume(mesh->nodes, t) > 0.0)) return false;
        r.tets.push_back(t);
        r.like.push_back(f);
      }
      score(&r);
      *out = std::move(r);
      return true;
    };

    long long this_round = 0;
    for (int32_t e : bad) {
      if (gone[e]) continue;
      Remake best;
      // The best by least angle; at a tie, the one that keeps the interfaces.
      auto consider = [&](Remake&& r) {
        if (r.worst > best.worst ||
            (r.worst == best.worst && best.moves_interface && !r.moves_interface)) {
          best = std::move(r);
        }
      };
      const auto t = mesh->tets[e];
      for (int i = 0; i < 4; ++i) {
        for (int j = i + 1; j < 4; ++j) {
          Remake r;
          if (remove_edge(t[i], t[j], &r)) consider(std::move(r));
        }
        Remake r;
        if (split_face(e, i, &r)) consider(std::move(r));
      }
      for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 4; ++j) {
          Remake r;
          if (i != j && collapse(t[i], t[j], &r)) consider(std::move(r));
        }
      }
      if (best.worst < 0.0) continue;
      double was = 180.0;
      int was_below = 0;
      for (int32_t o : best.old) {
        was = std::min(was, least[o]);
        was_below += least[o] < angle;
      }
      // Taken when it lifts every element over the angle, or raises the least angle with
      // fewer elements under it.
      if (!(best.worst >= angle || (best.worst > was && best.below < was_below))) continue;
      for (int32_t o : best.old) gone[o] = 1;
      for (size_t i = 0; i < best.tets.size(); ++i) {
        const int32_t phase = mesh->phase[best.like[i]], id = mesh->inclusion_id[best.like[i]];
        mesh->tets.push_back(best.tets[i]);
        mesh->phase.push_back(phase);
        mesh->inclusion_id.push_back(id);
      }
      ++this_round;
    }
    drop_elements(mesh, gone);
    remakes += this_round;
    if (this_round == 0) break;
  }
  drop_unused_nodes(mesh);  // the collapsed nodes
  return remakes;
}

int repair_slivers(TetMesh* mesh, const InclusionSet& set, double angle) {
  std::vector<double> least;
  size_t before = elements_under(*mesh, angle, &least).size();
  int rounds = 0;
  // A round may leave more than it found (an inserted node's new elements) and the next lift
  // them: two meshes of spheres and fibres saved before the repairs went from 7 and 6 elements
  // under 5 degrees to 14 and 13 in the first round and to none in the second. The rounds end
  // when one changes nothing.
  while (before > 0 && rounds < 4) {
    ++rounds;
    const long long lifted = lift_slivers(mesh, set, angle);
    const long long remade = remake_slivers(mesh, angle);
    const long long inserted = insert_nodes_in_slivers(mesh, angle);
    mesh->relocated_nodes += lifted;
    mesh->remade_slivers += remade;
    mesh->inserted_nodes += inserted;
    if (lifted == 0 && remade == 0 && inserted == 0) break;
    before = elements_under(*mesh, angle, &least).size();
  }
  return rounds;
}

void check_tet_meshable(const InclusionSet& set) {
  if (!set.box.periodic) {
    throw InputError("outputs: mesh_tet needs a periodic box (box.periodic false)");
  }
  for (const Inclusion& inc : set.inclusions) {
    const std::string name = inc.family < static_cast<int>(set.family_names.size())
                                 ? set.family_names[inc.family]
                                 : "family " + std::to_string(inc.family);
    const Modifiers& m = inc.mod;
    if (m.curved() || m.deformed()) {
      throw InputError(
          "outputs: mesh_tet meshes spheres, cylinders and ellipsoids, plain, coated or (spheres) "
          "debonded; family \"" +
          name + "\" has wavy, bent or deformed inclusions (use mesh_voxel for them)");
    }
  }
}

namespace {

// The surface mesher failed, or HXT refused the surface mesh (see mesh_with): what() says which,
// after "mesh_tet: ". tet_mesh meshes again from the start, another way.
struct SurfacesRefused : MeshError {
  using MeshError::MeshError;
  SurfacesRefused(const std::string& what, std::vector<int> at)
      : MeshError(what), inclusions(std::move(at)) {}
  // The inclusions (indices in the set) whose surfaces bound the curves the message names.
  std::vector<int> inclusions;
};

// The chord error of the curves in the last attempt (tet_mesh).
constexpr double kFinerCurveChord = 0.01;
// How many times tet_mesh builds the inclusions about a failed surface in another frame.
constexpr int kFrameTurns = 2;

// Whether the volume mesher, not the surface mesher, refused (mesh_with's words).
bool refused_volumes(const SurfacesRefused& e) {
  return std::string(e.what()).rfind("the volume mesher refused", 0) == 0;
}
constexpr const char* kDelaunayRetry =
    "meshing the volumes again with Gmsh's Delaunay mesher (one thread, several times slower)";

// A patch of a box face at the upper end of an axis, and the patch at the lower end whose
// translate it is.
struct FacePair {
  int upper, lower, axis;
};

Vec3 point_of(int tag) {
  std::vector<double> xyz;
  gmsh::model::getValue(0, tag, {}, xyz);
  return Vec3(xyz[0], xyz[1], xyz[2]);
}

// A curve's end points and the point at the middle of its parameter range.
struct CurveProbe {
  int tag;
  std::vector<Vec3> ends;
  Vec3 mid;
};

CurveProbe probe_curve(int tag) {
  CurveProbe p;
  p.tag = tag;
  std::vector<int> up, down;
  gmsh::model::getAdjacencies(1, tag, up, down);
  for (const int v : down) p.ends.push_back(point_of(v));
  std::vector<double> lo, hi, xyz;
  gmsh::model::getParametrizationBounds(1, tag, lo, hi);
  gmsh::model::getValue(1, tag, {0.5 * (lo[0] + hi[0])}, xyz);
  p.mid = Vec3(xyz[0], xyz[1], xyz[2]);
  return p;
}

std::vector<int> boundary_curves(int face) {
  gmsh::vectorpair b;
  gmsh::model::getBoundary({{2, face}}, b, false, false, false);
  std::vector<int> out;
  for (const auto& dt : b) {
    if (std::find(out.begin(), out.end(), std::abs(dt.second)) == out.end())
      out.push_back(std::abs(dt.second));
  }
  return out;
}

// Ties every curve of the upper patches to its image on the lower one (Gmsh then meshes it as a
// copy). Gmsh's own pairing of two periodic surfaces matches their curves by end points and,
// where two curves share both, takes the first whose middle or bounding box agrees within 1e-3
// of the curve's size. The line and the arc that bound the cut of a fibre's end by a box face
// share both end points, and where the arc is monotone along the face's axes their bounding
// boxes agree to 1e-4 of that; on a 2,500-fibre scene the copied faces then missed nodes
// ("Could not find periodic counterpart of triangle nodes", at 6 faces; the scene had 26 such
// pairs). Here each curve is paired with the image whose end points match and whose curve
// passes nearest its middle. A curve on two upper faces (a box edge) is tied by the first axis
// only: its image then has fewer coordinates at an upper end, so the ties make no cycle.
void tie_face_curves(const std::vector<FacePair>& pairs, const Vec3& len, double tol) {
  std::set<int> tied;
  for (const FacePair& fp : pairs) {
    Vec3 shift = Vec3::Zero();
    shift[fp.axis] = len[fp.axis];
    std::vector<CurveProbe> lower;
    for (const int c : boundary_curves(fp.lower)) lower.push_back(probe_curve(c));
    std::vector<double> T = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    T[4 * fp.axis + 3] = len[fp.axis];
    for (const int c : boundary_curves(fp.upper)) {
      if (tied.count(c)) continue;
      const CurveProbe u = probe_curve(c);
      int match = -1;
      double best = 1e300;
      for (const CurveProbe& l : lower) {
        if (l.ends.size() != u.ends.size()) continue;
        bool ends = true;
        for (const Vec3& e : u.ends) {
          bool found = false;
          for (const Vec3& f : l.ends) found = found || (e - shift - f).norm() <= tol;
          ends = ends && found;
        }
        if (!ends) continue;
        std::vector<double> closest, param;
        const Vec3 m = u.mid - shift;
        gmsh::model::getClosestPoint(1, l.tag, {m[0], m[1], m[2]}, closest, param);
        const double d = (Vec3(closest[0], closest[1], closest[2]) - m).norm();
        if (d < best) {
          best = d;
          match = l.tag;
        }
      }
      if (match < 0 || best > tol) {
        throw MeshError("mesh_tet: a curve of the upper box face normal to " +
                        std::string(1, "xyz"[fp.axis]) + " has no image on the lower face");
      }
      gmsh::model::mesh::setPeriodic(1, {c}, {match}, T);
      tied.insert(c);
    }
  }
}

// Nodes of a face's boundary (its curves and their end points): tag and position.
std::vector<std::pair<std::size_t, Vec3>> boundary_nodes(int face) {
  std::vector<std::pair<std::size_t, Vec3>> out;
  for (const int c : boundary_curves(face)) {
    std::vector<std::size_t> tags;
    std::vector<double> xyz, param;
    gmsh::model::mesh::getNodes(tags, xyz, param, 1, c, true, false);
    for (size_t i = 0; i < tags.size(); ++i) {
      out.push_back({tags[i], Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2])});
    }
  }
  return out;
}

// The largest tag of the model's nodes (Gmsh 4.8 has no call for it): new nodes take the next.
std::size_t largest_node_tag() {
  std::vector<std::size_t> tags;
  std::vector<double> xyz, param;
  gmsh::model::mesh::getNodes(tags, xyz, param, -1, -1, false, false);
  return tags.empty() ? 0 : *std::max_element(tags.begin(), tags.end());
}

// Replaces each upper patch's triangles with the translate of its lower patch's: the same
// triangles, on the upper patch's own boundary nodes (the curves are copies of the lower ones)
// and on new nodes translated from the lower patch's inside.
void copy_face_meshes(const std::vector<FacePair>& pairs, const Vec3& len, double tol) {
  std::size_t next_tag = largest_node_tag();
  for (const FacePair& fp : pairs) {
    Vec3 shift = Vec3::Zero();
    shift[fp.axis] = len[fp.axis];
    // The upper boundary's nodes, found by position on a grid of cells of the tolerance.
    const auto key = [tol](const Vec3& p, int dx, int dy, int dz) {
      return std::array<long long, 3>{static_cast<long long>(std::floor(p[0] / tol)) + dx,
                                      static_cast<long long>(std::floor(p[1] / tol)) + dy,
                                      static_cast<long long>(std::floor(p[2] / tol)) + dz};
    };
    std::map<std::array<long long, 3>, std::vector<std::pair<std::size_t, Vec3>>> grid;
    for (const auto& n : boundary_nodes(fp.upper)) grid[key(n.second, 0, 0, 0)].push_back(n);
    std::set<std::size_t> on_lower_boundary;
    for (const auto& n : boundary_nodes(fp.lower)) on_lower_boundary.insert(n.first);

    std::vector<std::size_t> tags;
    std::vector<double> xyz, param;
    gmsh::model::mesh::getNodes(tags, xyz, param, 2, fp.lower, true, false);
    std::map<std::size_t, std::size_t> image;
    std::vector<std::size_t> new_tags;
    std::vector<double> new_xyz;
    for (size_t i = 0; i < tags.size(); ++i) {
      const Vec3 p = Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]) + shift;
      if (!on_lower_boundary.count(tags[i])) {
        image[tags[i]] = ++next_tag;
        new_tags.push_back(next_tag);
        new_xyz.insert(new_xyz.end(), {p[0], p[1], p[2]});
        continue;
      }
      std::size_t found = 0;
      double best = tol;
      for (int d = 0; d < 27; ++d) {
        const auto it = grid.find(key(p, d % 3 - 1, d / 3 % 3 - 1, d / 9 - 1));
        if (it == grid.end()) continue;
        for (const auto& [t, q] : it->second) {
          if ((q - p).norm() <= best) {
            best = (q - p).norm();
            found = t;
          }
        }
      }
      if (!found) {
        throw MeshError(
            "mesh_tet: a node on the boundary of a lower box face patch has no image "
            "on the upper patch's boundary (normal to " +
            std::string(1, "xyz"[fp.axis]) + ")");
      }
      image[tags[i]] = found;
    }
    std::vector<int> types;
    std::vector<std::vector<std::size_t>> etags, enodes;
    gmsh::model::mesh::getElements(types, etags, enodes, 2, fp.lower);
    std::vector<std::size_t> triangles;
    for (size_t b = 0; b < types.size(); ++b) {
      if (types[b] != 2) throw MeshError("mesh_tet: the surface mesher gave other than triangles");
      for (const std::size_t n : enodes[b]) triangles.push_back(image.at(n));
    }
    std::vector<double> uv;
    if (!new_xyz.empty()) gmsh::model::getParametrization(2, fp.upper, new_xyz, uv);
    gmsh::model::mesh::clear({{2, fp.upper}});
    if (!new_tags.empty()) gmsh::model::mesh::addNodes(2, fp.upper, new_tags, new_xyz, uv);
    gmsh::model::mesh::addElementsByType(fp.upper, 2, {}, triangles);
  }
}

// Flips each of `chords` (edges of triangles flat in a box face) that joins two triangles of
// the surface, one of them with a node off that face: triangles (u, v, w1) and (v, u, w2)
// become (u, w2, w1) and (v, w1, w2). Such an edge is a chord of the face's cut of the surface
// and lies in the face, over the face's own triangles on one side of the cut or the other,
// which the volume mesher refuses ("A segment and a facet intersect", "Two segments
// intersect"); splitting the flat triangle about a node off the face keeps it. Flipped only
// where both new triangles face the way the two old ones do, and the new edge is not one
// already. Returns the edges flipped.
template <class FacesOf>
long long flip_chords(std::vector<std::array<std::size_t, 3>>* triangles,
                      const std::vector<std::array<std::size_t, 2>>& chords,
                      const std::unordered_map<std::size_t, Vec3>& at, const FacesOf& faces_of) {
  auto& tris = *triangles;
  auto key = [](std::size_t a, std::size_t b) {
    return std::make_pair(std::min(a, b), std::max(a, b));
  };
  auto normal = [&](std::size_t a, std::size_t b, std::size_t c) {
    const Vec3 n = (at.at(b) - at.at(a)).cross(at.at(c) - at.at(a));
    return Vec3(n / std::max(n.norm(), 1e-300));
  };
  std::map<std::pair<std::size_t, std::size_t>, std::vector<size_t>> edges;
  for (size_t t = 0; t < tris.size(); ++t) {
    for (int k = 0; k < 3; ++k) edges[key(tris[t][k], tris[t][(k + 1) % 3])].push_back(t);
  }
  long long flipped = 0;
  for (const auto& [u0, v0] : chords) {
    const auto it = edges.find(key(u0, v0));
    if (it == edges.end() || it->second.size() != 2) continue;
    // t1 holds the edge as u -> v, t2 as v -> u.
    size_t t1 = it->second[0], t2 = it->second[1];
    int k1 = 0;
    while (k1 < 3 && !(tris[t1][k1] == u0 || tris[t1][k1] == v0)) ++k1;
    if (tris[t1][(k1 + 1) % 3] != u0 && tris[t1][(k1 + 1) % 3] != v0) k1 = (k1 + 2) % 3;
    const std::size_t u = tris[t1][k1], v = tris[t1][(k1 + 1) % 3], w1 = tris[t1][(k1 + 2) % 3];
    std::size_t w2 = 0;
    for (const std::size_t x : tris[t2]) {
      if (x != u && x != v) w2 = x;
    }
    const int face = faces_of(at.at(u)) & faces_of(at.at(v));
    if ((face & faces_of(at.at(w1)) & faces_of(at.at(w2))) != 0) continue;
    if (edges.count(key(w1, w2))) continue;
    const Vec3 before = normal(u, v, w1) + normal(v, u, w2);
    if (normal(u, w2, w1).dot(before) <= 0.0 || normal(v, w1, w2).dot(before) <= 0.0) continue;
    tris[t1] = {u, w2, w1};
    tris[t2] = {v, w1, w2};
    // The edges' triangles as they are now: u-v is gone, w1-w2 is new, v-w1 moved to t2 and
    // u-w2 to t1.
    edges.erase(key(u, v));
    edges[key(w1, w2)] = {t1, t2};
    std::replace(edges[key(v, w1)].begin(), edges[key(v, w1)].end(), t1, t2);
    std::replace(edges[key(u, w2)].begin(), edges[key(u, w2)].end(), t2, t1);
    ++flipped;
  }
  return flipped;
}

// A curved surface's triangle whose three nodes lie on one box face is flat in that face, over
// the cut the face makes there (the surface meets the face along a curve, and where a strip of
// the surface between the face and another curve is thinner than the elements, the surface
// mesher joins three nodes of that curve). The face's own triangles then lie under it: two
// facets that overlap, which the volume mesher refuses ("Found two exactly self-intersecting
// facets", a 2,500-fibre scene). Each such triangle gets a node on the surface, at the point of
// the surface nearest its centre, and is split into three about it (those whose nearest surface
// point is not inside the box are left); then its edges that are not on a curve are flipped off
// the face (flip_chords; counted in `flipped`). Returns the triangles split.
long long raise_flat_triangles(const Box& box, double tol, long long* flipped) {
  long long raised = 0;
  std::size_t next_tag = 0;
  gmsh::vectorpair surfaces;
  gmsh::model::getEntities(surfaces, 2);
  for (const auto& s : surfaces) {
    std::string type;
    gmsh::model::getType(2, s.second, type);
    if (type == "Plane") continue;
    std::vector<int> types;
    std::vector<std::vector<std::size_t>> etags, enodes;
    gmsh::model::mesh::getElements(types, etags, enodes, 2, s.second);
    std::vector<std::size_t> tags;
    std::vector<double> xyz, param;
    gmsh::model::mesh::getNodes(tags, xyz, param, 2, s.second, true, false);
    std::unordered_map<std::size_t, Vec3> at;
    for (size_t i = 0; i < tags.size(); ++i) {
      at[tags[i]] = Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    }
    // A bit per box face: the faces a point lies on.
    const auto faces_of = [&](const Vec3& p) {
      int bits = 0;
      for (int a = 0; a < 3; ++a) {
        if (std::abs(p[a] - box.origin[a]) <= tol) bits |= 1 << (2 * a);
        if (std::abs(p[a] - box.origin[a] - box.size[a]) <= tol) bits |= 2 << (2 * a);
      }
      return bits;
    };
    // The surface's triangles (Gmsh gives them as one block of type 2), and which lie flat.
    const auto block = std::find(types.begin(), types.end(), 2);
    if (block == types.end()) continue;
    const std::vector<std::size_t>& tri = enodes[block - types.begin()];
    std::vector<char> flat(tri.size() / 3);
    for (size_t e = 0; e < flat.size(); ++e) {
      flat[e] = (faces_of(at[tri[3 * e]]) & faces_of(at[tri[3 * e + 1]]) &
                 faces_of(at[tri[3 * e + 2]])) != 0;
    }
    if (std::find(flat.begin(), flat.end(), 1) == flat.end()) continue;
    if (next_tag == 0) next_tag = largest_node_tag();
    // The surface's own nodes, to put back after its mesh is cleared, and its triangles, with
    // each flat one split about its new node.
    std::vector<std::size_t> own;
    std::vector<double> own_xyz, own_uv;
    gmsh::model::mesh::getNodes(own, own_xyz, own_uv, 2, s.second, false, true);
    std::vector<std::array<std::size_t, 3>> triangles;
    std::vector<std::array<std::size_t, 2>> chords;  // the flat triangles' edges
    for (size_t e = 0; e < flat.size(); ++e) {
      const std::size_t* n = &tri[3 * e];
      bool split = false;
      if (flat[e]) {
        for (int k = 0; k < 3; ++k) chords.push_back({n[k], n[(k + 1) % 3]});
        const Vec3 c = (at[n[0]] + at[n[1]] + at[n[2]]) / 3.0;
        std::vector<double> near, uv;
        gmsh::model::getClosestPoint(2, s.second, {c[0], c[1], c[2]}, near, uv);
        const Vec3 m(near[0], near[1], near[2]);
        const Vec3 lo = m - box.origin, hi = box.origin + box.size - m;
        if (uv.size() == 2 && std::min(lo.minCoeff(), hi.minCoeff()) > tol) {
          own.push_back(++next_tag);
          own_xyz.insert(own_xyz.end(), {m[0], m[1], m[2]});
          own_uv.insert(own_uv.end(), {uv[0], uv[1]});
          at[next_tag] = m;
          for (int k = 0; k < 3; ++k) triangles.push_back({n[k], n[(k + 1) % 3], next_tag});
          split = true;
          ++raised;
        }
      }
      if (!split) triangles.push_back({n[0], n[1], n[2]});
    }
    *flipped += flip_chords(&triangles, chords, at, faces_of);
    gmsh::model::mesh::clear({{2, s.second}});
    if (!own.empty()) gmsh::model::mesh::addNodes(2, s.second, own, own_xyz, own_uv);
    std::vector<std::size_t> flat_list;
    for (const auto& t : triangles) flat_list.insert(flat_list.end(), t.begin(), t.end());
    gmsh::model::mesh::addElementsByType(s.second, 2, {}, flat_list);
  }
  return raised;
}

// The matrix's volume, made of the faces after the box's faces (the first `box_faces` maps of
// `pieces`) were fragmented against the inclusions' pieces (`owner`'s volumes): the faces of the
// box that bound no piece and the pieces' faces that bound one piece only and lie in no box
// face. Its shells are the sets of those faces joined by their curves: the one that holds box
// faces is the outer shell, each other one a hole (an inclusion inside the box). Returns its tag.
int add_matrix(size_t box_faces, const std::vector<gmsh::vectorpair>& pieces,
               const std::map<int, std::pair<int, int32_t>>& owner) {
  std::set<int> on_box;
  for (size_t k = 0; k < box_faces && k < pieces.size(); ++k) {
    for (const auto& dt : pieces[k]) on_box.insert(dt.second);
  }
  std::map<int, int> uses;
  for (const auto& [volume, who] : owner) {
    gmsh::vectorpair faces;
    gmsh::model::getBoundary({{3, volume}}, faces, false, false, false);
    for (const auto& f : faces) ++uses[std::abs(f.second)];
  }
  std::vector<int> faces;
  for (const int f : on_box) {
    if (!uses.count(f)) faces.push_back(f);
  }
  const size_t box_patches = faces.size();
  for (const auto& [f, n] : uses) {
    if (n == 1 && !on_box.count(f)) faces.push_back(f);
  }
  // Shells: faces joined through the curves they share.
  std::vector<int> parent(faces.size());
  for (size_t i = 0; i < faces.size(); ++i) parent[i] = static_cast<int>(i);
  auto root = [&parent](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  std::unordered_map<int, int> face_of_curve;
  for (size_t i = 0; i < faces.size(); ++i) {
    gmsh::vectorpair curves;
    gmsh::model::getBoundary({{2, faces[i]}}, curves, false, false, false);
    for (const auto& c : curves) {
      const auto [it, fresh] = face_of_curve.emplace(std::abs(c.second), static_cast<int>(i));
      if (!fresh) parent[root(static_cast<int>(i))] = root(it->second);
    }
  }
  std::map<int, std::vector<int>> shells;
  for (size_t i = 0; i < faces.size(); ++i) shells[root(static_cast<int>(i))].push_back(faces[i]);
  if (box_patches == 0) throw MeshError("mesh_tet: the inclusions cover the box's faces");
  const int outer = root(0);
  // As they are: Gmsh's fixes would make new faces, and keep one shell of a loop.
  gmsh::option::setNumber("Geometry.OCCAutoFix", 0);
  // (Tagged here: Gmsh 4.8 returns -1 for a loop it numbers itself, and binds it as -1.)
  std::vector<int> loops;
  auto add_loop = [&loops](const std::vector<int>& shell) {
    loops.push_back(gmsh::model::occ::addSurfaceLoop(shell, gmsh::model::occ::getMaxTag(-2) + 1));
  };
  add_loop(shells[outer]);
  for (const auto& [r, shell] : shells) {
    if (r != outer) add_loop(shell);
  }
  const int matrix = gmsh::model::occ::addVolume(loops);
  gmsh::option::setNumber("Geometry.OCCAutoFix", 1);
  gmsh::model::occ::synchronize();
  return matrix;
}

// Gmsh's volume meshers: HXT (parallel, with its own optimiser) and Delaunay (one volume after
// another on one thread, Gmsh's optimiser).
constexpr int kHxt = 10, kDelaunay3d = 1;

// One attempt, with Gmsh's 2D algorithm `surface_algorithm` (6: Frontal-Delaunay, 5: Delaunay)
// and 3D algorithm `volume_algorithm` (kHxt or kDelaunay3d). With curve_chord > 0, the curves
// (the faces' cuts and the shells' rims) are divided as that chord error asks, where it is less
// than options.chord_error; the surfaces and volumes as options ask.
TetMesh mesh_with(const InclusionSet& set, const TetMeshOptions& options,
                  const TetMeshProgress& progress, int surface_algorithm, double curve_chord,
                  const std::vector<int>& frame_rank, int volume_algorithm = kHxt) {
  // Progress by stages, each a span of the whole; inside a long stage the size callback reports
  // too (every 2^16 calls, from the calling thread only: the volume mesher calls it from its
  // own threads as well), creeping towards the stage's end. Once progress returns false the
  // next stage does not start. (Gmsh cannot be interrupted inside a stage: answering the
  // largest size from then on, to end the stage sooner, made the volume stage three times
  // longer.)
  const std::thread::id caller = std::this_thread::get_id();
  std::atomic<bool> stop{false};
  std::atomic<long long> calls{0};
  double stage_from = 0.0, stage_to = 0.0;
  long long stage_calls = 0;
  auto report = [&](double fraction, const std::string& line) {
    if (progress && !progress(fraction, line)) stop = true;
  };
  auto stage = [&](double from, double to, const std::string& line) {
    if (stop) throw Cancelled();
    stage_from = from;
    stage_to = to;
    stage_calls = calls;
    report(from, line);
    if (stop) throw Cancelled();
  };
  const Box& box = set.box;
  const double side = box.size.minCoeff();
  const double max_size = options.largest_size(set.box), min_size = least_size(set, options);

  const int threads =
      std::max(1, options.threads > 0 ? options.threads
                                      : static_cast<int>(std::thread::hardware_concurrency()));

  std::lock_guard<std::mutex> lock(gmsh_mutex);
  GmshSession session;
  TetMesh mesh;
  mesh.box = box;
  mesh.phases = phase_table(set);
  try {
    // OpenCASCADE's boolean operations (the cuts by the cells and the fragment against the box)
    // in parallel when more than one thread is allowed; OpenCASCADE then uses its own pool of
    // all cores, not `threads`.
    // Not with coated ellipsoids: their shells' offset surfaces are evaluated through a cache
    // that OpenCASCADE's parallel booleans share between threads (a crash in
    // Geom_OsculatingSurface while 44 coated ellipsoids were cut by the cells on two threads;
    // made splines, the offsets crashed no more but the cut faces no longer matched their images).
    const bool offsets =
        std::any_of(set.inclusions.begin(), set.inclusions.end(), [](const Inclusion& in) {
          return in.mod.coated() && in.shape.kind == ShapeKind::Ellipsoid;
        });
    gmsh::option::setNumber("Geometry.OCCParallel", threads > 1 && !offsets ? 1 : 0);
    const Vec3 o = box.origin, len = box.size;
    // The box enters the fragment against the pieces as its six faces, not as a solid, and the
    // matrix is made of the faces afterwards: OpenCASCADE classifies every face of the other
    // arguments against each solid argument, and each test against the box, split by the pieces
    // into thousands of faces, explores all of them (2,484 fibres: 173 s, against 21 s for the
    // faces).
    gmsh::vectorpair box_faces;
    {
      const int box_tag = gmsh::model::occ::addBox(o[0], o[1], o[2], len[0], len[1], len[2]);
      gmsh::model::occ::synchronize();
      gmsh::model::getBoundary({{3, box_tag}}, box_faces, false, false, false);
      gmsh::model::occ::remove({{3, box_tag}}, false);
    }
    // Each inclusion's solid is cut by the box and by its shifted copies, and every piece is
    // brought into the box by its shift. A face cut by a box face then lies on both opposite faces
    // as one face and its exact translate, whatever the surface (OpenCASCADE makes spline
    // surfaces of ellipsoids, and the cuts of two translated images by opposite box faces,
    // computed apart, differed by 3 % of their area). Inclusions without a shell that have one
    // image, inside the box, go in as that image. All the others are cut in one boolean operation:
    // the solids (cores, and shells' outer surfaces) against the planes of the cells' faces, a
    // cell being the box moved by minus a shift (Gmsh's bookkeeping of OpenCASCADE's shapes costs
    // in proportion to the shapes it holds at each operation: cut one inclusion at a time, the
    // default scene's 1,269 pieces took 179 s).
    const std::vector<Image> images = images_near(set, 0.0);
    std::map<int, std::vector<Vec3>> shifts_of;
    for (const Image& im : images) shifts_of[im.inc].push_back(im.shift);
    gmsh::vectorpair tools;
    std::vector<int> tool_inc;
    std::vector<int32_t> tool_label;  // the phase of each piece
    const std::vector<int> shell_label =
        interphase_labels(mesh.phases, static_cast<int>(set.family_names.size()));
    const std::vector<int> void_label =
        void_labels(mesh.phases, static_cast<int>(set.family_names.size()));
    gmsh::vectorpair objects;
    std::vector<int> object_inc;
    std::vector<char> object_core;
    std::vector<Vec3> cell_shift;
    std::vector<Image> inside_images;         // made after the cut (see below)
    std::vector<std::pair<int, int>> to_cut;  // (inclusion, bit a: it crosses planes normal to a)
    for (const auto& [inc, shifts] : shifts_of) {
      const Inclusion& in = set.inclusions[inc];
      // (The cell is the box moved off the inclusions it would graze, so many of those inside
      // it are images.)
      Vec3 lo, hi;
      outer_aabb(in, &lo, &hi);
      const Vec3& t0 = shifts.front();
      const bool inside = shifts.size() == 1 && (lo + t0 - o).minCoeff() > 0.0 &&
                          (o + len - hi - t0).minCoeff() > 0.0;
      if (inside && !in.mod.coated() && !in.mod.debonded()) {
        inside_images.push_back({inc, t0});
        continue;
      }
      // The axes along which its images lie in more than one cell: the planes it crosses.
      int axes = 0;
      for (const Vec3& t : shifts) {
        for (int a = 0; a < 3; ++a) axes |= t[a] != t0[a] ? 1 << a : 0;
        if (std::find(cell_shift.begin(), cell_shift.end(), t) == cell_shift.end()) {
          cell_shift.push_back(t);
        }
      }
      to_cut.push_back({inc, axes});
    }
    if (!to_cut.empty()) {
      // The solids are cut by the planes of the cells' faces, entered as faces (squares wider
      // than the cells): with the cells as solids, OpenCASCADE classified every face of the
      // solids against each cell, split by the solids into hundreds of faces. Each piece goes to
      // the cell that holds its centre of mass (a piece lies in one cell, and its centre of mass
      // inside its convex hull).
      std::set<std::pair<int, long>> plane_at;  // (axis, k): the plane x_axis = o + k len
      for (const Vec3& t : cell_shift) {
        for (int a = 0; a < 3; ++a) {
          const long k = std::lround(-t[a] / len[a]);
          plane_at.insert({a, k});
          plane_at.insert({a, k + 1});
        }
      }
      // The solids of an inclusion (its core, and its shell's outer surface and its void);
      // map[k]: the pieces of objects[k] so far.
      std::vector<gmsh::vectorpair> map;
      auto make_solids = [&](int inc) {
        const Inclusion& in = set.inclusions[inc];
        const bool cone = in.mod.debonded() && in.mod.debond_fraction < 1.0;
        const Mat3 axis_frame = cone ? void_frame(in, box) : Mat3::Identity();
        objects.push_back(
            {3, add_solid(in.shape, box, 0.0, cone ? &axis_frame : nullptr, frame_rank[inc])});
        object_inc.push_back(inc);
        object_core.push_back(1);
        if (in.mod.coated()) {
          objects.push_back(
              {3, add_solid(in.shape, box, in.mod.coating, nullptr, frame_rank[inc])});
          object_inc.push_back(inc);
          object_core.push_back(0);
        }
        if (in.mod.debonded()) {
          objects.push_back({3, add_void_solid(in, box)});
          object_inc.push_back(inc);
          object_core.push_back(2);
        }
        while (map.size() < objects.size()) map.push_back({objects[map.size()]});
      };
      // Fragments the present pieces of objects[from, to) against the planes normal to the
      // axes of `axes` (bits).
      auto cut = [&](size_t from, size_t to, int axes) {
        gmsh::vectorpair present;  // each once (a shell's pieces hold its core's)
        std::set<int> seen;
        for (size_t k = from; k < to; ++k) {
          for (const auto& dt : map[k]) {
            if (seen.insert(dt.second).second) present.push_back(dt);
          }
        }
        if (present.empty()) return;
        gmsh::vectorpair planes;
        for (const auto& [a, k] : plane_at) {
          if (!(axes & (1 << a))) continue;
          const int b = (a + 1) % 3, c = (a + 2) % 3;
          int corner[4];
          for (int q = 0; q < 4; ++q) {
            Vec3 p;
            p[a] = o[a] + static_cast<double>(k) * len[a];
            p[b] = o[b] + ((q == 1 || q == 2) ? 3.0 : -2.0) * len[b];
            p[c] = o[c] + (q >= 2 ? 3.0 : -2.0) * len[c];
            corner[q] = gmsh::model::occ::addPoint(p[0], p[1], p[2]);
          }
          std::vector<int> sides;
          for (int q = 0; q < 4; ++q) {
            sides.push_back(gmsh::model::occ::addLine(corner[q], corner[(q + 1) % 4]));
          }
          planes.push_back(
              {2, gmsh::model::occ::addPlaneSurface({gmsh::model::occ::addCurveLoop(sides)})});
        }
        gmsh::vectorpair out;
        std::vector<gmsh::vectorpair> out_map;
        gmsh::model::occ::fragment(present, planes, out, out_map);
        std::map<int, const gmsh::vectorpair*> became;
        for (size_t i = 0; i < present.size() && i < out_map.size(); ++i) {
          became[present[i].second] = &out_map[i];
        }
        for (size_t k = from; k < to; ++k) {
          gmsh::vectorpair now;
          for (const auto& dt : map[k]) {
            for (const auto& n : *became.at(dt.second)) {
              if (std::find(now.begin(), now.end(), n) == now.end()) now.push_back(n);
            }
          }
          map[k] = std::move(now);
        }
        // The planes' pieces (those that bound a piece stay, as its faces): a later fragment
        // forgets the faces of the pieces it cuts.
        gmsh::vectorpair rest;
        for (const auto& dt : out) {
          if (dt.first == 2) rest.push_back(dt);
        }
        gmsh::model::occ::remove(rest, false);
      };
      // With the planes of two axes in one fragment, OpenCASCADE left an ellipsoid (a spline
      // surface) through which the line where two planes meet passes split by one of them only
      // (the default scene's cell, an ellipsoid across its x and z faces: its cap stood out of
      // the cell). The solids that cross planes of two or three axes are cut one axis at a time
      // (parallel planes never meet), and first, while the model holds little (each fragment
      // costs about 3 s for 2,484 fibres whatever it cuts, in Gmsh's bookkeeping of the
      // shapes it holds); the others are cut by all the planes at once.
      auto across = [](int axes) { return (axes & (axes - 1)) != 0; };
      for (const auto& [inc, axes] : to_cut) {
        if (across(axes)) make_solids(inc);
      }
      const size_t first = objects.size();
      for (int a = 0; a < 3; ++a) {
        // (Each pass takes every one of them: a solid it does not cut keeps its pieces.)
        cut(0, first, 1 << a);
      }
      for (const auto& [inc, axes] : to_cut) {
        if (!across(axes)) make_solids(inc);
      }
      cut(first, objects.size(), 7);
      // Each piece of a solid belongs to the first inclusion whose solids hold it (where shells
      // that may touch overlap), and is a core's when one of that inclusion's cores holds it.
      std::map<int, int> piece_inc;
      std::set<int> core_piece, void_piece;
      for (size_t k = 0; k < objects.size() && k < map.size(); ++k) {
        for (const auto& dt : map[k]) {
          const int owner_inc = piece_inc.emplace(dt.second, object_inc[k]).first->second;
          if (owner_inc != object_inc[k]) continue;
          if (object_core[k] == 1) core_piece.insert(dt.second);
          if (object_core[k] == 2) void_piece.insert(dt.second);
        }
      }
      std::map<std::array<long, 3>, gmsh::vectorpair> to_move;  // by the cell's index
      for (const auto& [piece, inc] : piece_inc) {
        double com[3];
        gmsh::model::occ::getCenterOfMass(3, piece, com[0], com[1], com[2]);
        std::array<long, 3> cell;
        for (int a = 0; a < 3; ++a) cell[a] = std::lround(std::floor((com[a] - o[a]) / len[a]));
        const Inclusion& in = set.inclusions[inc];
        to_move[cell].push_back({3, piece});
        tools.push_back({3, piece});
        tool_inc.push_back(inc);
        tool_label.push_back(core_piece.count(piece)   ? core_label(in.family)
                             : void_piece.count(piece) ? void_label[in.family]
                                                       : shell_label[in.family]);
      }
      for (const auto& [cell, mine] : to_move) {
        const Vec3 t(-cell[0] * len[0], -cell[1] * len[1], -cell[2] * len[2]);
        if (!t.isZero()) gmsh::model::occ::translate(mine, t[0], t[1], t[2]);
      }
      // The curves and points the planes' pieces left unused (removed with their curves, the
      // planes' pieces took 17 s: for each curve and point of them, Gmsh scans every face and
      // curve it holds).
      gmsh::model::occ::synchronize();
      gmsh::vectorpair curves, unused;
      gmsh::model::getEntities(curves, 1);
      for (const auto& e : curves) {
        std::vector<int> up, down;
        gmsh::model::getAdjacencies(e.first, e.second, up, down);
        if (up.empty()) unused.push_back(e);
      }
      gmsh::model::occ::remove(unused, true);
    }
    // Gmsh's bookkeeping after a boolean operation scans, for each shape of its inputs, every
    // shape it holds: the inclusions inside the box are made after the cut (2,484 fibres: the
    // cut's fragment took 76 s with the 1,699 made before, 11 s after).
    for (const Image& im : inside_images) {
      const Inclusion& in = set.inclusions[im.inc];
      Shape image = in.shape;
      image.center += im.shift;
      tools.push_back({3, add_inside_solid(image, box, frame_rank[im.inc])});
      tool_inc.push_back(im.inc);
      tool_label.push_back(core_label(in.family));
    }
    stage(0.0, 0.15,
          "mesh_tet: fragmenting " + std::to_string(tools.size()) +
              " inclusion pieces against the box");
    gmsh::vectorpair out;
    std::vector<gmsh::vectorpair> pieces;
    gmsh::model::occ::fragment(box_faces, tools, out, pieces);
    gmsh::model::occ::synchronize();
    // Which inclusion and phase each volume belongs to (the pieces of tool k; where shells
    // that may touch overlap, the first).
    const size_t first_tool = box_faces.size();
    std::map<int, std::pair<int, int32_t>> owner;
    for (size_t k = 0; k < tools.size() && first_tool + k < pieces.size(); ++k) {
      for (const auto& dt : pieces[first_tool + k]) {
        owner.emplace(dt.second, std::make_pair(tool_inc[k], tool_label[k]));
      }
    }
    add_matrix(box_faces.size(), pieces, owner);
    // The faces at the upper end of each axis mesh as translated copies of those at the lower
    // end (tie_face_curves, copy_face_meshes): matched by bounding box and area. The patches of a
    // box face are the planes whose normal is the axis and whose centre of mass lies in the face
    // (OpenCASCADE's bounding boxes of patches bounded by spline curves stand out of the plane by
    // the curves' tolerance).
    const double tol = 1e-6 * side;
    gmsh::vectorpair surfaces;
    gmsh::model::getEntities(surfaces, 2);
    std::vector<FacePair> face_pairs;
    for (int a = 0; a < 3; ++a) {
      std::vector<std::pair<int, std::array<double, 7>>> lower, upper;
      for (const auto& s : surfaces) {
        std::string type;
        gmsh::model::getType(2, s.second, type);
        if (type != "Plane") continue;
        double com[3];
        gmsh::model::occ::getCenterOfMass(2, s.second, com[0], com[1], com[2]);
        for (int end = 0; end < 2; ++end) {
          const double v = o[a] + (end ? len[a] : 0.0);
          if (std::abs(com[a] - v) > tol) continue;
          std::vector<double> lo, hi, normal;
          gmsh::model::getParametrizationBounds(2, s.second, lo, hi);
          gmsh::model::getNormal(s.second, {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])}, normal);
          if (normal.size() < 3 || std::abs(std::abs(normal[a]) - 1.0) > 1e-9) continue;
          double b[6];
          gmsh::model::getBoundingBox(2, s.second, b[0], b[1], b[2], b[3], b[4], b[5]);
          std::array<double, 7> key;
          for (int k = 0; k < 6; ++k) key[k] = b[k];
          gmsh::model::occ::getMass(2, s.second, key[6]);
          (end ? upper : lower).push_back({s.second, key});
        }
      }
      if (upper.size() != lower.size()) {
        throw MeshError("mesh_tet: the box faces normal to " + std::string(1, "xyz"[a]) +
                        " were cut into " + std::to_string(lower.size()) + " and " +
                        std::to_string(upper.size()) + " patches");
      }
      std::set<int> used;
      for (const auto& [tag, key] : upper) {
        // The lower patch nearest to this one's image, each taken once (OpenCASCADE's centres of
        // mass and areas of small patches differ from their images' by up to about 1e-5 of the
        // box and of their area: matched within 1e-3).
        int match = -1;
        double best = 1e300;
        for (const auto& [ltag, lkey] : lower) {
          double d = 0.0;
          for (int k = 0; k < 6; ++k) {
            d = std::max(d, std::abs(key[k] - (k % 3 == a ? len[a] : 0.0) - lkey[k]) / side);
          }
          d = std::max(d, std::abs(key[6] - lkey[6]) / std::max(key[6], 1e-6 * side * side));
          if (d < best) {
            best = d;
            match = ltag;
          }
        }
        if (best > 1e-3 || !used.insert(match).second) match = -1;
        if (match < 0) {
          throw MeshError("mesh_tet: a patch of the upper box face normal to " +
                          std::string(1, "xyz"[a]) + " has no image on the lower face");
        }
        face_pairs.push_back({tag, match, a});
      }
    }
    tie_face_curves(face_pairs, len, tol);
    // The fragment can leave a curve inside a box face's patch, not on its boundary, which Gmsh
    // then meshes with the patch as an edge its triangles must follow: a line of 8.8e-6 that
    // continued a face's cut of a fibre's end disk past the mantle's cut (the face met the disk
    // near its rim). Inside an upper patch, whose triangles are the lower one's translate, it
    // was a line the volume mesher could not recover ("failed to recover constrained
    // lines/triangles") or, recovered, a node with no image on the lower face. The patches
    // follow their boundaries only.
    for (const FacePair& fp : face_pairs) {
      gmsh::model::mesh::removeEmbedded({{2, fp.upper}, {2, fp.lower}});
    }

    const SizeField size(set, options, max_size, min_size);
    TetMeshOptions curve_options = options;
    std::optional<SizeField> curve_size;
    if (curve_chord > 0.0 && curve_chord < options.chord_error) {
      curve_options.chord_error = curve_chord;
      curve_size.emplace(set, curve_options, max_size, min_size);
    }
    gmsh::model::mesh::setSizeCallback([&](int dim, int, double x, double y, double z) {
      const long long n = ++calls;
      if (n % 65536 == 0 && !stop && std::this_thread::get_id() == caller) {
        const double done = static_cast<double>(n - stage_calls);
        report(stage_from + (stage_to - stage_from) * done / (done + 4e6), "");
      }
      return dim == 1 && curve_size ? (*curve_size)(Vec3(x, y, z)) : size(Vec3(x, y, z));
    });
    gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
    // Gmsh places a curve's nodes by integrating 1 / size along it, splitting each interval
    // until two estimates agree within this precision (in elements; Gmsh's default 1e-9). At
    // the default the curves of 2,484 fibres took 21 s, nearly all of it in the size callback;
    // at 1e-5, 2.4 s, with 983,491 surface nodes against 983,863.
    gmsh::option::setNumber("Mesh.LcIntegrationPrecision", 1e-5);
    gmsh::option::setNumber("Mesh.MeshSizeMax", max_size);
    gmsh::option::setNumber("Mesh.MeshSizeMin", min_size);
    gmsh::option::setNumber("Mesh.Algorithm", surface_algorithm);
    gmsh::option::setNumber("Mesh.Algorithm3D", volume_algorithm);
    gmsh::option::setNumber("Mesh.Optimize", options.optimize_threshold > 0.0 ? 1 : 0);
    gmsh::option::setNumber("Mesh.OptimizeThreshold", options.optimize_threshold);
    gmsh::option::setNumber("General.NumThreads", threads);
    gmsh::option::setNumber("Mesh.MeshOnlyVisible", 0);
    gmsh::option::setNumber("Mesh.MeshOnlyEmpty", 0);
    // Gmsh's errors are logged, not thrown, while it meshes: thrown inside its parallel loops
    // (a surface whose periodic copy fails), they would end the process. The log is read after
    // each stage.
    gmsh::option::setNumber("General.AbortOnError", 0);
    // (Gmsh's logger is not safe from its threads, so the last error is compared instead; Gmsh
    // clears it when it starts meshing.)
    std::string known;
    gmsh::logger::getLastError(known);
    auto logged_error = [&known] {
      std::string e;
      gmsh::logger::getLastError(e);
      if (e.empty() || e == known) return std::string();
      known = e;
      return e;
    };
    stage(0.15, 0.35, "mesh_tet: meshing the surfaces");
    // The curves and the lower box-face patches first, then their copies on the upper patches,
    // then the other surfaces. Each copy adds its triangles through Gmsh's API, which looks
    // their nodes up in a cache of the model's nodes, rebuilt after each call by walking every
    // entity and node: made with every surface meshed, the 934 copies of 2,484 fibres took
    // 18 s; made before the other surfaces, 12 s (the entities' walk is what is left).
    // Gmsh meshes only the visible surfaces in the first pass, and only those without elements
    // afterwards: the patches are left pending, so the volume stage runs the surface mesher
    // again, which must leave them too.
    std::set<int> lower_patches;
    for (const FacePair& fp : face_pairs) lower_patches.insert(fp.lower);
    gmsh::vectorpair hidden;
    for (const auto& s : surfaces) {
      if (!lower_patches.count(s.second)) hidden.push_back(s);
    }
    gmsh::model::setVisibility(hidden, 0, false);
    gmsh::option::setNumber("Mesh.MeshOnlyVisible", 1);
    gmsh::model::mesh::generate(2);
    gmsh::option::setNumber("Mesh.MeshOnlyVisible", 0);
    gmsh::model::setVisibility(hidden, 1, false);
    std::string surface_error = logged_error();
    if (surface_error.empty()) {
      copy_face_meshes(face_pairs, len, tol);
      gmsh::option::setNumber("Mesh.MeshOnlyEmpty", 1);
      gmsh::model::mesh::generate(2);
      surface_error = logged_error();
    }
    // The inclusions whose surfaces bound the curves a message names ("curve N"): the
    // surfaces about a curve's mesh that has no periodic counterpart.
    auto named_inclusions = [&owner](const std::string& e) {
      std::set<int> at;
      for (size_t k = e.find("curve "); k != std::string::npos; k = e.find("curve ", k + 6)) {
        const char* digits = e.c_str() + k + 6;
        char* end = nullptr;
        const long curve = std::strtol(digits, &end, 10);
        if (end == digits || curve <= 0) continue;
        std::vector<int> faces, ends;
        gmsh::model::getAdjacencies(1, static_cast<int>(curve), faces, ends);
        for (const int f : faces) {
          std::vector<int> volumes, edges;
          gmsh::model::getAdjacencies(2, f, volumes, edges);
          for (const int v : volumes) {
            const auto it = owner.find(v);
            if (it != owner.end()) at.insert(it->second.first);
          }
        }
      }
      return std::vector<int>(at.begin(), at.end());
    };
    if (const std::string& e = surface_error; !e.empty()) {
      // Where Gmsh fails on a curved surface it refines every curve around it and meshes it
      // again; a curve tied to its image on the opposite face then has nodes its image lacks.
      const bool refined_copy = e.find("periodic counterpart") != std::string::npos &&
                                e.find("curve") != std::string::npos;
      throw SurfacesRefused(
          "the surface mesher failed: " + e +
              (refined_copy ? " (Gmsh refined the curves of a curved surface it could not "
                              "mesh, one of them a copy of a curve on the opposite box "
                              "face: try a smaller mesh_tet.chord_error)"
                            : ""),
          named_inclusions(e));
    }
    mesh.raised_triangles = raise_flat_triangles(box, tol, &mesh.flipped_chords);
    stage(0.35, 0.85, "mesh_tet: meshing the volumes");
    gmsh::model::mesh::generate(3);
    gmsh::option::setNumber("Mesh.MeshOnlyEmpty", 0);
    // A volume left without elements is a failure even when the last error reads as the one
    // before (the second attempt's refusal repeats the first's words).
    std::string refused = logged_error();
    gmsh::vectorpair volumes_meshed;
    gmsh::model::getEntities(volumes_meshed, 3);
    for (const auto& v : volumes_meshed) {
      std::vector<int> types;
      gmsh::model::mesh::getElementTypes(types, 3, v.second);
      if (refused.empty() && types.empty()) refused = last_gmsh_error();
    }
    if (const std::string& e = refused; !e.empty()) {
      throw SurfacesRefused("the volume mesher refused the surfaces: " + e, named_inclusions(e));
    }
    // (The elements HXT's optimiser leaves under 5 degrees are lifted by repair_slivers below.
    // Gmsh's node relocation (Relocate3D) before it changed nothing it leaves: the same least
    // angle before the repair, the same 1, 5 and 50 % quantiles after it, for 12 s on 2,484
    // fibres and 5.6 s on the default scene.)

    // Nodes (renumbered from 0), then the tetrahedra of every volume with its phase.
    std::vector<std::size_t> tags;
    std::vector<double> xyz, param;
    gmsh::model::mesh::getNodes(tags, xyz, param);
    std::unordered_map<std::size_t, int32_t> index;
    index.reserve(tags.size());
    mesh.nodes.resize(tags.size());
    for (size_t i = 0; i < tags.size(); ++i) {
      index[tags[i]] = static_cast<int32_t>(i);
      mesh.nodes[i] = Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    }
    gmsh::vectorpair volumes;
    gmsh::model::getEntities(volumes, 3);
    for (const auto& v : volumes) {
      const auto it = owner.find(v.second);
      const int inc = it == owner.end() ? -1 : it->second.first;
      const int32_t label = inc < 0 ? 0 : it->second.second;
      const int32_t id = inc < 0 ? -1 : set.inclusions[inc].id;
      std::vector<int> types;
      std::vector<std::vector<std::size_t>> etags, enodes;
      gmsh::model::mesh::getElements(types, etags, enodes, 3, v.second);
      for (size_t b = 0; b < types.size(); ++b) {
        if (types[b] != 4)
          throw MeshError("mesh_tet: the mesher gave elements other than tetrahedra");
        for (size_t e = 0; e < etags[b].size(); ++e) {
          std::array<int32_t, 4> t;
          for (int c = 0; c < 4; ++c) t[c] = index.at(enodes[b][4 * e + c]);
          if (tet_volume(mesh.nodes, t) < 0.0) std::swap(t[2], t[3]);
          mesh.tets.push_back(t);
          mesh.phase.push_back(label);
          mesh.inclusion_id.push_back(id);
        }
      }
    }
  } catch (const MeshError&) {
    throw;
  } catch (const Cancelled&) {
    throw;
  } catch (const std::exception& e) {
    // Ours (a callback's) or Gmsh's: the message says which.
    throw MeshError(std::string("mesh_tet: the mesher failed: ") + e.what());
  } catch (...) {
    throw MeshError("mesh_tet: the mesher failed: " + last_gmsh_error());
  }

  stage(0.85, 1.0, "mesh_tet: checking the mesh");
  if (mesh.tets.empty()) throw MeshError("mesh_tet: the volume mesher made no elements");
  mesh.snapped_nodes = snap_periodic_nodes(&mesh);
  mesh.merged_nodes = merge_coincident_nodes(&mesh);
  mesh.flat_elements_removed = remove_flat_face_elements(&mesh);
  if (options.keep_volumes) mesh.moved_nodes = keep_phase_volumes(&mesh, set);
  mesh.sliver_rounds = repair_slivers(&mesh, set);
  check_conforming(mesh);
  if (options.order == 2) add_midside_nodes(&mesh);

  // Periodic pairs by coordinates: every node with a coordinate at an upper end, and the node
  // at its coordinates brought to the lower ends, within 3e-9 of the side (the reach of the
  // rounded keys that found it before; snap_periodic_nodes has put the corners exactly).
  for (const auto& [i, master] : lower_images(mesh, 1e-9 * side, 3e-9 * side)) {
    if (master < 0) {
      const Vec3& y = mesh.nodes[i];
      throw MeshError("mesh_tet: the node at (" + std::to_string(y[0]) + ", " +
                      std::to_string(y[1]) + ", " + std::to_string(y[2]) +
                      "), on an upper box face, has no image on the lower faces");
    }
    mesh.periodic.push_back({i, master});
  }
  report(1.0, "mesh_tet: " + std::to_string(mesh.tets.size()) +
                  (mesh.mid.empty() ? " tetrahedra, " : " 10-node tetrahedra, ") +
                  std::to_string(mesh.nodes.size()) + " nodes" +
                  (mesh.merged_nodes
                       ? " (" + std::to_string(mesh.merged_nodes) + " coincident nodes merged)"
                       : ""));
  return mesh;
}

}  // namespace

namespace {

// What a face normal to axis a should keep clear of, each with the length its clearance is
// measured in: the extremes along the axis of every sphere and ellipsoid, in units of its least
// size, and of both rims of every cylinder, in units of its radius (near them a face cuts a
// thin cap, or a thin strip of the mantle along the rim); the span along the axis of every
// cylinder end disk tilted by less than kSteepDisk from the face (a face crossing such a disk
// cuts a wedge that thin); and the span along the axis of the two lines of every cylinder's
// mantle furthest along a, where its axis is tilted by less than kShallowMantle from the face:
// a face within such a span is tangent to the mantle where it crosses the line, and cuts a
// wedge as thin as the tilt (a fibre 4.3 degrees off the face left six elements of 3.2-3.9
// degrees there). A face crossing a disk at 22 degrees, 0.2 radius from its centre, cut off a
// chip of the end a fifth of the radius thick, which left four elements of 2.1-4.7 degrees at
// chord error 0.1 (2,484 fibres): hence 30 degrees for kSteepDisk.
struct Extremes {
  std::vector<double> at, half, size;  // centre and half width of each span, its length unit
};
constexpr double kSteepDisk = 30.0 * M_PI / 180.0;
constexpr double kShallowMantle = 8.0 * M_PI / 180.0;
Extremes extremes(const InclusionSet& set, int a, bool disks = true,
                  double mantle_tilt = kShallowMantle) {
  Extremes e;
  auto add = [&](double at, double half, double size) {
    e.at.push_back(at);
    e.half.push_back(half);
    e.size.push_back(size);
  };
  for (const Inclusion& inc : set.inclusions) {
    const Shape& s = inc.shape;
    const double t =
        outer_offset(inc.mod);  // a shell's or void's outer surface: the core's extremes moved out
    if (s.kind != ShapeKind::Cylinder) {
      Vec3 lo, hi;
      s.aabb(&lo, &hi);
      add(lo[a], 0.0, s.min_size());
      add(hi[a], 0.0, s.min_size());
      if (t > 0.0) {
        add(lo[a] - t, 0.0, s.min_size() + t);
        add(hi[a] + t, 0.0, s.min_size() + t);
      }
      // A debonded sphere's void ends on a cone whose apex is the centre: a face through the
      // apex at the cone's angle would lie along it (a face nearly so, through the centre of a
      // sphere debonded over 0.3 of its surface, left 78 elements under 5 degrees, least 1.4,
      // along the cut); a face kept off the centre cuts the cone at an angle.
      // Its two rims (the cone's circles at r and r + gap) too: a face grazing a rim leaves a
      // sliver of surface between them (0.001 r from the inner rim, elements of 1.5 degrees).
      if (inc.mod.debonded() && inc.mod.debond_fraction < 1.0) {
        add(s.center[a], 0.0, s.radius);
        const Vec3& u = inc.mod.debond_axis;
        const double cos_cap = inc.mod.debond_cos_cap();
        const double sin_cap = std::sqrt(std::max(0.0, 1.0 - cos_cap * cos_cap));
        const double across = std::sqrt(std::max(0.0, 1.0 - u[a] * u[a]));
        for (const double rho : {s.radius, s.radius + t}) {
          add(s.center[a] + rho * cos_cap * u[a] - rho * sin_cap * across, 0.0, s.radius);
          add(s.center[a] + rho * cos_cap * u[a] + rho * sin_cap * across, 0.0, s.radius);
        }
      }
      continue;
    }
    const Vec3 u = s.half_axis.normalized();
    const double across = std::sqrt(std::max(0.0, 1.0 - u[a] * u[a]));
    const double half = s.radius * across;
    if (std::abs(u[a]) < std::sin(mantle_tilt)) {
      // The mantle's two lines furthest along a (and the shell's, of radius r + t), each over
      // the fibre's extent along a.
      const double span = std::abs(s.half_axis[a]);
      for (const double side : {-1.0, 1.0}) {
        add(s.center[a] + side * half, span, s.radius);
        if (t > 0.0) add(s.center[a] + side * (s.radius + t) * across, span, s.radius + t);
      }
    }
    for (const double end : {s.center[a] - s.half_axis[a], s.center[a] + s.half_axis[a]}) {
      add(end - half, 0.0, s.radius);
      add(end + half, 0.0, s.radius);
      if (disks && std::abs(u[a]) >= std::cos(kSteepDisk)) add(end, half, s.radius);
      if (t > 0.0) {
        add(end - half - t, 0.0, s.radius + t);
        add(end + half + t, 0.0, s.radius + t);
      }
    }
  }
  return e;
}

// The least clearance of a face at position z (mod the side) along one axis.
double clearance_at(const Extremes& e, double z, double side) {
  double least = 1e300;
  for (size_t k = 0; k < e.at.size(); ++k) {
    double d = std::fmod(std::abs(e.at[k] - z), side);
    d = std::max(0.0, std::min(d, side - d) - e.half[k]);
    least = std::min(least, d / e.size[k]);
  }
  return least;
}

// A position (mod side) whose clearance is at least t, if one exists: the first point the
// intervals (x - t size, x + t size) around the extremes leave uncovered.
bool uncovered(const Extremes& e, double t, double side, double* z) {
  std::vector<std::pair<double, double>> iv;
  for (size_t k = 0; k < e.at.size(); ++k) {
    const double r = e.half[k] + t * e.size[k];
    if (2.0 * r >= side) return false;
    const double a = e.at[k] - r - side * std::floor((e.at[k] - r) / side), b = a + 2.0 * r;
    if (b <= side) {
      iv.push_back({a, b});
    } else {
      iv.push_back({a, side});
      iv.push_back({0.0, b - side});
    }
  }
  std::sort(iv.begin(), iv.end());
  double reach = 0.0;
  for (const auto& [a, b] : iv) {
    if (a > reach) {
      *z = 0.5 * (reach + a);
      return true;
    }
    reach = std::max(reach, b);
  }
  if (reach < side) {
    *z = 0.5 * (reach + side);
    return true;
  }
  return false;
}

// The positions o + k side (k integer) within [lo, hi].
std::vector<double> positions(double o, double side, double lo, double hi) {
  std::vector<double> out;
  for (double f = o + side * std::ceil((lo - o) / side); f <= hi; f += side) out.push_back(f);
  return out;
}

// The clearance of the line through (fa, fb) along axis c (a box edge) from a shape's surface:
// how far the line is from grazing it, in the shape's length unit. Spheres and ellipsoids: the
// distance of the point from the outline of the shape's shadow along c (for ellipsoids, along
// the ray from the centre, times the shadow's least semi-axis); cylinders: from the mantle (the
// distance of the line to the axis against the radius, where it passes along the fibre's
// length) and from both rims (where the line meets an end disk's plane).
double line_clearance(const Shape& s, int a, int b, int c, double fa, double fb) {
  const double pa = fa - s.center[a], pb = fb - s.center[b];
  switch (s.kind) {
    case ShapeKind::Sphere:
      return std::abs(std::hypot(pa, pb) - s.radius) / s.radius;
    case ShapeKind::Ellipsoid: {
      const Mat3 M = s.rotation * s.semi_axes.asDiagonal();
      const Mat3 S = M * M.transpose();
      Eigen::Matrix2d shadow;
      shadow << S(a, a), S(a, b), S(b, a), S(b, b);
      const Eigen::Vector2d p(pa, pb);
      const double q = std::sqrt(p.dot(shadow.inverse() * p));
      const double least = std::sqrt(
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(shadow).eigenvalues().minCoeff());
      return std::abs(q - 1.0) * least / s.min_size();
    }
    case ShapeKind::Cylinder: {
      const double r = s.radius, hl = s.half_axis.norm();
      const Vec3 u = s.half_axis / hl;
      Vec3 e = Vec3::Zero(), d0 = Vec3::Zero();
      e[c] = 1.0;
      d0[a] = pa;
      d0[b] = pb;
      double best = 1e300;
      const Vec3 w = e.cross(u);
      if (w.squaredNorm() > 1e-18) {
        const double t = (d0.dot(u) - d0.dot(e) * u.dot(e)) / w.squaredNorm();
        if (std::abs(t) <= hl) best = std::abs(std::abs(d0.dot(w)) / w.norm() - r) / r;
      } else {
        best = std::abs(std::hypot(pa, pb) - r) / r;
      }
      if (std::abs(u[c]) > 1e-9) {
        for (const double sign : {-1.0, 1.0}) {
          const Vec3 end = sign * s.half_axis;  // from the centre
          const Vec3 at = d0 + ((end - d0).dot(u) / u[c]) * e;
          best = std::min(best, std::abs((at - end).norm() - r) / r);
        }
      }
      return best;
    }
  }
  return 1e300;
}

// The length an inclusion's moves off the cell's faces are counted in: a cylinder's radius, the
// least size of other shapes.
double size_of(const Inclusion& inc) {
  return inc.shape.kind == ShapeKind::Cylinder ? inc.shape.radius : inc.shape.min_size();
}

}  // namespace

double face_clearance(const InclusionSet& set, const Vec3& origin) {
  double least = 1e300;
  for (int a = 0; a < 3; ++a) {
    least = std::min(least, clearance_at(extremes(set, a), origin[a], set.box.size[a]));
  }
  return least;
}

double edge_clearance(const InclusionSet& set, const Vec3& origin) {
  const Vec3& len = set.box.size;
  double least = 1e300;
  for (const Inclusion& inc : set.inclusions) {
    const Shape& s = inc.shape;
    const double t = outer_offset(inc.mod);
    Vec3 lo, hi;
    outer_aabb(inc, &lo, &hi);
    // A shell's outer surface, as a shape: the sphere grown by t; for a cylinder, the one of
    // radius r + t and half length l + t that holds it (its rims are rounded); for an
    // ellipsoid, the one of semi-axes a + t.
    Shape grown = s;
    if (t > 0.0) {
      grown.radius += t;
      if (s.kind == ShapeKind::Cylinder) grown.half_axis *= 1.0 + t / s.half_axis.norm();
      // An ellipsoid's offset, by the ellipsoid of semi-axes a + t: they agree at the ends of
      // the axes, and its shadow's outline is within t of the offset's (a clearance, not a size).
      if (s.kind == ShapeKind::Ellipsoid) grown.semi_axes.array() += t;
    }
    std::vector<double> at[3];
    for (int a = 0; a < 3; ++a) at[a] = positions(origin[a], len[a], lo[a], hi[a]);
    for (int c = 0; c < 3; ++c) {
      const int a = (c + 1) % 3, b = (c + 2) % 3;
      for (const double fa : at[a]) {
        for (const double fb : at[b]) {
          least = std::min(least, line_clearance(s, a, b, c, fa, fb));
          if (t > 0.0) least = std::min(least, line_clearance(grown, a, b, c, fa, fb));
        }
      }
    }
    if (at[0].empty() || at[1].empty() || at[2].empty()) continue;
    const BodyQuery query(inc);
    const double unit = s.kind == ShapeKind::Cylinder ? s.radius : s.min_size();
    for (const double x : at[0]) {
      for (const double y : at[1]) {
        for (const double z : at[2]) {
          const double d = query.core_distance(Vec3(x, y, z));
          least = std::min(least, std::abs(d) / unit);
          if (t > 0.0) least = std::min(least, std::abs(d - t) / (unit + t));
        }
      }
    }
  }
  return least;
}

Vec3 cell_origin(const InclusionSet& set) {
  const Vec3 box = set.box.origin;
  if (set.inclusions.empty() ||
      std::min(face_clearance(set, box), edge_clearance(set, box)) >= kGoodClearance) {
    return box;
  }
  // Per axis, a few positions of large face clearance: the box's own, the best (by bisection
  // on the clearance), and the best of an even sampling, each at least a 64th of the side from
  // the others.
  constexpr int kSamples = 512, kKeep = 6;
  std::vector<std::pair<double, double>> candidates[3];  // (face clearance, position)
  for (int a = 0; a < 3; ++a) {
    Extremes e = extremes(set, a);
    const double side = set.box.size[a];
    double z = box[a];
    // Where the spans of shallow mantles cover the axis, those of the least shallow are let go
    // first (2 degrees at a time); then those of steep disks.
    for (int with_disks = 1; with_disks >= 0; --with_disks) {
      for (int tilt = 8; tilt >= 0 && !uncovered(e, 0.0, side, &z); tilt -= 2) {
        e = extremes(set, a, with_disks == 1, tilt * M_PI / 180.0);
      }
    }
    double lo = 0.0, hi = 0.5 * side / *std::min_element(e.size.begin(), e.size.end());
    double best = box[a];
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      if (uncovered(e, mid, side, &z)) {
        lo = mid;
        best = z;
      } else {
        hi = mid;
      }
    }
    std::vector<std::pair<double, double>> all = {{clearance_at(e, best, side), best}};
    for (int k = 0; k < kSamples; ++k) {
      const double f = box[a] + side * k / kSamples;
      all.push_back({clearance_at(e, f, side), f});
    }
    std::stable_sort(all.begin(), all.end(),
                     [](const auto& x, const auto& y) { return x.first > y.first; });
    candidates[a].push_back({clearance_at(e, box[a], side), box[a]});
    for (const auto& [c, f] : all) {
      if (static_cast<int>(candidates[a].size()) > kKeep) break;
      bool apart = true;
      for (const auto& kept : candidates[a]) {
        double d = std::fmod(std::abs(f - kept.second), side);
        apart = apart && std::min(d, side - d) >= side / 64.0;
      }
      if (apart) candidates[a].push_back({c, f});
    }
  }
  // The combination whose least clearance, of faces, edges and corners, is the largest; of
  // those, the one whose edges and corners are clearest (a face may hold the least for every
  // combination: one that crosses a fibre nearly along it wherever it lies); the box's own is
  // first, so that it is kept on a tie of both.
  Vec3 origin = box;
  double best = -1.0, best_edges = -1.0;
  for (const auto& [cx, x] : candidates[0]) {
    for (const auto& [cy, y] : candidates[1]) {
      for (const auto& [cz, z] : candidates[2]) {
        const double faces = std::min({cx, cy, cz});
        if (faces < best) continue;
        const Vec3 o(x, y, z);
        const double edges = edge_clearance(set, o), score = std::min(faces, edges);
        if (score > best || (score == best && edges > best_edges)) {
          best = score;
          best_edges = edges;
          origin = o;
        }
      }
    }
  }
  // Positions nearest the box's own (moved by less than half a side).
  for (int a = 0; a < 3; ++a) {
    const double side = set.box.size[a];
    origin[a] = box[a] + (origin[a] - box[a]) - side * std::round((origin[a] - box[a]) / side);
  }
  return origin;
}

Nudged nudge_off_cell(InclusionSet* set, const Vec3& origin, double min_gap) {
  Nudged out;
  const Box& box = set->box;
  auto own_clearance = [&](const Inclusion& inc) {
    InclusionSet one;
    one.box = box;
    one.inclusions = {inc};
    return std::min(face_clearance(one, origin), edge_clearance(one, origin));
  };
  const size_t n = set->inclusions.size();
  std::vector<Shape> env(n);
  std::vector<double> reach(n);
  double largest = 0.0;
  for (size_t i = 0; i < n; ++i) {
    env[i] = envelope(set->inclusions[i]);
    reach[i] = env[i].bounding_radius();
    largest = std::max(largest, size_of(set->inclusions[i]));
  }
  // Whether inclusion i's envelope, as `e`, keeps min_gap from every other in `among` (all when
  // null).
  auto apart = [&](size_t i, const Shape& e, const std::vector<size_t>* among) {
    const double ri = e.bounding_radius();
    auto clear_of_j = [&](size_t j) {
      if (j == i) return true;
      bool clear = true;
      for_each_image(box, e.center, ri + min_gap, env[j].center, reach[j], [&](const Vec3& shift) {
        if (clear && !clear_of(e, env[j].translated(shift), min_gap)) clear = false;
      });
      return clear;
    };
    if (among) return std::all_of(among->begin(), among->end(), clear_of_j);
    for (size_t j = 0; j < n; ++j)
      if (!clear_of_j(j)) return false;
    return true;
  };
  std::vector<char> moved(n, 0);
  // The first stage: along one axis, clear of every other.
  constexpr int kSteps = 24;  // 1.5 sizes in sixteenths
  std::vector<size_t> stuck;
  for (size_t i = 0; i < n; ++i) {
    Inclusion& inc = set->inclusions[i];
    if (own_clearance(inc) >= kGoodClearance) continue;
    const double size = size_of(inc);
    bool done = false;
    for (int k = 1; k <= kSteps && !done; ++k) {
      for (int a = 0; a < 3 && !done; ++a) {
        for (const double sign : {1.0, -1.0}) {
          Inclusion trial = inc;
          trial.shape.center[a] += sign * k * size / 16.0;
          trial.shape.center = box.wrapped(trial.shape.center);
          if (own_clearance(trial) < kGoodClearance) continue;
          const Shape e = envelope(trial);
          if (!apart(i, e, nullptr)) continue;
          inc = trial;
          env[i] = e;
          moved[i] = 1;
          done = true;
          break;
        }
      }
    }
    if (!done) stuck.push_back(i);
  }
  // The second stage, for those: the least translation in any of 26 directions (to 4 sizes) that
  // clears the cell's faces and keeps min_gap from every other; else the first of the least that
  // clear the faces and make room by pushing others (relax, below).
  std::vector<Vec3> dirs;
  for (int x = -1; x <= 1; ++x)
    for (int y = -1; y <= 1; ++y)
      for (int z = -1; z <= 1; ++z)
        if (x || y || z) dirs.push_back(Vec3(x, y, z).normalized());
  // for_each_image, with the nearest image alone where no other can be within reach (the hot
  // loops below, without the std::function call).
  auto images = [&](const Vec3& ca, double ra, const Vec3& cb, double rb, const auto& f) {
    const double r = ra + rb;
    if (2.0 * r >= box.size.minCoeff()) return for_each_image(box, ca, ra, cb, rb, f);
    Vec3 d = cb - ca;
    const std::array<int, 3> k = to_nearest_image(box, &d);
    if (d.squaredNorm() < r * r) f(box.size.cwiseProduct(Vec3(k[0], k[1], k[2])));
  };
  // The inclusions within reach of i's moves and of theirs (every periodic image's bounding
  // spheres, grown by the moves).
  std::map<size_t, std::vector<size_t>> near_of;
  constexpr int kFarSteps = 64;  // 4 sizes in sixteenths
  constexpr double kPushedGap = 1.2;
  const double slack = (kFarSteps / 16.0 + 2.0) * largest + 2.0 * kPushedGap * min_gap;
  auto near = [&](size_t i) -> const std::vector<size_t>& {
    auto it = near_of.find(i);
    if (it != near_of.end()) return it->second;
    std::vector<size_t>& list = near_of[i];
    for (size_t j = 0; j < n; ++j) {
      bool hit = false;
      if (j != i)
        images(env[i].center, reach[i] + slack, env[j].center, reach[j],
               [&](const Vec3&) { hit = true; });
      if (hit) list.push_back(j);
    }
    return list;
  };
  auto moved_by = [&](const Inclusion& inc, const Vec3& d) {
    Inclusion trial = inc;
    trial.shape.center = box.wrapped(trial.shape.center + d);
    return trial;
  };
  // The relaxation: i moved by d and held there, the inclusions it meets pushed off along their
  // contact's normal, and those they meet in turn (each pair apart by its depth, half each, all
  // of it when one is i), in sweeps until no two meet. Accepted when then every moved inclusion
  // keeps min_gap from every other (exact tests) and grazes the faces no more than before (or
  // under kGoodClearance), none moved more than 2 of its sizes, and at most kMostMoved moved.
  // Pairs are pushed to 1.2 min_gap: the volume mesher refused the surfaces of a 2,484-fibre
  // scene whose pushes had left 350 pairs at min_gap (the packer leaves none within 1.01 of it).
  constexpr int kSweeps = 200, kMostMoved = 64;
  auto relax = [&](size_t i, const Vec3& d) {
    std::vector<size_t> moving = {i};
    std::map<size_t, Vec3> shift = {{i, d}};
    auto at = [&](size_t j) {
      const auto it = shift.find(j);
      return it == shift.end() ? env[j] : env[j].translated(it->second);
    };
    auto push = [&](size_t j, const Vec3& p) {
      if (j == i) return true;
      auto [it, fresh] = shift.emplace(j, Vec3::Zero());
      if (fresh) moving.push_back(j);
      it->second += p;
      return it->second.norm() <= 2.0 * size_of(set->inclusions[j]) &&
             static_cast<int>(moving.size()) <= kMostMoved;
    };
    // Only the pairs of an inclusion pushed since its last visit can have come to meet.
    std::map<size_t, bool> dirty = {{i, true}};
    bool settled = false;
    for (int sweep = 0; sweep < kSweeps && !settled; ++sweep) {
      settled = true;
      for (size_t q = 0; q < moving.size(); ++q) {
        const size_t a = moving[q];
        if (!dirty[a]) continue;
        dirty[a] = false;
        Shape ea = padded(at(a), kPushedGap * min_gap);
        double ra = ea.bounding_radius();
        for (const size_t b : near(a)) {
          const Shape eb = at(b);
          Contact c;
          images(ea.center, ra, eb.center, reach[b], [&](const Vec3& t) {
            if (!c.overlap) c = intersect(ea, eb.translated(t));
          });
          if (!c.overlap) continue;
          settled = false;
          // A little past the depth, which is an upper bound or exact.
          const Vec3 p = (c.depth + 1e-3 * min_gap + 1e-9 * size_of(set->inclusions[b])) * c.normal;
          const bool ok = a == i   ? push(b, p)
                          : b == i ? push(a, -p)
                                   : push(a, -0.5 * p) && push(b, 0.5 * p);
          if (!ok) return false;
          if (a != i) {
            dirty[a] = true;
            ea = padded(at(a), kPushedGap * min_gap);
          }
          if (b != i) dirty[b] = true;
        }
      }
    }
    if (!settled) return false;
    // The exact checks, on the moved inclusions as they would be written.
    std::vector<std::pair<size_t, Inclusion>> trial;
    for (const size_t j : moving) {
      const Inclusion t = moved_by(set->inclusions[j], shift[j]);
      const double need =
          j == i ? kGoodClearance : std::min(kGoodClearance, own_clearance(set->inclusions[j]));
      if (own_clearance(t) < need) return false;
      trial.push_back({j, t});
    }
    std::vector<Shape> kept;
    for (const auto& [j, t] : trial) {
      kept.push_back(env[j]);
      env[j] = envelope(t);
    }
    bool clear = true;
    for (size_t q = 0; q < trial.size() && clear; ++q) {
      clear = apart(trial[q].first, env[trial[q].first], &near(trial[q].first));
    }
    if (!clear) {
      for (size_t q = 0; q < trial.size(); ++q) env[trial[q].first] = kept[q];
      return false;
    }
    for (const auto& [j, t] : trial) {
      set->inclusions[j] = t;
      moved[j] = 1;
    }
    return true;
  };
  constexpr int kTries = 24;
  for (const size_t i : stuck) {
    Inclusion& inc = set->inclusions[i];
    const double size = size_of(inc);
    near_of.clear();  // positions have moved since
    bool done = false;
    // Free moves first, then those that push.
    int tries = 0;
    for (int push = 0; push < 2 && !done; ++push) {
      for (int k = 1; k <= kFarSteps && !done && tries < kTries; ++k) {
        for (size_t q = 0; q < dirs.size() && !done && tries < kTries; ++q) {
          const Vec3 d = dirs[q] * (k * size / 16.0);
          const Inclusion trial = moved_by(inc, d);
          if (own_clearance(trial) < kGoodClearance) continue;
          if (push) {
            ++tries;
            done = relax(i, d);
            continue;
          }
          const Shape e = envelope(trial);
          if (!apart(i, e, &near(i))) continue;
          inc = trial;
          env[i] = e;
          moved[i] = 1;
          done = true;
        }
      }
    }
    if (!done) ++out.stuck;
  }
  out.moved = static_cast<int>(std::count(moved.begin(), moved.end(), 1));
  return out;
}

Nudged nudge_off_chosen_cell(InclusionSet* set, double min_gap) {
  Nudged total;
  std::vector<Vec3> start;
  for (const Inclusion& inc : set->inclusions) start.push_back(inc.shape.center);
  for (int round = 0; round < 4; ++round) {
    const Nudged n = nudge_off_cell(set, cell_origin(*set), min_gap);
    total.stuck = n.stuck;
    if (n.moved == 0) break;
  }
  for (size_t i = 0; i < start.size(); ++i)
    total.moved += set->inclusions[i].shape.center != start[i];
  return total;
}

TetMesh tet_mesh(const InclusionSet& set_in, const TetMeshOptions& options,
                 const TetMeshProgress& progress) {
  check_tet_meshable(set_in);
  InclusionSet moved;
  if (options.shift_cell) {
    moved = set_in;
    moved.box.origin = cell_origin(set_in);
  }
  const InclusionSet& set = options.shift_cell ? moved : set_in;
  // The share shown never falls, through a second attempt too.
  double shown = 0.0;
  const TetMeshProgress steady = [&](double f, const std::string& line) {
    shown = std::max(shown, f);
    return progress ? progress(shown, line) : true;
  };
  // Gmsh's Frontal-Delaunay fails on some spline surfaces of ellipsoids cut by a box face, in
  // one frame of the ellipsoid and not in others (three ellipsoids of a packing at 0.4: one
  // frame of 32 failed), refines the curves around the surface and leaves a curve and its image
  // on the opposite face with other nodes ("Can't find periodic counterpart of mesh edge ... on
  // curve ..."). The inclusions about the curves named are built again in their next frame,
  // up to kFrameTurns times.
  std::vector<int> rank(set.inclusions.size(), 0);
  // Each failure and what comes next: said as progress, and kept in the mesh made at last.
  std::vector<std::string> retries;
  auto retry = [&](const std::string& line) {
    retries.push_back(line);
    if (!steady(shown, "mesh_tet: " + line)) throw Cancelled();
  };
  auto made = [&](TetMesh mesh) {
    mesh.retries = retries;
    return mesh;
  };
  for (int turn = 0;; ++turn) {
    try {
      return made(mesh_with(set, options, steady, 6, 0.0, rank));
    } catch (const SurfacesRefused& e) {
      if (turn < kFrameTurns && !e.inclusions.empty()) {
        std::string ids;
        for (const int i : e.inclusions) {
          ++rank[i];
          ids += (ids.empty() ? "" : ", ") + std::to_string(set.inclusions[i].id);
        }
        retry(std::string(e.what()) + "; meshing again with " +
              (e.inclusions.size() > 1 ? "inclusions " : "inclusion ") + ids +
              " built in another frame");
        continue;
      }
      // HXT refuses some surface meshes of Gmsh's default surface mesher (Frontal-Delaunay):
      // "Found two exactly self-intersecting facets", in 3 of 12 sphere scenes of the benchmark.
      // Meshed from the start with Gmsh's Delaunay surface mesher, all three went through.
      // (Meshing the surfaces again in the same model gave no elements; Gmsh's Delaunay volume
      // mesher on the first surfaces gave none either.) The surface mesher's own failures that
      // other frames do not end go the same way.
      retry(std::string(e.what()) + "; meshing the surfaces again with Delaunay");
      break;
    }
  }
  try {
    return made(mesh_with(set, options, steady, 5, 0.0, rank));
  } catch (const SurfacesRefused& e) {
    // Where two curves of a face meet at a small angle (a face cutting a fibre nearly along it
    // and its end disk), segments as long as a coarse chord error allows cross each other
    // ("PLC Error: Two segments intersect", with either surface mesher: seen in 2 of 8 packings
    // of 311 fibres of L/D 10 at chord error 0.1). Curves divided as a chord error of
    // kFinerCurveChord asks do not cross there; the surfaces keep the sizes asked. (The one of
    // them kept as a test was a flat triangle's chord in the face, which raise_flat_triangles
    // now flips: it meshes at the first attempt. The other was not kept.)
    // A refusal of the volume mesher goes on to the Delaunay volume mesher (below); any other
    // failure ends here.
    auto to_delaunay = [&](const SurfacesRefused& refusal) {
      if (!refused_volumes(refusal)) throw MeshError("mesh_tet: " + std::string(refusal.what()));
      retry("again, " + std::string(refusal.what()) + "; " + kDelaunayRetry);
    };
    if (options.chord_error > kFinerCurveChord) {
      retry("again, " + std::string(e.what()) + "; meshing them again with curves divided finer");
      try {
        return made(mesh_with(set, options, steady, 6, kFinerCurveChord, rank));
      } catch (const SurfacesRefused& again) {
        to_delaunay(again);
      }
    } else {
      to_delaunay(e);
    }
  }
  // Where HXT refuses the surfaces of all three attempts, Gmsh's Delaunay volume mesher takes
  // the first attempt's surfaces, in several times HXT's time (one thread). It meshed the two
  // refusals seen: a packing of 429 fibres at 0.2 ("failed to recover constrained
  // lines/triangles"; 3.6 M elements in 189 s against HXT's 10 s, least angle 5.04 degrees),
  // since meshed at once with HXT (its cause, a curve inside a box face, is no longer meshed),
  // and fibres pushed to exactly min_gap apart by a move off the cell's faces that was not
  // kept ("No elements in volume"). So it comes last.
  try {
    TetMesh mesh = made(mesh_with(set, options, steady, 6, 0.0, rank, kDelaunay3d));
    mesh.volume_mesher = "Delaunay";
    return mesh;
  } catch (const SurfacesRefused& e) {
    throw MeshError("mesh_tet: " + std::string(e.what()));
  }
}

TetQuality tet_quality(const TetMesh& mesh) {
  TetQuality q;
  q.phase_volume.assign(mesh.phases.size(), 0.0);
  q.dihedral_counts.assign(TetQuality::kBins.size(), 0);
  q.min_volume = mesh.tets.empty() ? 0.0 : 1e300;
  std::vector<double> least(mesh.tets.size());
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    Vec3 p[4];
    for (int c = 0; c < 4; ++c) p[c] = mesh.nodes[mesh.tets[e][c]];
    const double v = tet_volume(mesh.nodes, mesh.tets[e]);
    q.min_volume = std::min(q.min_volume, v);
    const int label = mesh.phase[e];
    if (label >= 0 && label < static_cast<int>(q.phase_volume.size())) q.phase_volume[label] += v;
    const double m = least_dihedral(p);
    least[e] = m;
    size_t bin = 0;
    while (bin + 1 < TetQuality::kBins.size() && m >= TetQuality::kBins[bin + 1]) ++bin;
    ++q.dihedral_counts[bin];
    q.below_5_degrees += m < 5.0;
  }
  if (!least.empty()) {
    std::sort(least.begin(), least.end());
    q.min_dihedral = least.front();
    const double at[3] = {0.01, 0.05, 0.5};
    for (int k = 0; k < 3; ++k)
      q.quantiles[k] = least[static_cast<size_t>(at[k] * (least.size() - 1))];
  }
  return q;
}

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
  if (running.load() > stop) return std::max(cap, 1e-3 * per_unit * running.load());
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
