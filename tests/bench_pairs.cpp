// Pair tests per second for each shape pair, on near-contact configurations (the hard ones:
// far pairs are rejected by the bounding-sphere test before any of this runs).
#include <benchmark/benchmark.h>

#include <vector>

#include "reference_overlap.hpp"
#include "rvegen/geometry/pair.hpp"
#include "rvegen/geometry/random.hpp"

using namespace rvegen;

namespace {

Shape make(ShapeKind k, Random& rng) {
  switch (k) {
    case ShapeKind::Sphere:
      return Shape::sphere(Vec3::Zero(), rng.uniform(0.5, 1.5));
    case ShapeKind::Cylinder: {
      const double r = rng.uniform(0.3, 1.0);
      return Shape::cylinder(Vec3::Zero(), r, rng.unit_vector() * r * rng.uniform(1, 8));
    }
    case ShapeKind::Ellipsoid:
      return Shape::ellipsoid(Vec3::Zero(),
                              Vec3(rng.uniform(0.5, 2), rng.uniform(0.5, 2), rng.uniform(0.3, 1)),
                              rng.rotation());
  }
  return Shape::sphere(Vec3::Zero(), 1);
}

// Pairs at 0.9 to 1.1 times their contact distance along a random direction: about half overlap.
std::vector<std::pair<Shape, Shape>> near_pairs(ShapeKind ka, ShapeKind kb) {
  Random rng(11);
  std::vector<std::pair<Shape, Shape>> out;
  for (int i = 0; i < 4096; ++i) {
    Shape a = make(ka, rng), b = make(kb, rng);
    const Vec3 u = rng.unit_vector();
    double lo = 0, hi = a.bounding_radius() + b.bounding_radius();
    for (int it = 0; it < 40; ++it) {
      const double m = 0.5 * (lo + hi);
      (reference::overlap(a, b.translated(m * u)) ? lo : hi) = m;
    }
    out.emplace_back(a, b.translated(lo * rng.uniform(0.9, 1.1) * u));
  }
  return out;
}

void BM_Intersect(benchmark::State& state) {
  const auto pairs =
      near_pairs(static_cast<ShapeKind>(state.range(0)), static_cast<ShapeKind>(state.range(1)));
  size_t i = 0, hits = 0;
  for (auto _ : state) {
    const auto& p = pairs[i++ & 4095];
    hits += intersect(p.first, p.second).overlap;
  }
  benchmark::DoNotOptimize(hits);
  state.SetItemsProcessed(state.iterations());
}

void pair_args(benchmark::internal::Benchmark* b) {
  b->ArgNames({"a", "b"});
  for (auto [x, y] : {std::pair{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}}) b->Args({x, y});
}

BENCHMARK(BM_Intersect)->Apply(pair_args);

}  // namespace

BENCHMARK_MAIN();
