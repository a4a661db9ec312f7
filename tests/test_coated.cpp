// Coated fibres pack like plain ones (aligned ones keep their length and grow in radius, the
// coating keeps its thickness), and continuous fibres ("length": "through"): parsing, geometry
// without ends, the audit across the box, the voxel image, and their transverse isotropy.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "rvegen/homogenize/effective.hpp"
#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/cut_voxels.hpp"
#include "rvegen/raster/voxelize.hpp"
#include "test_util.hpp"

namespace rvegen {
namespace {

constexpr double kCoat = 0.002;

std::string fibre_scene(double r, const std::string& length, double vf, double coating,
                        const std::string& box, const std::string& law, uint64_t seed) {
  std::string s = R"({"box": {"size": )" + box + R"(}, "seed": )" + std::to_string(seed) +
                  R"(, "families": [{"name": "fibres", "shape": "cylinder", "radius": )" +
                  std::to_string(r) + ", " + length + R"(, "volume_fraction": )" +
                  std::to_string(vf);
  if (!law.empty()) s += R"(, "orientation": )" + law;
  if (coating > 0.0) s += R"(, "coating": {"thickness": )" + std::to_string(coating) + "}";
  return s + "}]}";
}

// The written RVE: every inclusion of the family has the core it was drawn with (a fibre's
// length, radius r unless scaled), the coating's thickness, and the target is reached.
void expect_reached(const std::string& text, double coating) {
  SCOPED_TRACE(text);
  const Scene scene = parse_scene(text);
  const PackingResult r = generate(scene);
  ASSERT_EQ(r.status, PackingStatus::kOk) << stop_reason_name(r.stop_reason);
  EXPECT_TRUE(audit(r.set).clean());
  double cores = 0.0;
  for (const Inclusion& inc : r.set.inclusions) {
    EXPECT_EQ(inc.mod.coating, coating);
    cores += inc.shape.volume();
  }
  EXPECT_GE(cores / r.set.box.volume(), r.target_volume_fraction[0] * (1.0 - 1e-12));
}

// The issue's coated scenes, seeds 1-5: each reaches its target (it jammed at 0.171, 0.520 and
// 0.282 when coated fibres lost the aligned fibres' growth rule and their self-images).
TEST(CoatedFibres, AlignedFibresReachTheirTargetLikePlainOnes) {
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    expect_reached(fibre_scene(0.05, R"("aspect_ratio": 6)", 0.30, kCoat, "[1,1,1]",
                               R"({"law": "aligned", "axis": [0,0,1]})", seed),
                   kCoat);
  }
}

TEST(CoatedFibres, FibresThroughTheBoxReachTheirTarget) {
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    for (double vf : {0.30, 0.55}) {
      // As the issue wrote it (a length of the box's height) and as "through".
      expect_reached(fibre_scene(0.03, R"("aspect_ratio": 3.3333333333333335)", vf, kCoat,
                                 "[1,1,0.2]", R"({"law": "aligned", "axis": [0,0,1]})", seed),
                     kCoat);
      expect_reached(fibre_scene(0.03, R"("length": "through")", vf, kCoat, "[1,1,0.2]", "", seed),
                     kCoat);
    }
  }
}

TEST(CoatedFibres, IsotropicFibresReachTheirTarget) {
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    expect_reached(fibre_scene(0.03, R"("aspect_ratio": 5)", 0.25, kCoat, "[1,1,1]",
                               R"({"law": "isotropic"})", seed),
                   kCoat);
  }
}

TEST(CoatedFibres, AlignedCoatedFibresKeepTheirLengthWhenShrunk) {
  // Out of steps: the best valid configuration is shrunk in radius only, and its
  // shells keep their thickness (the certified force shape is core s r + t).
  Scene s = parse_scene(fibre_scene(0.05, R"("aspect_ratio": 6)", 0.6, 0.005, "[1,1,1]",
                                    R"({"law": "aligned", "axis": [0,0,1]})", 1));
  s.md.max_steps = 20;
  const PackingResult r = generate(s);
  ASSERT_EQ(r.status, PackingStatus::kTargetNotReached);
  ASSERT_LT(r.scale, 1.0);
  EXPECT_TRUE(audit(r.set).clean());
  for (const Inclusion& inc : r.set.inclusions) {
    EXPECT_NEAR(inc.shape.half_axis.norm(), 0.3, 1e-12);
    EXPECT_NEAR(inc.shape.radius, 0.05 * r.scale, 1e-12);
    EXPECT_EQ(inc.mod.coating, 0.005);
  }
}

// --- Continuous fibres -------------------------------------------------------------------

TEST(ContinuousFibres, SceneIsReadAndBadOnesAreNamed) {
  const Scene s =
      parse_scene(fibre_scene(0.03, R"("length": "through")", 0.5, 0.0, "[1,0.8,0.2]", "", 1));
  ASSERT_TRUE(s.families[0].through());
  EXPECT_EQ(s.families[0].through_length, 0.2);
  EXPECT_EQ(s.families[0].orientation.axis, Vec3::UnitZ());
  // Along x, from the law; written back as "through".
  const Scene x = parse_scene(fibre_scene(0.03, R"("length": "through")", 0.5, 0.0, "[0.3,1,1]",
                                          R"({"law": "aligned", "axis": [-1,0,0]})", 1));
  EXPECT_EQ(x.families[0].through_length, 0.3);
  EXPECT_EQ(x.families[0].orientation.axis, -Vec3::UnitX());
  EXPECT_NE(scene_to_json(x).find(R"("length": "through")"), std::string::npos);
  EXPECT_EQ(parse_scene(scene_to_json(x)).families[0].through_length, 0.3);
  // Their mean volume is the box's length times the mean section.
  EXPECT_NEAR(x.families[0].mean_volume(), M_PI * 0.03 * 0.03 * 0.3, 1e-15);

  auto error = [](const std::string& fam, const std::string& box = R"({"size": [1,1,0.2]})") {
    return scene_error(
        R"({"box": )" + box +
        R"(, "families": [{"shape": "cylinder", "radius": 0.03, "volume_fraction": 0.3, )" + fam +
        "}]}");
  };
  EXPECT_NE(error(R"("length": "through", "orientation": {"law": "isotropic"})")
                .find("families[0].orientation: continuous fibres run along a box axis"),
            std::string::npos);
  EXPECT_NE(error(R"("length": "through", "orientation": {"law": "aligned", "axis": [1,1,0]})")
                .find("families[0].orientation"),
            std::string::npos);
  EXPECT_NE(error(R"("length": "through", "aspect_ratio": 3)").find("families[0].aspect_ratio"),
            std::string::npos);
  EXPECT_NE(error(R"("length": 0.2)").find("families[0].length: expected \"through\""),
            std::string::npos);
  EXPECT_NE(error(R"("length": "through")", R"({"size": [1,1,0.2], "periodic": false})")
                .find("families[0].length: continuous fibres need a periodic box"),
            std::string::npos);
  EXPECT_NE(error(R"("length": "through", "waviness": {"amplitude": 0.01, "wavelength": 0.1})")
                .find("families[0].length: continuous fibres are straight"),
            std::string::npos);
  // Continuous fibres pack only beside continuous fibres along their axis (mixed with spheres,
  // one seed collapsed to 0.0087; cross-plies jammed at 0.12).
  const std::string fam_z =
      R"({"shape": "cylinder", "radius": 0.03, "length": "through", "volume_fraction": 0.3})";
  EXPECT_NE(scene_error(R"({"box": {"size": [1,1,1]}, "families": [)" + fam_z +
                        R"(, {"shape": "sphere", "radius": 0.05, "volume_fraction": 0.05}]})")
                .find("families[1]: continuous fibres (families[0], along z) pack only with "
                      "continuous fibres along the same axis"),
            std::string::npos);
  EXPECT_NE(
      scene_error(
          R"({"box": {"size": [1,1,1]}, "families": [)" + fam_z +
          R"(, {"shape": "cylinder", "radius": 0.03, "length": "through", "volume_fraction": 0.1, "orientation": {"law": "aligned", "axis": [1,0,0]}}]})")
          .find("families[1]: continuous fibres"),
      std::string::npos);
  EXPECT_EQ(
      scene_error(R"({"box": {"size": [1,1,1]}, "families": [)" + fam_z + ", " + fam_z + "]}"),
      "no error");
  // The section must fit across the box (not along it: the box is 0.05 high).
  EXPECT_EQ(error(R"("length": "through")", R"({"size": [1,1,0.05]})"), "no error");
  EXPECT_NE(error(R"("length": "through")", R"({"size": [0.05,1,1]})").find("fit across the box"),
            std::string::npos);
}

TEST(ContinuousFibres, FibresAsLongAsTheBoxAreContinuous) {
  // Aligned fibres whose length is the box's along their axis, to rounding: continuous.
  const Scene s =
      parse_scene(fibre_scene(0.03, R"("aspect_ratio": 3.3333333333333335)", 0.3, 0.0, "[1,1,0.2]",
                              R"({"law": "aligned", "axis": [0,0,1]})", 1));
  EXPECT_EQ(s.families[0].through_length, 0.2);
  // Beside other inclusions they stay finite fibres, as they were (continuous fibres pack only
  // beside continuous fibres).
  const Scene mixed = parse_scene(
      R"({"box": {"size": [1,1,0.2]}, "families": [{"shape": "cylinder", "radius": 0.03,
          "aspect_ratio": 3.3333333333333335, "volume_fraction": 0.3,
          "orientation": {"law": "aligned", "axis": [0,0,1]}},
         {"shape": "sphere", "radius": 0.03, "volume_fraction": 0.05}]})");
  EXPECT_FALSE(mixed.families[0].through());
  // Shorter ones are not; nor are fibres of a length law.
  EXPECT_FALSE(parse_scene(fibre_scene(0.03, R"("aspect_ratio": 3.3)", 0.3, 0.0, "[1,1,0.2]",
                                       R"({"law": "aligned", "axis": [0,0,1]})", 1))
                   .families[0]
                   .through());
}

Inclusion through_fibre(const Vec3& c, double r, double L, double coating) {
  Inclusion inc;
  inc.shape = Shape::cylinder(c, r, Vec3(0, 0, 0.5 * L));
  inc.mod.coating = coating;
  inc.mod.through = true;
  return inc;
}

TEST(ContinuousFibres, ShellIsATubeWithoutEnds) {
  const Inclusion inc = through_fibre(Vec3(0.5, 0.5, 0.05), 0.03, 0.2, 0.01);
  const RegionVolumes v = region_volumes(inc);
  EXPECT_NEAR(v.core, M_PI * 0.03 * 0.03 * 0.2, 1e-15);
  EXPECT_NEAR(v.shell, M_PI * (0.04 * 0.04 - 0.03 * 0.03) * 0.2, 1e-15);
  const BodyQuery q(inc);
  // Beyond the end face (z = 0.15): the image continues the core and the shell.
  EXPECT_EQ(q.region(Vec3(0.5, 0.5, 0.155)), Region::kCore);
  EXPECT_EQ(q.region(Vec3(0.535, 0.5, 0.155)), Region::kShell);
  EXPECT_EQ(q.region(Vec3(0.545, 0.5, 0.155)), Region::kOutside);
  EXPECT_NEAR(q.core_distance(Vec3(0.5, 0.56, 0.149)), 0.03, 1e-15);
  // Its envelope does not grow along the axis.
  EXPECT_NEAR(envelope(inc).half_axis.norm(), 0.1, 1e-15);
  EXPECT_NEAR(envelope(inc).radius, 0.04, 1e-15);
}

TEST(ContinuousFibres, AuditSkipsTheFibreContinuedAndFindsRealOverlaps) {
  InclusionSet set;
  set.box.size = Vec3(1, 1, 0.2);
  set.inclusions.push_back(through_fibre(Vec3(0.3, 0.3, 0.03), 0.03, 0.2, 0.002));
  set.inclusions.push_back(through_fibre(Vec3(0.5, 0.5, 0.17), 0.03, 0.2, 0.002));
  set.inclusions[1].id = 1;
  EXPECT_TRUE(audit(set).clean());
  // Coated and finite, the same fibre overlaps its own image (its shell caps the ends).
  InclusionSet finite = set;
  for (Inclusion& inc : finite.inclusions) inc.mod.through = false;
  EXPECT_FALSE(audit(finite).clean());
  // Two continuous fibres 0.05 apart (0.064 with shells) overlap, whatever their heights.
  set.inclusions[1].shape.center = Vec3(0.35, 0.3, 0.17);
  const AuditReport a = audit(set);
  ASSERT_FALSE(a.clean());
  EXPECT_EQ(a.overlaps.size(), 1u);
  // A sphere at the junction of a fibre and its image (z = 0.23 = 0.03 + 0.2) is found.
  set.inclusions[1].shape = Shape::sphere(Vec3(0.3 + 0.06, 0.3, 0.13 - 1e-3), 0.03);
  set.inclusions[1].mod = Modifiers{};
  EXPECT_FALSE(audit(set).clean());
  set.inclusions[1].shape.center.x() = 0.3 + 0.066;
  EXPECT_TRUE(audit(set).clean());
  // Read back from the inclusion list; a wrong length is refused by name.
  const InclusionSet back = read_inclusions_json(write_inclusions_json(set));
  EXPECT_TRUE(back.inclusions[0].mod.through);
  std::string text = write_inclusions_json(set);
  const size_t at = text.find("0.1\n");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 3, "0.09");
  try {
    read_inclusions_json(text);
    ADD_FAILURE() << "a continuous fibre shorter than the box was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("inclusions[0].half_axis"), std::string::npos);
  }
}

TEST(ContinuousFibres, VoxelImageHasTheExactPhaseFractions) {
  // One voxel along the fibres: the section, sampled with partial volumes.
  Scene s =
      parse_scene(fibre_scene(0.03, R"("length": "through")", 0.55, kCoat, "[1,1,0.2]", "", 2));
  const PackingResult r = generate(s);
  ASSERT_EQ(r.status, PackingStatus::kOk);
  double core = 0.0, shell = 0.0;
  for (const Inclusion& inc : r.set.inclusions) {
    const RegionVolumes v = region_volumes(inc);
    core += v.core;
    shell += v.shell;
  }
  const double V = r.set.box.volume();
  EXPECT_NEAR(shell / V, 0.55 * (std::pow(1.0 + kCoat / 0.03, 2) - 1.0), 1e-3);
  VoxelOptions opt;
  const VoxelImage img = voxelize(r.set, {400, 400, 1}, opt);
  double f = 0.0;
  long long shells = 0;
  for (size_t k = 0; k < img.fraction.size(); ++k) {
    f += img.fraction[k];
    shells += img.phase[k] == 2;
  }
  EXPECT_NEAR(f / img.fraction.size(), core / V, 2e-3);
  EXPECT_NEAR(double(shells) / img.fraction.size(), shell / V, 0.01);
}

TEST(ContinuousFibres, CutVoxelsAreFoundOncePerPeriod) {
  // One fibre crossing the box's faces along its axis (z 0.03, length 0.2): an image one voxel
  // high along the fibres cuts the same voxels as one four voxels high, each once (it found
  // them twice, across the box, and dropped them as cut by two cores), with the shares of the
  // section.
  InclusionSet set;
  set.box.size = Vec3(1, 1, 0.2);
  set.family_names = {"fibres"};
  set.inclusions.push_back(through_fibre(Vec3(0.5, 0.5, 0.03), 0.1, 0.2, 0.02));
  size_t per_layer = 0;
  for (int nz : {1, 4}) {
    SCOPED_TRACE(nz);
    const VoxelImage layout = voxel_layout(set, {32, 32, nz});
    const CutVoxels cut = cut_voxels(set, layout);
    EXPECT_EQ(cut.shared, 0u);
    // The core's share over the cut voxels and the whole voxels inside it: its section.
    double core = 0.0;
    for (const CutVoxel& v : cut.voxels) core += v.fraction;
    const VoxelImage img = voxelize(set, {32, 32, nz});
    for (size_t k = 0; k < img.phase.size(); ++k) {
      bool listed = false;
      for (const CutVoxel& v : cut.voxels) listed |= v.voxel == k;
      if (!listed && img.phase[k] == 1) core += 1.0;
    }
    EXPECT_NEAR(core / (32.0 * 32.0 * nz), M_PI * 0.01, 2e-3);
    if (nz == 1) per_layer = cut.voxels.size();
    EXPECT_GT(per_layer, 20u);  // the rims of the core and the shell
    EXPECT_EQ(cut.voxels.size(), per_layer * nz);
    for (const CutVoxel& v : cut.voxels) EXPECT_LT(std::abs(v.normal.z()), 1e-6);
  }
}

TEST(ContinuousFibres, EffectivePropertiesAreTransverselyIsotropic) {
  // 300 fibres at 0.6, 0.2 radii apart (gaps of 2.7 voxels), one voxel along the fibres:
  // k11 = k22, C11 = C22, C66 = C11 - C12 (Mandel). (Touching fibres make chains of touching
  // voxels that conduct and stiffen along their own direction: 1-5 % apart on seeds 1-3.)
  Scene s = parse_scene(R"({"box": {"size": [0.2854,0.2854,0.01]}, "seed": 1, "min_gap": 0.00144,
    "families": [{"name": "fibres", "shape": "cylinder", "radius": 0.0072, "length": "through",
                  "volume_fraction": 0.6}],
    "voxels": {"resolution": [384,384,1]},
    "materials": {"matrix": {"conductivity": 1, "young": 3.5, "poisson": 0.35},
                  "fibres": {"conductivity": 10, "young": 72, "poisson": 0.22}},
    "homogenization": {"physics": ["conductivity", "elasticity"]}})");
  const PackingResult r = generate(s);
  ASSERT_EQ(r.status, PackingStatus::kOk);
  ASSERT_GT(r.set.inclusions.size(), 280u);
  VoxelOptions vo;
  vo.partial_volume = true;
  const VoxelImage image = voxelize(r.set, s.resolution, vo);
  const EffectiveProperties e = effective_properties(s, r.set, image);
  ASSERT_TRUE(e.conductivity.converged && e.stiffness.converged);
  const Mat3& k = e.conductivity.tensor;
  EXPECT_NEAR(k(0, 0) / k(1, 1), 1.0, 0.01);
  // Along the fibres, the rule of mixtures (parallel layers; the laminate voxels hold the
  // exact shares).
  double cores = 0.0;
  for (const Inclusion& inc : r.set.inclusions) cores += inc.shape.volume();
  const double phi = cores / r.set.box.volume();
  EXPECT_NEAR(k(2, 2), (1.0 - phi) * 1.0 + phi * 10.0, 1e-3);
  const Mat6& C = e.stiffness.stiffness;
  EXPECT_NEAR(C(0, 0) / C(1, 1), 1.0, 0.01);
  EXPECT_NEAR(C(5, 5) / (C(0, 0) - C(0, 1)), 1.0, 0.02);
}

}  // namespace
}  // namespace rvegen
