#include "rvegen/model/neighbours.hpp"

#include <algorithm>
#include <cmath>
#include <thread>

#include "rvegen/model/parallel.hpp"

namespace rvegen {

void for_each_image(const Box& box, const Vec3& ca, double ra, const Vec3& cb, double rb,
                    const std::function<void(const Vec3&)>& f) {
  const Vec3 d = cb - ca;
  const double reach = ra + rb;
  if (!box.periodic) {
    if (d.squaredNorm() < reach * reach) f(Vec3::Zero());
    return;
  }
  int lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = static_cast<int>(std::ceil((-reach - d[k]) / box.size[k]));
    hi[k] = static_cast<int>(std::floor((reach - d[k]) / box.size[k]));
  }
  for (int i = lo[0]; i <= hi[0]; ++i) {
    for (int j = lo[1]; j <= hi[1]; ++j) {
      for (int k = lo[2]; k <= hi[2]; ++k) {
        const Vec3 shift(i * box.size[0], j * box.size[1], k * box.size[2]);
        if ((d + shift).squaredNorm() < reach * reach) f(shift);
      }
    }
  }
}

NeighbourGrid::NeighbourGrid(const Box& box, double reach, size_t expected_count) : box_(box) {
  size_t total = 1;
  // Cells no smaller than `reach`, and no more than about two per inclusion.
  const double min_cell =
      std::max(reach, std::cbrt(box.volume() / (2.0 * std::max<size_t>(expected_count, 1))));
  for (int k = 0; k < 3; ++k) {
    int n = min_cell > 0.0 ? static_cast<int>(std::floor(box.size[k] / min_cell)) : 1;
    n = std::clamp(n, 1, 1024);
    // With fewer than 3 periodic cells the +-1 neighbours would alias: use one cell.
    if (box.periodic && n < 3) n = 1;
    n_[k] = n;
    cell_[k] = box.size[k] / n;
    total *= static_cast<size_t>(n);
  }
  (void)total;
}

std::array<int, 3> to_nearest_image(const Box& box, Vec3* d) {
  std::array<int, 3> k = {0, 0, 0};
  if (!box.periodic) return k;
  for (int a = 0; a < 3; ++a) {
    const int m = static_cast<int>(std::floor((*d)[a] / box.size[a] + 0.5));
    (*d)[a] -= m * box.size[a];
    k[a] = -m;
  }
  return k;
}

int cell_coordinate(const Box& box, int n, double width, double x, int axis) {
  int i = static_cast<int>(std::floor((x - box.origin[axis]) / width));
  if (box.periodic) {
    i %= n;
    if (i < 0) i += n;
  } else {
    i = std::clamp(i, 0, n - 1);
  }
  return i;
}

int NeighbourGrid::cell_of(const Vec3& c, int k) const {
  return cell_coordinate(box_, n_[k], cell_[k], c[k], k);
}

size_t NeighbourGrid::cell_index(const Vec3& c) const {
  return (static_cast<size_t>(cell_of(c, 2)) * n_[1] + cell_of(c, 1)) * n_[0] + cell_of(c, 0);
}

void NeighbourGrid::insert(int index, const Vec3& center) {
  if (cells_.empty()) cells_.resize(cell_count());
  cells_[cell_index(center)].push_back(index);
}

void NeighbourGrid::insert_reaching(int index, const Vec3& center, double radius) {
  if (cells_.empty()) cells_.resize(cell_count());
  int lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = static_cast<int>(std::floor((center[k] - radius - box_.origin[k]) / cell_[k]));
    hi[k] = static_cast<int>(std::floor((center[k] + radius - box_.origin[k]) / cell_[k]));
    if (box_.periodic) {
      if (hi[k] - lo[k] + 1 >= n_[k]) {
        lo[k] = 0;
        hi[k] = n_[k] - 1;
      }
    } else {
      lo[k] = std::clamp(lo[k], 0, n_[k] - 1);
      hi[k] = std::clamp(hi[k], 0, n_[k] - 1);
    }
  }
  for (int z = lo[2]; z <= hi[2]; ++z) {
    const int zz = (z % n_[2] + n_[2]) % n_[2];
    for (int y = lo[1]; y <= hi[1]; ++y) {
      const int yy = (y % n_[1] + n_[1]) % n_[1];
      for (int x = lo[0]; x <= hi[0]; ++x) {
        const int xx = (x % n_[0] + n_[0]) % n_[0];
        cells_[(static_cast<size_t>(zz) * n_[1] + yy) * n_[0] + xx].push_back(index);
      }
    }
  }
}

void NeighbourGrid::neighbour_range(const Vec3& c, int lo[3], int hi[3]) const {
  for (int k = 0; k < 3; ++k) {
    const int ci = cell_of(c, k);
    if (n_[k] == 1) {
      lo[k] = hi[k] = 0;
    } else if (box_.periodic) {
      lo[k] = ci - 1;
      hi[k] = ci + 1;
    } else {
      lo[k] = std::max(0, ci - 1);
      hi[k] = std::min(n_[k] - 1, ci + 1);
    }
  }
}

bool NeighbourGrid::nearest_image_suffices() const {
  if (!box_.periodic) return true;
  return n_[0] >= 3 && n_[1] >= 3 && n_[2] >= 3;
}

namespace {

// The two-level broad phase, set up for one set of spheres: spheres up to twice the median
// radius are "small" and sorted into a grid sized for them; larger ones are registered in
// every cell they reach.
class PairSearch {
 public:
  PairSearch(const Box& box, const std::vector<Vec3>& c, const std::vector<double>& r)
      : box_(box), c_(c), r_(r), grid_(box, 1.0, 1), reach_grid_(box, 1.0, 1) {
    const size_t n = c.size();
    std::vector<double> radii(r);
    std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
    const double r_cut = 2.0 * radii[radii.size() / 2];
    for (size_t p = 0; p < n; ++p) (r[p] <= r_cut ? small_ : large_).push_back(static_cast<int>(p));
    if (large_.size() > 2000) {
      // Too many large spheres for the direct large-large pass: one level for all.
      small_.clear();
      large_.clear();
      for (size_t p = 0; p < n; ++p) small_.push_back(static_cast<int>(p));
    }
    for (int p : small_) r_small_ = std::max(r_small_, r[p]);
    // The grid's cells, filled by a counting sort (the spheres are all known: no per-cell
    // lists).
    grid_ = NeighbourGrid(box, 2.0 * r_small_, 4 * small_.size());
    start_.assign(grid_.cell_count() + 1, 0);
    std::vector<int> cell_of(small_.size());
    order_.resize(small_.size());
    for (size_t t = 0; t < small_.size(); ++t) {
      cell_of[t] = static_cast<int>(grid_.cell_index(c[small_[t]]));
      ++start_[cell_of[t] + 1];
    }
    for (size_t k = 0; k + 1 < start_.size(); ++k) start_[k + 1] += start_[k];
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (size_t t = 0; t < small_.size(); ++t) order_[fill[cell_of[t]]++] = small_[t];
    nearest_ = grid_.nearest_image_suffices();
    if (!large_.empty()) {
      reach_grid_ = NeighbourGrid(box, 2.0 * r_small_, 4 * small_.size());
      for (int q : large_) reach_grid_.insert_reaching(q, c[q], r[q] + r_small_);
    }
  }
  size_t small_count() const { return small_.size(); }
  size_t large_count() const { return large_.size(); }

  /// The pairs of the small sphere small[t] with the small spheres of larger index.
  template <class Emit>
  void small_pairs(size_t t, const Emit& emit) const {
    const int p = small_[t];
    grid_.for_each_neighbour_cell(c_[p], [&](size_t cell) {
      for (int u = start_[cell]; u < start_[cell + 1]; ++u) {
        const int q = order_[u];
        if (q < p) continue;
        if (!nearest_) {
          all_images(p, q, emit);
          continue;
        }
        if (q == p) continue;  // a small sphere cannot reach its own image (3 cells per axis)
        // Only the nearest image of q can be within reach: the box is at least 3 reaches wide.
        Vec3 d = c_[q] - c_[p];
        const std::array<int, 3> k = to_nearest_image(box_, &d);
        const double rr = r_[p] + r_[q];
        if (d.squaredNorm() <= rr * rr) emit({p, q, k});
      }
    });
  }
  /// The pairs of small sphere small[t] with the large ones.
  template <class Emit>
  void small_large_pairs(size_t t, const Emit& emit) const {
    reach_grid_.for_each_in_cell(c_[small_[t]], [&](int q) { all_images(small_[t], q, emit); });
  }
  /// The pairs of large[u] with large[v], v >= u.
  template <class Emit>
  void large_pairs(size_t u, const Emit& emit) const {
    for (size_t v = u; v < large_.size(); ++v) all_images(large_[u], large_[v], emit);
  }

 private:
  template <class Emit>
  void all_images(int p, int q, const Emit& emit) const {
    for_each_image(box_, c_[p], r_[p], c_[q], r_[q], [&](const Vec3& s) {
      std::array<int, 3> k = {0, 0, 0};
      if (box_.periodic) {
        for (int a = 0; a < 3; ++a) {
          k[a] = static_cast<int>(std::floor(s[a] / box_.size[a] + 0.5));
        }
      }
      if (p == q && k[0] == 0 && k[1] == 0 && k[2] == 0) return;
      emit({p, q, k});
    });
  }

  const Box& box_;
  const std::vector<Vec3>& c_;
  const std::vector<double>& r_;
  std::vector<int> small_, large_, start_, order_;
  double r_small_ = 0.0;
  NeighbourGrid grid_, reach_grid_;
  bool nearest_ = true;
};

}  // namespace

void sphere_pairs(const Box& box, const std::vector<Vec3>& c, const std::vector<double>& r,
                  std::vector<SpherePair>* pairs, const std::function<void()>& tick) {
  pairs->clear();
  if (c.empty()) return;
  const PairSearch search(box, c, r);
  // The small spheres on all cores, in blocks whose pairs are joined in block order: the list
  // is the one a single pass makes, whatever the block size. Blocks of 256 give scenes of a few
  // thousand covering spheres (chains, grains) more blocks than cores.
  constexpr size_t kBlock = 256;
  const size_t nb = (search.small_count() + kBlock - 1) / kBlock;
  std::vector<std::vector<SpherePair>> found(nb), reaching(nb);
  const bool large = search.large_count() > 0;
  const auto caller = std::this_thread::get_id();
  rvegen::parallel_for(size_t(0), nb, [&](size_t b) {
    if (tick && std::this_thread::get_id() == caller) tick();
    const size_t end = std::min(search.small_count(), (b + 1) * kBlock);
    for (size_t t = b * kBlock; t < end; ++t) {
      search.small_pairs(t, [&](const SpherePair& p) { found[b].push_back(p); });
      if (large)
        search.small_large_pairs(t, [&](const SpherePair& p) { reaching[b].push_back(p); });
    }
  });
  size_t total = 0;
  for (size_t b = 0; b < nb; ++b) total += found[b].size() + reaching[b].size();
  pairs->reserve(total);
  for (const auto& f : found) pairs->insert(pairs->end(), f.begin(), f.end());
  for (const auto& f : reaching) pairs->insert(pairs->end(), f.begin(), f.end());
  auto add = [pairs](const SpherePair& p) { pairs->push_back(p); };
  for (size_t u = 0; u < search.large_count(); ++u) {
    if (tick) tick();
    search.large_pairs(u, add);
  }
}

bool for_each_sphere_pair(const Box& box, const std::vector<Vec3>& c, const std::vector<double>& r,
                          const std::function<bool(const SpherePair&)>& f,
                          const std::function<void()>& tick) {
  if (c.empty()) return true;
  const PairSearch search(box, c, r);
  bool go = true;  // false once f asked to stop
  auto emit = [&](const SpherePair& p) {
    if (go) go = f(p);
  };
  for (size_t t = 0; t < search.small_count() && go; ++t) {
    if (tick && (t & 1023) == 0) tick();
    search.small_pairs(t, emit);
  }
  for (size_t t = 0; t < search.small_count() && search.large_count() > 0 && go; ++t) {
    if (tick && (t & 1023) == 0) tick();
    search.small_large_pairs(t, emit);
  }
  for (size_t u = 0; u < search.large_count() && go; ++u) {
    if (tick) tick();
    search.large_pairs(u, emit);
  }
  return go;
}

}  // namespace rvegen
