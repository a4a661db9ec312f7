// Molecular-dynamics packing, part 2: the neighbour (Verlet) list. The pairs of bodies (with the
// periodic image) whose bounding capsules, inflated by a skin, intersect; rebuilt when some body
// could have moved by more than half its skin.
#pragma once

#include <array>
#include <functional>
#include <memory>
#include <vector>

#include "rvegen/model/neighbours.hpp"
#include "rvegen/packing/md_bodies.hpp"

namespace rvegen::md {

/// A listed pair: body b is taken at its centre + shift.
struct PairEntry {
  int a, b;
  Vec3 shift;
};

class VerletList {
 public:
  /// True when the list was never built, or when some body could have moved since it was last
  /// referenced (translation, turn times its capsule size, growth to s_out) by more than half
  /// its skin.
  bool stale(const std::vector<Body>& bodies, double s_out) const;
  /// Wraps the centres into a periodic box, then lists every pair whose capsules at s_out,
  /// inflated by their half skins, intersect. Bodies are covered by strings of spheres for the
  /// broad phase (model/neighbours), so long fibres do not force huge cells. `tick` is called
  /// in long loops (a time budget may throw from it).
  void build(std::vector<Body>* bodies, const Box& box, double s_out,
             const std::function<void()>& tick);
  /// Keeps the list valid for the current configuration. Only the bodies that could have left
  /// their skin are referenced again (wrapped, their capsule and skin taken at s_out) and
  /// their pairs found again against the other bodies' reference capsules, through a grid of
  /// the covering spheres that is kept between calls. A pair left out is one whose inflated
  /// reference capsules are disjoint, and each body stays within its half skin of its
  /// reference, so no overlapping pair is ever missing. Everything is rebuilt when many bodies
  /// are stale (over a quarter), when a new covering sphere no longer fits the grid's cells,
  /// and where the grid is not kept (covering spheres of very different sizes, or a box under
  /// three cells wide).
  void update(std::vector<Body>* bodies, const Box& box, double s_out,
              const std::function<void()>& tick);
  const std::vector<PairEntry>& pairs() const { return pairs_; }
  /// Records that body i turned by `angle` radians since the last build.
  void turned(int i, double angle) { turned_since_build_[i] += angle; }
  /// Full builds, and bodies referenced again one by one.
  long long rebuilds() const { return rebuilds_; }
  long long refreshed() const { return refreshed_; }

 private:
  bool stale_body(const Body& b, size_t i, double s_out) const;
  // References body i at s_out: wraps it, sets its reference centre, scale, skin and inflated
  // capsule, and strings its covering spheres (appended to sub_c/sub_r/sub_body).
  void reference(Body* b, size_t i, const Box& box, double s_out);
  bool refresh(std::vector<Body>* bodies, const Box& box, double s_out,
               const std::vector<int>& stale_ids, const std::function<void()>& tick);
  void keep_grid(const Box& box);
  int grid_coord(double x, int a) const;  // kept grid: cell coordinate, cell index
  size_t grid_cell(const Vec3& c) const;
  void insert_spheres(int i);
  void remove_spheres(int i);
  void emit_pairs(const Box& box);

  std::vector<PairEntry> pairs_;
  // Per body, the state it was referenced in. Centres are wrapped into a periodic box only
  // when a body is referenced, so the stored shifts stay right until then.
  std::vector<Vec3> built_center_;
  std::vector<double> half_skin_;
  std::vector<double> turned_since_build_;
  std::vector<double> built_scale_;
  std::vector<Vec3> seg_p_, seg_q_;  // reference capsule axis and radius (with the half skin)
  std::vector<double> cap_r_;
  long long rebuilds_ = 0, refreshed_ = 0;
  // Covering spheres of the last build or refresh: spheres of body i are sub_first_[i] ..
  // sub_first_[i] + sub_count_[i] - 1 of its own block (a refreshed body gets a new block).
  std::vector<Vec3> sub_c_;
  std::vector<double> sub_r_;
  std::vector<int> sub_body_, sub_first_, sub_count_;
  // The kept grid (when grid_kept_): the largest sphere it takes, cells per axis, sphere ids by
  // cell.
  bool grid_kept_ = false;
  double grid_reach_ = 0.0;  // the largest covering sphere the grid takes
  int grid_n_[3] = {0, 0, 0};
  std::vector<std::vector<int>> cells_;
  // Pairs by body, both ways: (other body, lattice shift k of the other body).
  struct Link {
    int other;
    std::array<int, 3> k;
  };
  std::vector<std::vector<Link>> links_;
  // Work space, kept for its capacity.
  std::vector<SpherePair> sphere_pairs_;
  std::vector<std::array<int, 5>> keys_;
  // refresh: each thread's stamps (by call and body), each refreshed body's links found.
  struct FindScratch {
    std::vector<long long> stamp;
    std::vector<std::array<int, 3>> stamp_k;
  };
  std::shared_ptr<void> find_scratch_;  // tbb::enumerable_thread_specific<FindScratch>
  long long find_calls_ = 0;
  std::vector<std::vector<Link>> found_;
  std::vector<size_t> emit_first_;
  std::vector<char> key_meets_;
  std::vector<int> stale_ids_;
  std::vector<char> is_stale_;
  size_t dead_spheres_ = 0;
  Box box_;
};

}  // namespace rvegen::md
