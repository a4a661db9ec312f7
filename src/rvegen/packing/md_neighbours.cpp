#include "rvegen/packing/md_neighbours.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <thread>

#include "rvegen/geometry/convex.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/model/parallel.hpp"

namespace rvegen::md {

namespace {

constexpr double kSkin = 0.5;         // Verlet skin, in capsule radii of each body
constexpr double kSkinLength = 0.5;   // or in half lengths of each body if more
constexpr double kGridRoom = 1.25;    // kept grid: cells 2 x 1.25 x the largest covering sphere
constexpr double kSizeSpread = 4.0;   // kept only when no covering sphere exceeds 4 x the median
constexpr size_t kRefreshShare = 32;  // a full build when over 1/32 of the bodies are stale

// A candidate pair {a, b, kx, ky, kz}: ordered lexicographically.
using Key = std::array<int, 5>;

// f(i) for i in [0, n) on all cores, in chunks of about `grain`.
template <class F>
void each_index(size_t n, size_t grain, const F& f) {
  rvegen::parallel_for_range(tbb::blocked_range<size_t>(0, n, grain),
                             [&](const tbb::blocked_range<size_t>& r) {
                               for (size_t i = r.begin(); i != r.end(); ++i) f(i);
                             });
}

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

bool VerletList::stale_body(const Body& b, size_t i, double s_out) const {
  const double d = (b.shape.center - built_center_[i]).norm();
  const double grow = (b.radial ? b.cap_radius : b.bound) * std::max(0.0, s_out - built_scale_[i]);
  const double r = b.cap_half_at(s_out) + b.cap_radius_at(s_out);
  return d + turned_since_build_[i] * r + grow > half_skin_[i];
}

bool VerletList::stale(const std::vector<Body>& bodies, double s_out) const {
  if (rebuilds_ == 0 || built_scale_.size() != bodies.size()) return true;
  for (size_t i = 0; i < bodies.size(); ++i) {
    if (stale_body(bodies[i], i, s_out)) return true;
  }
  return false;
}

void VerletList::reference(Body* body, size_t i, const Box& box, double s_out) {
  Body& b = *body;
  wrap(box, &b);
  built_center_[i] = b.shape.center;
  built_scale_[i] = s_out;
  turned_since_build_[i] = 0.0;
  // Long bodies get a skin of a fraction of their length too: their ends sweep far when
  // they grow or turn, and the capsule test in contacts() keeps the extra pairs cheap.
  // Aligned fibres (radial) neither turn nor grow in length: the skin of a half-grown fibre.
  half_skin_[i] = b.radial ? 0.5 * kSkin * b.cap_radius * std::max(s_out, 0.5)
                           : 0.5 * kSkin * std::max(b.cap_radius, kSkinLength * b.cap_half) *
                                 b.force_scale(s_out);
  // A string of spheres covers the capsule inflated by the half skin.
  const Vec3 e = principal_axis(b.shape) * b.cap_half_at(s_out);
  const double rho = b.cap_radius_at(s_out) + half_skin_[i];
  seg_p_[i] = b.shape.center - e;
  seg_q_[i] = b.shape.center + e;
  cap_r_[i] = rho;
  const int k = b.cap_half > 0.0 ? static_cast<int>(std::ceil(2.0 * e.norm() / rho)) + 1 : 1;
  const double spacing = k > 1 ? 2.0 * e.norm() / (k - 1) : 0.0;
  const double rs = std::sqrt(rho * rho + 0.25 * spacing * spacing);
  sub_first_[i] = static_cast<int>(sub_c_.size());
  sub_count_[i] = k;
  for (int t = 0; t < k; ++t) {
    const double u = k > 1 ? -1.0 + 2.0 * t / (k - 1) : 0.0;
    sub_c_.push_back(b.shape.center + u * e);
    sub_r_.push_back(rs);
    sub_body_.push_back(static_cast<int>(i));
  }
}

void VerletList::build(std::vector<Body>* all, const Box& box, double s_out,
                       const std::function<void()>& tick) {
  std::vector<Body>& bodies = *all;
  const size_t n = bodies.size();
  built_center_.resize(n);
  half_skin_.resize(n);
  turned_since_build_.assign(n, 0.0);
  built_scale_.assign(n, s_out);
  seg_p_.resize(n);
  seg_q_.resize(n);
  cap_r_.resize(n);
  sub_first_.assign(n, 0);
  sub_count_.assign(n, 0);
  links_.resize(n);
  for (auto& l : links_) l.clear();
  ++rebuilds_;
  pairs_.clear();
  sub_c_.clear();
  sub_r_.clear();
  sub_body_.clear();
  dead_spheres_ = 0;
  box_ = box;
  for (size_t i = 0; i < n; ++i) reference(&bodies[i], i, box, s_out);
  // Every pair of covering spheres that meet (the broad phase the audit and RSA use too).
  std::vector<Key>& keys = keys_;
  keys.clear();
  sphere_pairs(box, sub_c_, sub_r_, &sphere_pairs_, tick);
  for (const SpherePair& sp : sphere_pairs_) {
    const int a = sub_body_[sp.i], b = sub_body_[sp.j];
    if (a == b && sp.k[0] == 0 && sp.k[1] == 0 && sp.k[2] == 0) continue;
    keys.push_back(make_key(a, b, sp.k[0], sp.k[1], sp.k[2]));
  }
  if (tick) tick();
  rvegen::parallel_sort(keys.begin(), keys.end());  // equal keys are equal: one order
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  if (tick) tick();
  // The capsules' test on all cores, the list made in key order.
  std::vector<char>& meets = key_meets_;
  meets.resize(keys.size());
  each_index(keys.size(), 4096, [&](size_t t) {
    const Key& k = keys[t];
    const int a = k[0], b = k[1];
    const Vec3 shift(k[2] * box.size[0], k[3] * box.size[1], k[4] * box.size[2]);
    const double rr = cap_r_[a] + cap_r_[b];
    meets[t] =
        segment_distance2(seg_p_[a], seg_q_[a], seg_p_[b] + shift, seg_q_[b] + shift) <= rr * rr;
  });
  pairs_.reserve(keys.size());
  for (size_t t = 0; t < keys.size(); ++t) {
    if (!meets[t]) continue;
    const Key& k = keys[t];
    const int a = k[0], b = k[1];
    const Vec3 shift(k[2] * box.size[0], k[3] * box.size[1], k[4] * box.size[2]);
    pairs_.push_back({a, b, shift});
    links_[a].push_back({b, {k[2], k[3], k[4]}});
    if (a != b) links_[b].push_back({a, {-k[2], -k[3], -k[4]}});
  }
  keep_grid(box);
}

// The grid kept between calls: cells of 2 kGridRoom times the median covering sphere, searched
// as far as the sphere's radius plus the largest radius a sphere may have before a full build
// (kGridRoom times the largest now). In a periodic box only the nearest image of a sphere may
// reach another (reach under half the box), and a search never wraps onto itself.
void VerletList::keep_grid(const Box& box) {
  grid_kept_ = false;
  cells_.clear();
  if (sub_r_.empty()) return;
  std::vector<double> r(sub_r_);
  std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
  const double median = r[r.size() / 2];
  const double largest = *std::max_element(sub_r_.begin(), sub_r_.end());
  if (largest > kSizeSpread * median) return;
  const double cell = 2.0 * kGridRoom * median;
  grid_reach_ = kGridRoom * largest;
  size_t total = 1;
  for (int a = 0; a < 3; ++a) {
    grid_n_[a] = std::max(1, static_cast<int>(std::floor(box.size[a] / cell)));
    total *= grid_n_[a];
  }
  // Coarsen a grid with far more cells than spheres (cells may only grow).
  while (total > 8 * sub_c_.size() + 27 && total > 1) {
    total = 1;
    for (int a = 0; a < 3; ++a) {
      grid_n_[a] = std::max(1, grid_n_[a] / 2);
      total *= grid_n_[a];
    }
  }
  if (box.periodic) {
    for (int a = 0; a < 3; ++a) {
      const int range = static_cast<int>(std::ceil(2.0 * grid_reach_ * grid_n_[a] / box.size[a]));
      if (4.0 * grid_reach_ >= box.size[a] || 2 * range + 1 > grid_n_[a]) return;
    }
  }
  grid_kept_ = true;
  cells_.assign(total, {});
  for (size_t i = 0; i < sub_first_.size(); ++i) insert_spheres(static_cast<int>(i));
}

int VerletList::grid_coord(double x, int a) const {
  return cell_coordinate(box_, grid_n_[a], box_.size[a] / grid_n_[a], x, a);
}

size_t VerletList::grid_cell(const Vec3& c) const {
  return (static_cast<size_t>(grid_coord(c[2], 2)) * grid_n_[1] + grid_coord(c[1], 1)) *
             grid_n_[0] +
         grid_coord(c[0], 0);
}

void VerletList::insert_spheres(int i) {
  for (int q = sub_first_[i]; q < sub_first_[i] + sub_count_[i]; ++q) {
    cells_[grid_cell(sub_c_[q])].push_back(q);
  }
}

void VerletList::remove_spheres(int i) {
  for (int q = sub_first_[i]; q < sub_first_[i] + sub_count_[i]; ++q) {
    std::vector<int>& v = cells_[grid_cell(sub_c_[q])];
    const auto it = std::find(v.begin(), v.end(), q);
    *it = v.back();
    v.pop_back();
  }
}

bool VerletList::refresh(std::vector<Body>* all, const Box& box, double s_out,
                         const std::vector<int>& ids, const std::function<void()>& tick) {
  std::vector<Body>& bodies = *all;
  const size_t n = bodies.size();
  for (int i : ids) remove_spheres(i);
  for (int i : ids) {
    reference(&bodies[i], i, box, s_out);
    // A covering sphere too large for the cells: the grid must be made again.
    if (sub_r_.back() > grid_reach_) return false;
  }
  for (int i : ids) insert_spheres(i);
  ++refreshed_;
  std::vector<char>& is_stale = is_stale_;
  is_stale.assign(n, 0);
  for (int i : ids) is_stale[i] = 1;
  // Drop every pair of a refreshed body, on both sides.
  for (int i : ids) {
    for (const Link& l : links_[i]) {
      if (l.other == i) continue;
      std::vector<Link>& o = links_[l.other];
      for (size_t t = 0; t < o.size(); ++t) {
        if (o[t].other == i && o[t].k[0] == -l.k[0] && o[t].k[1] == -l.k[1] &&
            o[t].k[2] == -l.k[2]) {
          o[t] = o.back();
          o.pop_back();
          break;
        }
      }
    }
    links_[i].clear();
  }
  // Find them again: the covering spheres of a refreshed body against all kept ones (a pair of
  // two refreshed bodies from the side of the larger index). Each body's links are found on
  // all cores (the search reads the grid only), then added in the order of `ids`, both ways, as
  // one pass would.
  if (!find_scratch_)
    find_scratch_ = std::make_shared<tbb::enumerable_thread_specific<FindScratch>>();
  auto& scratch = *static_cast<tbb::enumerable_thread_specific<FindScratch>*>(find_scratch_.get());
  ++find_calls_;
  found_.resize(ids.size());
  const auto caller = std::this_thread::get_id();
  each_index(ids.size(), 1, [&](size_t t) {
    if (tick && (t & 63) == 63 && std::this_thread::get_id() == caller) tick();
    const int i = ids[t];
    FindScratch& sc = scratch.local();
    if (sc.stamp.size() != n) {
      sc.stamp.assign(n, -1);
      sc.stamp_k.resize(n);
    }
    // Stamps name the call and the body: no reset between calls.
    const long long mark = find_calls_ * static_cast<long long>(n) + i;
    std::vector<Link>& seen = found_[t];
    seen.clear();
    for (int p = sub_first_[i]; p < sub_first_[i] + sub_count_[i]; ++p) {
      const Vec3& c = sub_c_[p];
      int lo[3], hi[3];
      for (int a = 0; a < 3; ++a) {
        const int m = grid_coord(c[a], a);
        const int range =
            static_cast<int>(std::ceil((sub_r_[p] + grid_reach_) * grid_n_[a] / box.size[a]));
        lo[a] = m - range;
        hi[a] = m + range;
        if (!box.periodic) {
          lo[a] = std::max(lo[a], 0);
          hi[a] = std::min(hi[a], grid_n_[a] - 1);
        }
      }
      for (int z = lo[2]; z <= hi[2]; ++z) {
        const int zz = (z + 2 * grid_n_[2]) % grid_n_[2];
        for (int y = lo[1]; y <= hi[1]; ++y) {
          const int yy = (y + 2 * grid_n_[1]) % grid_n_[1];
          for (int x = lo[0]; x <= hi[0]; ++x) {
            const int xx = (x + 2 * grid_n_[0]) % grid_n_[0];
            for (int q : cells_[(static_cast<size_t>(zz) * grid_n_[1] + yy) * grid_n_[0] + xx]) {
              const int j = sub_body_[q];
              if (j < i && is_stale[j]) continue;
              Vec3 d = sub_c_[q] - c;
              std::array<int, 3> k = to_nearest_image(box, &d);
              if (j == i && k[0] == 0 && k[1] == 0 && k[2] == 0) continue;
              const double rr = sub_r_[p] + sub_r_[q];
              if (d.squaredNorm() > rr * rr) continue;
              if (j == i) {  // a body and its own image: one of k and -k
                const Key key = make_key(i, i, k[0], k[1], k[2]);
                k = {key[2], key[3], key[4]};
              }
              // Each (body, image) once: the first image met is stamped, others are looked up.
              if (sc.stamp[j] == mark) {
                if (sc.stamp_k[j] == k) continue;
                bool met = false;
                for (const Link& l : seen) met |= (l.other == j && l.k == k);
                if (met) continue;
              } else {
                sc.stamp[j] = mark;
                sc.stamp_k[j] = k;
              }
              seen.push_back({j, k});
            }
          }
        }
      }
    }
    // Of the (body, image) met, those whose capsules meet.
    size_t kept = 0;
    for (const Link& l : seen) {
      const int j = l.other;
      const Vec3 shift(l.k[0] * box.size[0], l.k[1] * box.size[1], l.k[2] * box.size[2]);
      const double cr = cap_r_[i] + cap_r_[j];
      if (segment_distance2(seg_p_[i], seg_q_[i], seg_p_[j] + shift, seg_q_[j] + shift) > cr * cr) {
        continue;
      }
      seen[kept++] = l;
    }
    seen.resize(kept);
  });
  for (size_t t = 0; t < ids.size(); ++t) {
    const int i = ids[t];
    for (const Link& l : found_[t]) {
      links_[i].push_back(l);
      if (l.other != i) links_[l.other].push_back({i, {-l.k[0], -l.k[1], -l.k[2]}});
    }
  }
  return true;
}

// The flat list for the contact pass: each pair once, from the side of the smaller index.
void VerletList::emit_pairs(const Box& box) {
  // Counted per body, then filled on all cores at each body's place: the list is the one a
  // single pass over the bodies makes.
  const size_t n = links_.size();
  std::vector<size_t>& first = emit_first_;
  first.assign(n + 1, 0);
  each_index(n, 1024, [&](size_t a) {
    size_t c = 0;
    for (const Link& l : links_[a]) c += l.other >= static_cast<int>(a);
    first[a + 1] = c;
  });
  for (size_t a = 0; a < n; ++a) first[a + 1] += first[a];
  pairs_.resize(first[n]);
  each_index(n, 1024, [&](size_t a) {
    size_t at = first[a];
    for (const Link& l : links_[a]) {
      if (l.other < static_cast<int>(a)) continue;
      pairs_[at++] = {static_cast<int>(a), l.other,
                      Vec3(l.k[0] * box.size[0], l.k[1] * box.size[1], l.k[2] * box.size[2])};
    }
  });
}

void VerletList::update(std::vector<Body>* all, const Box& box, double s_out,
                        const std::function<void()>& tick) {
  std::vector<Body>& bodies = *all;
  const size_t n = bodies.size();
  if (rebuilds_ == 0 || built_scale_.size() != n) return build(all, box, s_out, tick);
  std::vector<int>& ids = stale_ids_;
  ids.clear();
  std::vector<char>& flag = is_stale_;
  flag.resize(n);
  each_index(n, 512, [&](size_t i) { flag[i] = stale_body(bodies[i], i, s_out) ? 1 : 0; });
  for (size_t i = 0; i < n; ++i) {
    if (flag[i]) ids.push_back(static_cast<int>(i));
  }
  if (ids.empty()) return;
  // Refreshed bodies leave their old covering spheres behind: rebuild once they outnumber the
  // live ones three to one.
  const bool crowded = sub_c_.size() > 4 * (sub_c_.size() - dead_spheres_) + 4096;
  if (!grid_kept_ || kRefreshShare * ids.size() > n || crowded) {
    return build(all, box, s_out, tick);
  }
  for (int i : ids) dead_spheres_ += sub_count_[i];
  if (!refresh(all, box, s_out, ids, tick)) return build(all, box, s_out, tick);
  emit_pairs(box);
}

}  // namespace rvegen::md
