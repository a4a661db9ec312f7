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

#include "rvegen/femesh/mesh_parts.hpp"
#include "rvegen/femesh/offset_solid.hpp"
#include "rvegen/geometry/pair.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/errors.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/model/parallel.hpp"
#include "rvegen/model/resources.hpp"

namespace rvegen {

using namespace mesh_parts;

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

}  // namespace

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
