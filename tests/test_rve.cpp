// Periodic images, the overlap audit, scene validation, RSA packing and voxels.
#include <gtest/gtest.h>

#include <cmath>

#include "rvegen/geometry/random.hpp"
#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/report.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/voxelize.hpp"
#include "test_util.hpp"

using namespace rvegen;

namespace {

InclusionSet unit_box(bool periodic) {
  InclusionSet s;
  s.box.size = Vec3(1, 1, 1);
  s.box.periodic = periodic;
  return s;
}

void add(InclusionSet& s, const Shape& shape) {
  Inclusion inc;
  inc.id = static_cast<int>(s.inclusions.size());
  inc.shape = shape;
  s.inclusions.push_back(inc);
}

TEST(Periodic, OverlapThroughTheBoxFace) {
  InclusionSet s = unit_box(true);
  add(s, Shape::sphere({0.02, 0.5, 0.5}, 0.05));
  add(s, Shape::sphere({0.95, 0.5, 0.5}, 0.05));
  const auto o = find_overlaps(s);
  ASSERT_EQ(o.size(), 1u);
  EXPECT_NEAR(std::abs(o[0].shift.x()), 1.0, 0);
  s.box.periodic = false;
  EXPECT_TRUE(find_overlaps(s).empty());
}

TEST(Periodic, EveryImageOfAFibreLongerThanHalfTheBox) {
  // The fibre spans x in [0.05, 0.95]; a sphere at x = 0 touches both of its ends, one
  // directly and one through the image shifted by -1: the minimum image would see one only.
  InclusionSet s = unit_box(true);
  add(s, Shape::cylinder({0.5, 0.5, 0.5}, 0.05, Vec3(0.45, 0, 0)));
  add(s, Shape::sphere({0.0, 0.5, 0.5}, 0.1));
  const auto o = find_overlaps(s);
  ASSERT_EQ(o.size(), 2u);
  EXPECT_NE(o[0].shift.x(), o[1].shift.x());
  for (const auto& r : o) EXPECT_EQ(r.contact.type, ContactType::kSC3);
}

TEST(Periodic, FibreLongerThanTheBoxOverlapsItsOwnImage) {
  InclusionSet s = unit_box(true);
  add(s, Shape::cylinder({0.5, 0.5, 0.5}, 0.05, Vec3(0.6, 0, 0)));
  const auto o = find_overlaps(s);
  ASSERT_EQ(o.size(), 1u);  // +1 and -1 images are the same pair, reported once
  EXPECT_EQ(o[0].a, o[0].b);
  // Along a face diagonal the same length fits: images are 1/sqrt(2) apart.
  InclusionSet d = unit_box(true);
  add(d, Shape::cylinder({0.5, 0.5, 0.5}, 0.05, Vec3(0.6, 0.6, 0).normalized() * 0.6));
  EXPECT_TRUE(find_overlaps(d).empty());
}

TEST(Periodic, GridAuditMatchesBruteForceOverAllImages) {
  Random rng(7);
  InclusionSet s = unit_box(true);
  for (int i = 0; i < 300; ++i) {
    const Vec3 c(rng.uniform(), rng.uniform(), rng.uniform());
    switch (i % 3) {
      case 0:
        add(s, Shape::sphere(c, rng.uniform(0.01, 0.05)));
        break;
      case 1:
        add(s, Shape::cylinder(c, 0.01, rng.unit_vector() * rng.uniform(0.02, 0.1)));
        break;
      default:
        add(s, Shape::ellipsoid(c, Vec3(0.05, 0.03, 0.02), rng.rotation()));
    }
  }
  const auto o = find_overlaps(s);
  size_t brute = 0;
  for (size_t i = 0; i < s.inclusions.size(); ++i) {
    for (size_t j = i + 1; j < s.inclusions.size(); ++j) {
      for (int x = -1; x <= 1; ++x) {
        for (int y = -1; y <= 1; ++y) {
          for (int z = -1; z <= 1; ++z) {
            brute +=
                intersect(s.inclusions[i].shape, s.inclusions[j].shape.translated(Vec3(x, y, z)))
                    .overlap;
          }
        }
      }
    }
  }
  EXPECT_GT(brute, 10u);
  EXPECT_EQ(o.size(), brute);
}

TEST(NonPeriodic, OutsideTheBoxIsReported) {
  InclusionSet s = unit_box(false);
  add(s, Shape::sphere({0.5, 0.5, 0.5}, 0.1));
  add(s, Shape::cylinder({0.5, 0.5, 0.9}, 0.05, Vec3(0, 0, 0.2)));
  const auto out = find_outside(s);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0], 1);
}

TEST(InclusionFile, RoundTripIsExact) {
  Random rng(3);
  InclusionSet s = unit_box(true);
  add(s, Shape::sphere({0.1, 0.2, 0.3}, 0.05));
  add(s, Shape::cylinder({0.4, 0.5, 0.6}, 0.02, rng.unit_vector() * 0.1));
  add(s, Shape::ellipsoid({0.7, 0.8, 0.9}, Vec3(0.06, 0.04, 0.03), rng.rotation()));
  const std::string text = write_inclusions_json(s);
  const InclusionSet back = read_inclusions_json(text);
  ASSERT_EQ(back.inclusions.size(), 3u);
  EXPECT_EQ(write_inclusions_json(back), text);
  EXPECT_EQ(back.inclusions[2].shape.rotation, s.inclusions[2].shape.rotation);
}

TEST(InclusionFile, ErrorsNameTheKey) {
  auto err = [](const std::string& text) {
    try {
      read_inclusions_json(text);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string head =
      R"({"format":"rvegen.inclusions/1","box":{"size":[1,1,1]},"inclusions":[)";
  EXPECT_NE(err(head + R"({"id":0,"shape":"sphere","center":[0,0,0],"radius":-1}]})")
                .find("inclusions[0].radius"),
            std::string::npos);
  EXPECT_NE(err(head + R"({"id":0,"shape":"cube","center":[0,0,0]}]})").find("inclusions[0].shape"),
            std::string::npos);
  EXPECT_NE(err(head + R"({"id":0,"shape":"ellipsoid","center":[0,0,0],"semi_axes":[1,1,1],)"
                       R"("rotation":[[1,0,0],[0,1,0],[0,0,2]]}]})")
                .find("inclusions[0].rotation"),
            std::string::npos);
  EXPECT_NE(err(R"({"format":"other","box":{"size":[1,1,1]},"inclusions":[]})").find("format"),
            std::string::npos);
}

TEST(Scene, DefaultSceneRoundTrips) {
  const Scene s = default_scene();
  const Scene back = parse_scene(scene_to_json(s));
  EXPECT_EQ(scene_to_json(back), scene_to_json(s));
}

// md.shake: unset (the packer's default for the scene) is not written, so earlier scenes read
// the same; set, it round-trips, and out of [0, 1] it is refused by name.
TEST(Scene, ShakeRoundTripsOnlyWhenSet) {
  const std::string head =
      R"({"box":{"size":[1,1,1]},"families":[{"shape":"sphere","radius":0.1,"count":3}])";
  const Scene plain = parse_scene(head + "}");
  EXPECT_FALSE(plain.md.shake.has_value());
  EXPECT_EQ(scene_to_json(plain).find("shake"), std::string::npos);
  const Scene set = parse_scene(head + R"(,"md":{"shake":0.5}})");
  ASSERT_TRUE(set.md.shake.has_value());
  EXPECT_EQ(*set.md.shake, 0.5);
  EXPECT_EQ(parse_scene(scene_to_json(set)).md.shake, set.md.shake);
  EXPECT_EQ(*parse_scene(head + R"(,"md":{"shake":0}})").md.shake, 0.0);
  for (const char* bad : {R"(,"md":{"shake":1.5}})", R"(,"md":{"shake":-0.1}})"}) {
    try {
      parse_scene(head + bad);
      ADD_FAILURE() << bad;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("md.shake"), std::string::npos) << e.what();
    }
  }
}

TEST(Scene, TetMeshSizesRoundTripAndBadOnesAreNamed) {
  const std::string head =
      R"({"box":{"size":[1,1,1]},"families":[{"shape":"sphere","radius":0.1,"count":3}],)";
  const Scene s = parse_scene(
      head + R"("mesh_tet":{"max_size":0.05,"min_size":0.002,"chord_error":0.01,"gap_elements":3,)"
             R"("shift_cell":false,"keep_volumes":false,"order":2,"optimize_threshold":0.15}})");
  EXPECT_EQ(s.tet_mesh.order, 2);
  EXPECT_FALSE(s.tet_mesh.shift_cell);
  EXPECT_FALSE(s.tet_mesh.keep_volumes);
  EXPECT_EQ(s.tet_mesh.max_size, 0.05);
  EXPECT_EQ(s.tet_mesh.min_size, 0.002);
  EXPECT_EQ(s.tet_mesh.chord_error, 0.01);
  EXPECT_EQ(s.tet_mesh.gap_elements, 3.0);
  EXPECT_EQ(s.tet_mesh.optimize_threshold, 0.15);
  EXPECT_TRUE(parse_scene(scene_to_json(s)).tet_mesh == s.tet_mesh);
  EXPECT_TRUE(parse_scene(head + R"("outputs":["mesh_tet"]})").tet_mesh == TetMeshSpec{});
  for (const auto& [bad, named] : std::vector<std::pair<std::string, std::string>>{
           {R"({"max_size":-1})", "mesh_tet.max_size"},
           {R"({"max_size":2})", "mesh_tet.max_size"},
           {R"({"max_size":0.01,"min_size":0.02})", "mesh_tet.min_size"},
           {R"({"chord_error":0.5})", "mesh_tet.chord_error"},
           {R"({"gap_elements":0.1})", "mesh_tet.gap_elements"},
           {R"({"shift_cell":1})", "mesh_tet.shift_cell"},
           {R"({"keep_volumes":"yes"})", "mesh_tet.keep_volumes"},
           {R"({"order":3})", "mesh_tet.order"},
           {R"({"order":1.5})", "mesh_tet.order"},
           {R"({"order":"quadratic"})", "mesh_tet.order"},
           {R"({"optimize_threshold":1})", "mesh_tet.optimize_threshold"},
           {R"({"optimize_threshold":-0.1})", "mesh_tet.optimize_threshold"},
           {R"({"optimize_threshold":"fast"})", "mesh_tet.optimize_threshold"},
           {R"({"chord":0.01})", "mesh_tet.chord: unknown key"}}) {
    EXPECT_NE(scene_error(head + R"("mesh_tet":)" + bad + "}").find(named), std::string::npos)
        << bad << ": " << scene_error(head + R"("mesh_tet":)" + bad + "}");
  }
}

TEST(Scene, BadInputNamesTheProblem) {
  const std::string box = R"("box":{"size":[1,1,1]},)";
  EXPECT_NE(scene_error(R"({"box":{"size":[1,1,1]},"familes":[]})").find("familes: unknown key"),
            std::string::npos);
  EXPECT_NE(scene_error("{" + box + R"("families":[{"shape":"sphere","radius":-0.1,"count":3}]})")
                .find("families[0].radius"),
            std::string::npos);
  EXPECT_NE(scene_error("{" + box + R"("families":[{"shape":"sphere","radius":0.1}]})")
                .find("volume_fraction"),
            std::string::npos);
  EXPECT_NE(scene_error("{" + box +
                        R"("families":[{"shape":"sphere","radius":0.1,"count":1,"colour":1}]})")
                .find("families[0].colour: unknown key"),
            std::string::npos);
  EXPECT_NE(scene_error("{" + box + R"("families":[{"shape":"sphere","radius":NaN,"count":1}]})")
                .find("not valid JSON"),
            std::string::npos);
  EXPECT_NE(scene_error("{" + box +
                        R"("families":[{"shape":"sphere","radius":0.05,"volume_fraction":0.8}]})")
                .find("exceeds"),
            std::string::npos);
  EXPECT_NE(scene_error("{" + box + R"("families":[{"shape":"sphere","radius":0.6,"count":1}]})")
                .find("does not fit"),
            std::string::npos);
  EXPECT_NE(
      scene_error(
          R"({"box":{"size":[1,0,1]},"families":[{"shape":"sphere","radius":0.1,"count":1}]})")
          .find("box.size[1]"),
      std::string::npos);
  EXPECT_NE(
      scene_error("{" + box +
                  R"("method":"magic","families":[{"shape":"sphere","radius":0.1,"count":1}]})")
          .find("method"),
      std::string::npos);
}

Scene small_scene(bool periodic) {
  Scene s = parse_scene(R"({"box":{"size":[1,1,1],"periodic":)" +
                        std::string(periodic ? "true" : "false") +
                        R"(},"seed":5,"families":[
      {"shape":"sphere","radius":0.06,"volume_fraction":0.12},
      {"shape":"cylinder","radius":0.02,"aspect_ratio":4,"volume_fraction":0.05},
      {"shape":"ellipsoid","semi_axes":[0.06,0.04,0.03],"volume_fraction":0.04}],
      "voxels":{"resolution":48}})");
  return s;
}

TEST(Rsa, ReachesTargetWithoutOverlapPeriodicAndNot) {
  for (bool periodic : {true, false}) {
    const Scene scene = small_scene(periodic);
    const PackingResult r = pack_rsa(scene);
    EXPECT_EQ(r.status, PackingStatus::kOk);
    EXPECT_TRUE(find_overlaps(r.set).empty());
    EXPECT_TRUE(find_outside(r.set).empty());
    const auto vf = family_volume_fractions(r.set, 3);
    EXPECT_NEAR(vf[0], 0.12, 0.003);
    EXPECT_NEAR(vf[1], 0.05, 0.003);
    EXPECT_NEAR(vf[2], 0.04, 0.003);
  }
}

TEST(Rsa, SameSeedSameRveOtherSeedOtherRve) {
  Scene scene = small_scene(true);
  const std::string a = write_inclusions_json(pack_rsa(scene).set);
  EXPECT_EQ(a, write_inclusions_json(pack_rsa(scene).set));
  scene.seed = 6;
  EXPECT_NE(a, write_inclusions_json(pack_rsa(scene).set));
}

TEST(Rsa, MinGapIsHonoured) {
  Scene scene = small_scene(true);
  scene.min_gap = 0.01;
  const PackingResult r = pack_rsa(scene);
  ASSERT_EQ(r.status, PackingStatus::kOk);
  const auto& inc = r.set.inclusions;
  for (size_t i = 0; i < inc.size(); ++i) {
    for (size_t j = i + 1; j < inc.size(); ++j) {
      for_each_image(r.set.box, inc[i].shape.center, inc[i].shape.bounding_radius() + 0.01,
                     inc[j].shape.center, inc[j].shape.bounding_radius(), [&](const Vec3& sh) {
                       EXPECT_TRUE(clear_of(inc[i].shape, inc[j].shape.translated(sh), 0.0099));
                     });
    }
  }
}

TEST(Rsa, ImpossibleTargetStopsCleanly) {
  // 50 % of monodisperse spheres is beyond RSA's saturation (about 38 %): a bounded failure.
  Scene scene = parse_scene(R"({"box":{"size":[1,1,1]},"families":[
      {"shape":"sphere","radius":0.08,"volume_fraction":0.5}]})");
  scene.rsa_max_attempts = 2000;
  const PackingResult r = pack_rsa(scene);
  EXPECT_EQ(r.status, PackingStatus::kTargetNotReached);
  EXPECT_LT(r.placed_count[0], r.target_count[0]);
  EXPECT_GT(r.placed_count[0], 0);
  EXPECT_TRUE(find_overlaps(r.set).empty());
}

TEST(Voxels, LabelsMatchTheGeometry) {
  const Scene scene = small_scene(true);
  const PackingResult r = pack_rsa(scene);
  const VoxelImage im = voxelize(r.set, {48, 48, 48});
  const auto vf = family_volume_fractions(r.set, 3);
  std::vector<double> count(4, 0.0);
  for (uint8_t p : im.phase) count[p] += 1.0;
  for (int f = 0; f < 3; ++f) EXPECT_NEAR(count[f + 1] / im.phase.size(), vf[f], 0.01);
  // Every labelled voxel centre lies in the inclusion it names (or its periodic image).
  Random rng(1);
  for (int n = 0; n < 2000; ++n) {
    const int i = static_cast<int>(rng.uniform() * 48), j = static_cast<int>(rng.uniform() * 48),
              k = static_cast<int>(rng.uniform() * 48);
    const Vec3 x = im.origin + Vec3((i + 0.5) * im.spacing[0], (j + 0.5) * im.spacing[1],
                                    (k + 0.5) * im.spacing[2]);
    int inside = -1;
    for (const auto& inc : r.set.inclusions) {
      for_each_image(r.set.box, x, 0.0, inc.shape.center, inc.shape.bounding_radius() + 1e-12,
                     [&](const Vec3& sh) {
                       if (inc.shape.translated(sh).contains(x)) inside = inc.id;
                     });
    }
    EXPECT_EQ(im.inclusion_id[im.index(i, j, k)], inside);
  }
}

}  // namespace
