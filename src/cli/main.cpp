// rvegen: command-line generator and auditor of Representative Volume Elements.
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "io/hdf5_writer.hpp"
#include "rvegen/inclusion_set.hpp"
#include "rvegen/levelset.hpp"
#include "rvegen/mesh.hpp"
#include "rvegen/packing.hpp"
#include "rvegen/report.hpp"
#include "rvegen/scene.hpp"
#include "rvegen/voxelize.hpp"
#include "rvegen/writers.hpp"

namespace {

constexpr int kExitOk = 0;
constexpr int kExitOverlap = 1;
constexpr int kExitInvalid = 2;
constexpr int kExitNotReached = 3;

const char* kUsage =
    "usage:\n"
    "  rvegen generate [SCENE.json] [-o DIR] [--quiet]\n"
    "      Packs the scene (the built-in default scene when none is given) and writes, in DIR\n"
    "      (default ./rve): inclusions.json (the inclusion list), inclusions.vtp (surfaces),\n"
    "      voxels.vti (phase, inclusion_id, fraction), rve.h5 + rve.xdmf (voxels, inclusion\n"
    "      table, metadata), material.vtk (AMITEX_FFTP material map), report.json and, when\n"
    "      inclusions are wavy, deformed or coated, levelsets.vdb.\n"
    "      Exit 0 on success, 2 on invalid input (nothing written), 3 when the target volume\n"
    "      fraction cannot be reached (report.json says so).\n"
    "  rvegen check FILE.json [--json]\n"
    "      Audits an inclusion list with the exact pair tests. Exit 0 when no pair overlaps,\n"
    "      1 when some do, 2 on invalid input.\n"
    "  rvegen default-scene\n"
    "      Prints the built-in default scene.\n";

int usage_error(const std::string& msg) {
  std::cerr << "rvegen: " << msg << "\n" << kUsage;
  return kExitInvalid;
}

int cmd_generate(const std::vector<std::string>& args) {
  std::string scene_path, out_dir = "rve";
  bool quiet = false;
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "-o" || args[i] == "--output") {
      if (i + 1 >= args.size()) return usage_error("-o needs a directory");
      out_dir = args[++i];
    } else if (args[i] == "--quiet" || args[i] == "-q") {
      quiet = true;
    } else if (!args[i].empty() && args[i][0] == '-') {
      return usage_error("unknown option " + args[i]);
    } else if (scene_path.empty()) {
      scene_path = args[i];
    } else {
      return usage_error("more than one scene file given");
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  rvegen::Scene scene;
  try {
    scene = scene_path.empty() ? rvegen::default_scene()
                               : rvegen::parse_scene(rvegen::read_file(scene_path));
  } catch (const rvegen::InputError& e) {
    std::cerr << "rvegen: invalid scene" << (scene_path.empty() ? "" : " " + scene_path) << ": "
              << e.what() << "\n";
    return kExitInvalid;
  } catch (const std::exception& e) {
    std::cerr << "rvegen: " << e.what() << "\n";
    return kExitInvalid;
  }
  rvegen::ProgressFn progress;
  if (!quiet) progress = [](const std::string& line) { std::cerr << line << "\n"; };
  const rvegen::PackingResult result = rvegen::generate(scene, progress);
  rvegen::VoxelOptions vopt;
  vopt.partial_volume = scene.partial_volume;
  vopt.subsamples = scene.subsamples;
  const auto tv = std::chrono::steady_clock::now();
  const rvegen::VoxelImage image = rvegen::voxelize(result.set, scene.resolution, vopt);
  if (progress) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "voxels: %d x %d x %d in %.2f s", image.dims[0], image.dims[1],
                  image.dims[2],
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - tv).count());
    progress(buf);
  }
  rvegen::MeshOptions mopt;
  mopt.clip_to_box = scene.clip_surfaces;
  const rvegen::SurfaceMesh mesh = rvegen::tessellate(result.set, mopt);
  rvegen::LevelSetOptions lopt;
  lopt.voxel_size = scene.levelset_voxel_size;
  lopt.half_width = scene.levelset_half_width;
  const rvegen::LevelSets levelsets = rvegen::build_level_sets(result.set, lopt);
  if (progress && !levelsets.empty()) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "level sets: %zu grids, %.1f MB sparse (dense: %.1f MB)",
                  levelsets.grids.size(), levelsets.memory_bytes / 1e6,
                  levelsets.dense_bytes / 1e6);
    progress(buf);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::string report = rvegen::report_json(scene, result, &image, seconds, &levelsets);
  rvegen::OutputTransaction out(out_dir);
  const std::string inclusions = rvegen::write_inclusions_json(result.set);
  out.add("inclusions.json", inclusions);
  out.add("inclusions.vtp", rvegen::vtp_bytes(mesh, inclusions));
  out.add("voxels.vti", rvegen::vti_bytes(image));
  out.add("material.vtk", rvegen::material_vtk_bytes(image));
  try {
    out.add("rve.h5", rvegen::hdf5_bytes(image, result.set, rvegen::scene_to_json(scene), report));
  } catch (const std::exception& e) {
    std::cerr << "rvegen: " << e.what() << "\n";
    return 1;
  }
  out.add("rve.xdmf", rvegen::xdmf_text(image, "rve.h5"));
  if (!levelsets.empty()) {
    out.add("levelsets.vdb", rvegen::vdb_bytes(levelsets, result.set));
  }
  out.add("report.json", report);
  try {
    out.commit();
  } catch (const std::exception& e) {
    std::cerr << "rvegen: " << e.what() << "\n";
    return 1;
  }
  const auto vf =
      rvegen::family_volume_fractions(result.set, static_cast<int>(scene.families.size()));
  double total = 0.0;
  for (double v : vf) total += v;
  if (!quiet) {
    std::fprintf(stderr, "rvegen: %zu inclusions, volume fraction %.4f, %.2f s -> %s\n",
                 result.set.inclusions.size(), total, seconds, out_dir.c_str());
  }
  if (result.status != "ok") {
    std::cerr << "rvegen: target volume fraction not reached (status " << result.status
              << "); the best configuration found was written\n";
    return kExitNotReached;
  }
  return kExitOk;
}

int cmd_check(const std::vector<std::string>& args) {
  std::string path;
  bool as_json = false;
  for (const auto& a : args) {
    if (a == "--json") {
      as_json = true;
    } else if (!a.empty() && a[0] == '-') {
      return usage_error("unknown option " + a);
    } else if (path.empty()) {
      path = a;
    } else {
      return usage_error("more than one file given");
    }
  }
  if (path.empty()) return usage_error("check needs an inclusion file");
  rvegen::InclusionSet set;
  try {
    set = rvegen::read_inclusions_json(rvegen::read_file(path));
  } catch (const std::exception& e) {
    std::cerr << "rvegen: invalid inclusion file " << path << ": " << e.what() << "\n";
    return kExitInvalid;
  }
  const auto overlaps = rvegen::find_overlaps(set);
  const auto outside = rvegen::find_outside(set);
  const auto& inc = set.inclusions;
  if (as_json) {
    nlohmann::ordered_json j;
    j["n"] = inc.size();
    j["count"] = overlaps.size();
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    for (const auto& o : overlaps) {
      list.push_back({{"a", inc[o.a].id},
                      {"b", inc[o.b].id},
                      {"type", rvegen::contact_type_name(o.contact.type)},
                      {"depth", o.contact.depth},
                      {"shift", {o.shift[0], o.shift[1], o.shift[2]}}});
    }
    j["overlapping_pairs"] = list;
    nlohmann::ordered_json out = nlohmann::ordered_json::array();
    for (int i : outside) out.push_back(inc[i].id);
    j["outside_box"] = out;
    std::cout << j.dump(1) << "\n";
  } else {
    for (const auto& o : overlaps) {
      std::printf("overlap: %d %d type %s depth %.6g%s\n", inc[o.a].id, inc[o.b].id,
                  rvegen::contact_type_name(o.contact.type), o.contact.depth,
                  o.shift.isZero() ? "" : " (periodic image)");
    }
    for (int i : outside) std::printf("outside box: %d\n", inc[i].id);
    std::printf("%zu inclusions, %zu overlapping pairs, %zu outside the box\n", inc.size(),
                overlaps.size(), outside.size());
  }
  return overlaps.empty() && outside.empty() ? kExitOk : kExitOverlap;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "-h" || args[0] == "--help" || args[0] == "help") {
    std::cout << kUsage;
    return args.empty() ? kExitInvalid : kExitOk;
  }
  const std::string cmd = args[0];
  args.erase(args.begin());
  if (cmd == "generate") return cmd_generate(args);
  if (cmd == "check") return cmd_check(args);
  if (cmd == "default-scene") {
    std::cout << rvegen::scene_to_json(rvegen::default_scene());
    return kExitOk;
  }
  return usage_error("unknown command \"" + cmd + "\"");
}
