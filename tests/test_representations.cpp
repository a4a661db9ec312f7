// Representations and modifiers: voxel accuracy and partial volumes, modifier geometry and
// volumes, packing with envelopes, level sets, files.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>

#include "rvegen/geometry/random.hpp"
#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/report.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/io/writers.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/model/shell_overlaps.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/levelset.hpp"
#include "rvegen/raster/mesh.hpp"
#include "rvegen/raster/voxelize.hpp"
#include "test_util.hpp"

using namespace rvegen;

namespace {

double analytic_fraction(const InclusionSet& set) {
  double v = 0.0;
  for (const auto& inc : set.inclusions) v += region_volumes(inc).core;
  return v / set.box.volume();
}

double centre_fraction(const VoxelImage& im) {
  const auto lf = label_fractions(im);
  double v = 0.0;
  for (const auto& p : im.phases) {
    if (p.kind == PhaseKind::kCore) v += lf[p.label];
  }
  return v;
}

const PackingResult& default_rve() {
  static const PackingResult r = generate(default_scene());
  return r;
}

InclusionSet single(const Shape& s, const Modifiers& m = {}) {
  InclusionSet set;
  set.box.size = Vec3(1, 1, 1);
  Inclusion inc;
  inc.shape = s;
  inc.mod = m;
  set.inclusions.push_back(inc);
  return set;
}

Mat3 some_rotation() {
  return Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
}

Modifiers deformation(double e, double smooth, uint64_t seed) {
  FamilyModifiers f;
  f.deform_amplitude = e;
  f.smoothness = smooth;
  Random rng(seed);
  return f.draw(rng);
}

// The issue's accuracy targets for the default scene: 0.005 at 64^3, 0.002 at 128^3.
TEST(Voxels, DefaultSceneVolumeFractionWithinTargets) {
  const InclusionSet& set = default_rve().set;
  const double exact = analytic_fraction(set);
  for (const auto& [n, tol] : {std::pair<int, double>{64, 0.005}, {128, 0.002}}) {
    const VoxelImage im = voxelize(set, {n, n, n});
    EXPECT_NEAR(centre_fraction(im), exact, tol) << n;
    EXPECT_NEAR(partial_volume_fraction(im), exact, tol) << n;
    EXPECT_EQ(im.conflicts, 0);
  }
}

// Partial volumes of single voxels against brute-force sampling (32^3 points per voxel), for
// the exact line path (plain shapes) and the clearance + subsampling path (modified shapes).
TEST(Voxels, PartialVolumesMatchBruteForcePerVoxel) {
  const std::vector<InclusionSet> sets = {
      single(Shape::sphere({0.43, 0.52, 0.48}, 0.27)),
      single(Shape::cylinder({0.5, 0.47, 0.51}, 0.12, Vec3(0.2, 0.15, 0.25))),
      single(Shape::ellipsoid({0.5, 0.5, 0.5}, Vec3(0.3, 0.2, 0.15), some_rotation())),
      single(Shape::sphere({0.5, 0.5, 0.5}, 0.25), deformation(0.2, 1.0, 7)),
  };
  for (size_t s = 0; s < sets.size(); ++s) {
    VoxelOptions o;
    o.subsamples = 8;
    const VoxelImage im = voxelize(sets[s], {12, 12, 12}, o);
    const BodyQuery body(sets[s].inclusions[0]);
    double worst = 0.0, sum = 0.0;
    for (int k = 0; k < 12; ++k) {
      for (int j = 0; j < 12; ++j) {
        for (int i = 0; i < 12; ++i) {
          int inside = 0;
          const int q = 32;
          for (int c = 0; c < q; ++c) {
            for (int b = 0; b < q; ++b) {
              for (int a = 0; a < q; ++a) {
                const Vec3 x = (Vec3(i, j, k) + (Vec3(a, b, c) + Vec3::Constant(0.5)) / q) / 12.0;
                inside += body.region(x) == Region::kCore;
              }
            }
          }
          const double brute = inside / double(q * q * q);
          worst = std::max(worst, std::abs(brute - im.fraction[im.index(i, j, k)]));
          sum += im.fraction[im.index(i, j, k)];
        }
      }
    }
    EXPECT_LT(worst, 0.03) << "set " << s;
    EXPECT_NEAR(sum / (12.0 * 12 * 12), analytic_fraction(sets[s]), 2e-3) << "set " << s;
  }
}

TEST(Voxels, SameImageWithOneThreadOrMany) {
  const InclusionSet& set = default_rve().set;
  const VoxelImage many = voxelize(set, {40, 40, 40});
  VoxelImage one;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = voxelize(set, {40, 40, 40});
  }
  EXPECT_EQ(one.phase, many.phase);
  EXPECT_EQ(one.inclusion_id, many.inclusion_id);
  EXPECT_EQ(one.fraction, many.fraction);
}

TEST(Voxels, SubExtentIsTheSameSliceOfTheWholeImage) {
  const InclusionSet& set = default_rve().set;
  const VoxelImage whole = voxelize(set, {24, 20, 28});
  VoxelOptions o;
  o.extent = {3, 17, 0, 20, 9, 21};
  const VoxelImage part = voxelize(set, {24, 20, 28}, o);
  ASSERT_EQ(part.count(), size_t(14 * 20 * 12));
  for (int k = 9; k < 21; ++k) {
    for (int j = 0; j < 20; ++j) {
      for (int i = 3; i < 17; ++i) {
        ASSERT_EQ(part.phase[part.index(i, j, k)], whole.phase[whole.index(i, j, k)]);
        ASSERT_EQ(part.inclusion_id[part.index(i, j, k)], whole.inclusion_id[whole.index(i, j, k)]);
        ASSERT_EQ(part.fraction[part.index(i, j, k)], whole.fraction[whole.index(i, j, k)]);
      }
    }
  }
}

TEST(Voxels, PeriodicWrapKeepsTheVolumeAndAxesMayDiffer) {
  // A sphere across the corner of the box: its eight pieces add up to the whole sphere.
  const InclusionSet set = single(Shape::sphere({0.02, 0.97, 0.01}, 0.2));
  const VoxelImage im = voxelize(set, {50, 40, 60});
  EXPECT_NEAR(partial_volume_fraction(im), analytic_fraction(set), 2e-4);
  EXPECT_NEAR(centre_fraction(im), analytic_fraction(set), 3e-3);
  EXPECT_EQ(im.phase[im.index(0, 39, 0)], 1);  // the corner voxel is inside
  EXPECT_EQ(im.phase[im.index(25, 20, 30)], 0);
}

// Every point near an inclusion: the ball of radius clearance(x) about x lies in one region.
TEST(Bodies, ClearanceIsALowerBoundOnTheDistanceToRegionBoundaries) {
  Modifiers coat;
  coat.coating = 0.05;
  Modifiers wave;
  wave.wave_amplitude = 0.04;
  wave.wave_length = 0.3;
  wave.wave_phase = 0.4;
  wave.wave_angle = 1.1;
  Modifiers debond;
  debond.debond_fraction = 0.3;
  debond.debond_gap = 0.04;
  debond.debond_axis = Vec3(1, 1, 0).normalized();
  Modifiers wavy_coated = wave;
  wavy_coated.coating = 0.03;
  Modifiers bent_wavy_coated = wavy_coated;  // a bend to 1.5 lengths on top of the wave
  bent_wavy_coated.bend_radius = 1.0;
  bent_wavy_coated.bend_angle = 2.5;
  const std::vector<Inclusion> cases = {
      single(Shape::sphere({0.5, 0.5, 0.5}, 0.2), coat).inclusions[0],
      single(Shape::cylinder({0.5, 0.5, 0.5}, 0.1, Vec3(0.1, 0.2, 0.1)), coat).inclusions[0],
      single(Shape::ellipsoid({0.5, 0.5, 0.5}, Vec3(0.25, 0.15, 0.1), some_rotation()), coat)
          .inclusions[0],
      single(Shape::cylinder({0.5, 0.5, 0.5}, 0.08, Vec3(0.0, 0.1, 0.3)), wave).inclusions[0],
      single(Shape::cylinder({0.5, 0.5, 0.5}, 0.08, Vec3(0.2, 0.1, 0.1)), wavy_coated)
          .inclusions[0],
      single(Shape::cylinder({0.5, 0.5, 0.5}, 0.06, Vec3(0.1, 0.25, -0.1)), bent_wavy_coated)
          .inclusions[0],
      single(Shape::sphere({0.5, 0.5, 0.5}, 0.2), debond).inclusions[0],
      single(Shape::sphere({0.5, 0.5, 0.5}, 0.2), deformation(0.3, 0.5, 3)).inclusions[0],
      single(Shape::ellipsoid({0.5, 0.5, 0.5}, Vec3(0.25, 0.15, 0.1), some_rotation()),
             deformation(0.2, 1.0, 4))
          .inclusions[0],
  };
  Random rng(11);
  for (size_t c = 0; c < cases.size(); ++c) {
    const BodyQuery body(cases[c]);
    int tested = 0;
    for (int n = 0; n < 20000; ++n) {
      const Vec3 x(rng.uniform(0.1, 0.9), rng.uniform(0.1, 0.9), rng.uniform(0.1, 0.9));
      const double r = body.clearance(x);
      if (!(r > 0.0)) continue;
      const Region here = body.region(x);
      // Points in the ball, the farthest ones especially.
      const Vec3 y = x + r * 0.999 * rng.unit_vector() * std::cbrt(rng.uniform(0.5, 1.0));
      ASSERT_EQ(body.region(y), here) << "case " << c << " x " << x.transpose() << " r " << r;
      ++tested;
    }
    EXPECT_GT(tested, 15000) << "case " << c;
  }
}

// Region volumes (closed forms, Steiner, quadrature) against fine partial-volume images.
TEST(Bodies, RegionVolumesMatchTheVoxelImage) {
  Modifiers coat;
  coat.coating = 0.04;
  Modifiers debond;
  debond.debond_fraction = 0.35;
  debond.debond_gap = 0.05;
  debond.debond_axis = Vec3(0, 0.6, 0.8);
  Modifiers wave;
  wave.wave_amplitude = 0.05;
  wave.wave_length = 0.25;
  Modifiers bend;  // to one fibre length, coated
  bend.bend_radius = 0.65;
  bend.bend_angle = 0.7;
  bend.coating = 0.03;
  const std::vector<InclusionSet> sets = {
      single(Shape::sphere({0.5, 0.5, 0.5}, 0.2), coat),
      single(Shape::cylinder({0.5, 0.5, 0.5}, 0.1, Vec3(0.1, 0.2, 0.1)), coat),
      single(Shape::ellipsoid({0.5, 0.5, 0.5}, Vec3(0.25, 0.15, 0.1), some_rotation()), coat),
      single(Shape::sphere({0.5, 0.5, 0.5}, 0.2), debond),
      single(Shape::cylinder({0.5, 0.5, 0.5}, 0.08, Vec3(0.0, 0.1, 0.3)), wave),
      single(Shape::ellipsoid({0.5, 0.5, 0.5}, Vec3(0.25, 0.15, 0.1), some_rotation()),
             deformation(0.25, 0.7, 5)),
      single(Shape::cylinder({0.5, 0.5, 0.5}, 0.07, Vec3(0.1, 0.3, 0.0)), bend),
  };
  for (size_t s = 0; s < sets.size(); ++s) {
    const RegionVolumes v = region_volumes(sets[s].inclusions[0]);
    const VoxelImage im = voxelize(sets[s], {160, 160, 160});
    const auto lf = label_fractions(im);
    EXPECT_NEAR(partial_volume_fraction(im), v.core, 2e-4 + 1e-3 * v.core) << "set " << s;
    for (const auto& p : im.phases) {
      if (p.kind == PhaseKind::kInterphase)
        EXPECT_NEAR(lf[p.label], v.shell, 0.01 * v.shell) << "set " << s;
      if (p.kind == PhaseKind::kVoid)
        EXPECT_NEAR(lf[p.label], v.void_, 0.02 * v.void_) << "set " << s;
    }
  }
}

TEST(Bodies, DeformationKeepsTheVolumeAndStaysInItsEnvelope) {
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const Inclusion inc =
        single(Shape::ellipsoid({0.5, 0.5, 0.5}, Vec3(0.2, 0.15, 0.1), some_rotation()),
               deformation(0.3, 0.6, seed))
            .inclusions[0];
    const Shape env = envelope(inc);
    const BodyQuery body(inc);
    Random rng(seed);
    int core = 0;
    const int n = 200000;
    for (int k = 0; k < n; ++k) {
      const Vec3 x(rng.uniform(0.25, 0.75), rng.uniform(0.25, 0.75), rng.uniform(0.25, 0.75));
      if (body.region(x) != Region::kCore) continue;
      ++core;
      ASSERT_TRUE(env.contains(x));
    }
    const double mc = core / double(n) * 0.125, exact = inc.shape.volume();
    EXPECT_NEAR(mc, exact, 4.0 * std::sqrt(exact * 0.125 / n)) << "seed " << seed;
  }
}

Scene modified_scene() {
  return parse_scene(R"({
    "box": {"size": [1, 1, 1]}, "seed": 5,
    "families": [
      {"name": "coated", "shape": "sphere", "radius": 0.07, "volume_fraction": 0.10,
       "coating": {"thickness": 0.015}},
      {"name": "touching", "shape": "sphere", "radius": 0.05, "volume_fraction": 0.06,
       "coating": {"thickness": 0.012, "shells_may_touch": true}},
      {"name": "wavy", "shape": "cylinder", "radius": 0.02, "aspect_ratio": 6, "volume_fraction": 0.03,
       "waviness": {"amplitude": 0.01, "wavelength": 0.12}},
      {"name": "bumpy", "shape": "ellipsoid", "semi_axes": [0.07, 0.05, 0.04], "volume_fraction": 0.05,
       "deformation": {"amplitude": 0.2, "smoothness": 0.8}},
      {"name": "debonded", "shape": "sphere", "radius": 0.05, "volume_fraction": 0.04,
       "debonding": {"fraction": 0.3, "gap": 0.01}}
    ]})");
}

const PackingResult& modified_rve() {
  static const PackingResult r = generate(modified_scene());
  return r;
}

// No core ever meets another inclusion's core, shell or void; shells meet only shells of
// "shells_may_touch" neighbours. Checked point by point with the exact regions.
TEST(Modifiers, PackedBodiesDoNotOverlap) {
  const PackingResult& r = modified_rve();
  ASSERT_EQ(r.status, PackingStatus::kOk);
  EXPECT_TRUE(find_overlaps(r.set).empty());
  const auto& incs = r.set.inclusions;
  std::vector<BodyQuery> bodies;
  for (const auto& inc : incs) bodies.emplace_back(inc);
  // Points near every inclusion's envelope surface (where contacts happen), 300 per inclusion.
  Random rng(3);
  long long pairs_seen = 0;
  for (size_t a = 0; a < incs.size(); ++a) {
    const Shape env = outer_bound(incs[a]);
    for (int n = 0; n < 300; ++n) {
      const Vec3 x = env.support(rng.unit_vector()) - 0.01 * rng.uniform() * rng.unit_vector();
      const Region ra = bodies[a].region(x);
      if (ra == Region::kOutside) continue;
      for (size_t b = 0; b < incs.size(); ++b) {
        if (b == a) continue;
        const Vec3 d = x - incs[b].shape.center;
        // Nearest periodic image of b.
        Vec3 shift = Vec3::Zero();
        for (int k = 0; k < 3; ++k)
          shift[k] = -std::round(d[k] / r.set.box.size[k]) * r.set.box.size[k];
        if ((d + shift).norm() > outer_bound(incs[b]).bounding_radius()) continue;
        const Region rb = bodies[b].region(x + shift);
        if (rb == Region::kOutside) continue;
        ++pairs_seen;
        const bool shells = ra == Region::kShell && rb == Region::kShell;
        ASSERT_TRUE(shells && incs[a].mod.shells_may_touch && incs[b].mod.shells_may_touch)
            << "inclusions " << a << " and " << b << " meet at " << x.transpose();
      }
    }
  }
  // Merged shells exist (the family allows them and is packed close): the test saw some.
  EXPECT_GT(pairs_seen, 0);
  const VoxelImage im = voxelize(r.set, {96, 96, 96});
  EXPECT_EQ(im.conflicts, 0);
}

TEST(Modifiers, PhaseVolumeFractionsAreExactAndVoxelsAgree) {
  const PackingResult& r = modified_rve();
  const VoxelImage im = voxelize(r.set, {128, 128, 128});
  const auto lf = label_fractions(im);
  ASSERT_EQ(im.phases.size(), 1u + 5u + 2u + 1u);  // matrix, 5 cores, 2 interphases, 1 void
  std::vector<double> exact(im.phases.size(), 0.0);
  for (const auto& inc : r.set.inclusions) {
    const RegionVolumes v = region_volumes(inc);
    for (const auto& p : im.phases) {
      if (p.family != inc.family) continue;
      exact[p.label] += p.kind == PhaseKind::kCore         ? v.core
                        : p.kind == PhaseKind::kInterphase ? v.shell
                                                           : v.void_;
    }
  }
  // The report's exact volumes: the same, except that the lenses where touching shells
  // overlap count once (here no point lies in three shells, so they are exact).
  const ShellOverlaps o = shell_overlaps(r.set);
  ASSERT_TRUE(o.exact) << o.why_not;
  EXPECT_GT(o.pairs, 0);
  const std::vector<double> reported = phase_volume_fractions(r.set, im.phases);
  for (const auto& p : im.phases) {
    if (p.kind == PhaseKind::kMatrix) continue;
    if (p.name == "touching interphase") {
      // Merged shells count once in the image: the sum of shells is an upper bound.
      EXPECT_LT(lf[p.label], exact[p.label]) << p.name;
      EXPECT_LT(reported[p.label], exact[p.label]) << p.name;
    } else {
      EXPECT_NEAR(reported[p.label], exact[p.label], 1e-12) << p.name;
    }
    EXPECT_NEAR(lf[p.label], reported[p.label], 0.002 + 0.02 * reported[p.label]) << p.name;
  }
  // Cores: the drawn volume fraction of each family to within half an inclusion.
  EXPECT_NEAR(exact[1], 0.10, 0.5 * 4.0 / 3.0 * M_PI * std::pow(0.07, 3));
}

// The lens of two balls against the sum of its two caps (pi h^2 (3 r - h) / 3, h the height of
// each cap over the plane of the rim), and its limits.
TEST(ShellOverlaps, ALensIsItsTwoCaps) {
  auto cap = [](double r, double h) { return M_PI * h * h * (3.0 * r - h) / 3.0; };
  for (const auto& [r1, r2, d] : {std::array<double, 3>{0.14, 0.14, 0.22},
                                  {0.1, 0.05, 0.12},
                                  {0.2, 0.07, 0.16},
                                  {1.0, 0.9, 1.85}}) {
    const double x = (d * d + r1 * r1 - r2 * r2) / (2.0 * d);  // rim plane from the first centre
    const double want = cap(r1, r1 - x) + cap(r2, r2 - (d - x));
    EXPECT_NEAR(ball_lens_volume(r1, r2, d), want, 1e-12 * want) << r1 << " " << r2 << " " << d;
  }
  EXPECT_EQ(ball_lens_volume(0.1, 0.2, 0.31), 0.0);
  EXPECT_NEAR(ball_lens_volume(0.1, 0.3, 0.15), 4.0 / 3.0 * M_PI * 1e-3, 1e-15);
}

// Whether three balls share a point, against a dense sampling of the first two balls' lens:
// where the sampled distance to the third centre is clearly under or over its radius.
TEST(ShellOverlaps, ThreeBallsMeetWhereTheLensReachesTheThird) {
  Random rng(11);
  int meet = 0, apart = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const Vec3 c1 = Vec3::Zero();
    const double r1 = rng.uniform(0.5, 1.0), r2 = rng.uniform(0.5, 1.0), r3 = rng.uniform(0.3, 1.0);
    const Vec3 c2 = rng.uniform(0.3, 0.98) * (r1 + r2) * rng.unit_vector();
    const Vec3 c3 = rng.uniform(0.0, 2.5) * rng.unit_vector();
    double nearest = 1e300;
    for (int n = 0; n < 20000; ++n) {
      const Vec3 p = c1 + r1 * std::cbrt(rng.uniform()) * rng.unit_vector();
      if ((p - c2).norm() <= r2) nearest = std::min(nearest, (p - c3).norm());
    }
    if (nearest == 1e300) continue;  // a lens too thin to sample
    if (nearest < r3 - 0.02) {
      EXPECT_TRUE(balls_meet(c1, r1, c2, r2, c3, r3)) << trial;
      ++meet;
    } else if (nearest > r3 + 0.05) {
      // Sampling finds a lens point within about 0.05 of the true nearest one.
      EXPECT_FALSE(balls_meet(c1, r1, c2, r2, c3, r3)) << trial;
      ++apart;
    }
  }
  EXPECT_GT(meet, 50);
  EXPECT_GT(apart, 50);
}

namespace {

Inclusion coated_sphere(int family, const Vec3& c, double r, double t) {
  Inclusion inc;
  inc.id = 0;
  inc.family = family;
  inc.shape = Shape::sphere(c, r);
  inc.mod.coating = t;
  inc.mod.shells_may_touch = true;
  return inc;
}

// Monte Carlo share of each phase (matrix, 2 cores, 2 interphases), with a shell point given to
// the first inclusion whose shell holds it; plain distances to the nearest image.
std::vector<double> sampled_phases(const InclusionSet& set, long long n) {
  std::vector<long long> count(5, 0);
  Random rng(17);
  for (long long s = 0; s < n; ++s) {
    const Vec3 x(rng.uniform(), rng.uniform(), rng.uniform());
    int phase = 0;
    for (const Inclusion& inc : set.inclusions) {
      Vec3 d = x - inc.shape.center;
      for (int k = 0; k < 3; ++k) d[k] -= std::round(d[k]);
      if (d.norm() <= inc.shape.radius) {
        phase = 1 + inc.family;
        break;
      }
      if (phase == 0 && d.norm() <= inc.shape.radius + inc.mod.coating) phase = 3 + inc.family;
    }
    ++count[phase];
  }
  std::vector<double> f(5);
  for (int k = 0; k < 5; ++k) f[k] = count[k] / double(n);
  return f;
}

}  // namespace

// Shells that may touch: where two overlap (once across the periodic boundary), the exact
// phase volumes count the lens once, in the earlier inclusion's shell, and agree with a Monte
// Carlo sampling that the sum of shells is far from. A third shell through a lens makes the
// overlaps inexact: then the sum of shells stands, and the report says why.
TEST(ShellOverlaps, MergedShellsCountOnceInThePhaseVolumes) {
  InclusionSet set;
  set.family_names = {"a", "b"};
  const double r = 0.08, t = 0.06;
  set.inclusions = {
      coated_sphere(0, {0.3, 0.3, 0.3}, r, t), coated_sphere(0, {0.52, 0.3, 0.3}, r, t),
      coated_sphere(1, {0.1, 0.8, 0.5}, r, t), coated_sphere(0, {0.88, 0.8, 0.5}, r, t)};
  for (size_t i = 0; i < set.inclusions.size(); ++i) set.inclusions[i].id = static_cast<int>(i);
  const ShellOverlaps o = shell_overlaps(set);
  ASSERT_TRUE(o.exact) << o.why_not;
  EXPECT_EQ(o.pairs, 2);
  EXPECT_EQ(o.triples, 0);
  const double lens = ball_lens_volume(r + t, r + t, 0.22);
  ASSERT_EQ(o.taken.size(), 2u);
  EXPECT_NEAR(o.taken[0], 2.0 * lens, 1e-12);  // both lenses leave family a's shells
  EXPECT_EQ(o.taken[1], 0.0);                  // b's sphere came before its partner
  const std::vector<Phase> phases = phase_table(set);
  ASSERT_EQ(phases.size(), 5u);
  ASSERT_EQ(phases[3].kind, PhaseKind::kInterphase);
  const std::vector<double> exact = phase_volume_fractions(set, phases);
  const long long n = 8000000;
  const std::vector<double> mc = sampled_phases(set, n);
  const double shell = 4.0 / 3.0 * M_PI * (std::pow(r + t, 3) - std::pow(r, 3));
  for (int k = 0; k < 5; ++k) {
    const double sigma = std::sqrt(exact[k] * (1.0 - exact[k]) / n);
    EXPECT_NEAR(mc[k], exact[k], 4.0 * sigma) << phases[k].name;
  }
  // The sum of shells (what was reported before) is many deviations off.
  const double sigma_a = std::sqrt(exact[3] / n);
  EXPECT_GT(3.0 * shell - mc[3], 10.0 * sigma_a);
  EXPECT_NEAR(exact[3], 3.0 * shell - 2.0 * lens, 1e-12);

  // Three shells through one point (cores 0.22 apart in a triangle: the centroid is 0.127 from
  // each centre, within 0.14).
  InclusionSet three = set;
  three.inclusions.push_back(
      coated_sphere(1, {0.41, 0.3 + 0.22 * std::sqrt(3.0) / 2.0, 0.3}, r, t));
  three.inclusions.back().id = 4;
  const ShellOverlaps o3 = shell_overlaps(three);
  EXPECT_FALSE(o3.exact);
  EXPECT_EQ(o3.triples, 1);
  EXPECT_NE(o3.why_not.find("triples"), std::string::npos) << o3.why_not;
  const std::vector<double> upper = phase_volume_fractions(three, phase_table(three));
  EXPECT_NEAR(upper[3], 3.0 * shell, 1e-12);
  EXPECT_NEAR(upper[4], 2.0 * shell, 1e-12);
}

// A shell wider than the box meets its own periodic images: each such pair (the image along +x,
// +y and +z; the diagonal ones are out of reach) counts once.
TEST(ShellOverlaps, AShellMeetsItsOwnImagesOncePerPair) {
  InclusionSet set;
  set.box.size = Vec3(0.3, 0.3, 0.3);
  set.family_names = {"a"};
  set.inclusions = {coated_sphere(0, {0.1, 0.2, 0.15}, 0.1, 0.06)};
  const ShellOverlaps o = shell_overlaps(set);
  ASSERT_TRUE(o.exact) << o.why_not;
  EXPECT_EQ(o.pairs, 3);
  EXPECT_EQ(o.triples, 0);
  EXPECT_NEAR(o.taken[0], 3.0 * ball_lens_volume(0.16, 0.16, 0.3), 1e-15);
}

TEST(Modifiers, SameSeedSameModifiedRve) {
  const PackingResult again = generate(modified_scene());
  EXPECT_EQ(write_inclusions_json(again.set), write_inclusions_json(modified_rve().set));
  // The inclusion file carries the modifiers: read back, it gives the same bytes.
  const InclusionSet back = read_inclusions_json(write_inclusions_json(again.set));
  EXPECT_EQ(write_inclusions_json(back), write_inclusions_json(again.set));
}

TEST(Modifiers, BadInputNamesTheKey) {
  const std::string head = R"({"box": {"size": [1, 1, 1]}, "families": [)";
  auto err = [&](const std::string& fam) { return scene_error(head + fam + "]}"); };
  EXPECT_NE(
      err(R"({"shape": "sphere", "radius": 0.05, "volume_fraction": 0.1, "waviness": {"amplitude": 0.01, "wavelength": 0.1}})")
          .find("families[0].waviness: waviness applies to cylinders only"),
      std::string::npos);
  EXPECT_NE(
      err(R"({"shape": "sphere", "radius": 0.05, "volume_fraction": 0.1, "deformation": {"amplitude": 0.7}})")
          .find("families[0].deformation.amplitude"),
      std::string::npos);
  EXPECT_NE(
      err(R"({"shape": "sphere", "radius": 0.05, "volume_fraction": 0.1, "coating": {"thickness": -0.01}})")
          .find("families[0].coating.thickness"),
      std::string::npos);
  EXPECT_NE(
      err(R"({"shape": "sphere", "radius": 0.05, "volume_fraction": 0.1, "coating": {"thickness": 0.01, "colour": 1}})")
          .find("families[0].coating.colour: unknown key"),
      std::string::npos);
  EXPECT_NE(
      err(R"({"shape": "sphere", "radius": 0.05, "volume_fraction": 0.1, "coating": {"thickness": 0.01}, "deformation": {"amplitude": 0.1}})")
          .find("coating and deformation together"),
      std::string::npos);
  EXPECT_NE(
      err(R"({"shape": "cylinder", "radius": 0.02, "aspect_ratio": 4, "volume_fraction": 0.1, "debonding": {"fraction": 0.2, "gap": 0.01}})")
          .find("families[0].debonding"),
      std::string::npos);
  EXPECT_NE(
      err(R"({"shape": "sphere", "radius": 0.05, "volume_fraction": 0.1, "curvature": {"radius": 1}})")
          .find("families[0].curvature: curvature applies to cylinders only"),
      std::string::npos);
  // A radius of curvature below the fibre's length (0.16 + 2 x 0.01 with the coating).
  EXPECT_NE(
      err(R"({"shape": "cylinder", "radius": 0.02, "aspect_ratio": 4, "volume_fraction": 0.1, "coating": {"thickness": 0.01}, "curvature": {"radius": 0.17}})")
          .find("families[0].curvature.radius: must be at least the longest fibre's length with "
                "its coating (0.18)"),
      std::string::npos);
  EXPECT_NE(
      err(R"({"shape": "cylinder", "radius": 0.02, "aspect_ratio": 4, "volume_fraction": 0.1, "curvature": {"radius": -1}})")
          .find("families[0].curvature.radius"),
      std::string::npos);
  EXPECT_NE(
      err(R"({"shape": "cylinder", "radius": 0.02, "aspect_ratio": 4, "volume_fraction": 0.1, "curvature": {"radius": 1, "plane": 0}})")
          .find("families[0].curvature.plane: unknown key"),
      std::string::npos);
  // Thick coatings: 0.5 of cores, but the envelopes would fill more than any packing allows.
  EXPECT_NE(
      err(R"({"shape": "sphere", "radius": 0.05, "volume_fraction": 0.5, "coating": {"thickness": 0.02}})")
          .find("envelopes"),
      std::string::npos);
}

TEST(LevelSets, OnlyForWhatNeedsOneAndSignsMatchTheRegions) {
  EXPECT_TRUE(build_level_sets(default_rve().set).empty());
  const PackingResult& r = modified_rve();
  LevelSetOptions o;
  o.voxel_size = 1.0 / 160.0;
  // By default the wavy and bumpy cores only: the coated spheres' shells are exact in closed
  // form (their glyph and thickness say it all).
  const LevelSets needed = build_level_sets(r.set, o);
  ASSERT_EQ(needed.grids.size(), 2u);
  for (const LevelSetInfo& info : needed.grids) EXPECT_EQ(info.kind, PhaseKind::kCore);
  // Asked for: coated + touching interphases too.
  o.exact_shapes = true;
  const LevelSets ls = build_level_sets(r.set, o);
  ASSERT_EQ(ls.grids.size(), 4u);
  // Sparse memory grows as the surface area over h^2, dense as the volume over h^3: halving
  // the voxel size must halve (about) the ratio. (At this coarse size the narrow band fills most
  // OpenVDB leaves, so the ratio itself is not small; see the README's chart.)
  LevelSetOptions coarse = o;
  coarse.voxel_size = 2.0 * o.voxel_size;
  const LevelSets lc = build_level_sets(r.set, coarse);
  const double ratio_fine = double(ls.memory_bytes) / ls.dense_bytes;
  const double ratio_coarse = double(lc.memory_bytes) / lc.dense_bytes;
  EXPECT_LT(ratio_fine, 0.7 * ratio_coarse);
  Random rng(8);
  std::vector<BodyQuery> bodies;
  for (const auto& inc : r.set.inclusions) bodies.emplace_back(inc);
  int checked = 0;
  for (size_t g = 0; g < ls.grids.size(); ++g) {
    const LevelSetInfo& info = ls.grids[g];
    for (size_t i = 0; i < r.set.inclusions.size(); ++i) {
      const Inclusion& inc = r.set.inclusions[i];
      if (inc.family != info.family) continue;
      const Shape env = outer_bound(inc);
      for (int n = 0; n < 200; ++n) {
        const Vec3 x =
            inc.shape.center + env.bounding_radius() * std::cbrt(rng.uniform()) * rng.unit_vector();
        const double d = info.kind == PhaseKind::kCore ? bodies[i].core_distance(x)
                                                       : bodies[i].shell_distance(x);
        if (std::abs(d) < 2.0 * o.voxel_size) continue;  // the sign is decided at the voxel scale
        const Region reg = bodies[i].region(x);
        const bool inside =
            info.kind == PhaseKind::kCore ? reg == Region::kCore : reg == Region::kShell;
        // Points outside this body may lie in a neighbour of the same grid: skip them.
        if (!inside) continue;
        EXPECT_LT(level_set_value(ls, g, x), 0.0) << info.name << " at " << x.transpose();
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 1000);
  // No point lies inside two grids (wavy and bumpy cores, interphases of different families).
  for (int n = 0; n < 100000; ++n) {
    const Vec3 x(rng.uniform(), rng.uniform(), rng.uniform());
    int inside = 0;
    for (size_t g = 0; g < ls.grids.size(); ++g)
      inside += level_set_value(ls, g, x) < -o.voxel_size;
    ASSERT_LE(inside, 1) << x.transpose();
  }
}

TEST(LevelSets, VdbFileReadsBack) {
  const PackingResult& r = modified_rve();
  LevelSetOptions o;
  o.voxel_size = 1.0 / 64.0;
  const LevelSets ls = build_level_sets(r.set, o);
  const std::string path = (std::filesystem::temp_directory_path() / "rvegen_test.vdb").string();
  {
    std::ofstream out(path, std::ios::binary);
    out << vdb_bytes(ls, r.set);
  }
  const auto grids = read_vdb_summary(path);
  std::remove(path.c_str());
  ASSERT_EQ(grids.size(), ls.grids.size());
  for (size_t g = 0; g < grids.size(); ++g) {
    EXPECT_EQ(grids[g].first, ls.grids[g].name);
    EXPECT_EQ(grids[g].second, ls.grids[g].active_voxels);
  }
  // Meshed at the zero level: closed surfaces with outward normals (positive volume).
  const SurfaceMesh m = level_set_surfaces(ls);
  double volume = 0.0;
  for (const auto& t : m.triangles) {
    volume += m.points[t[0]].dot(m.points[t[1]].cross(m.points[t[2]])) / 6.0;
  }
  EXPECT_GT(volume, 0.0);
}

// With a chord error the segments around a cylinder are the fewest that keep every chord within
// it of the true surface (r (1 - cos(pi / n)) <= e < r (1 - cos(pi / (n - 1)))).
TEST(Surfaces, ChordErrorChoosesTheSegments) {
  for (const double r : {0.03, 0.1}) {
    for (const double e : {2e-4, 1e-3}) {
      const InclusionSet set = single(Shape::cylinder({0.5, 0.5, 0.5}, r, Vec3(0.0, 0.0, 0.2)));
      MeshOptions o;
      o.chord_error = e;
      o.min_segments = 3;
      o.max_segments = 1000;
      const SurfaceMesh m = tessellate(set, o);
      int side = 0;  // points on the lateral surface (two rings of n)
      for (const Vec3& p : m.points) {
        side += std::abs(std::hypot(p[0] - 0.5, p[1] - 0.5) - r) < 1e-12;
      }
      const int n = side / 2;
      ASSERT_GT(n, 3);
      EXPECT_LE(r * (1.0 - std::cos(M_PI / n)), e * (1.0 + 1e-12)) << r << " " << e;
      EXPECT_GT(r * (1.0 - std::cos(M_PI / (n - 1))), e) << r << " " << e;
    }
  }
  // mesh_options turns the scene's chord error in voxels into a length.
  Scene scene = default_scene();
  scene.resolution = {64, 128, 32};
  scene.surface_chord_error = 0.5;
  EXPECT_DOUBLE_EQ(mesh_options(scene, scene.box).chord_error, 0.5 * scene.box.size[1] / 128);
}

TEST(Surfaces, ClippedToTheBoxAndCarryCellData) {
  const InclusionSet& set = default_rve().set;
  MeshOptions o;
  const SurfaceMesh open = tessellate(set, o);
  o.clip_to_box = true;
  const SurfaceMesh clipped = tessellate(set, o);
  auto outside = [&](const SurfaceMesh& m) {
    int n = 0;
    for (const auto& p : m.points) n += (p.array() < -1e-12).any() || (p.array() > 1 + 1e-12).any();
    return n;
  };
  EXPECT_GT(outside(open), 0);
  EXPECT_EQ(outside(clipped), 0);
  ASSERT_EQ(clipped.phase.size(), clipped.triangles.size());
  ASSERT_EQ(clipped.axis.size(), clipped.triangles.size());
  // Small inclusions get fewer segments than large ones.
  InclusionSet two = single(Shape::sphere({0.3, 0.3, 0.3}, 0.02));
  two.inclusions.push_back(single(Shape::sphere({0.7, 0.7, 0.7}, 0.2)).inclusions[0]);
  two.inclusions[1].id = 1;
  const SurfaceMesh m = tessellate(two);
  const auto small = std::count(m.inclusion_id.begin(), m.inclusion_id.end(), 0);
  const auto large = std::count(m.inclusion_id.begin(), m.inclusion_id.end(), 1);
  EXPECT_LT(4 * small, large);
}

TEST(Files, AmitexMaterialMapHeaderAndNumbering) {
  const VoxelImage im = voxelize(default_rve().set, {8, 6, 4});
  const std::string b = material_vtk_bytes(im);
  std::vector<std::string> lines;
  size_t pos = 0;
  for (int i = 0; i < 10; ++i) {
    const size_t nl = b.find('\n', pos);
    lines.push_back(b.substr(pos, nl - pos));
    pos = nl + 1;
  }
  EXPECT_EQ(lines[0], "# vtk DataFile Version 4.5");
  EXPECT_EQ(lines[2], "BINARY");
  EXPECT_EQ(lines[3], "DATASET STRUCTURED_POINTS");
  EXPECT_EQ(lines[4], "DIMENSIONS 9 7 5");
  EXPECT_EQ(lines[7], "CELL_DATA 192");
  EXPECT_EQ(lines[8], "SCALARS MaterialId unsigned_short");
  ASSERT_EQ(b.size() - pos, 2u * 192u);
  // Big-endian, 1..N without holes.
  std::set<int> seen;
  for (size_t i = 0; i < 192; ++i) {
    const int v = (static_cast<unsigned char>(b[pos + 2 * i]) << 8) |
                  static_cast<unsigned char>(b[pos + 2 * i + 1]);
    seen.insert(v);
    EXPECT_EQ(v >= 1, true);
  }
  EXPECT_EQ(*seen.begin(), 1);
  EXPECT_EQ(*seen.rbegin(), static_cast<int>(seen.size()));
}

}  // namespace
