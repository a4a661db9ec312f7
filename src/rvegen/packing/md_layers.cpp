#include "rvegen/packing/md_layers.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <memory>
#include <numeric>

#include "rvegen/geometry/convex.hpp"
#include "rvegen/model/neighbours.hpp"

namespace rvegen::md {

namespace {

// A plane normal within kOnAxisCos of a box axis (1 - |cos|) is that axis; a fibre whose axis
// leaves the plane by at most kInPlaneSine of its length lies in it; a fibre within
// kOnAxisRounding of a box axis runs along it (rounding of an axis drawn along it).
constexpr double kOnAxisCos = 1e-9, kInPlaneSine = 1e-9, kOnAxisRounding = 1e-12;

constexpr int kMoves = 30;       // in-plane moves of a fibre to find a free layer
constexpr int kSlides = 3000;    // then places where it slides out of a few fibres of a layer,
constexpr int kSlideFibres = 3;  // at most that many,
constexpr int kSlideSteps = 8;   // in that many pushes; then it takes the least crowded layer
constexpr long long kSlideBudget = 200;  // slide places per fibre, in all
constexpr double kCrowdedShare = 0.01;   // no slides once that share of fibres is crowded
constexpr int kSlidesFirst = 100;        // slide places before evictions are tried there too
constexpr int kEvictPlaces = 200;        // then places where it takes a layer from the few
constexpr int kEvictFibres = 2;          // (at most that many) fibres that meet it there,
constexpr double kEvictShare = 0.05;     // which are placed again (that share of all fibres)
constexpr int kSweeps = 16;              // height sweeps after layering
constexpr double kLinesFull = 0.7;       // aligned fibres: slots where sections fill more
constexpr double kShrink = 0.95;         // layers for smaller sizes ...
constexpr double kMinScale = 0.7;        // ... down to this scale
constexpr double kTimeShare = 0.5;       // of md.max_seconds at most, then no slides or shrinking

// The box axis k normal to the plane the family's law confines axes to, or -1.
int plane_normal_axis(const OrientationLaw& law) {
  if (law.kind == OrientationLaw::Kind::kAligned) return -1;
  const OrientationLaw::NullSpace null = law.null_space();
  if (null.count != 1) return -1;
  const Vec3& n = null.normal;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(n[k]) > 1.0 - kOnAxisCos) return k;
  }
  return -1;
}

struct Fibre {
  int body;
  double t;      // radius at full size with the gap's pad: half thickness and capsule radius
  Vec3 half;     // half axis at full size (in the plane)
  Vec3 normal;   // unit normal of the axis in the plane
  double reach;  // |half| + t
};

class Layering {
 public:
  Layering(const Box& box, int k, std::vector<Body>* all, std::vector<Fibre> fibres)
      : box_(box), k_(k), all_(*all), fibres_(std::move(fibres)) {
    double reach = 0.0, tmax = 0.0;
    for (const Fibre& f : fibres_) {
      reach = std::max(reach, f.reach);
      tmax = std::max(tmax, f.t);
    }
    reach_ = 2.0 * reach;
    height_ = box.size[k];
    layers_ = static_cast<int>(std::floor(height_ / (2.0 * tmax)));
    // The grid is over projected centres (height = origin). Where the plane is at least twice
    // the largest reach wide, only the nearest image of a pair can meet.
    grid_ = std::make_unique<NeighbourGrid>(box, reach_, fibres_.size());
    unique_image_ = true;
    for (int x = 0; x < 3; ++x) {
      if (x != k && box.size[x] < 2.0 * reach_) unique_image_ = false;
    }
  }

  int layers() const { return layers_; }
  /// Fibres the last place() left crowded (in the least crowded layer).
  size_t crowded() const { return crowded_; }

  // Steps 1 and 2 (see md_layers.hpp): layers, largest first.
  // Returns false, unfinished, once more than kCrowdedShare of the fibres are crowded, unless
  // `finish` or past `deadline` (then they go on without slides or evictions).
  bool place(Random& rng, bool finish, std::chrono::steady_clock::time_point deadline) {
    std::vector<int> order(fibres_.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return fibres_[a].reach > fibres_[b].reach; });
    layer_.assign(fibres_.size(), -1);
    adj_.assign(fibres_.size(), {});
    members_.assign(layers_, {});
    std::vector<int> held(layers_), hits, perm(layers_);
    std::iota(perm.begin(), perm.end(), 0);
    // The work is bounded: kSlideBudget slide places per fibre in all, and none once
    // kCrowdedShare of the fibres are crowded (the target is then out of reach of layers);
    // kEvictShare of the fibres evicted in all.
    long long slides = kSlideBudget * static_cast<long long>(fibres_.size());
    long long evictions = std::llround(kEvictShare * static_cast<double>(fibres_.size()));
    crowded_ = 0;
    std::deque<int> queue(order.begin(), order.end());
    while (!queue.empty()) {
      const int f = queue.front();
      queue.pop_front();
      if (crowded_ > kCrowdedShare * fibres_.size() ||
          ((slides > 0 || evictions > 0) && std::chrono::steady_clock::now() > deadline)) {
        if (!finish && crowded_ > kCrowdedShare * fibres_.size()) return false;
        finish = true;
        slides = evictions = 0;
      }
      int layer = -1;
      for (int move = 0; move <= kMoves && layer < 0; ++move) {
        // Moved in its plane when every layer was taken here; in a box with walls, placed
        // inside it from the start.
        if (move > 0 || !box_.periodic) draw_center(f, rng);
        layer = free_layer(f, rng, &perm);
      }
      // Crowded: tries layers where the fibre meets a few others, sliding it out of them.
      for (int slid = 0; slid < kSlides && layer < 0 && slides > 0; ++slid, --slides) {
        draw_center(f, rng);
        conflicts(f, &hits, &held);
        const Vec3 at = all_[fibres_[f].body].shape.center;
        for (int c = 0; c < layers_ && layer < 0; ++c) {
          if (held[c] > kSlideFibres) continue;
          if (slide(f, c)) {
            layer = c;
          } else {
            all_[fibres_[f].body].shape.center = at;
          }
        }
        if (layer < 0 && slid >= kSlidesFirst)
          layer = evict_for(hits, held, rng, &perm, &queue, &evictions);
      }
      // Still no room: a place where some layer holds at most kEvictFibres fibres that meet
      // it; it takes that layer and they go back to the queue, to be placed anew (as in
      // cuckoo hashing: the last fibres of a nearly full stack of layers find room this way
      // where random places and slides no longer do).
      for (int tries = 0; tries < kEvictPlaces && layer < 0 && evictions > 0; ++tries) {
        draw_center(f, rng);
        conflicts(f, &hits, &held);
        layer = evict_for(hits, held, rng, &perm, &queue, &evictions);
      }
      if (layer < 0) {  // crowded: the layer fewest neighbours hold
        conflicts(f, &hits, &held);
        layer = static_cast<int>(std::min_element(held.begin(), held.end()) - held.begin());
        ++crowded_;
      }
      layer_[f] = layer;
      members_[layer].push_back(f);
      grid_->insert(f, projected(f));
    }
    // Crossing neighbours (any layer), for the height sweeps. The grid holds every fibre at
    // its place (and, for fibres placed again, stale entries that conflicts() skips).
    for (size_t f = 0; f < fibres_.size(); ++f) {
      conflicts(static_cast<int>(f), &hits);
      for (int g : hits) {
        adj_[f].push_back(g);
        adj_[g].push_back(static_cast<int>(f));
      }
    }
    for (std::vector<int>& a : adj_) {
      std::sort(a.begin(), a.end());
      a.erase(std::unique(a.begin(), a.end()), a.end());
    }
    const double pitch = height_ / layers_;
    for (size_t f = 0; f < fibres_.size(); ++f) {
      all_[fibres_[f].body].shape.center[k_] = box_.origin[k_] + (layer_[f] + 0.5) * pitch;
    }
    return true;
  }

  // Step 3: each fibre to a uniform height in the room its crossing neighbours leave.
  void shake(Random& rng) {
    for (int sweep = 0; sweep < kSweeps; ++sweep) {
      for (size_t f = 0; f < fibres_.size(); ++f) {
        double up, down;
        if (!room(static_cast<int>(f), &up, &down)) continue;
        Vec3& c = all_[fibres_[f].body].shape.center;
        c[k_] += rng.uniform(-down, up);
        if (box_.periodic) {
          c[k_] -= std::floor((c[k_] - box_.origin[k_]) / height_) * height_;
        }
      }
    }
  }

 private:
  Vec3 projected(int f) const {
    Vec3 c = all_[fibres_[f].body].shape.center;
    c[k_] = box_.origin[k_];
    return c;
  }

  // A random centre in the plane: anywhere in a periodic box, else where f is inside the box
  // (in its middle where it cannot be).
  void draw_center(int f, Random& rng) {
    Vec3& c = all_[fibres_[f].body].shape.center;
    for (int a = 0; a < 3; ++a) {
      if (a == k_) continue;
      const double margin = box_.periodic ? 0.0 : std::abs(fibres_[f].half[a]) + fibres_[f].t;
      const double room = std::max(0.0, box_.size[a] - 2.0 * margin);
      c[a] = box_.origin[a] + std::min(margin, 0.5 * box_.size[a]) + room * rng.uniform();
    }
  }

  // A uniformly random layer where f meets no fibre (the first free one in a random order), or
  // -1.
  int free_layer(int f, Random& rng, std::vector<int>* perm) const {
    shuffle(rng, perm);
    for (int c : *perm) {
      if (!meets_layer(f, c, -1)) return c;
    }
    return -1;
  }

  // At f's place, where `hits` meet it and held[c] of them are in layer c: the layer that
  // fewest hold, with its fibres sent back to the queue, when they are at most kEvictFibres and
  // the budget allows; -1 otherwise.
  int evict_for(const std::vector<int>& hits, const std::vector<int>& held, Random& rng,
                std::vector<int>* perm, std::deque<int>* queue, long long* evictions) {
    if (*evictions <= 0) return -1;
    shuffle(rng, perm);
    int c = (*perm)[0];
    for (int q : *perm) {
      if (held[q] < held[c]) c = q;
    }
    if (held[c] > kEvictFibres) return -1;
    for (int g : hits) {
      if (layer_[g] != c) continue;
      std::vector<int>& m = members_[c];
      m.erase(std::find(m.begin(), m.end(), g));
      layer_[g] = -1;
      queue->push_back(g);
      --*evictions;
    }
    return c;
  }

  static void shuffle(Random& rng, std::vector<int>* perm) {
    for (int q = static_cast<int>(perm->size()) - 1; q > 0; --q) {
      std::swap((*perm)[q], (*perm)[std::min<int>(q, rng.uniform() * (q + 1))]);
    }
  }

  // f meets a fibre of layer c other than `except`.
  bool meets_layer(int f, int c, int except) const {
    for (int g : members_[c]) {
      if (g != except && meets(f, g)) return true;
    }
    return false;
  }

  // Fibres placed (other than f) whose projections meet f's, each once.
  void conflicts(int f, std::vector<int>* hits) const {
    hits->clear();
    grid_->for_each_candidate(projected(f), [&](int g) {
      if (g != f && layer_[g] >= 0 && meets(f, g)) hits->push_back(g);
    });
    std::sort(hits->begin(), hits->end());
    hits->erase(std::unique(hits->begin(), hits->end()), hits->end());
  }
  // The same, and how many of them each layer holds.
  void conflicts(int f, std::vector<int>* hits, std::vector<int>* held) const {
    conflicts(f, hits);
    std::fill(held->begin(), held->end(), 0);
    for (int g : *hits) ++(*held)[layer_[g]];
  }

  // The projections of f and g (capsules of radius t about their axes, in the plane) meet, for
  // some periodic image of g.
  bool meets(int f, int g) const {
    return each_meeting(f, g, [](const Vec3&, double) { return true; });
  }

  // Calls on_hit(q, d2) for every image of g whose projection meets f's (q: g's centre from
  // f's, d2: squared distance of the axes) until it returns true; returns whether it did.
  template <class F>
  bool each_meeting(int f, int g, F&& on_hit) const {
    const Fibre& a = fibres_[f];
    const Fibre& b = fibres_[g];
    const double reach = a.reach + b.reach;
    const double tt = a.t + b.t;
    Vec3 d = projected(g) - projected(f);
    int lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    if (box_.periodic) {
      for (int x = 0; x < 3; ++x) {
        if (x == k_) continue;
        const double L = box_.size[x];
        // Nearest image; an inlined round (this is the layering's innermost loop).
        const double k = d[x] / L;
        d[x] -= static_cast<double>(static_cast<long long>(k + (k >= 0.0 ? 0.5 : -0.5))) * L;
        if (unique_image_) continue;
        lo[x] = static_cast<int>(std::ceil((-reach - d[x]) / L));
        hi[x] = static_cast<int>(std::floor((reach - d[x]) / L));
      }
    }
    for (int i = lo[0]; i <= hi[0]; ++i) {
      for (int j = lo[1]; j <= hi[1]; ++j) {
        for (int l = lo[2]; l <= hi[2]; ++l) {
          const Vec3 q = d + Vec3(i * box_.size[0], j * box_.size[1], l * box_.size[2]);
          if (q.squaredNorm() >= reach * reach) continue;
          // b's centre within |h_b . n_a| + t_a + t_b of a's line (n_a: a's in-plane normal)
          if (std::abs(q.dot(a.normal)) >= std::abs(b.half.dot(a.normal)) + tt) continue;
          const double d2 = segment_distance2(-a.half, a.half, q - b.half, q + b.half);
          if (d2 < tt * tt && on_hit(q, d2)) return true;
        }
      }
    }
    return false;
  }

  // Slides f in its plane out of the few fibres of layer c it meets (each pushes it along the
  // line of the axes' closest points by the overlap plus a little), kSlideSteps times at most;
  // true when f then meets none. Gives up where axes cross (no short slide frees them) or more
  // than kSlideFibres are met.
  bool slide(int f, int c) {
    const Fibre& a = fibres_[f];
    Vec3& centre = all_[a.body].shape.center;
    for (int step = 0;; ++step) {
      Vec3 push = Vec3::Zero();
      int met = 0;
      bool stuck = false;
      for (int g : members_[c]) {
        const Fibre& b = fibres_[g];
        const double tt = a.t + b.t;
        each_meeting(f, g, [&](const Vec3& q, double d2) {
          const double dist = std::sqrt(d2);
          if (++met > kSlideFibres || dist < 0.05 * tt) return stuck = true;
          double s, t;
          segment_closest(-a.half, a.half, q - b.half, q + b.half, &s, &t);
          const Vec3 pa = a.half * (2.0 * s - 1.0), pb = q + b.half * (2.0 * t - 1.0);
          push += (pa - pb) * ((1.02 * tt - dist) / dist);
          return false;
        });
        if (stuck) return false;
      }
      if (met == 0) return true;
      if (step == kSlideSteps) return false;
      push[k_] = 0.0;
      centre += push;
      if (!box_.periodic) {
        for (int x = 0; x < 3; ++x) {
          if (x == k_) continue;
          const double margin = std::abs(a.half[x]) + a.t;
          if (centre[x] < box_.origin[x] + margin ||
              centre[x] > box_.origin[x] + box_.size[x] - margin) {
            return false;
          }
        }
      }
    }
  }

  // The room above and below f's height; false when a neighbour is already too close.
  bool room(int f, double* up, double* down) const {
    const double z = all_[fibres_[f].body].shape.center[k_];
    if (box_.periodic) {
      *up = *down = 0.5 * height_;
    } else {
      *up = box_.origin[k_] + height_ - fibres_[f].t - z;
      *down = z - box_.origin[k_] - fibres_[f].t;
    }
    for (int g : adj_[f]) {
      const double sep = fibres_[f].t + fibres_[g].t;
      double d = all_[fibres_[g].body].shape.center[k_] - z;
      if (box_.periodic) {
        d -= std::floor(d / height_) * height_;  // [0, H): g above by d, below by H - d
        *up = std::min(*up, d - sep);
        *down = std::min(*down, height_ - d - sep);
      } else if (d >= 0.0) {
        *up = std::min(*up, d - sep);
      } else {
        *down = std::min(*down, -d - sep);
      }
    }
    return *up >= 0.0 && *down >= 0.0;
  }

  const Box& box_;
  int k_;
  std::vector<Body>& all_;
  std::vector<Fibre> fibres_;
  double reach_ = 0.0, height_ = 0.0;
  bool unique_image_ = false;
  std::vector<std::vector<int>> members_;  // per layer
  int layers_ = 0;
  std::unique_ptr<NeighbourGrid> grid_;
  std::vector<int> layer_;
  std::vector<std::vector<int>> adj_;
  size_t crowded_ = 0;
};

}  // namespace

void layer_planar_fibres(const PackingSpec& spec, Random& rng, Bodies* bodies,
                         const ProgressFn& progress) {
  const auto start = std::chrono::steady_clock::now();
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(kTimeShare * spec.md.max_seconds));
  std::vector<Fibre> by_axis[3];
  for (size_t i = 0; i < bodies->all.size(); ++i) {
    const Body& b = bodies->all[i];
    if (b.shape.kind != ShapeKind::Cylinder || b.radial) continue;
    const int k = plane_normal_axis(spec.families[b.family].orientation);
    if (k < 0 || std::abs(b.shape.half_axis[k]) > kInPlaneSine * b.shape.half_axis.norm()) continue;
    Vec3 half = b.shape.half_axis * (1.0 + b.pad);
    half[k] = 0.0;
    const double t = b.shape.radius * (1.0 + b.pad);
    by_axis[k].push_back(
        {static_cast<int>(i), t, half, Vec3::Unit(k).cross(half).normalized(), half.norm() + t});
  }
  for (int k = 0; k < 3; ++k) {
    if (by_axis[k].size() < 2) continue;
    // Layers for the drawn sizes; where more than kCrowdedShare of the fibres find no room in
    // them (a target beyond what layers hold), for sizes kShrink smaller, down to kMinScale.
    for (double scale = 1.0;;) {
      std::vector<Fibre> fibres = by_axis[k];
      for (Fibre& f : fibres) {
        f.t *= scale;
        f.half *= scale;
        f.reach *= scale;
      }
      Layering layering(spec.box, k, &bodies->all, std::move(fibres));
      if (layering.layers() < 2) break;
      const bool last = scale * kShrink < kMinScale || std::chrono::steady_clock::now() > deadline;
      const bool done = layering.place(rng, last, deadline);
      if (progress) {
        char buf[200];
        std::snprintf(
            buf, sizeof buf,
            "md: %zu planar fibres in %d layers at scale %.4f: %s (%zu crowded), %.1f s",
            by_axis[k].size(), layering.layers(), scale, done ? "placed" : "no room, smaller",
            layering.crowded(),
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        progress(buf);
      }
      if (done) {
        layering.shake(rng);
        break;
      }
      scale = std::max(kMinScale, scale * kShrink);
    }
  }
}

void slot_aligned_fibres(const PackingSpec& spec, Random& rng, Bodies* bodies) {
  const Box& box = spec.box;
  std::vector<int> by_axis[3];
  double longest[3] = {0.0, 0.0, 0.0};
  for (size_t i = 0; i < bodies->all.size(); ++i) {
    const Body& b = bodies->all[i];
    if (!b.radial) continue;
    const Vec3 u = b.shape.half_axis / b.cap_half;
    for (int k = 0; k < 3; ++k) {
      if (std::abs(u[k]) > 1.0 - kOnAxisRounding) {
        by_axis[k].push_back(static_cast<int>(i));
        longest[k] = std::max(longest[k], 2.0 * (b.cap_half + b.add_half));
      }
    }
  }
  for (int k = 0; k < 3; ++k) {
    if (by_axis[k].empty()) continue;
    const int slots = static_cast<int>(std::floor(box.size[k] / longest[k]));
    if (slots < 2) continue;  // one slot: any two fibres side by side already share their span
    // Only where one fibre per line would not fit: their sections would fill more than
    // kLinesFull of the box's cross-section.
    double section = 0.0;
    for (int i : by_axis[k]) {
      const Body& b = bodies->all[i];
      section += M_PI * (b.shape.radius + b.add_radius) * (b.shape.radius + b.add_radius);
    }
    if (section * box.size[k] <= kLinesFull * box.volume()) continue;
    const double pitch = box.size[k] / slots;
    // Equal counts per slot, in a random order.
    std::vector<int>& fibres = by_axis[k];
    for (size_t q = fibres.size() - 1; q > 0; --q) {
      std::swap(fibres[q], fibres[std::min<size_t>(q, rng.uniform() * (q + 1))]);
    }
    for (size_t q = 0; q < fibres.size(); ++q) {
      Body& b = bodies->all[fibres[q]];
      const double room = std::max(0.0, pitch - 2.0 * (b.cap_half + b.add_half));
      b.shape.center[k] = box.origin[k] + (static_cast<double>(q % slots) + 0.5) * pitch +
                          room * (rng.uniform() - 0.5);
    }
  }
}

}  // namespace rvegen::md
