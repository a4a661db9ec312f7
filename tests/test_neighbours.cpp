// The broad phase (model/neighbours): every intersecting pair of spheres and periodic image,
// against brute force over all images.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <tuple>

#include "rvegen/geometry/random.hpp"
#include "rvegen/model/neighbours.hpp"

namespace rvegen {
namespace {

using PairKey = std::tuple<int, int, int, int, int>;

// (i, j, k) and (j, i, -k) are the same pair; keep the one with i < j (or, for i == j, k > 0).
PairKey canonical(int i, int j, const std::array<int, 3>& k) {
  if (i > j || (i == j && std::make_tuple(k[0], k[1], k[2]) < std::make_tuple(0, 0, 0))) {
    return {j, i, -k[0], -k[1], -k[2]};
  }
  return {i, j, k[0], k[1], k[2]};
}

// Every image within +-range lattice vectors, tested directly.
std::set<PairKey> brute_force(const Box& box, const std::vector<Vec3>& c,
                              const std::vector<double>& r, int range) {
  std::set<PairKey> out;
  const int m = box.periodic ? range : 0;
  for (size_t i = 0; i < c.size(); ++i) {
    for (size_t j = i; j < c.size(); ++j) {
      for (int x = -m; x <= m; ++x) {
        for (int y = -m; y <= m; ++y) {
          for (int z = -m; z <= m; ++z) {
            if (i == j && x == 0 && y == 0 && z == 0) continue;
            const Vec3 shift(x * box.size[0], y * box.size[1], z * box.size[2]);
            const double rr = r[i] + r[j];
            if ((c[j] + shift - c[i]).squaredNorm() < rr * rr * (1.0 - 1e-12)) {
              out.insert(canonical(static_cast<int>(i), static_cast<int>(j), {x, y, z}));
            }
          }
        }
      }
    }
  }
  return out;
}

struct Case {
  const char* name;
  Vec3 size;
  bool periodic;
  int count;
  double r_small, r_large;
  int large;  // how many large spheres
};

TEST(Neighbours, SpherePairsMatchBruteForceOverAllImages) {
  const Case cases[] = {
      {"periodic monodisperse", Vec3(1, 1, 1), true, 600, 0.04, 0.04, 0},
      {"periodic with large spheres", Vec3(1, 1, 1), true, 500, 0.03, 0.35, 6},
      {"large sphere wider than the box", Vec3(1, 1, 1), true, 200, 0.05, 0.8, 2},
      {"thin periodic slab (1-2 cells)", Vec3(2, 2, 0.15), true, 400, 0.06, 0.06, 0},
      {"flat non-periodic box", Vec3(4, 1, 0.3), false, 400, 0.05, 0.4, 5},
      {"non-periodic, few cells", Vec3(1, 1, 1), false, 50, 0.2, 0.2, 0},
  };
  for (const Case& cs : cases) {
    Box box;
    box.size = cs.size;
    box.origin = Vec3(-0.3, 0.1, 2.0);
    box.periodic = cs.periodic;
    Random rng(7);
    std::vector<Vec3> c(cs.count);
    std::vector<double> r(cs.count);
    for (int i = 0; i < cs.count; ++i) {
      for (int a = 0; a < 3; ++a) {
        // Some centres outside the box (the packers wrap them only at rebuilds).
        c[i][a] = box.origin[a] + box.size[a] * (1.2 * rng.uniform() - 0.1);
      }
      r[i] = i < cs.large ? cs.r_large : cs.r_small * (0.5 + rng.uniform());
    }
    std::map<PairKey, int> seen;
    std::vector<SpherePair> pairs;
    sphere_pairs(box, c, r, &pairs);
    for (const SpherePair& p : pairs) ++seen[canonical(p.i, p.j, p.k)];
    const double rmax = std::max(cs.r_large, 1.5 * cs.r_small);
    const int range = static_cast<int>(std::ceil(2.0 * rmax / box.size.minCoeff())) + 1;
    const std::set<PairKey> expected = brute_force(box, c, r, range);
    EXPECT_GT(expected.size(), 20u) << cs.name;
    size_t missed = 0, extra = 0;
    for (const PairKey& p : expected) missed += seen.count(p) ? 0 : 1;
    for (const auto& [p, n] : seen) {
      const bool self = std::get<0>(p) == std::get<1>(p);
      // Distinct spheres: once; a sphere with its own image: as +k and as -k.
      EXPECT_EQ(n, self ? 2 : 1) << cs.name;
      // Reported pairs must intersect (up to rounding at exact contact).
      const int i = std::get<0>(p), j = std::get<1>(p);
      const Vec3 shift(std::get<2>(p) * box.size[0], std::get<3>(p) * box.size[1],
                       std::get<4>(p) * box.size[2]);
      const double rr = r[i] + r[j];
      if ((c[j] + shift - c[i]).squaredNorm() > rr * rr * (1.0 + 1e-12)) ++extra;
    }
    EXPECT_EQ(missed, 0u) << cs.name;
    EXPECT_EQ(extra, 0u) << cs.name;
  }
}

TEST(Neighbours, SpherePairStreamIsTheListAndStopsWhenAsked) {
  Box box;
  Random rng(5);
  std::vector<Vec3> c(400);
  std::vector<double> r(400);
  for (int i = 0; i < 400; ++i) {
    c[i] = Vec3(rng.uniform(), rng.uniform(), rng.uniform());
    r[i] = i < 3 ? 0.3 : 0.05;  // large ones too: both passes
  }
  std::vector<SpherePair> list, streamed;
  sphere_pairs(box, c, r, &list);
  ASSERT_GT(list.size(), 50u);
  EXPECT_TRUE(for_each_sphere_pair(box, c, r, [&](const SpherePair& p) {
    streamed.push_back(p);
    return true;
  }));
  ASSERT_EQ(streamed.size(), list.size());
  for (size_t k = 0; k < list.size(); ++k) {
    EXPECT_EQ(streamed[k].i, list[k].i);
    EXPECT_EQ(streamed[k].j, list[k].j);
    EXPECT_EQ(streamed[k].k, list[k].k);
  }
  size_t calls = 0;
  EXPECT_FALSE(for_each_sphere_pair(box, c, r, [&](const SpherePair&) { return ++calls < 7; }));
  EXPECT_EQ(calls, 7u);
}

TEST(Neighbours, GridQueriesFindEveryCentreWithinReach) {
  Box box;
  box.size = Vec3(1.0, 0.7, 1.3);
  for (bool periodic : {true, false}) {
    box.periodic = periodic;
    Random rng(3);
    const double reach = 0.09;
    NeighbourGrid grid(box, reach, 800);
    std::vector<Vec3> c(800);
    for (int i = 0; i < 800; ++i) {
      for (int a = 0; a < 3; ++a) c[i][a] = box.size[a] * rng.uniform();
      grid.insert(i, c[i]);
    }
    for (int i = 0; i < 800; ++i) {
      std::set<int> cand;
      grid.for_each_candidate(c[i], [&](int j) { cand.insert(j); });
      for (int j = 0; j < 800; ++j) {
        bool near = false;
        for_each_image(box, c[i], 0.5 * reach, c[j], 0.5 * reach,
                       [&](const Vec3&) { near = true; });
        if (near) EXPECT_TRUE(cand.count(j)) << "periodic " << periodic << " " << i << " " << j;
      }
    }
  }
}

}  // namespace
}  // namespace rvegen
