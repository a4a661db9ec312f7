// Hostile and careless input, and the guarantees that hold anyway: every scene field is
// validated however the scene was built, the audit stops an overlapping RVE, budgets hold,
// output sets are replaced whole.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <string>

#include "rvegen/geometry/random.hpp"
#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/io/writers.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/resources.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/model/stats.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/levelset.hpp"
#include "rvegen/raster/voxelize.hpp"
#include "test_util.hpp"

namespace rvegen {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string validation_error(const Scene& s) {
  try {
    validate_scene(s);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

Scene small_scene() {
  return parse_scene(R"({"box":{"size":[1,1,1]},"seed":1,"families":[
      {"shape":"sphere","radius":0.05,"volume_fraction":0.1},
      {"name":"fibres","shape":"cylinder","radius":0.02,"aspect_ratio":4,"volume_fraction":0.05,
       "orientation":{"law":"von_mises_fisher","axis":[0,0,1],"kappa":2}}],
      "voxels":{"resolution":16}})");
}

// --- Scenes built in code (as the VTK source builds them) -------------------------------

TEST(Validation, EveryBadFieldOfASceneBuiltInCodeIsNamed) {
  struct Case {
    const char* key;
    std::function<void(Scene&)> spoil;
  };
  const Case cases[] = {
      {"md.patience", [](Scene& s) { s.md.patience = 0; }},
      {"md.pressure", [](Scene& s) { s.md.pressure = 0.0; }},
      {"md.pressure", [](Scene& s) { s.md.pressure = kNaN; }},
      {"md.max_seconds", [](Scene& s) { s.md.max_seconds = -1.0; }},
      {"md.max_steps", [](Scene& s) { s.md.max_steps = 0; }},
      {"md.shake", [](Scene& s) { s.md.shake = -0.1; }},
      {"md.shake", [](Scene& s) { s.md.shake = kNaN; }},
      {"md.shake", [](Scene& s) { s.md.shake = 1.5; }},
      {"rsa.max_attempts", [](Scene& s) { s.rsa_max_attempts = 0; }},
      {"rsa.max_seconds", [](Scene& s) { s.rsa_max_seconds = kNaN; }},
      {"voxels.subsamples", [](Scene& s) { s.subsamples = 0; }},
      {"voxels.resolution[1]", [](Scene& s) { s.resolution[1] = 0; }},
      {"levelsets.half_width", [](Scene& s) { s.levelset_half_width = 0.0; }},
      {"levelsets.voxel_size", [](Scene& s) { s.levelset_voxel_size = 10.0; }},
      {"levelsets.voxel_size", [](Scene& s) { s.levelset_voxel_size = -1.0; }},
      {"min_gap", [](Scene& s) { s.min_gap = kNaN; }},
      {"box.origin[0]", [](Scene& s) { s.box.origin[0] = 1e200; }},
      {"box.origin[2]", [](Scene& s) { s.box.origin[2] = kNaN; }},
      {"box.size[0]", [](Scene& s) { s.box.size[0] = 1e300; }},
      {"box.size", [](Scene& s) { s.box.size = Vec3(1e-7, 1, 1); }},
      {"method", [](Scene& s) { s.method = static_cast<Method>(7); }},
      {"families[0].radius", [](Scene& s) { s.families[0].radius = SizeLaw(-0.05); }},
      {"families[0].radius", [](Scene& s) { s.families[0].radius = SizeLaw(kNaN); }},
      {"families[1].aspect_ratio.std",
       [](Scene& s) {
         s.families[1].aspect_ratio.kind = SizeLaw::Kind::kNormal;
         s.families[1].aspect_ratio.p1 = 4.0;
         s.families[1].aspect_ratio.p2 = -1.0;
       }},
      {"families[1].orientation.axis",
       [](Scene& s) { s.families[1].orientation.axis = Vec3(kNaN, 0, 1); }},
      {"families[1].orientation.axis",
       [](Scene& s) { s.families[1].orientation.axis = Vec3(0, 0, 2); }},
      {"families[1].orientation.kappa", [](Scene& s) { s.families[1].orientation.kappa = -1.0; }},
      {"families[0].volume_fraction", [](Scene& s) { s.families[0].volume_fraction = 1.5; }},
      {"families[0].count", [](Scene& s) { s.families[0].count = 200000000; }},
      {"families[0]", [](Scene& s) { s.families[0].radius = SizeLaw(1e-8); }},
  };
  for (const Case& c : cases) {
    Scene s = small_scene();
    ASSERT_EQ(validation_error(s), "no error");
    c.spoil(s);
    const std::string msg = validation_error(s);
    EXPECT_EQ(msg.rfind(std::string(c.key) + ":", 0), 0u) << c.key << " -> " << msg;
  }
}

TEST(Validation, AtMost256PhasesFor8BitLabels) {
  Scene s = small_scene();
  Family f = s.families[0];
  f.volume_fraction = -1.0;
  f.count = 1;
  f.radius = SizeLaw(0.01);
  s.families.assign(200, f);
  EXPECT_EQ(validation_error(s), "no error");
  for (auto& fam : s.families) fam.modifiers.coating = 0.001;  // 1 + 200 + 200 phases
  EXPECT_NE(validation_error(s).find("too many phases"), std::string::npos);

  // An inclusion list (RVE Voxelize reads one) cannot get past the voxelizer either.
  InclusionSet set;
  for (int k = 0; k < 300; ++k) {
    Inclusion inc;
    inc.id = k;
    inc.family = k;
    inc.shape = Shape::sphere(Vec3(0.5, 0.5, 0.5), 0.01);
    set.inclusions.push_back(inc);
  }
  EXPECT_THROW(voxelize(set, {4, 4, 4}), InputError);
}

// --- Parsing --------------------------------------------------------------------------

TEST(Parsing, DuplicateKeysAreRefusedWithTheirPlace) {
  EXPECT_EQ(scene_error(R"({"box":{"size":[1,1,1]},"seed":1,"seed":2,"families":[
      {"shape":"sphere","radius":0.05,"volume_fraction":0.1}]})")
                .rfind("seed: key given twice", 0),
            0u);
  const std::string nested = scene_error(R"({"box":{"size":[1,1,1]},"families":[
      {"shape":"sphere","radius":0.05,"volume_fraction":0.1},
      {"shape":"sphere","radius":0.05,"radius":0.06,"volume_fraction":0.1}]})");
  EXPECT_EQ(nested.rfind("families[1].radius: key given twice", 0), 0u) << nested;
  // The same key in two different objects is fine.
  EXPECT_EQ(scene_error(R"({"box":{"size":[1,1,1]},"families":[
      {"shape":"sphere","radius":0.05,"volume_fraction":0.1},
      {"shape":"sphere","radius":0.06,"volume_fraction":0.1}]})"),
            "no error");
}

TEST(Parsing, NumberOverflowNamesItsKey) {
  const std::string msg = scene_error(R"({"box":{"size":[1,1e999,1]},"families":[
      {"shape":"sphere","radius":0.05,"volume_fraction":0.1}]})");
  EXPECT_NE(msg.find("box.size[1]"), std::string::npos) << msg;
  EXPECT_NE(msg.find("not valid JSON"), std::string::npos) << msg;
}

TEST(Parsing, ErrorsInsideArraysNameTheElement) {
  // After complete objects, inside an open one, and at a bare element.
  std::string msg = scene_error(R"({"box":{"size":[1,1,1]},"families":[
      {"shape":"sphere","radius":0.05,"volume_fraction":0.1},
      {"shape":"sphere","radius":1e999,"volume_fraction":0.1}]})");
  EXPECT_NE(msg.find("families[1].radius"), std::string::npos) << msg;
  msg = scene_error(R"({"box":{"size":[1,1,1]},"families":[
      {"shape":"sphere","radius":0.05,"volume_fraction":0.1},{},1e999]})");
  EXPECT_NE(msg.find("families[2]"), std::string::npos) << msg;
  msg = scene_error(R"({"box":{"size":[[1],[2],]}})");
  EXPECT_NE(msg.find("box.size[2]"), std::string::npos) << msg;
}

TEST(Parsing, HugeDirectionComponentsAreNormalisedWithoutOverflow) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"families":[
      {"shape":"cylinder","radius":0.02,"aspect_ratio":5,"volume_fraction":0.1,
       "orientation":{"law":"aligned","axis":[1e308,1e308,0]}}]})");
  const Vec3 a = s.families[0].orientation.axis;
  EXPECT_NEAR(a.x(), std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(a.y(), std::sqrt(0.5), 1e-15);
  EXPECT_EQ(a.z(), 0.0);
}

TEST(Parsing, InclusionIdsInRangeAndUnique) {
  auto list = [](const std::string& body) {
    return R"({"format":"rvegen.inclusions/1","box":{"size":[1,1,1]},"inclusions":[)" + body + "]}";
  };
  const std::string a = R"({"id":0,"shape":"sphere","center":[0.2,0.2,0.2],"radius":0.05})";
  EXPECT_NO_THROW(read_inclusions_json(list(a)));
  try {
    read_inclusions_json(
        list(R"({"id":3000000000,"shape":"sphere","center":[0.2,0.2,0.2],"radius":0.05})"));
    FAIL() << "id above 2^31 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("inclusions[0].id"), std::string::npos);
  }
  try {
    read_inclusions_json(list(a + "," + a));
    FAIL() << "duplicate id accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("id 0 appears twice"), std::string::npos);
  }
  // A sphere much larger than the periodic box (the audit would visit ~1e6 images a pair).
  EXPECT_THROW(
      read_inclusions_json(list(R"({"id":0,"shape":"sphere","center":[0.5,0.5,0.5],"radius":50})")),
      InputError);
  EXPECT_THROW(read_inclusions_json(
                   list(R"({"id":0,"shape":"sphere","center":[1e200,0.5,0.5],"radius":0.1})")),
               InputError);
  // A bend tighter than the fibre's length (0.2 with its coating): refused, naming the key.
  const std::string bent =
      R"({"id":0,"shape":"cylinder","center":[0.5,0.5,0.5],"radius":0.02,"half_axis":[0.09,0,0],)"
      R"("modifiers":{"coating":0.01,"bend_radius":%s,"bend_angle":1}})";
  auto with = [&](const char* radius) {
    std::string t = bent;
    t.replace(t.find("%s"), 2, radius);
    return list(t);
  };
  EXPECT_NO_THROW(read_inclusions_json(with("0.2")));
  try {
    read_inclusions_json(with("0.19"));
    FAIL() << "bend radius below the fibre length accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("inclusions[0].modifiers.bend_radius"), std::string::npos);
  }
}

// Reading an inclusion list is linear in its length (a reader that walked
// the parent array at every closing brace took minutes for a million spheres). A complexity
// check, not a timing: the process CPU time of 8n inclusions over that of n, each the best of
// three (two for 8n), on the same machine in the same process. Linear reading gives about 9;
// the quadratic reader, put back for a try, gave 52 at these sizes.
TEST(Parsing, ReadingIsLinearInTheNumberOfInclusions) {
  auto lattice = [](int m) {
    std::string t = R"({"format":"rvegen.inclusions/1","box":{"size":[1,1,1]},"inclusions":[)";
    char buf[160];
    int id = 0;
    for (int z = 0; z < m; ++z)
      for (int y = 0; y < m; ++y)
        for (int x = 0; x < m; ++x) {
          std::snprintf(
              buf, sizeof buf,
              R"(%s{"id":%d,"shape":"sphere","center":[%.17g,%.17g,%.17g],"radius":%.17g})",
              id ? "," : "", id, (x + 0.5) / m, (y + 0.5) / m, (z + 0.5) / m, 0.45 / m);
          t += buf;
          ++id;
        }
    return t + "]}";
  };
  auto best_cpu_seconds = [](const std::string& text, size_t expect, int tries) {
    double best = std::numeric_limits<double>::infinity();
    for (int k = 0; k < tries; ++k) {
      const std::clock_t t0 = std::clock();
      const InclusionSet set = read_inclusions_json(text);
      const double s = double(std::clock() - t0) / CLOCKS_PER_SEC;
      EXPECT_EQ(set.inclusions.size(), expect);
      best = std::min(best, s);
    }
    return best;
  };
  const int m = 30;  // 27,000 spheres, then 216,000
  const double small = best_cpu_seconds(lattice(m), size_t(m) * m * m, 3);
  const double large = best_cpu_seconds(lattice(2 * m), size_t(8) * m * m * m, 2);
  ASSERT_GT(small, 0.0);
  EXPECT_LT(large / small, 16.0) << "n: " << small << " s, 8n: " << large << " s";
}

TEST(Files, ReadFileRefusesDevicesAndOversizedFiles) {
  EXPECT_THROW(read_file("/dev/zero"), InputError);
  const std::string path = testing::TempDir() + "rvegen_big.json";
  {
    std::ofstream out(path);
    out << std::string(2000, ' ');
  }
  EXPECT_THROW(read_file(path, 1000), InputError);
  EXPECT_EQ(read_file(path, 2000).size(), 2000u);
  std::remove(path.c_str());
}

// --- The audit ------------------------------------------------------------------------

TEST(Audit, StopsAtTheLimitOnAPileOfSpheres) {
  // 10,000 spheres at one point: 5e7 overlapping pairs, never all stored.
  InclusionSet set;
  for (int k = 0; k < 10000; ++k) {
    Inclusion inc;
    inc.id = k;
    inc.shape = Shape::sphere(Vec3(0.5, 0.5, 0.5), 0.01);
    set.inclusions.push_back(inc);
  }
  const AuditReport r = audit(set, 500);
  EXPECT_EQ(r.overlaps.size(), 500u);
  EXPECT_TRUE(r.truncated);
  EXPECT_FALSE(r.clean());
  EXPECT_NE(describe_failure(r, set).find("or more"), std::string::npos);
}

TEST(Audit, StaysNearLinearForAHundredToOneSizeRatio) {
  // One sphere of radius 0.3 among 20,000 of radius 0.003 (a 100:1 mixture): a single grid sized
  // to the large sphere made every small one a candidate of every other (2e8 candidates); the
  // two-level broad phase gives a few per sphere. Every overlap is still found: two small
  // spheres pushed into each other and one pushed into the large one.
  InclusionSet set;
  Inclusion big;
  big.shape = Shape::sphere(Vec3(0.5, 0.5, 0.5), 0.3);
  set.inclusions.push_back(big);
  Random rng(11);
  while (set.inclusions.size() < 20001) {
    Inclusion inc;
    inc.id = static_cast<int>(set.inclusions.size());
    inc.shape = Shape::sphere(Vec3(rng.uniform(), rng.uniform(), rng.uniform()), 0.003);
    if ((inc.shape.center - big.shape.center).norm() > 0.31) set.inclusions.push_back(inc);
  }
  const size_t n = set.inclusions.size();
  AuditReport r = audit(set);
  const size_t random_overlaps = r.overlaps.size();  // a few small ones drawn into each other
  EXPECT_LT(r.candidates, 20 * n) << r.candidates;
  set.inclusions[1].shape.center = big.shape.center + Vec3(0.3025, 0, 0);
  set.inclusions[2].shape.center = set.inclusions[3].shape.center + Vec3(0, 0.005, 0);
  r = audit(set);
  EXPECT_GE(r.overlaps.size(), random_overlaps + 1);
  bool big_met = false, pair_met = false;
  for (const OverlapRecord& o : r.overlaps) {
    big_met |= o.a == 0 && o.b == 1;
    pair_met |= o.a == 2 && o.b == 3;
  }
  EXPECT_TRUE(big_met);
  EXPECT_TRUE(pair_met);
}

TEST(Audit, GenerateNeverReturnsAnOverlappingRve) {
  const Scene s = small_scene();
  EXPECT_NO_THROW(generate(s));
  try {
    generate(s, nullptr, [](InclusionSet& set) {
      set.inclusions[1].shape.center = set.inclusions[0].shape.center;
    });
    FAIL() << "an overlapping RVE was returned";
  } catch (const AuditFailure& e) {
    EXPECT_NE(std::string(e.what()).find("inclusions 0 and 1 overlap"), std::string::npos)
        << e.what();
  }
  // In a non-periodic box, an inclusion pushed out of the box is caught too.
  Scene closed = s;
  closed.box.periodic = false;
  EXPECT_THROW(generate(closed, nullptr,
                        [](InclusionSet& set) { set.inclusions.back().shape.center.x() = 1.0; }),
               AuditFailure);
}

// --- Budgets --------------------------------------------------------------------------

TEST(Budgets, MdTimeBudgetHoldsInsideACrowdedPairListBuild) {
  // 30,000 thin disks of radius 0.05 (aspect ratio 1e-3): each meets hundreds of others, so
  // one pair-list build takes longer than the budget; the run stops in the second step (the
  // first always completes: its configuration is the least a run returns), validly.
  Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":1,"md":{"max_seconds":0.01},
      "families":[{"shape":"cylinder","radius":0.05,"aspect_ratio":0.001,"count":30000}],
      "voxels":{"resolution":8}})");
  const PackingResult r = generate(s);
  EXPECT_EQ(r.status, PackingStatus::kTargetNotReached);
  EXPECT_EQ(r.stop_reason, StopReason::kTimeBudget);
  // The clock was once read every 16 steps only: the budget now stops a step half-way.
  EXPECT_LT(r.steps, 16);
  EXPECT_GE(r.scale, 0.0);
  EXPECT_TRUE(audit(r.set).clean());
}

TEST(Budgets, RsaTimeBudget) {
  Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":1,"method":"rsa",
      "rsa":{"max_attempts":1000000000,"max_seconds":0.2},
      "families":[{"shape":"sphere","radius":0.07,"volume_fraction":0.5}]})");
  const PackingResult r = generate(s);
  EXPECT_EQ(r.status, PackingStatus::kTargetNotReached);
  EXPECT_EQ(r.stop_reason, StopReason::kTimeBudget);
  EXPECT_TRUE(audit(r.set).clean());
}

TEST(Budgets, MemoryEstimateGrowsWithWhatTheSceneAsks) {
  Scene s = small_scene();
  const ResourceEstimate base = estimate_resources(s);
  EXPECT_GT(base.total_bytes(), 0.0);
  s.resolution = {1024, 1024, 1024};
  const ResourceEstimate big = estimate_resources(s);
  EXPECT_GE(big.voxel_bytes, 9.0 * 1024 * 1024 * 1024);
  for (auto& f : s.families) f.modifiers.coating = 0.005;
  s.levelset_voxel_size = 1.0 / 8000;
  // Straight coated shapes get level sets only when they are asked for.
  EXPECT_EQ(estimate_resources(s).levelset_bytes, 0.0);
  s.outputs.levelsets_asked = true;
  EXPECT_GT(estimate_resources(s).levelset_bytes, 1e10);
  EXPECT_GT(available_memory_bytes(), 0.0);
  // The tetrahedral mesh: asked for, it counts; a finer chord error needs more.
  Scene m = small_scene();
  EXPECT_EQ(estimate_resources(m).tet_mesh_bytes, 0.0);
  m.outputs.mesh_tet = true;
  const ResourceEstimate tets = estimate_resources(m);
  EXPECT_GT(tets.tetrahedra, 0.0);
  m.tet_mesh.chord_error /= 10.0;
  EXPECT_GT(estimate_resources(m).tet_mesh_bytes, 5.0 * tets.tet_mesh_bytes);
  EXPECT_NE(describe(estimate_resources(m)).find("tetrahedral mesh"), std::string::npos);
}

TEST(Budgets, AMeshThatDoesNotFitIsOfferedCoarserSettingsLeastLossFirst) {
  Scene m = small_scene();
  m.outputs.mesh_tet = true;
  const std::vector<TetMeshSpec> offers = coarser_tet_meshes(m.tet_mesh);
  ASSERT_FALSE(offers.empty());
  double last = -1.0;
  for (const TetMeshSpec& t : offers) {
    // Each coarser in every setting, none the spec itself, and each cheaper to the scene's
    // estimate than the spec.
    EXPECT_FALSE(t == m.tet_mesh);
    EXPECT_GE(t.chord_error, m.tet_mesh.chord_error);
    EXPECT_LE(t.gap_elements, m.tet_mesh.gap_elements);
    Scene c = m;
    c.tet_mesh = t;
    EXPECT_LT(estimate_resources(c).tetrahedra, estimate_resources(m).tetrahedra);
    // Gap elements only drop with 10-node elements (the accuracy kept across the gap).
    if (t.gap_elements < m.tet_mesh.gap_elements) EXPECT_EQ(t.order, 2);
    EXPECT_GE(t.chord_error, last);
    last = t.chord_error;
  }
  // The chord error alone first.
  EXPECT_GT(offers.front().chord_error, m.tet_mesh.chord_error);
  EXPECT_EQ(offers.front().gap_elements, m.tet_mesh.gap_elements);
  EXPECT_EQ(describe_tet_mesh_change(m.tet_mesh, offers.front()),
            "\"mesh_tet\": {\"chord_error\": 0.01}");
  // The coarsest: half an element across the gaps, 10-node, at chord error 0.1; nothing
  // coarser than it is offered.
  EXPECT_EQ(offers.back().chord_error, 0.1);
  EXPECT_EQ(offers.back().gap_elements, 0.5);
  EXPECT_EQ(offers.back().order, 2);
  EXPECT_TRUE(coarser_tet_meshes(offers.back()).empty());
  // Named as the filter's properties, too.
  TetMeshSpec one = m.tet_mesh;
  one.gap_elements = 1.0;
  one.order = 2;
  EXPECT_EQ(describe_tet_mesh_change(m.tet_mesh, one, SettingNames::kProperties),
            "GapElements 1, Order 2");
}
// --- Level sets -----------------------------------------------------------------------

TEST(LevelSetNames, FamiliesWhoseNamesCollideGetDistinctGrids) {
  InclusionSet set;
  set.family_names = {"a b", "a_b", "a b"};
  for (int f = 0; f < 3; ++f) {
    Inclusion inc;
    inc.id = f;
    inc.family = f;
    inc.shape = Shape::sphere(Vec3(0.2 + 0.3 * f, 0.5, 0.5), 0.08);
    inc.mod.coating = 0.02;
    set.inclusions.push_back(inc);
  }
  LevelSetOptions opt;
  opt.voxel_size = 1.0 / 64;
  opt.exact_shapes = true;
  const LevelSets ls = build_level_sets(set, opt);
  ASSERT_EQ(ls.grids.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    for (size_t j = i + 1; j < 3; ++j) EXPECT_NE(ls.grids[i].name, ls.grids[j].name);
  }
}

// --- Output sets ----------------------------------------------------------------------

class OutputSetTest : public testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::path(testing::TempDir()) /
            ("rvegen_outset_" + std::to_string(::getpid()) + "_" +
             testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    fs::create_directories(root_);
    dir_ = (root_ / "rve").string();
  }
  void TearDown() override { fs::remove_all(root_); }
  std::string read(const std::string& name) const {
    std::ifstream in(fs::path(dir_) / name);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  // Entries of the parent directory other than the output directory.
  std::vector<std::string> leftovers() const {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(root_)) {
      if (e.path().filename() != "rve" && e.path().filename() != "outside.txt")
        out.push_back(e.path().filename().string());
    }
    return out;
  }
  fs::path root_;
  std::string dir_;
};

// The report every set rvegen writes ends with: its keys, and the files staged with their
// sizes (what a later run checks before it replaces them).
std::string report_of(const OutputSet& out, const std::string& extra = "") {
  return "{\"status\": \"ok\", \"seed\": 1, \"timings\": {}" + extra +
         ", \"files\": " + out.files_json() + "}";
}

TEST_F(OutputSetTest, ASetReplacesThePreviousOneWholeStaleFilesIncluded) {
  {
    OutputSet out(dir_);
    out.write("inclusions.json", "first");
    out.write("levelsets.vdb", "grids");
    out.write("report.json", report_of(out));  // as every set rvegen writes
    out.commit();
  }
  EXPECT_EQ(read("inclusions.json"), "first");
  {
    OutputSet out(dir_);
    out.write("inclusions.json", "second");
    out.write("report.json", report_of(out));
    out.commit();
  }
  EXPECT_EQ(read("inclusions.json"), "second");
  EXPECT_FALSE(fs::exists(fs::path(dir_) / "levelsets.vdb"));  // stale: gone
  EXPECT_TRUE(leftovers().empty());
}

TEST_F(OutputSetTest, WithoutCommitNothingChanges) {
  {
    OutputSet out(dir_);
    out.write("inclusions.json", "first");
    out.write("report.json", report_of(out, ", \"run\": 1"));
    out.commit();
  }
  {
    OutputSet out(dir_);
    out.write("inclusions.json", "second");
    out.write("report.json", report_of(out));
    // No commit: an error happened.
  }
  EXPECT_EQ(read("inclusions.json"), "first");
  EXPECT_NE(read("report.json").find("\"run\": 1"), std::string::npos);
  EXPECT_TRUE(leftovers().empty());
}

TEST_F(OutputSetTest, RefusesADirectoryWithOtherFilesBeforeAnyWork) {
  fs::create_directories(dir_);
  std::ofstream(fs::path(dir_) / "notes.txt") << "mine";
  try {
    OutputSet out(dir_);
    FAIL() << "a directory with a foreign file was accepted";
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("notes.txt"), std::string::npos);
  }
  EXPECT_TRUE(fs::exists(fs::path(dir_) / "notes.txt"));
  EXPECT_THROW(OutputSet(dir_ + "/notes.txt/sub"), OutputError);  // under a file
}

TEST_F(OutputSetTest, AHandMadeInclusionListIsTheUsers) {
  // Files under rvegen's names without the report.json every set holds: no earlier run wrote
  // them, so they are not replaced.
  fs::create_directories(dir_);
  std::ofstream(fs::path(dir_) / "inclusions.json") << "my own";
  try {
    OutputSet out(dir_);
    ADD_FAILURE() << "a directory holding only a hand-made inclusions.json was taken";
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("holds inclusions.json but no report.json"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(read("inclusions.json"), "my own");
}

TEST_F(OutputSetTest, AReportThatDoesNotListTheFilesBesideItIsTheUsers) {
  // A report.json of the user's own, alone; then a real report copied beside the user's own
  // inclusions.json: neither is a set an earlier run wrote, and nothing is replaced.
  fs::create_directories(dir_);
  std::ofstream(fs::path(dir_) / "report.json") << "{\"my\": \"report\"}";
  EXPECT_THROW(OutputSet{dir_}, OutputError);
  EXPECT_EQ(read("report.json"), "{\"my\": \"report\"}");
  const std::string other = root_.string() + "/other";
  {
    OutputSet out(other);
    out.write("inclusions.json", "packed");
    out.write("report.json", report_of(out));
    out.commit();
  }
  fs::copy_file(fs::path(other) / "report.json", fs::path(dir_) / "report.json",
                fs::copy_options::overwrite_existing);
  std::ofstream(fs::path(dir_) / "inclusions.json") << "{\"mine\": 1}";
  try {
    OutputSet out(dir_);
    ADD_FAILURE() << "a copied report was taken for the user's inclusions.json";
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("not the report of the files beside it"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(read("inclusions.json"), "{\"mine\": 1}");
  fs::remove_all(other);
}

TEST_F(OutputSetTest, AReportWithoutTheFilesListIsNotTakenForASet) {
  // The report's keys alone, beside the user's voxels.vti: not a set rvegen wrote.
  fs::create_directories(dir_);
  std::ofstream(fs::path(dir_) / "report.json")
      << "{\"status\": \"ok\", \"seed\": 1, \"timings\": {}}";
  std::ofstream(fs::path(dir_) / "voxels.vti") << "mine";
  EXPECT_THROW(OutputSet{dir_}, OutputError);
  EXPECT_EQ(read("voxels.vti"), "mine");
}

TEST_F(OutputSetTest, FoldersThatLookLikeStagingButHoldTheUsersFilesStay) {
  const fs::path a = root_ / ".rve.rvegen-4194305-abcdef", b = root_ / ".rve.rvegen-backup";
  fs::create_directories(a);
  fs::create_directories(b);
  std::ofstream(a / "my_thesis.tex") << "thesis";
  std::ofstream(b / "old_results.csv") << "1,2";
  {
    OutputSet out(dir_);
    out.write("inclusions.json", "x");
    out.write("report.json", report_of(out));
    out.commit();
  }
  EXPECT_TRUE(fs::exists(a / "my_thesis.tex"));
  EXPECT_TRUE(fs::exists(b / "old_results.csv"));
  EXPECT_FALSE(fs::exists(fs::path(dir_) / "my_thesis.tex"));
}

TEST_F(OutputSetTest, AUsersFileLeftByARunKilledAfterTheSwapGoesBackIntoTheDirectory) {
  // The previous set under the staging name of a run killed between the swap and the move
  // back, with the file the user put into the directory meanwhile.
  {
    OutputSet out(dir_);
    out.write("inclusions.json", "new");
    out.write("report.json", report_of(out));
    out.commit();
  }
  const fs::path stale = root_ / ".rve.rvegen-4194305-qwerty";
  fs::create_directories(stale);
  {
    const std::string old = root_.string() + "/old";
    OutputSet out(old);
    out.write("inclusions.json", "old");
    out.write("report.json", report_of(out));
    out.commit();
    for (const auto& e : fs::directory_iterator(old))
      fs::rename(e.path(), stale / e.path().filename());
    fs::remove(old);
  }
  std::ofstream(stale / "notes.txt") << "mine";
  {
    OutputSet out(dir_);
    out.write("inclusions.json", "newer");
    out.write("report.json", report_of(out));
    out.commit();
  }
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_EQ(read("notes.txt"), "mine");
  EXPECT_EQ(read("inclusions.json"), "newer");
}

TEST_F(OutputSetTest, AFileAddedWhileTheRunWorksStays) {
  {
    OutputSet out(dir_);
    out.write("inclusions.json", "first");
    out.write("levelsets.vdb", "grids");
    out.write("report.json", report_of(out));
    out.commit();
  }
  {
    OutputSet out(dir_);  // checked: an earlier set
    out.write("inclusions.json", "second");
    out.write("report.json", report_of(out));
    // The user puts a file and a folder into DIR while the run works.
    std::ofstream(fs::path(dir_) / "notes.txt") << "mine";
    fs::create_directories(fs::path(dir_) / "plots");
    out.commit();
    EXPECT_TRUE(out.leftover().empty());
  }
  EXPECT_EQ(read("inclusions.json"), "second");
  EXPECT_EQ(read("notes.txt"), "mine");
  EXPECT_TRUE(fs::is_directory(fs::path(dir_) / "plots"));
  EXPECT_FALSE(fs::exists(fs::path(dir_) / "levelsets.vdb"));  // the old set's stale file: gone
  EXPECT_TRUE(leftovers().empty());
}

TEST_F(OutputSetTest, OrphanedStagingOfAKilledRunIsRemoved) {
  // A staging directory whose process is gone (pid 2^22 + 1 is above the kernel's pid range).
  const fs::path orphan = root_ / ".rve.rvegen-4194305-abcdef";
  fs::create_directories(orphan);
  std::ofstream(orphan / "voxels.vti") << std::string(1000, 'x');
  OutputSet out(dir_);
  EXPECT_FALSE(fs::exists(orphan));
  out.write("inclusions.json", "x");
  out.commit();
}

TEST_F(OutputSetTest, PlantedLinksAreNeverFollowed) {
  // A link where earlier versions put predictable temporary names: rvegen writes regular files
  // only, so a link under one of its names is not its own; the directory is refused and the
  // target outside does not change.
  const fs::path target = root_ / "outside.txt";
  std::ofstream(target) << "precious";
  fs::create_directories(dir_);
  const fs::path link = fs::path(dir_) / (".inclusions.json.tmp." + std::to_string(::getpid()));
  fs::create_symlink(target, link);
  EXPECT_THROW(OutputSet{dir_}, OutputError);
  EXPECT_TRUE(fs::is_symlink(link));
  fs::remove(link);
  {
    OutputSet out(dir_);
    struct stat st {};
    ASSERT_EQ(::stat(out.staging_dir().c_str(), &st), 0);
    EXPECT_EQ(st.st_mode & 0777, 0700u);  // private while it is written
    out.write("inclusions.json", "new");
    out.commit();
  }
  std::ifstream in(target);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), "precious");
  EXPECT_EQ(read("inclusions.json"), "new");
}

TEST_F(OutputSetTest, ADirectoryUnderAnOutputNameIsTheUsers) {
  fs::create_directories(fs::path(dir_) / "levelsets.vdb");
  std::ofstream(fs::path(dir_) / "levelsets.vdb" / "mine.txt") << "mine";
  std::ofstream(fs::path(dir_) / "report.json")
      << "{\"status\": \"ok\", \"seed\": 1, \"timings\": {}}";
  try {
    OutputSet out(dir_);
    ADD_FAILURE() << "a directory named levelsets.vdb was taken for an output";
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("levelsets.vdb (not a regular file)"), std::string::npos)
        << e.what();
  }
  EXPECT_TRUE(fs::exists(fs::path(dir_) / "levelsets.vdb" / "mine.txt"));
}

}  // namespace
}  // namespace rvegen

namespace rvegen {
namespace {
// --- Orientation tensors typed by users ---------------------------------------------------

TEST(TypedTensors, ATraceOffOneWithinTheToleranceIsTakenOverItsTrace) {
  // A trace of 1 + 5e-7 (within the 1e-6 the validation grants) gave an orientation tensor
  // error of 0.155 with 8 fibres: the law fitted a tensor no set of unit vectors has.
  Mat3 typed;
  typed << 0.5000005, 0, 0, 0, 0.3, 0, 0, 0, 0.2;
  const Mat3 taken = OrientationLaw::as_typed(typed);
  EXPECT_NEAR(taken.trace(), 1.0, 1e-15);
  EXPECT_NEAR(taken(0, 0), 0.5000005 / 1.0000005, 1e-15);
  Mat3 off = typed;
  off(0, 0) = 0.51;  // far off: left for the validation to name
  EXPECT_EQ(OrientationLaw::as_typed(off), off);
  const Scene s = parse_scene(
      R"({"box": {"size": [1,1,1]}, "families": [{"shape": "cylinder", "radius": 0.02,
          "aspect_ratio": 5, "count": 8, "orientation": {"law": "tensor",
          "a2": [[0.5000005,0,0],[0,0.3,0],[0,0,0.2]]}}]})");
  EXPECT_NEAR(s.families[0].orientation.a2.trace(), 1.0, 1e-15);
  const PackingResult r = generate(s);
  EXPECT_LT((orientation_tensor(r.set, 0) - s.families[0].orientation.a2).cwiseAbs().maxCoeff(),
            1e-6);
  // An eigenvalue within the tolerance of 0 is 0: diag(0.5, 0.5, 1e-12) is the planar law,
  // held exactly (the fibres came out 0.58 / 0.42); a negative one beyond it is left for the
  // validation to refuse.
  for (const double tiny : {1e-12, -5e-10, 1e-6}) {
    Mat3 near_planar = Mat3::Zero();
    near_planar(0, 0) = near_planar(1, 1) = 0.5 * (1.0 - tiny);
    near_planar(2, 2) = tiny;
    const Mat3 planar = OrientationLaw::as_typed(near_planar);
    EXPECT_EQ(planar(2, 2), 0.0) << tiny;
    EXPECT_NEAR(planar(0, 0), 0.5, 1e-15) << tiny;
  }
  Mat3 negative = Mat3::Zero();
  negative(0, 0) = 0.8, negative(1, 1) = 0.5, negative(2, 2) = -0.3;
  EXPECT_EQ(OrientationLaw::as_typed(negative), negative);
  Scene planar_scene = s;
  planar_scene.families[0].orientation.a2 << 0.4999999999995, 0, 0, 0, 0.4999999999995, 0, 0, 0,
      1e-12;
  planar_scene.families[0].orientation.a2 =
      OrientationLaw::as_typed(planar_scene.families[0].orientation.a2);
  const PackingResult rp = generate(planar_scene);
  EXPECT_LT((orientation_tensor(rp.set, 0) - planar_scene.families[0].orientation.a2)
                .cwiseAbs()
                .maxCoeff(),
            1e-6);
}

// --- Seeds --------------------------------------------------------------------------------

TEST(Seeds, TheWholeUnsignedRangeIsReadExactly) {
  auto seed_of = [](const std::string& text) {
    return parse_scene(
               R"({"box": {"size": [1,1,1]}, "seed": )" + text +
               R"(, "families": [{"shape": "sphere", "radius": 0.05, "volume_fraction": 0.1}]})")
        .seed;
  };
  // 2^53 + 1 was read through a double as 2^53; 2^64 - 1 was refused.
  EXPECT_EQ(seed_of("9007199254740993"), 9007199254740993ULL);
  EXPECT_NE(seed_of("9007199254740993"), seed_of("9007199254740992"));
  EXPECT_EQ(seed_of("18446744073709551615"), 18446744073709551615ULL);
  EXPECT_EQ(seed_of("0"), 0ULL);
  EXPECT_EQ(seed_of("12.0"), 12ULL);
  // Written with a fraction or an exponent from 2^53 up, a seed is read through a double
  // (9007199254740993.0 read as ...992): refused, the seed to be given as digits.
  for (const char* bad :
       {"18446744073709551616", "-1", "1.5", "1e300", "\"7\"", "9007199254740993.0",
        "9.007199254740992e15", "5000000000000000.3", "4503599627370496.5"}) {
    const std::string e = scene_error(
        std::string(R"({"box": {"size": [1,1,1]}, "seed": )") + bad +
        R"(, "families": [{"shape": "sphere", "radius": 0.05, "volume_fraction": 0.1}]})");
    EXPECT_EQ(e.rfind("seed", 0), 0u) << bad << ": " << e;
  }
  // Written back exactly.
  Scene s = default_scene();
  s.seed = 18446744073709551615ULL;
  EXPECT_EQ(parse_scene(scene_to_json(s)).seed, s.seed);
}

}  // namespace
}  // namespace rvegen
