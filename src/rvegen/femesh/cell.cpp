// The cell the tetrahedral mesh fills: the box moved along its axes off the inclusions it
// would graze (its faces and edges cut thin caps, strips and wedges that bound the elements'
// angles), and the inclusions that every cell grazes nudged off its faces where there is room.
// No Gmsh here: the cell is chosen, and the set nudged, from the inclusions alone.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <vector>

#include "rvegen/femesh/mesh_parts.hpp"
#include "rvegen/femesh/mesh_tolerances.hpp"
#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/geometry/pair.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/neighbours.hpp"

namespace rvegen {

using namespace mesh_parts;

namespace {

// What a face normal to axis a should keep clear of, each with the length its clearance is
// measured in: the extremes along the axis of every sphere and ellipsoid, in units of its least
// size, and of both rims of every cylinder, in units of its radius (near them a face cuts a
// thin cap, or a thin strip of the mantle along the rim); the span along the axis of every
// cylinder end disk tilted by less than kSteepDisk from the face (a face crossing such a disk
// cuts a wedge that thin); and the span along the axis of the two lines of every cylinder's
// mantle furthest along a, where its axis is tilted by less than kShallowMantle from the face:
// a face within such a span is tangent to the mantle where it crosses the line, and cuts a
// wedge as thin as the tilt (a fibre slightly off the face left slivers there). A face crossing
// a disk at a moderate angle, near its centre, cut off a thin chip of the end, which left
// slivers too: hence 30 degrees for kSteepDisk.
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
      // debonded sphere, left slivers along the cut); a face kept off the centre cuts the cone
      // at an angle.
      // Its two rims (the cone's circles at r and r + gap) too: a face grazing a rim leaves a
      // sliver of surface between them (a face just off the inner rim left slivers).
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
      if (w.squaredNorm() > kParallel2) {
        const double t = (d0.dot(u) - d0.dot(e) * u.dot(e)) / w.squaredNorm();
        if (std::abs(t) <= hl) best = std::abs(std::abs(d0.dot(w)) / w.norm() - r) / r;
      } else {
        best = std::abs(std::hypot(pa, pb) - r) / r;
      }
      if (std::abs(u[c]) > kParallelComponent) {
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

namespace {

// The moves of nudge_off_cell, on one set and cell.
class Nudger {
 public:
  Nudger(InclusionSet* set, const Vec3& origin, double min_gap)
      : set_(*set), box_(set->box), origin_(origin), min_gap_(min_gap) {
    const size_t n = set_.inclusions.size();
    env_.resize(n);
    reach_.resize(n);
    moved_.assign(n, 0);
    for (size_t i = 0; i < n; ++i) {
      env_[i] = envelope(set_.inclusions[i]);
      reach_[i] = env_[i].bounding_radius();
      largest_ = std::max(largest_, size_of(set_.inclusions[i]));
    }
    for (int x = -1; x <= 1; ++x)
      for (int y = -1; y <= 1; ++y)
        for (int z = -1; z <= 1; ++z)
          if (x || y || z) dirs_.push_back(Vec3(x, y, z).normalized());
  }

  // The first stage: each inclusion that grazes the cell moved along one axis, by up to
  // kSteps sixteenths of its size, where it grazes no more and keeps min_gap from every other.
  // Returns those it could not move.
  std::vector<size_t> along_axes() {
    std::vector<size_t> stuck;
    for (size_t i = 0; i < set_.inclusions.size(); ++i) {
      Inclusion& inc = set_.inclusions[i];
      if (own_clearance(inc) >= kGoodClearance) continue;
      const double size = size_of(inc);
      bool done = false;
      for (int k = 1; k <= kSteps && !done; ++k) {
        for (int a = 0; a < 3 && !done; ++a) {
          for (const double sign : {1.0, -1.0}) {
            Inclusion trial = inc;
            trial.shape.center[a] += sign * k * size / 16.0;
            trial.shape.center = box_.wrapped(trial.shape.center);
            if (own_clearance(trial) < kGoodClearance) continue;
            const Shape e = envelope(trial);
            if (!apart(i, e, nullptr)) continue;
            take(i, trial, e);
            done = true;
            break;
          }
        }
      }
      if (!done) stuck.push_back(i);
    }
    return stuck;
  }

  // The second stage, for those: the least translation in any of 26 directions (to kFarSteps
  // sixteenths of its size) that clears the cell's faces and keeps min_gap from every other;
  // else the first of the least (kTries of them) that clear the faces and make room by pushing
  // others (relax). Returns whether it moved.
  bool anywhere(size_t i) {
    Inclusion& inc = set_.inclusions[i];
    const double size = size_of(inc);
    near_of_.clear();  // positions have moved since
    int tries = 0;
    // Free moves first, then those that push.
    for (int push = 0; push < 2; ++push) {
      for (int k = 1; k <= kFarSteps && tries < kTries; ++k) {
        for (size_t q = 0; q < dirs_.size() && tries < kTries; ++q) {
          const Vec3 d = dirs_[q] * (k * size / 16.0);
          const Inclusion trial = moved_by(inc, d);
          if (own_clearance(trial) < kGoodClearance) continue;
          if (push) {
            ++tries;
            if (relax(i, d)) return true;
            continue;
          }
          const Shape e = envelope(trial);
          if (!apart(i, e, &near(i))) continue;
          take(i, trial, e);
          return true;
        }
      }
    }
    return false;
  }

  int moved() const { return static_cast<int>(std::count(moved_.begin(), moved_.end(), 1)); }

 private:
  static constexpr int kSteps = 24;     // 1.5 sizes in sixteenths
  static constexpr int kFarSteps = 64;  // 4 sizes in sixteenths
  static constexpr int kTries = 24;
  // Pairs are pushed to kPushedGap min_gap: pairs pushed to exactly min_gap made surfaces the
  // volume mesher refused (the packer itself leaves no pair that close).
  static constexpr double kPushedGap = 1.2;
  static constexpr int kSweeps = 200, kMostMoved = 64;

  double own_clearance(const Inclusion& inc) const {
    InclusionSet one;
    one.box = box_;
    one.inclusions = {inc};
    return std::min(face_clearance(one, origin_), edge_clearance(one, origin_));
  }

  void take(size_t i, const Inclusion& trial, const Shape& e) {
    set_.inclusions[i] = trial;
    env_[i] = e;
    moved_[i] = 1;
  }

  Inclusion moved_by(const Inclusion& inc, const Vec3& d) const {
    Inclusion trial = inc;
    trial.shape.center = box_.wrapped(trial.shape.center + d);
    return trial;
  }

  // Whether inclusion i's envelope, as `e`, keeps min_gap from every other in `among` (all
  // when null).
  bool apart(size_t i, const Shape& e, const std::vector<size_t>* among) const {
    const double ri = e.bounding_radius();
    auto clear_of_j = [&](size_t j) {
      if (j == i) return true;
      bool clear = true;
      for_each_image(box_, e.center, ri + min_gap_, env_[j].center, reach_[j],
                     [&](const Vec3& shift) {
                       if (clear && !clear_of(e, env_[j].translated(shift), min_gap_)) {
                         clear = false;
                       }
                     });
      return clear;
    };
    if (among) return std::all_of(among->begin(), among->end(), clear_of_j);
    for (size_t j = 0; j < set_.inclusions.size(); ++j)
      if (!clear_of_j(j)) return false;
    return true;
  }

  // for_each_image, with the nearest image alone where no other can be within reach (the hot
  // loops, without the std::function call).
  template <class F>
  void images(const Vec3& ca, double ra, const Vec3& cb, double rb, const F& f) const {
    const double r = ra + rb;
    if (2.0 * r >= box_.size.minCoeff()) return for_each_image(box_, ca, ra, cb, rb, f);
    Vec3 d = cb - ca;
    const std::array<int, 3> k = to_nearest_image(box_, &d);
    if (d.squaredNorm() < r * r) f(box_.size.cwiseProduct(Vec3(k[0], k[1], k[2])));
  }

  // The inclusions within reach of i's moves and of theirs (every periodic image's bounding
  // spheres, grown by the moves).
  const std::vector<size_t>& near(size_t i) {
    auto it = near_of_.find(i);
    if (it != near_of_.end()) return it->second;
    const double slack = (kFarSteps / 16.0 + 2.0) * largest_ + 2.0 * kPushedGap * min_gap_;
    std::vector<size_t>& list = near_of_[i];
    for (size_t j = 0; j < set_.inclusions.size(); ++j) {
      bool hit = false;
      if (j != i) {
        images(env_[i].center, reach_[i] + slack, env_[j].center, reach_[j],
               [&](const Vec3&) { hit = true; });
      }
      if (hit) list.push_back(j);
    }
    return list;
  }

  // The relaxation: i moved by d and held there, the inclusions it meets pushed off along
  // their contact's normal, and those they meet in turn (each pair apart by its depth, half
  // each, all of it when one is i), in sweeps until no two meet. Accepted (settle) when then
  // every moved inclusion keeps min_gap from every other (exact tests) and grazes the faces no
  // more than before (or under kGoodClearance), none moved more than 2 of its sizes, and at
  // most kMostMoved moved.
  bool relax(size_t i, const Vec3& d) {
    std::vector<size_t> moving = {i};
    std::map<size_t, Vec3> shift = {{i, d}};
    auto at = [&](size_t j) {
      const auto it = shift.find(j);
      return it == shift.end() ? env_[j] : env_[j].translated(it->second);
    };
    auto push = [&](size_t j, const Vec3& p) {
      if (j == i) return true;
      auto [it, fresh] = shift.emplace(j, Vec3::Zero());
      if (fresh) moving.push_back(j);
      it->second += p;
      return it->second.norm() <= 2.0 * size_of(set_.inclusions[j]) &&
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
        Shape ea = padded(at(a), kPushedGap * min_gap_);
        const double ra = ea.bounding_radius();
        for (const size_t b : near(a)) {
          const Shape eb = at(b);
          Contact c;
          images(ea.center, ra, eb.center, reach_[b], [&](const Vec3& t) {
            if (!c.overlap) c = intersect(ea, eb.translated(t));
          });
          if (!c.overlap) continue;
          settled = false;
          // A little past the depth, which is an upper bound or exact.
          const Vec3 p =
              (c.depth + kPastGap * min_gap_ + kPastSize * size_of(set_.inclusions[b])) * c.normal;
          const bool ok = a == i   ? push(b, p)
                          : b == i ? push(a, -p)
                                   : push(a, -0.5 * p) && push(b, 0.5 * p);
          if (!ok) return false;
          if (a != i) {
            dirty[a] = true;
            ea = padded(at(a), kPushedGap * min_gap_);
          }
          if (b != i) dirty[b] = true;
        }
      }
    }
    return settled && settle(i, moving, shift);
  }

  // The exact checks of a relaxation, on the moved inclusions as they would be written; keeps
  // the moves when they pass.
  bool settle(size_t i, const std::vector<size_t>& moving, std::map<size_t, Vec3>& shift) {
    std::vector<std::pair<size_t, Inclusion>> trial;
    for (const size_t j : moving) {
      const Inclusion t = moved_by(set_.inclusions[j], shift[j]);
      const double need =
          j == i ? kGoodClearance : std::min(kGoodClearance, own_clearance(set_.inclusions[j]));
      if (own_clearance(t) < need) return false;
      trial.push_back({j, t});
    }
    std::vector<Shape> kept;
    for (const auto& [j, t] : trial) {
      kept.push_back(env_[j]);
      env_[j] = envelope(t);
    }
    bool clear = true;
    for (size_t q = 0; q < trial.size() && clear; ++q) {
      clear = apart(trial[q].first, env_[trial[q].first], &near(trial[q].first));
    }
    if (!clear) {
      for (size_t q = 0; q < trial.size(); ++q) env_[trial[q].first] = kept[q];
      return false;
    }
    for (const auto& [j, t] : trial) {
      set_.inclusions[j] = t;
      moved_[j] = 1;
    }
    return true;
  }

  InclusionSet& set_;
  const Box& box_;
  const Vec3 origin_;
  const double min_gap_;
  std::vector<Shape> env_;
  std::vector<double> reach_;
  double largest_ = 0.0;
  std::vector<char> moved_;
  std::vector<Vec3> dirs_;
  std::map<size_t, std::vector<size_t>> near_of_;
};

}  // namespace

Nudged nudge_off_cell(InclusionSet* set, const Vec3& origin, double min_gap) {
  Nudger nudger(set, origin, min_gap);
  Nudged out;
  for (const size_t i : nudger.along_axes()) {
    if (!nudger.anywhere(i)) ++out.stuck;
  }
  out.moved = nudger.moved();
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

}  // namespace rvegen
