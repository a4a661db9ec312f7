// Short-fibre composites: orientation tensors as input (ACG), the orientation of the result
// against the law's, the rotation modes of the packer, weibull lengths and aligned fibres.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "rvegen/io/scene_json.hpp"
#include "rvegen/model/orientation.hpp"
#include "rvegen/model/stats.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/packing.hpp"
#include "test_util.hpp"

namespace rvegen {
namespace {

Mat3 sample_tensor(const AcgLaw& law, int n, uint64_t seed) {
  Random rng(seed);
  Mat3 a = Mat3::Zero();
  for (int i = 0; i < n; ++i) {
    const Vec3 p = law.sample(rng);
    a += p * p.transpose();
  }
  return a / n;
}

Mat3 rotated(const Mat3& d) {
  const Mat3 r = Eigen::AngleAxisd(0.8, Vec3(1, -2, 0.5).normalized()).toRotationMatrix();
  return r * d * r.transpose();
}

TEST(OrientationLaws, NullSpaceIsWhatTheLawForbids) {
  OrientationLaw law;  // isotropic
  EXPECT_EQ(law.null_space().count, 0);
  law.kind = OrientationLaw::Kind::kVonMisesFisher;
  law.kappa = 5.0;
  law.axis = Vec3(0, 1, 0);
  EXPECT_EQ(law.null_space().count, 0);
  law.kind = OrientationLaw::Kind::kPlanar;
  law.axis = Vec3(1, 0, 0);
  OrientationLaw::NullSpace n = law.null_space();
  EXPECT_EQ(n.count, 1);
  EXPECT_NEAR(std::abs(n.normal.x()), 1.0, 1e-12);
  law.kind = OrientationLaw::Kind::kTensor;
  law.a2 = Vec3(0.7, 0.0, 0.3).asDiagonal();
  n = law.null_space();
  EXPECT_EQ(n.count, 1);
  EXPECT_NEAR(std::abs(n.normal.y()), 1.0, 1e-12);
  law.kind = OrientationLaw::Kind::kAligned;
  law.axis = Vec3(0, 0, 1);
  EXPECT_GE(law.null_space().count, 2);
}

TEST(Acg, SecondMomentsOfKnownCases) {
  // Isotropic: B = I gives I/3; scaling B does not change the law.
  EXPECT_NEAR(acg_second_moments(Vec3(1, 1, 1))[0], 1.0 / 3.0, 1e-14);
  const Vec3 a = acg_second_moments(Vec3(2, 0.5, 0.1)), b = acg_second_moments(Vec3(20, 5, 1));
  EXPECT_NEAR((a - b).norm(), 0.0, 1e-13);
  EXPECT_NEAR(a.sum(), 1.0, 1e-13);
  EXPECT_GT(a[0], a[1]);
  EXPECT_GT(a[1], a[2]);
  // Against sampling.
  AcgLaw law;
  law.scale = Vec3(2, 0.5, 0.1).cwiseSqrt();
  const Mat3 s = sample_tensor(law, 400000, 1);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(s(k, k), a[k], 0.003);
}

TEST(Acg, FittedLawHasTheTensorAskedFor) {
  const std::vector<Mat3> targets = {
      Vec3(0.7, 0.25, 0.05).asDiagonal(),           rotated(Vec3(0.7, 0.25, 0.05).asDiagonal()),
      rotated(Vec3(0.9, 0.1, 0.0).asDiagonal()),    Vec3(0.5, 0.5, 0.0).asDiagonal(),
      rotated(Vec3(0.98, 0.01, 0.01).asDiagonal()), Mat3::Identity() / 3.0,
      rotated(Vec3(1.0, 0.0, 0.0).asDiagonal())};
  for (const Mat3& t : targets) {
    const AcgLaw law = fit_acg(t);
    // Exactly, from the closed form where all three scales are positive ...
    if (law.scale.minCoeff() > 0.0) {
      const Vec3 e = acg_second_moments(law.scale.cwiseProduct(law.scale));
      const Mat3 exact = law.frame * e.asDiagonal() * law.frame.transpose();
      EXPECT_LT((exact - t).cwiseAbs().maxCoeff(), 1e-10) << t;
    }
    // ... and by sampling, whatever the rank.
    EXPECT_LT((sample_tensor(law, 200000, 2) - t).cwiseAbs().maxCoeff(), 0.004) << t;
  }
}

TEST(Acg, FourthMomentsAgreeWithTheSecondAndWithSampling) {
  const Vec3 b(3.0, 1.0, 0.2);
  const Mat3 a4 = acg_fourth_moments(b);
  const Vec3 a2 = acg_second_moments(b);
  // sum_j A4_iijj = A2_ii (|p| = 1).
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(a4.row(i).sum(), a2[i], 1e-7);
  AcgLaw law;
  law.scale = b.cwiseSqrt();
  Random rng(4);
  Mat3 m = Mat3::Zero();
  const int n = 300000;
  for (int k = 0; k < n; ++k) {
    const Vec3 p = law.sample(rng);
    const Vec3 q = p.cwiseProduct(p);
    m += q * q.transpose();
  }
  EXPECT_LT((m / n - a4).cwiseAbs().maxCoeff(), 0.003);
}

TEST(Acg, SampleCorrectionGivesTheExactTensor) {
  Random rng(5);
  std::vector<Vec3> dirs(1000);
  for (Vec3& d : dirs) d = rng.unit_vector();
  const Mat3 target = Mat3::Identity() / 3.0;
  Mat3 before = Mat3::Zero();
  for (const Vec3& d : dirs) before += d * d.transpose() / 1000.0;
  EXPECT_GT((before - target).cwiseAbs().maxCoeff(), 1e-3);  // sampling error alone
  ASSERT_TRUE(match_orientation_tensor(&dirs, target));
  Mat3 after = Mat3::Zero();
  for (const Vec3& d : dirs) {
    EXPECT_NEAR(d.norm(), 1.0, 1e-12);
    after += d * d.transpose() / 1000.0;
  }
  EXPECT_LT((after - target).cwiseAbs().maxCoeff(), 1e-12);
  // A sample with no spread along a direction the target wants cannot be corrected.
  std::vector<Vec3> flat(100, Vec3(1, 0, 0));
  EXPECT_FALSE(match_orientation_tensor(&flat, target));
  EXPECT_EQ(flat[0], Vec3(1, 0, 0));
}

// --- Input ------------------------------------------------------------------------------

std::string tensor_scene(const std::string& a2) {
  return R"({"box":{"size":[1,1,1]},"families":[{"shape":"cylinder","radius":0.01,
      "aspect_ratio":10,"volume_fraction":0.05,"orientation":{"law":"tensor","a2":)" +
         a2 + "}}]}";
}

TEST(FibreInput, TensorLawIsReadAndBadTensorsAreRefusedByName) {
  const Scene s = parse_scene(tensor_scene("[[0.7,0,0],[0,0.25,0],[0,0,0.05]]"));
  EXPECT_EQ(s.families[0].orientation.kind, OrientationLaw::Kind::kTensor);
  EXPECT_NEAR(s.families[0].orientation.a2(1, 1), 0.25, 1e-15);
  // Round trip through the scene JSON.
  EXPECT_EQ(scene_to_json(parse_scene(scene_to_json(s))), scene_to_json(s));
  const std::string key = "families[0].orientation.a2";
  for (const auto& [a2, why] : std::vector<std::pair<std::string, std::string>>{
           {"[[0.7,0.1,0],[0,0.25,0],[0,0,0.05]]", "symmetric"},
           {"[[0.7,0,0],[0,0.25,0],[0,0,0.1]]", "trace 1"},
           {"[[1.2,0,0],[0,-0.1,0],[0,0,-0.1]]", "positive semi-definite"},
           {"[[0.5,0.6,0],[0.6,0.5,0],[0,0,0]]", "positive semi-definite"},
           {"[[0.7,0],[0,0.3]]", "3 x 3"},
           {"[[0.7,0,0],[0,0.25,0],[0,0,\"x\"]]", "a2[2][2]"}}) {
    const std::string e = scene_error(tensor_scene(a2));
    EXPECT_NE(e.find(key), std::string::npos) << a2 << ": " << e;
    EXPECT_NE(e.find(why), std::string::npos) << a2 << ": " << e;
  }
  // Built in code (as the ParaView source does), validation says the same.
  Scene c = s;
  c.families[0].orientation.a2(2, 2) = std::nan("");
  try {
    validate_scene(c);
    ADD_FAILURE() << "NaN tensor accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
  }
  EXPECT_NE(scene_error(R"({"box":{"size":[1,1,1]},"md":{"rotation":"sometimes"},
      "families":[{"shape":"sphere","radius":0.1,"count":1}]})")
                .find("md.rotation"),
            std::string::npos);
}

TEST(FibreInput, WeibullLawHasItsMomentsAndBounds) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"families":[{"shape":"cylinder",
      "radius":0.005,"aspect_ratio":{"law":"weibull","shape":2.5,"scale":20},
      "volume_fraction":0.05}]})");
  const SizeLaw& w = s.families[0].aspect_ratio;
  EXPECT_EQ(w.kind, SizeLaw::Kind::kWeibull);
  // Untruncated mean lambda Gamma(1 + 1/k); the truncation at 1e-9 changes it by far less.
  EXPECT_NEAR(w.mean(), 20.0 * std::tgamma(1.0 + 1.0 / 2.5), 1e-6);
  EXPECT_NEAR(w.moment(2), 400.0 * std::tgamma(1.0 + 2.0 / 2.5), 1e-3);
  Random rng(6);
  double sum = 0.0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double x = w.sample(rng);
    ASSERT_GE(x, w.lower());
    ASSERT_LE(x, w.upper());
    sum += x;
  }
  EXPECT_NEAR(sum / n, w.mean(), 0.02 * w.mean());
  EXPECT_NE(scene_error(R"({"box":{"size":[1,1,1]},"families":[{"shape":"cylinder",
      "radius":0.005,"aspect_ratio":{"law":"weibull","shape":0.01,"scale":20},"count":5}]})")
                .find("families[0].aspect_ratio.shape"),
            std::string::npos);
}

// --- Orientation delivered --------------------------------------------------------------

Scene fibre_scene(const std::string& orientation, double vf, double a, int n,
                  const std::string& md = "{}") {
  const double r = std::cbrt(vf / (2.0 * M_PI * a * n));
  return parse_scene(R"({"box":{"size":[1,1,1]},"seed":3,"md":)" + md +
                     R"(,"families":[{"shape":"cylinder","radius":)" + std::to_string(r) +
                     R"(,"aspect_ratio":)" + std::to_string(a) + R"(,"volume_fraction":)" +
                     std::to_string(vf) + R"(,"orientation":)" + orientation + "}]}");
}

double tensor_error(const PackingResult& r, const Scene& s, int f = 0) {
  return (orientation_tensor(r.set, f) - s.families[f].orientation.tensor()).cwiseAbs().maxCoeff();
}

// Every law, 1,000 fibres of L/D 10 near what the packer reaches for it: the result's A2 is the
// law's (the issue asks for 0.02; the correction gives far better).
TEST(FibreOrientation, EveryLawIsDeliveredNearItsDensityLimit) {
  const std::vector<std::pair<std::string, double>> laws = {
      {R"({"law":"isotropic"})", 0.30},
      {R"({"law":"von_mises_fisher","axis":[1,1,0],"kappa":3})", 0.30},
      {R"({"law":"planar","normal":[0,0,1]})", 0.08},
      {R"({"law":"tensor","a2":[[0.7,0,0],[0,0.25,0],[0,0,0.05]]})", 0.30},
      {R"({"law":"aligned","axis":[0,0,1]})", 0.40}};
  for (const auto& [law, vf] : laws) {
    const Scene s = fibre_scene(law, vf, 10.0, 1000);
    const PackingResult r = pack_md(s);
    EXPECT_EQ(r.status, PackingStatus::kOk) << law << " reached " << r.scale;
    EXPECT_TRUE(find_overlaps(r.set).empty()) << law;
    ASSERT_GE(r.set.inclusions.size(), 1000u);
    EXPECT_LT(tensor_error(r, s), 0.02) << law;
    EXPECT_LT(tensor_error(r, s), 1e-8) << law;
  }
}

TEST(FibreOrientation, EllipsoidsWithATensorKeepIt) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":4,"families":[
      {"shape":"ellipsoid","semi_axes":[0.05,0.02,0.015],"volume_fraction":0.3,
       "orientation":{"law":"tensor","a2":[[0.2,0.1,0],[0.1,0.6,0],[0,0,0.2]]}}]})");
  const PackingResult r = pack_md(s);
  EXPECT_EQ(r.status, PackingStatus::kOk);
  EXPECT_TRUE(find_overlaps(r.set).empty());
  EXPECT_GE(r.set.inclusions.size(), 1000u);
  EXPECT_LT(tensor_error(r, s), 1e-8);
}

TEST(FibreOrientation, FixedRotationKeepsEveryDrawnDirectionAndFreeRotationDrifts) {
  const Scene fixed =
      fibre_scene(R"({"law":"isotropic"})", 0.12, 10.0, 500, R"({"rotation":"fixed"})");
  Random rng(fixed.seed);
  const std::vector<Inclusion> drawn = draw_population(fixed, rng);
  const PackingResult r = pack_md(fixed);
  ASSERT_EQ(r.status, PackingStatus::kOk);
  ASSERT_EQ(r.set.inclusions.size(), drawn.size());
  for (size_t i = 0; i < drawn.size(); ++i) {
    EXPECT_LT((law_axis(r.set.inclusions[i].shape) - law_axis(drawn[i].shape)).norm(), 1e-12);
  }
  // The paper's free turning changes the directions (and the tensor, a little at this density).
  const Scene free =
      fibre_scene(R"({"law":"isotropic"})", 0.30, 10.0, 500, R"({"rotation":"free"})");
  const PackingResult f = pack_md(free);
  EXPECT_GT(tensor_error(f, free), 1e-6);
}

// A target above jamming ends as target_not_reached, the orientation still the law's, every
// fibre still its drawn length for aligned fibres (they grow in radius only).
TEST(FibreOrientation, AboveJammingStopsWithTheOrientationKept) {
  Scene s = fibre_scene(R"({"law":"tensor","a2":[[0.7,0,0],[0,0.25,0],[0,0,0.05]]})", 0.45, 20.0,
                        400, R"({"max_seconds":4})");
  PackingResult r = pack_md(s);
  EXPECT_EQ(r.status, PackingStatus::kTargetNotReached);
  EXPECT_LT(r.scale, 1.0);
  EXPECT_TRUE(find_overlaps(r.set).empty());
  EXPECT_LT(tensor_error(r, s), 1e-8);

  s = fibre_scene(R"({"law":"aligned","axis":[1,0,0]})", 0.85, 20.0, 1500, R"({"max_seconds":4})");
  r = pack_md(s);
  EXPECT_EQ(r.status, PackingStatus::kTargetNotReached);
  EXPECT_TRUE(find_overlaps(r.set).empty());
  Random rng(s.seed);
  const std::vector<Inclusion> drawn = draw_population(s, rng);
  ASSERT_EQ(r.set.inclusions.size(), drawn.size());
  for (size_t i = 0; i < drawn.size(); ++i) {
    EXPECT_NEAR(r.set.inclusions[i].shape.half_axis.norm(), drawn[i].shape.half_axis.norm(), 1e-12);
    EXPECT_NEAR(r.set.inclusions[i].shape.radius, drawn[i].shape.radius * r.scale, 1e-12);
  }
}

// Planar fibres start at heights in layers (md_layers.hpp). With random heights, 1,000 fibres
// of L/D 20 jammed near 0.07; in layers they reach 0.20 with their directions kept.
TEST(PlanarFibres, LayeredHeightsReachFarBeyondRandomOnes) {
  for (const std::string md : {std::string("{}"), std::string(R"({"rotation":"fixed"})")}) {
    const Scene s = fibre_scene(R"({"law":"planar","normal":[0,0,1]})", 0.20, 20.0, 1000, md);
    Random rng(s.seed);
    const std::vector<Inclusion> drawn = draw_population(s, rng);
    const PackingResult r = pack_md(s);
    EXPECT_EQ(r.status, PackingStatus::kOk) << md << " reached " << r.scale;
    EXPECT_TRUE(find_overlaps(r.set).empty()) << md;
    EXPECT_LT(tensor_error(r, s), 1e-8) << md;
    ASSERT_EQ(r.set.inclusions.size(), drawn.size());
    if (md == "{}") continue;
    for (size_t i = 0; i < drawn.size(); ++i) {  // fixed: every fibre its drawn direction
      EXPECT_LT((r.set.inclusions[i].shape.half_axis - drawn[i].shape.half_axis).norm(), 1e-12);
    }
  }
}

// The last fibres of nearly full layers: random places and slides left some fibres crowded,
// and since crossing fibres push each other only along the plane's normal the packing kept
// them (1,000 fibres of L/D 10 at 0.32 jammed at 0.291 for every seed tried). A fibre that
// finds no room takes a layer from at most two fibres, which are placed anew: the target is
// reached with the law's tensor and no overlap.
TEST(PlanarFibres, EvictionsPlaceTheLastFibresOfFullLayers) {
  const Scene s = fibre_scene(R"({"law":"planar","normal":[0,0,1]})", 0.32, 10.0, 1000);
  const PackingResult r = pack_md(s);
  EXPECT_EQ(r.status, PackingStatus::kOk) << "reached " << r.scale;
  EXPECT_TRUE(find_overlaps(r.set).empty());
  ASSERT_EQ(r.set.inclusions.size(), 1000u);
  EXPECT_LT(tensor_error(r, s), 1e-8);
}

// Layering comes before the packing's first step and can take seconds: each try (a scale of
// the layers) is reported as progress, the last one as placed.
TEST(PlanarFibres, LayeringIsReportedAsProgress) {
  const Scene s = fibre_scene(R"({"law":"planar","normal":[0,0,1]})", 0.20, 20.0, 1000);
  std::vector<std::string> lines;
  const PackingResult r = pack_md(s, [&](const std::string& m) { lines.push_back(m); });
  ASSERT_EQ(r.status, PackingStatus::kOk);
  std::vector<std::string> layering;
  for (const std::string& m : lines) {
    if (m.find("planar fibres in") != std::string::npos) layering.push_back(m);
  }
  ASSERT_FALSE(layering.empty());
  EXPECT_NE(layering.back().find("1000 planar fibres"), std::string::npos) << layering.back();
  EXPECT_NE(layering.back().find(": placed"), std::string::npos) << layering.back();
  // Before the packing's first progress line.
  EXPECT_EQ(lines.front(), layering.front());
}

// Where there is room, the heights are spread uniformly, not left on the layers: at 0.05 every
// fibre has its own height and tenths of the box hold about a tenth of them each. In a box
// with walls the layers lie inside it, and a plane normal to x works as z does.
TEST(PlanarFibres, HeightsAreUniformWhereThereIsRoom) {
  const Scene s = fibre_scene(R"({"law":"planar","normal":[1,0,0]})", 0.05, 20.0, 1000);
  const PackingResult r = pack_md(s);
  ASSERT_EQ(r.status, PackingStatus::kOk);
  std::set<long long> heights;
  std::vector<int> tenth(10, 0);
  for (const Inclusion& inc : r.set.inclusions) {
    const double x = inc.shape.center[0];
    heights.insert(std::llround(x * 1e9));
    ++tenth[std::clamp(static_cast<int>(x * 10.0), 0, 9)];
  }
  EXPECT_EQ(heights.size(), r.set.inclusions.size());
  for (int t : tenth) {
    EXPECT_GT(t, 60);
    EXPECT_LT(t, 140);
  }
  const Scene walls = parse_scene(R"({"box":{"size":[1,1,1],"periodic":false},"seed":5,
      "families":[{"shape":"cylinder","radius":0.012,"aspect_ratio":12,"volume_fraction":0.2,
      "orientation":{"law":"planar","normal":[0,0,1]}}]})");
  const PackingResult w = pack_md(walls);
  EXPECT_EQ(w.status, PackingStatus::kOk) << w.scale;
  EXPECT_TRUE(find_overlaps(w.set).empty());
  EXPECT_TRUE(find_outside(w.set).empty());
}

// Aligned fibres about a third of the box long: with random positions along the axis each line
// holds about one fibre and the packing jammed near 0.45; in slots along the axis two share a
// line and 0.58 is reached, every fibre its drawn length and direction.
TEST(AlignedFibres, SlotsAlongTheAxisReachDensePackings) {
  const Scene s = fibre_scene(R"({"law":"aligned","axis":[1,0,0]})", 0.58, 10.0, 1500);
  Random rng(s.seed);
  const std::vector<Inclusion> drawn = draw_population(s, rng);
  const PackingResult r = pack_md(s);
  EXPECT_EQ(r.status, PackingStatus::kOk) << r.scale;
  EXPECT_TRUE(find_overlaps(r.set).empty());
  ASSERT_EQ(r.set.inclusions.size(), drawn.size());
  for (size_t i = 0; i < drawn.size(); ++i) {
    EXPECT_LT((r.set.inclusions[i].shape.half_axis - drawn[i].shape.half_axis).norm(), 1e-12);
  }
}

// Where one fibre per line fits (sections filling less than 0.7 of the cross-section), no slots:
// the fibres' ends are spread evenly along the axis.
TEST(AlignedFibres, NoSlotsWhereOneFibrePerLineFits) {
  const Scene s = fibre_scene(R"({"law":"aligned","axis":[1,0,0]})", 0.15, 10.0, 1500);
  const PackingResult r = pack_md(s);
  ASSERT_EQ(r.status, PackingStatus::kOk);
  std::vector<int> tenth(10, 0);
  for (const Inclusion& inc : r.set.inclusions) {
    const double end = inc.shape.center[0] - std::abs(inc.shape.half_axis[0]);
    ++tenth[std::clamp(static_cast<int>((end - std::floor(end)) * 10.0), 0, 9)];
  }
  for (int t : tenth) {
    EXPECT_GT(t, 90);
    EXPECT_LT(t, 210);
  }
}

TEST(FibreOrientation, AlignedFibresKeepTheGapInANonPeriodicBox) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1],"periodic":false},"seed":9,
      "min_gap":0.004,"families":[{"shape":"cylinder","radius":0.02,"aspect_ratio":8,
      "volume_fraction":0.3,"orientation":{"law":"aligned","axis":[0,1,0]}}]})");
  const PackingResult r = pack_md(s);
  ASSERT_EQ(r.status, PackingStatus::kOk) << r.scale;
  EXPECT_TRUE(find_overlaps(r.set).empty());
  EXPECT_TRUE(find_outside(r.set).empty());
  const auto& inc = r.set.inclusions;
  for (size_t i = 0; i < inc.size(); ++i) {
    for (size_t j = i + 1; j < inc.size(); ++j) {
      if ((inc[i].shape.center - inc[j].shape.center).norm() >
          inc[i].shape.bounding_radius() + inc[j].shape.bounding_radius() + 0.01) {
        continue;
      }
      EXPECT_TRUE(clear_of(inc[i].shape, inc[j].shape, 0.004 * (1 - 1e-9))) << i << " " << j;
    }
  }
}

}  // namespace
}  // namespace rvegen
