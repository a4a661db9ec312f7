// Molecular-dynamics packing: contact response, laws, and the places where packers fail.
#include <gtest/gtest.h>

#include <cmath>

#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/report.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/model/stats.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/contacts.hpp"
#include "rvegen/packing/packing.hpp"
#include "test_util.hpp"

namespace rvegen {
namespace {

double total_fraction(const PackingResult& r) {
  double vf = 0.0;
  for (double v : family_volume_fractions(r.set, static_cast<int>(r.target_count.size()))) vf += v;
  return vf;
}

// Every result: no overlap by the exact tests, inside a non-periodic box, centres in the box.
void expect_valid(const PackingResult& r) {
  EXPECT_TRUE(find_overlaps(r.set).empty());
  EXPECT_TRUE(find_outside(r.set).empty());
  const Box& b = r.set.box;
  for (const auto& inc : r.set.inclusions) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_TRUE(std::isfinite(inc.shape.center[k]));
      EXPECT_GE(inc.shape.center[k], b.origin[k]);
      EXPECT_LE(inc.shape.center[k], b.origin[k] + b.size[k]);
    }
  }
}

// --- Contact response -------------------------------------------------------------------

struct ResponseCase {
  Shape a, b;
};

std::vector<ResponseCase> overlapping_pairs() {
  const Mat3 R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  return {
      {Shape::sphere(Vec3(0, 0, 0), 1.0), Shape::sphere(Vec3(1.5, 0.2, 0), 0.8)},
      {Shape::cylinder(Vec3(0, 0, 0), 0.3, Vec3(0, 0, 2)),
       Shape::cylinder(Vec3(0.5, 0, 1.2), 0.3, Vec3(2, 0, 0))},
      {Shape::cylinder(Vec3(0, 0, 0), 0.5, Vec3(0, 0, 1)), Shape::sphere(Vec3(0.3, 0.6, 1.2), 0.5)},
      {Shape::ellipsoid(Vec3(0, 0, 0), Vec3(1.5, 1.0, 0.5), R),
       Shape::ellipsoid(Vec3(1.2, 0.9, 0.2), Vec3(1.2, 0.6, 0.4), Mat3::Identity())},
      {Shape::cylinder(Vec3(0, 0, 0), 0.3, Vec3(0, 0, 1.5)),
       Shape::ellipsoid(Vec3(0.6, 0.3, 1.0), Vec3(0.8, 0.5, 0.3), R)},
  };
}

TEST(ContactResponse, RepulsiveProportionalEqualOppositeWithConsistentTorques) {
  for (const auto& pc : overlapping_pairs()) {
    const Contact c = intersect(pc.a, pc.b);
    ASSERT_TRUE(c.overlap);
    const BodyMobility ma = body_mobility(pc.a, true, Vec3::Zero());
    const BodyMobility mb = body_mobility(pc.b, true, Vec3::Zero());
    const ContactResponse r = contact_response(pc.a.center, ma, pc.b.center, mb, c, 1.0);
    // Repulsive: b is pushed along the normal from a to b, a the other way.
    EXPECT_GT(r.impulse.dot(c.normal), 0.0);
    EXPECT_NEAR(r.impulse.cross(c.normal).norm(), 0.0, 1e-12 * r.impulse.norm());
    EXPECT_GT(r.move_b.dot(c.normal), 0.0);
    EXPECT_LT(r.move_a.dot(c.normal), 0.0);
    // Equal and opposite impulses: momentum (volume x displacement) is conserved.
    EXPECT_NEAR((r.move_a / ma.inv_volume + r.move_b / mb.inv_volume).norm(), 0.0,
                1e-12 * r.impulse.norm());
    // Torques are those of the two forces at the contact point, so angular momentum about
    // the origin is conserved too: ca x (-J) + tau_a + cb x J + tau_b = 0.
    const Vec3 tau_a = (c.point - pc.a.center).cross(-r.impulse);
    const Vec3 tau_b = (c.point - pc.b.center).cross(r.impulse);
    EXPECT_NEAR((ma.inv_inertia * tau_a - r.turn_a).norm(), 0.0, 1e-12 * (1 + r.turn_a.norm()));
    EXPECT_NEAR((mb.inv_inertia * tau_b - r.turn_b).norm(), 0.0, 1e-12 * (1 + r.turn_b.norm()));
    EXPECT_NEAR(
        (pc.a.center.cross(-r.impulse) + tau_a + pc.b.center.cross(r.impulse) + tau_b).norm(), 0.0,
        1e-12 * (1 + r.impulse.norm()));
    // Proportional to the overlap: twice the depth, twice the impulse.
    Contact c2 = c;
    c2.depth *= 2.0;
    const ContactResponse r2 = contact_response(pc.a.center, ma, pc.b.center, mb, c2, 1.0);
    EXPECT_NEAR((r2.impulse - 2.0 * r.impulse).norm(), 0.0, 1e-12 * r.impulse.norm());
    // Alone, the contact point of b moves away from that of a by exactly the depth along n
    // (linearised: translation plus small rotation).
    const Vec3 va = r.move_a + r.turn_a.cross(c.point - pc.a.center);
    const Vec3 vb = r.move_b + r.turn_b.cross(c.point - pc.b.center);
    EXPECT_NEAR((vb - va).dot(c.normal), c.depth, 1e-9 * c.depth);
  }
}

TEST(ContactResponse, SeparatesTwoSpheresExactlyInOneStep) {
  const Shape a = Shape::sphere(Vec3(0, 0, 0), 1.0), b = Shape::sphere(Vec3(1.2, 0.5, 0), 0.5);
  const Contact c = intersect(a, b);
  ASSERT_TRUE(c.overlap);
  const ContactResponse r =
      contact_response(a.center, body_mobility(a, true, Vec3::Zero()), b.center,
                       body_mobility(b, true, Vec3::Zero()), c, 1.0);
  EXPECT_TRUE(r.turn_a.isZero() && r.turn_b.isZero());  // spheres do not turn
  // The lighter sphere moves more, in inverse proportion to the volumes.
  EXPECT_NEAR(r.move_b.norm() / r.move_a.norm(), 8.0, 1e-12);
  const double after = (b.center + r.move_b - a.center - r.move_a).norm();
  EXPECT_NEAR(after, 1.5, 1e-12);
}

TEST(ContactResponse, TurningLimitedToTheAllowedAxis) {
  const Shape a = Shape::cylinder(Vec3(0, 0, 0), 0.2, Vec3(1, 0, 0));
  const Shape b = Shape::sphere(Vec3(0.9, 0.3, 0.1), 0.2);
  const Contact c = intersect(a, b);
  ASSERT_TRUE(c.overlap);
  const Vec3 normal_axis(0, 0, 1);  // planar law in the xy plane: turns about z only
  const ContactResponse r =
      contact_response(a.center, body_mobility(a, true, normal_axis), b.center,
                       body_mobility(b, true, Vec3::Zero()), c, 1.0);
  EXPECT_GT(std::abs(r.turn_a.z()), 0.0);
  EXPECT_NEAR(r.turn_a.head<2>().norm(), 0.0, 1e-15);
  const ContactResponse locked =
      contact_response(a.center, body_mobility(a, false, Vec3::Zero()), b.center,
                       body_mobility(b, true, Vec3::Zero()), c, 1.0);
  EXPECT_TRUE(locked.turn_a.isZero());
}

// --- Laws -------------------------------------------------------------------------------

TEST(Laws, SizeLawsHaveTheirMeanAndSpread) {
  Random rng(7);
  SizeLaw logn;
  logn.kind = SizeLaw::Kind::kLognormal;
  logn.p1 = 2.0;
  logn.p2 = 0.6;
  SizeLaw norm;
  norm.kind = SizeLaw::Kind::kNormal;
  norm.p1 = 1.0;
  norm.p2 = 0.8;  // heavy truncation at 0
  SizeLaw uni;
  uni.kind = SizeLaw::Kind::kUniform;
  uni.p1 = 1.0;
  uni.p2 = 3.0;
  for (const SizeLaw* law : {&logn, &norm, &uni}) {
    double s = 0.0, s2 = 0.0, s3 = 0.0;
    const int n = 200000;
    for (int i = 0; i < n; ++i) {
      const double x = law->sample(rng);
      ASSERT_GT(x, 0.0);
      ASSERT_GE(x, law->lower());
      ASSERT_LE(x, law->upper());
      s += x;
      s2 += x * x;
      s3 += x * x * x;
    }
    EXPECT_NEAR(s / n, law->moment(1), 0.01 * law->moment(1));
    EXPECT_NEAR(s2 / n, law->moment(2), 0.02 * law->moment(2));
    EXPECT_NEAR(s3 / n, law->moment(3), 0.03 * law->moment(3));
  }
  // The lognormal law takes the mean and std of the size itself.
  EXPECT_NEAR(logn.moment(1), 2.0, 1e-3);
  EXPECT_NEAR(std::sqrt(logn.moment(2) - 4.0), 0.6, 1e-3);
}

TEST(Laws, OrientationLawsGiveTheirTensors) {
  Random rng(3);
  const int n = 100000;
  auto tensor = [&](const OrientationLaw& law) {
    Mat3 a = Mat3::Zero();
    for (int i = 0; i < n; ++i) {
      const Vec3 u = law.sample(rng);
      EXPECT_NEAR(u.norm(), 1.0, 1e-12);
      a += u * u.transpose();
    }
    return Mat3(a / n);
  };
  OrientationLaw iso;
  EXPECT_NEAR((tensor(iso) - Mat3::Identity() / 3.0).norm(), 0.0, 0.01);
  OrientationLaw planar;
  planar.kind = OrientationLaw::Kind::kPlanar;
  planar.axis = Vec3(0, 0, 1);
  const Mat3 ap = tensor(planar);
  EXPECT_NEAR(ap(2, 2), 0.0, 1e-12);
  EXPECT_NEAR(ap(0, 0), 0.5, 0.01);
  OrientationLaw vmf;
  vmf.kind = OrientationLaw::Kind::kVonMisesFisher;
  vmf.axis = Vec3(1, 0, 0);
  vmf.kappa = 10.0;
  // <cos^2> for the von Mises-Fisher law: 1 - 2 / kappa (coth kappa - 1 / kappa).
  const double k = vmf.kappa, L = 1.0 / std::tanh(k) - 1.0 / k;
  EXPECT_NEAR(tensor(vmf)(0, 0), 1.0 - 2.0 * L / k, 0.005);
}

TEST(Laws, VolumeFractionAndCountGiveTheSize) {
  const Scene s = parse_scene(R"({"box":{"size":[2,1,1]},"families":[
      {"shape":"sphere","volume_fraction":0.3,"count":100},
      {"shape":"cylinder","aspect_ratio":4,"volume_fraction":0.1,"count":50},
      {"shape":"ellipsoid","axis_ratios":[3,2,1],"volume_fraction":0.05,"count":20}]})");
  EXPECT_NEAR(100 * s.families[0].mean_volume(), 0.6, 1e-12);
  EXPECT_NEAR(50 * s.families[1].mean_volume(), 0.2, 1e-12);
  EXPECT_NEAR(20 * s.families[2].mean_volume(), 0.1, 1e-12);
  EXPECT_NEAR(s.families[2].semi_axes[0].p1 / s.families[2].semi_axes[2].p1, 3.0, 1e-12);
  EXPECT_NE(scene_error(R"({"box":{"size":[1,1,1]},"families":[
      {"shape":"sphere","radius":0.1,"volume_fraction":0.3,"count":100}]})")
                .find("families[0].radius"),
            std::string::npos);
}

// --- Packing ----------------------------------------------------------------------------

TEST(Md, ReachesDenseSpherePackingWithoutOverlap) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":2,"families":[
      {"shape":"sphere","volume_fraction":0.6,"count":1000}]})");
  const PackingResult r = pack_md(s);
  EXPECT_EQ(r.status, PackingStatus::kOk);
  EXPECT_EQ(r.scale, 1.0);
  EXPECT_NEAR(total_fraction(r), 0.6, 1e-9);
  expect_valid(r);
}

TEST(Md, MixedShapesWithLawsNonPeriodicAndGap) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1],"periodic":false},"seed":4,
      "min_gap":0.005,"families":[
      {"shape":"sphere","radius":{"law":"uniform","min":0.03,"max":0.06},"volume_fraction":0.2},
      {"shape":"cylinder","radius":0.02,"aspect_ratio":{"law":"normal","mean":4,"std":1},
       "volume_fraction":0.1,"orientation":{"law":"von_mises_fisher","axis":[0,0,1],"kappa":5}},
      {"shape":"ellipsoid","semi_axes":[0.06,0.04,{"law":"lognormal","mean":0.03,"std":0.005}],
       "volume_fraction":0.1,"orientation":{"law":"planar","normal":[0,0,1]}}]})");
  const PackingResult r = pack_md(s);
  ASSERT_EQ(r.status, PackingStatus::kOk);
  expect_valid(r);
  const auto& inc = r.set.inclusions;
  for (size_t i = 0; i < inc.size(); ++i) {
    for (size_t j = i + 1; j < inc.size(); ++j) {
      if ((inc[i].shape.center - inc[j].shape.center).norm() >
          inc[i].shape.bounding_radius() + inc[j].shape.bounding_radius() + 0.01) {
        continue;
      }
      EXPECT_TRUE(clear_of(inc[i].shape, inc[j].shape, 0.005 * (1 - 1e-9))) << i << " " << j;
    }
  }
  // Planar ellipsoids keep their long axis in the plane through the packing.
  const Mat3 a = orientation_tensor(r.set, 2);
  EXPECT_NEAR(a(2, 2), 0.0, 1e-9);
}

TEST(Md, AlignedFibresStayAligned) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":5,"families":[
      {"shape":"cylinder","radius":0.03,"aspect_ratio":5,"volume_fraction":0.45,
       "orientation":{"law":"aligned","axis":[0,1,0]}}]})");
  const PackingResult r = pack_md(s);
  EXPECT_EQ(r.status, PackingStatus::kOk);
  expect_valid(r);
  EXPECT_NEAR(orientation_tensor(r.set, 0)(1, 1), 1.0, 1e-12);
}

TEST(Md, SameSeedSameRve) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":8,"families":[
      {"shape":"sphere","radius":0.06,"volume_fraction":0.3},
      {"shape":"cylinder","radius":0.03,"aspect_ratio":3,"volume_fraction":0.15}]})");
  const std::string a = write_inclusions_json(pack_md(s).set);
  EXPECT_EQ(a, write_inclusions_json(pack_md(s).set));
  Scene other = s;
  other.seed = 9;
  EXPECT_NE(a, write_inclusions_json(pack_md(other).set));
}

TEST(Md, ImpossibleVolumeFractionJamsCleanly) {
  // 70 % of monodisperse spheres is beyond random close packing: a bounded, valid failure.
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":1,"families":[
      {"shape":"sphere","volume_fraction":0.7,"count":500}]})");
  const PackingResult r = pack_md(s);
  EXPECT_EQ(r.status, PackingStatus::kTargetNotReached);
  EXPECT_EQ(r.stop_reason, StopReason::kJammed);
  EXPECT_LT(r.scale, 1.0);
  EXPECT_GT(total_fraction(r), 0.58);  // far beyond RSA's 0.38
  EXPECT_EQ(r.set.inclusions.size(), 500u);
  expect_valid(r);
}

TEST(Md, BudgetStopsWithTheBestValidConfiguration) {
  Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":1,"families":[
      {"shape":"sphere","volume_fraction":0.6,"count":2000}]})");
  s.md.max_steps = 5;
  const PackingResult r = pack_md(s);
  EXPECT_EQ(r.status, PackingStatus::kTargetNotReached);
  EXPECT_EQ(r.stop_reason, StopReason::kStepBudget);
  EXPECT_EQ(r.steps, 5);
  EXPECT_GT(r.scale, 0.0);
  expect_valid(r);
}

TEST(Md, TenToOneSizeRatio) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":3,"families":[
      {"shape":"sphere","radius":0.15,"count":10},
      {"shape":"sphere","radius":0.015,"count":6000}]})");
  const PackingResult r = pack_md(s);
  EXPECT_EQ(r.status, PackingStatus::kOk);
  expect_valid(r);
}

TEST(Md, VeryLongFibresAtLowVolumeFraction) {
  // a = 50: each fibre is longer than the box, so fibres also meet their own images.
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":3,"families":[
      {"shape":"cylinder","radius":0.012,"aspect_ratio":50,"volume_fraction":0.05}]})");
  const PackingResult r = pack_md(s);
  EXPECT_EQ(r.status, PackingStatus::kOk);
  expect_valid(r);
}

TEST(Md, NonPeriodicBoxesWithOneOrTwoCellsAlongAnAxis) {
  // Inclusions of 1/6 of the box and up leave the broad phase 1 or 2 cells along an axis. Each
  // of these was once declared valid (exit 0, or exit 3 with a "best valid" configuration) with
  // overlapping pairs.
  const char* cases[] = {
      R"({"box":{"size":[1,1,1],"periodic":false},"seed":1,"families":[
          {"shape":"sphere","radius":0.3,"volume_fraction":0.2}]})",
      R"({"box":{"size":[4,1,1],"periodic":false},"seed":1,"families":[
          {"shape":"sphere","radius":0.2,"volume_fraction":0.3}]})",
      R"({"box":{"size":[1,1,1],"periodic":false},"seed":1,"min_gap":0.1,"families":[
          {"shape":"sphere","radius":0.1,"volume_fraction":0.3}]})",
      R"({"box":{"size":[1,1,1],"periodic":false},"seed":2,"families":[
          {"shape":"sphere","radius":0.12,"volume_fraction":0.3,"coating":{"thickness":0.02}}]})",
      R"({"box":{"size":[2,1,1],"periodic":false},"seed":3,"families":[
          {"shape":"cylinder","radius":0.08,"aspect_ratio":2,"volume_fraction":0.25}]})"};
  for (const char* text : cases) {
    const PackingResult r = pack_md(parse_scene(text));
    EXPECT_GE(r.set.inclusions.size(), 2u) << text;
    expect_valid(r);
  }
}

TEST(Md, SingleInclusionAndBarelyLargerBox) {
  for (const char* periodic : {"true", "false"}) {
    const Scene one = parse_scene(std::string(R"({"box":{"size":[1,1,1],"periodic":)") + periodic +
                                  R"(},"families":[{"shape":"sphere","radius":0.49,"count":1}]})");
    const PackingResult r = pack_md(one);
    EXPECT_EQ(r.status, PackingStatus::kOk);
    expect_valid(r);
  }
  // A cylinder whose bounding sphere spans 0.91 of a non-periodic box.
  const Scene tight = parse_scene(R"({"box":{"size":[1,1,1],"periodic":false},"seed":2,
      "families":[{"shape":"cylinder","radius":0.05,"aspect_ratio":9,"count":1}]})");
  const PackingResult r = pack_md(tight);
  EXPECT_EQ(r.status, PackingStatus::kOk);
  expect_valid(r);
}

}  // namespace
}  // namespace rvegen
