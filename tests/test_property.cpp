// Randomized property test: the library's exact pair tests against the independent MPR
// reference (reference_overlap.hpp) on near-contact pairs of every shape combination,
// degenerate configurations included.
//
// For each geometry (shapes, orientations and a direction u) the reference finds by bisection
// the translation t* of b along u at which the pair stops overlapping; the pair is then tested
// at t = t* (1 + delta) for several delta, |delta| in [1e-5, 5e-2], and the library must say
// "overlap" exactly when delta < 0. For every overlap found, translating b by the reported
// depth along the reported normal must separate the pair (checked with the reference).
#include <gtest/gtest.h>

#include <cstdlib>
#include <map>
#include <ostream>
#include <string>
#include <vector>

#include "reference_overlap.hpp"
#include "rvegen/geometry/pair.hpp"
#include "rvegen/geometry/random.hpp"

using namespace rvegen;

namespace {

long pairs_per_combination() {
  const char* env = std::getenv("RVEGEN_PROPERTY_PAIRS");
  return env ? std::atol(env) : 1000000L;
}

Shape random_shape(ShapeKind kind, Random& rng, const Vec3& axis) {
  switch (kind) {
    case ShapeKind::Sphere:
      return Shape::sphere(Vec3::Zero(), rng.uniform(0.3, 2.0));
    case ShapeKind::Cylinder: {
      const double r = rng.uniform(0.3, 1.5);
      // Aspect ratios from flat disks (0.1) to long fibres (10).
      const double a = std::exp(rng.uniform(std::log(0.1), std::log(10.0)));
      return Shape::cylinder(Vec3::Zero(), r, axis * (a * r));
    }
    case ShapeKind::Ellipsoid: {
      Mat3 R = rng.rotation();
      // Principal axis 0 along `axis` (keeps the degenerate modes meaningful).
      const Vec3 b0 = any_orthogonal(axis);
      R.col(0) = axis;
      R.col(1) = b0;
      R.col(2) = axis.cross(b0);
      const Vec3 semi(rng.uniform(0.3, 2.0), rng.uniform(0.3, 2.0), rng.uniform(0.3, 2.0));
      return Shape::ellipsoid(Vec3::Zero(), semi, R);
    }
  }
  return Shape::sphere(Vec3::Zero(), 1.0);
}

struct Combo {
  ShapeKind a, b;
  const char* name;
  std::vector<std::string> expected_types;  // each must be met at least once
};

void PrintTo(const Combo& c, std::ostream* os) {
  *os << c.name;
}

class PropertyTest : public ::testing::TestWithParam<Combo> {};

TEST_P(PropertyTest, AgreesWithReferenceNearContact) {
  const Combo combo = GetParam();
  const long total = pairs_per_combination();
  const int offsets_per_geometry = 10;
  Random rng(1234 + static_cast<int>(combo.a) * 7 + static_cast<int>(combo.b));
  long tested = 0, disagreements = 0, bad_separation = 0;
  std::map<std::string, long> types;
  std::map<int, long> modes;
  std::string first_failure;
  while (tested < total) {
    // Degenerate modes: 0 generic, 1 parallel or anti-parallel axes, 2 coaxial (end to end),
    // 3 perpendicular axes along the common perpendicular, 4 direction along or across a's
    // axis (caps and rims), 5 axes in one plane with u in that plane (coplanar axes).
    const int mode = static_cast<int>(rng.uniform() * 6);
    Vec3 ua = rng.unit_vector(), ub = rng.unit_vector(), u = rng.unit_vector();
    switch (mode) {
      case 1:
        ub = rng.uniform() < 0.5 ? ua : Vec3(-ua);
        break;
      case 2:
        ub = rng.uniform() < 0.5 ? ua : Vec3(-ua);
        u = rng.uniform() < 0.5 ? ua : Vec3(-ua);
        break;
      case 3:
        ub = any_orthogonal(ua);
        u = ua.cross(ub);
        break;
      case 4:
        u = rng.uniform() < 0.5 ? ua : any_orthogonal(ua);
        break;
      case 5: {
        const Vec3 e = any_orthogonal(ua);
        const double th = rng.uniform(0, 2 * M_PI), ph = rng.uniform(0, 2 * M_PI);
        ub = std::cos(th) * ua + std::sin(th) * e;
        u = std::cos(ph) * ua + std::sin(ph) * e;
        break;
      }
      default:
        break;
    }
    ++modes[mode];
    Shape a = random_shape(combo.a, rng, ua);
    Shape b0 = random_shape(combo.b, rng, ub);
    a.center = Vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
    b0.center = a.center;
    // Contact translation along u by bisection on the reference (b at a's centre overlaps).
    double lo = 0.0, hi = a.bounding_radius() + b0.bounding_radius();
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      (reference::overlap(a, b0.translated(mid * u)) ? lo : hi) = mid;
    }
    const double tstar = 0.5 * (lo + hi);
    for (int k = 0; k < offsets_per_geometry && tested < total; ++k, ++tested) {
      const double mag = std::exp(rng.uniform(std::log(1e-5), std::log(5e-2)));
      const double delta = (k % 2 == 0) ? -mag : mag;
      const Shape b = b0.translated(tstar * (1.0 + delta) * u);
      const bool expected = delta < 0;
      const Contact c = intersect(a, b);
      if (c.overlap != expected) {
        ++disagreements;
        if (first_failure.empty()) {
          char buf[512];
          std::snprintf(buf, sizeof buf,
                        "mode %d delta %.3g expected %d got %d type %s | a kind %d c(%.17g %.17g "
                        "%.17g) r %.17g l(%.17g %.17g %.17g) | b kind %d c(%.17g %.17g %.17g) r "
                        "%.17g l(%.17g %.17g %.17g)",
                        mode, delta, expected, c.overlap, contact_type_name(c.type),
                        static_cast<int>(a.kind), a.center.x(), a.center.y(), a.center.z(),
                        a.radius, a.half_axis.x(), a.half_axis.y(), a.half_axis.z(),
                        static_cast<int>(b.kind), b.center.x(), b.center.y(), b.center.z(),
                        b.radius, b.half_axis.x(), b.half_axis.y(), b.half_axis.z());
          first_failure = buf;
        }
        continue;
      }
      if (c.overlap) {
        ++types[contact_type_name(c.type)];
        const double margin = 1e-7 * std::min(a.min_size(), b.min_size());
        const Shape moved = b.translated((c.depth + margin) * c.normal);
        if (reference::overlap(a, moved)) ++bad_separation;
      }
    }
  }
  std::string summary;
  for (const auto& [t, n] : types) summary += t + "=" + std::to_string(n) + " ";
  RecordProperty("types", summary);
  std::printf("[ %s ] %ld pairs; overlap types: %s\n", combo.name, tested, summary.c_str());
  EXPECT_EQ(disagreements, 0) << "first: " << first_failure;
  EXPECT_EQ(bad_separation, 0) << "reported depth/normal did not separate the pair";
  for (const auto& t : combo.expected_types)
    EXPECT_GT(types[t], 0) << "type never exercised: " << t;
}

INSTANTIATE_TEST_SUITE_P(
    AllCombinations, PropertyTest,
    ::testing::Values(
        Combo{ShapeKind::Sphere, ShapeKind::Sphere, "sphere-sphere", {"ss"}},
        Combo{ShapeKind::Sphere, ShapeKind::Cylinder, "sphere-cylinder", {"sc2", "sc3", "sc4"}},
        Combo{ShapeKind::Cylinder, ShapeKind::Sphere, "cylinder-sphere", {"sc2", "sc3", "sc4"}},
        Combo{ShapeKind::Sphere, ShapeKind::Ellipsoid, "sphere-ellipsoid", {"pw"}},
        Combo{ShapeKind::Cylinder,
              ShapeKind::Cylinder,
              "cylinder-cylinder",
              {"cc1", "cd1", "cd2", "cd3", "d1", "d2"}},
        Combo{ShapeKind::Cylinder, ShapeKind::Ellipsoid, "cylinder-ellipsoid", {"ce"}},
        Combo{ShapeKind::Ellipsoid, ShapeKind::Ellipsoid, "ellipsoid-ellipsoid", {"pw"}}),
    [](const ::testing::TestParamInfo<Combo>& info) {
      std::string s = info.param.name;
      for (char& ch : s) {
        if (ch == '-') ch = '_';
      }
      return s;
    });

}  // namespace
