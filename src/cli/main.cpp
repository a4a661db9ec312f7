// rvegen: command-line generator and auditor of Representative Volume Elements.
#include <tbb/global_control.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "effective.hpp"
#include "process.hpp"
#include "ranks.hpp"
#include "rvegen/femesh/lsan_suppressions.hpp"  // in sanitizer builds
#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/io/amitex.hpp"
#include "rvegen/io/fe_mesh.hpp"
#include "rvegen/io/hdf5_writer.hpp"
#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/report.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/io/writers.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/resources.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/glyphs.hpp"
#include "rvegen/raster/levelset.hpp"
#include "rvegen/raster/mesh.hpp"
#include "rvegen/raster/voxelize.hpp"
#include "study.hpp"

namespace {

constexpr int kExitOk = 0;
constexpr int kExitOverlap = 1;  // check: overlaps found
constexpr int kExitOutput = 1;   // generate: the outputs could not be written
constexpr int kExitInvalid = 2;
constexpr int kExitNotReached = 3;
constexpr int kExitAudit = 4;
constexpr int kExitNotConverged = 5;  // generate, homogenize: a solve stopped above its tolerance

// Before unconverged()'s sentence: what a tensor that did not converge is not.
constexpr const char* kNotConverged =
    "rvegen: homogenization did not converge, so its tensors are not the RVE's effective "
    "properties (report.json: \"converged\": false): ";

using rvegen::cli::kMaxSceneBytes;
using rvegen::cli::parse_size;
using rvegen::cli::peak_memory_mb;
constexpr size_t kMaxInclusionFileBytes = size_t(2) << 30;

#ifndef RVEGEN_VERSION
#define RVEGEN_VERSION "unknown"
#endif

const char* kGenerateUsage =
    "usage: rvegen generate [SCENE.json] [-o DIR] [--outputs LIST] [--quiet]\n"
    "                       [--max-memory SIZE] [--threads N]\n"
    "  Packs the scene (the built-in default scene when none is given; see rvegen\n"
    "  default-scene) and writes, in DIR (default ./rve), report.json and the outputs:\n"
    "    inclusions  inclusions.json (the inclusion list) and inclusions.vtp (points for\n"
    "                glyphs in ParaView)\n"
    "    voxels      voxels.vti (phase, inclusion_id, fraction; zlib-compressed)\n"
    "    levelsets   levelsets.vdb, when inclusions are wavy, bent or deformed (named in\n"
    "                --outputs: the shells of straight coated inclusions too)\n"
    "    h5          rve.h5 + rve.xdmf (voxels, inclusion table, scene, report)\n"
    "    amitex      material.vtk, zoneID.vtk and the amitex_*.xml and amitex_run.sh files that\n"
    "                run AMITEX_FFTP on them (materials from the scene; with conductivities,\n"
    "                also its stationary diffusion)\n"
    "    mesh        surfaces.vtp of every inclusion (otherwise of the modified ones only)\n"
    "    mesh_voxel  mesh_voxel.inp, .msh, .vtu (a hexahedron per voxel; periodic node sets\n"
    "                and equations or Gmsh's $Periodic) and, with\n"
    "                materials, run_voxel_conductivity.inp and run_voxel_elasticity.inp\n"
    "                (CalculiX and Abaqus decks with periodic equations)\n"
    "    mesh_tet    mesh_tet.inp, .msh, .vtu: a conforming tetrahedral mesh (Gmsh),\n"
    "                periodic: opposite box faces carry the same triangles; node sets of the\n"
    "                faces, edges and corners; with materials, run_tet_conductivity.inp and\n"
    "                run_tet_elasticity.inp (plain spheres, cylinders, ellipsoids; sizes:\n"
    "                the scene's \"mesh_tet\" object; the cell may be the box moved along\n"
    "                its axes, off inclusions it would graze: report.json's cell_origin;\n"
    "                those it still grazes move off its faces where there is room, before\n"
    "                anything is written: mesh_tet.nudge, report.json's nudged_inclusions)\n"
    "    statistics  g(r) of sphere families and nearest-neighbour distances in report.json\n"
    "  By default inclusions, voxels, levelsets and statistics; the scene's \"outputs\" list or\n"
    "  --outputs LIST (names separated by commas) chooses others. DIR is replaced as a whole:\n"
    "  it holds the complete new set or, on any failure, the previous one; a DIR holding files\n"
    "  rvegen did not write is refused. The last line gives the count, the volume fraction,\n"
    "  the time and the bytes written.\n"
    "  --max-memory SIZE (bytes, or with K, M, G) refuses a scene whose estimated peak memory\n"
    "  exceeds SIZE (default: the memory available on the machine).\n"
    "  --threads N runs the packing, voxels and FFT on at most N cores (default: all); the same\n"
    "  scene gives the same RVE with any number.\n"
    "  Exit 0 on success; 1 when the outputs cannot be written (checked before packing); 2 on\n"
    "  invalid input or a scene too large for the memory (nothing written); 3 when the target\n"
    "  volume fraction cannot be reached (report.json says so; the best valid configuration is\n"
    "  written); 4 when the packed RVE fails the exact audit (an internal error: nothing\n"
    "  written); 5 when a homogenization solve stopped above its tolerance (everything is\n"
    "  written, report.json has \"converged\": false, and a message names the load cases).\n";
const char* kCheckUsage =
    "usage: rvegen check FILE.json [--json] [--max-pairs N]\n"
    "  Audits an inclusion list (inclusions.json) with the exact pair tests. Exit 0 when no\n"
    "  pair overlaps, 1 when some do (listing at most N pairs, default 10000), 2 on invalid\n"
    "  input.\n";
const char* kHomogenizeUsage =
    "usage: rvegen homogenize DIR SCENE.json [--threads N] [--max-memory SIZE] [--quiet]\n"
    "  Computes the effective properties of an RVE written earlier (DIR/inclusions.json) with\n"
    "  the scene's \"materials\", \"homogenization\" and voxel resolution, and prints them as\n"
    "  JSON (the \"effective\" object of report.json). The scene's families must be the RVE's\n"
    "  (same names, same order). Under an MPI launcher (mpirun -np N rvegen homogenize ...)\n"
    "  the ranks share the voxel grid in z slabs (FFTW's MPI transforms): each voxelizes and\n"
    "  solves its own slab, the image is never gathered, and rank 0 prints the result.\n"
    "  --threads N solves on at most N cores a process (default: all, shared among the\n"
    "  processes a launcher put on the machine; the result does not depend on it); --quiet\n"
    "  prints no progress. --max-memory SIZE (bytes, or with K, M, G) refuses a solve whose\n"
    "  estimated memory on this machine exceeds SIZE (default: the memory available), before\n"
    "  any work.\n"
    "  Exit 0 on success, 2 on invalid input, 5 when a solve stopped above its tolerance (the\n"
    "  result is printed with \"converged\": false).\n";
const char* kDefaultSceneUsage =
    "usage: rvegen default-scene\n"
    "  Prints the built-in default scene (a scene file to start from).\n";

std::string usage() {
  return std::string("rvegen " RVEGEN_VERSION
                     ": random Representative Volume Elements of composite materials.\n\n") +
         kGenerateUsage + "\n" + kCheckUsage + "\n" + kHomogenizeUsage + "\n" +
         rvegen::cli::study_usage() + "\n" + kDefaultSceneUsage +
         "\nrvegen --version prints the version; rvegen COMMAND --help the help of one command.\n";
}

bool wants_help(const std::vector<std::string>& args) {
  for (const std::string& a : args) {
    if (a == "-h" || a == "--help") return true;
  }
  return false;
}

// An argument error: one line, then where the usage is (not the whole help around it).
// `command`: "generate", "check", ...; empty for the top level.
int usage_error(const std::string& msg, const std::string& command = "") {
  std::cerr << "rvegen: " << msg << "\n"
            << "(rvegen " << (command.empty() ? "" : command + " ") << "--help shows the usage)\n";
  return kExitInvalid;
}

// An unknown option of `command`, with the nearest known one when it is close.
int unknown_option(const std::string& option, const std::string& command,
                   std::initializer_list<const char*> known) {
  return usage_error(
      "unknown option " + option + " of " + command + rvegen::cli::did_you_mean(option, known),
      command);
}

// "812 KB", "71.1 MB", "1.54 GB" (decimal units, three significant figures or so).
std::string human_bytes(uintmax_t bytes) {
  char buf[32];
  const double b = static_cast<double>(bytes);
  if (b < 1e3) {
    std::snprintf(buf, sizeof buf, "%.0f B", b);
  } else if (b < 1e6) {
    std::snprintf(buf, sizeof buf, "%.0f KB", b / 1e3);
  } else if (b < 1e9) {
    std::snprintf(buf, sizeof buf, "%.1f MB", b / 1e6);
  } else {
    std::snprintf(buf, sizeof buf, "%.2f GB", b / 1e9);
  }
  return buf;
}

// Bytes of the regular files in `dir` (what a run wrote).
uintmax_t directory_bytes(const std::string& dir, int* files) {
  uintmax_t total = 0;
  *files = 0;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    if (e.is_regular_file(ec)) {
      total += e.file_size(ec);
      ++*files;
    }
  }
  return total;
}

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// Test hook (fault injection), never for users: RVEGEN_TEST_FAULT=overlap moves the second
// inclusion onto the first after packing, to prove that the audit stops such an RVE.
std::function<void(rvegen::InclusionSet&)> fault_hook() {
  const char* fault = std::getenv("RVEGEN_TEST_FAULT");
  if (!fault || std::string(fault) != "overlap") return nullptr;
  return [](rvegen::InclusionSet& set) {
    if (set.inclusions.size() >= 2) {
      set.inclusions[1].shape.center = set.inclusions[0].shape.center;
    }
  };
}

// A mesh's three files (STEM.inp, .msh, .vtu), formatted side by side: each writer is serial,
// and they only read the mesh.
using Fill = std::function<void(std::FILE*)>;
void write_mesh_files(rvegen::OutputSet& out, const std::string& stem, const Fill& inp,
                      const Fill& msh, const Fill& vtu) {
  tbb::parallel_invoke([&] { out.write_with(stem + ".inp", inp); },
                       [&] { out.write_with(stem + ".msh", msh); },
                       [&] { out.write_with(stem + ".vtu", vtu); });
}

// report.json's "mesh_tet": counts, the volume of each phase against the exact one, the least
// element volume and the distribution of the elements' least dihedral angles.
nlohmann::ordered_json tet_mesh_report(const rvegen::InclusionSet& set,
                                       const rvegen::TetMesh& mesh) {
  const rvegen::TetQuality q = rvegen::tet_quality(mesh);
  std::vector<double> exact = rvegen::phase_volume_fractions(set, mesh.phases);
  for (double& v : exact) v *= set.box.volume();
  nlohmann::ordered_json r;
  r["files"] = {"mesh_tet.inp", "mesh_tet.msh", "mesh_tet.vtu"};
  r["mesher"] = "Gmsh (OpenCASCADE, " + mesh.volume_mesher + ")";
  r["tetrahedra"] = mesh.tets.size();
  // 1: 4-node tetrahedra (C3D4); 2: 10-node (C3D10), straight edges (mesh_tet.order).
  r["order"] = mesh.mid.empty() ? 1 : 2;
  r["nodes"] = mesh.nodes.size();
  r["periodic_pairs"] = mesh.periodic.size();
  r["merged_nodes"] = mesh.merged_nodes;
  r["snapped_nodes"] = mesh.snapped_nodes;
  // Interface nodes moved along the normal to keep the phases' volumes (mesh_tet.keep_volumes).
  r["moved_nodes"] = mesh.moved_nodes;
  // Nodes inside one region moved to lift elements under 5 degrees.
  r["relocated_nodes"] = mesh.relocated_nodes;
  // Nodes added inside one region where elements under 5 degrees were left.
  r["inserted_nodes"] = mesh.inserted_nodes;
  r["remade_slivers"] = mesh.remade_slivers;
  r["sliver_rounds"] = mesh.sliver_rounds;
  r["flat_elements_removed"] = mesh.flat_elements_removed;
  r["raised_triangles"] = mesh.raised_triangles;
  r["flipped_chords"] = mesh.flipped_chords;
  r["retries"] = mesh.retries;
  // The cell meshed: the box, or the box moved along its axes (mesh_tet.shift_cell).
  r["cell_origin"] = {mesh.box.origin[0], mesh.box.origin[1], mesh.box.origin[2]};
  // (1 and more alike: far from grazing anything; no inclusion near an edge gives 1.)
  r["face_clearance"] = std::min(1.0, rvegen::face_clearance(set, mesh.box.origin));
  r["edge_clearance"] = std::min(1.0, rvegen::edge_clearance(set, mesh.box.origin));
  r["min_element_volume"] = q.min_volume;
  nlohmann::ordered_json phases = nlohmann::ordered_json::array();
  for (const rvegen::Phase& p : mesh.phases) {
    const double v = q.phase_volume[p.label];
    phases.push_back({{"label", p.label},
                      {"name", p.name},
                      {"volume", v},
                      {"exact_volume", exact[p.label]},
                      {"relative_error", exact[p.label] > 0.0 ? v / exact[p.label] - 1.0 : 0.0}});
  }
  r["phases"] = phases;
  nlohmann::ordered_json d;
  d["min"] = q.min_dihedral;
  d["quantile_1_percent"] = q.quantiles[0];
  d["quantile_5_percent"] = q.quantiles[1];
  d["median"] = q.quantiles[2];
  d["below_5_degrees"] = q.below_5_degrees;
  d["bins_from"] = rvegen::TetQuality::kBins;
  d["counts"] = q.dihedral_counts;
  r["min_dihedral_degrees"] = d;
  return r;
}

const char* kThreadsNeed = "--threads needs a whole number in [1, 4096]";
// The count after --threads at args[*i] into *threads, *i moved past it; false when none is
// there or it is not a whole number in [1, 4096].
bool read_threads(const std::vector<std::string>& args, size_t* i, int* threads) {
  if (*i + 1 >= args.size()) return false;
  char* end = nullptr;
  const long t = std::strtol(args[*i + 1].c_str(), &end, 10);
  if (args[*i + 1].empty() || *end != '\0' || t < 1 || t > 4096) return false;
  *threads = static_cast<int>(t);
  ++*i;
  return true;
}

int cmd_generate(const std::vector<std::string>& args) {
  if (wants_help(args)) {
    std::cout << kGenerateUsage;
    return kExitOk;
  }
  std::string scene_path, out_dir = "rve", outputs_list;
  bool quiet = false, outputs_given = false;
  double max_memory = 0.0;
  int threads = 0;  // all cores
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "-o" || args[i] == "--output") {
      if (i + 1 >= args.size()) return usage_error("-o needs a directory", "generate");
      out_dir = args[++i];
    } else if (args[i] == "--outputs") {
      if (i + 1 >= args.size()) {
        return usage_error("--outputs needs a list such as inclusions,voxels,h5", "generate");
      }
      outputs_list = args[++i];
      outputs_given = true;
    } else if (args[i] == "--quiet" || args[i] == "-q") {
      quiet = true;
    } else if (args[i] == "--threads") {
      if (!read_threads(args, &i, &threads)) return usage_error(kThreadsNeed, "generate");
    } else if (args[i] == "--max-memory") {
      if (i + 1 >= args.size()) return usage_error("--max-memory needs a size", "generate");
      max_memory = parse_size(args[++i]);
      if (max_memory <= 0.0) {
        return usage_error("--max-memory: not a size: " + args[i], "generate");
      }
    } else if (!args[i].empty() && args[i][0] == '-') {
      return unknown_option(
          args[i], "generate",
          {"-o", "--output", "--outputs", "--quiet", "--threads", "--max-memory", "--help"});
    } else if (scene_path.empty()) {
      scene_path = args[i];
    } else {
      return usage_error("more than one scene file given", "generate");
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  rvegen::Scene scene;
  try {
    scene = scene_path.empty() ? rvegen::default_scene()
                               : rvegen::parse_scene(rvegen::read_file(scene_path, kMaxSceneBytes));
    if (outputs_given) {
      std::vector<std::string> names;
      size_t at = 0;
      while (at <= outputs_list.size()) {
        const size_t comma = std::min(outputs_list.find(',', at), outputs_list.size());
        names.push_back(outputs_list.substr(at, comma - at));
        at = comma + 1;
      }
      scene.outputs = rvegen::outputs_from_names(names, scene.outputs.mesh, "--outputs");
    }
    if (scene.homogenization.fields && !(scene.homogenization.any() && scene.outputs.h5)) {
      throw rvegen::InputError(
          "homogenization.fields: the local fields go into rve.h5: ask for a physics and add "
          "\"h5\" to the outputs");
    }
  } catch (const std::exception& e) {
    std::cerr << "rvegen: invalid scene" << (scene_path.empty() ? "" : " " + scene_path) << ": "
              << e.what() << "\n";
    return kExitInvalid;
  }
  // Memory: the estimated peak against the limit, before any large allocation. The tetrahedral
  // mesh's share is only a guess before packing (its thin gaps are not known yet): when the
  // scene fits without it, the inclusions are packed and the mesher's own size field decides
  // below, and offers settings that fit this RVE, so that one run reaches them.
  const rvegen::ResourceEstimate need = rvegen::estimate_resources(scene);
  const double limit = max_memory > 0.0 ? max_memory : rvegen::available_memory_bytes();
  const std::string above_limit =
      std::string(", above the ") +
      (max_memory > 0.0 ? "--max-memory limit of " : "memory available, ") +
      rvegen::format_bytes(limit);
  const bool over = limit > 0.0 && need.total_bytes() > limit;
  bool mesh_guess_over = false;
  if (over && scene.outputs.mesh_tet) {
    rvegen::Scene without = scene;
    without.outputs.mesh_tet = false;
    mesh_guess_over = rvegen::estimate_resources(without).total_bytes() <= limit;
  }
  if (over && !mesh_guess_over) {
    std::cerr << "rvegen: the scene needs about " << rvegen::describe(need) << above_limit << "\n";
    return kExitInvalid;
  }
  // --threads: every parallel phase (packing, voxels, FFT) on at most that many cores; the same
  // scene gives the same RVE with any number.
  std::unique_ptr<tbb::global_control> thread_limit;
  if (threads > 0) {
    thread_limit = std::make_unique<tbb::global_control>(
        tbb::global_control::max_allowed_parallelism, static_cast<size_t>(threads));
  }
  rvegen::ProgressFn progress;
  if (!quiet) progress = [](const std::string& line) { std::cerr << line << "\n"; };
  rvegen::RunTimings timings;
  try {
    // The output place is checked (and a private staging directory made) before the work.
    rvegen::OutputSet out(out_dir);
    if (mesh_guess_over && progress) {
      progress("tetrahedral mesh: about " +
               std::to_string(static_cast<long long>(need.tetrahedra)) +
               " elements guessed from the scene, " + rvegen::format_bytes(need.total_bytes()) +
               " at peak" + above_limit + ": packing, then the packed inclusions' gaps decide");
    }
    rvegen::PackingResult result = rvegen::generate(scene, progress, fault_hook());
    timings.phases.emplace_back("packing", result.seconds);
    timings.phases.emplace_back("audit", result.audit_seconds);
    // Inclusions that the mesh's cell cannot keep off are moved off its faces where there is
    // room, before anything is written; the moved set is audited like the packed one (and, should
    // that fail, the packed set is kept).
    rvegen::Nudged nudged;
    if (scene.outputs.mesh_tet) rvegen::check_tet_meshable(result.set);
    if (scene.outputs.mesh_tet && scene.tet_mesh.shift_cell && scene.tet_mesh.nudge) {
      rvegen::InclusionSet moved = result.set;
      nudged = rvegen::nudge_off_chosen_cell(&moved, scene.min_gap);
      if (nudged.moved > 0) {
        if (rvegen::audit(moved, 16).clean()) {
          result.set = std::move(moved);
        } else {
          nudged.stuck += nudged.moved;
          nudged.moved = 0;
        }
      }
      if (progress && (nudged.moved > 0 || nudged.stuck > 0)) {
        progress("tetrahedral mesh: " + std::to_string(nudged.moved) +
                 " inclusions moved off the cell's faces, " + std::to_string(nudged.stuck) +
                 " with no room to");
      }
    }
    // The tetrahedral mesh of the packed set, from the mesher's own size field (the gaps between
    // the inclusions are known now), against the same limit, before anything is written.
    rvegen::TetMeshNeed mesh_need;
    if (scene.outputs.mesh_tet) {
      mesh_need = rvegen::tet_mesh_need(result.set, scene.tet_mesh, limit);
      rvegen::ResourceEstimate packed = need;
      packed.tetrahedra = mesh_need.elements;
      packed.tet_mesh_bytes = mesh_need.bytes;
      const std::string about = (mesh_need.capped ? "more than " : "about ") +
                                std::to_string(static_cast<long long>(mesh_need.elements)) +
                                " elements, " + rvegen::format_bytes(packed.total_bytes());
      if (limit > 0.0 && packed.total_bytes() > limit) {
        // The first coarser mesh of this RVE that would fit, if any.
        rvegen::TetMeshSpec fit;
        rvegen::TetMeshNeed fit_need;
        std::string instead;
        if (rvegen::coarser_tet_mesh_that_fits(
                result.set, scene.tet_mesh, limit,
                [&](const rvegen::TetMeshNeed& n) {
                  rvegen::ResourceEstimate e = packed;
                  e.tet_mesh_bytes = n.bytes;
                  return e.total_bytes() <= limit;
                },
                &fit, &fit_need)) {
          packed.tet_mesh_bytes = fit_need.bytes;
          instead = "; with " + rvegen::describe_tet_mesh_change(scene.tet_mesh, fit) +
                    " this RVE's mesh would need about " +
                    std::to_string(static_cast<long long>(fit_need.elements)) + " elements, " +
                    rvegen::format_bytes(packed.total_bytes());
        }
        throw rvegen::InputError(
            "mesh_tet: the tetrahedral mesh of this RVE needs " + about + " at peak" + above_limit +
            instead +
            " (raise mesh_tet.chord_error or max_size, lower gap_elements, or give a larger "
            "min_gap: thin gaps take the smallest elements)");
      }
      if (progress) progress("tetrahedral mesh: " + about + " expected");
    }
    auto timed = [&](const std::string& what, const std::function<void()>& f) {
      const auto t = std::chrono::steady_clock::now();
      f();
      const double sec = seconds_since(t);
      timings.phases.emplace_back(what, sec);
      if (progress) {
        char buf[160];
        std::snprintf(buf, sizeof buf, "%s: %.2f s", what.c_str(), sec);
        progress(buf);
      }
    };
    const rvegen::Outputs& want = scene.outputs;
    std::string inclusions;
    if (want.inclusions) {
      timed("write inclusions.json", [&] {
        inclusions = rvegen::write_inclusions_json(result.set);
        out.write("inclusions.json", inclusions);
      });
      timed("write inclusions.vtp", [&] {
        out.write_with("inclusions.vtp",
                       [&](std::FILE* f) { rvegen::write_points_vtp(result.set, inclusions, f); });
      });
    }
    // Surfaces: of every inclusion when the mesh is asked for; otherwise of the wavy, deformed,
    // coated and debonded ones only (their shape is not a glyph), when there are any.
    rvegen::InclusionSet meshed = rvegen::meshed_inclusions(result.set, want.mesh, true);
    if (!meshed.inclusions.empty()) {
      timed("surfaces", [&] {
        const rvegen::SurfaceMesh mesh =
            rvegen::tessellate(meshed, rvegen::mesh_options(scene, scene.box));
        out.write_with("surfaces.vtp",
                       [&](std::FILE* f) { rvegen::write_surfaces_vtp(mesh, inclusions, f); });
      });
    }
    meshed = rvegen::InclusionSet{};
    inclusions.clear();
    inclusions.shrink_to_fit();
    rvegen::LevelSets levelsets;
    if (progress && need.band_voxels > 0.0) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "level sets: about %.3g narrow-band voxels to compute",
                    need.band_voxels);
      progress(buf);
    }
    if (want.levelsets)
      timed("level sets", [&] {
        rvegen::LevelSetOptions lopt;
        lopt.voxel_size = scene.levelset_voxel_size;
        lopt.half_width = scene.levelset_half_width;
        lopt.exact_shapes = want.levelsets_asked;
        levelsets = rvegen::build_level_sets(result.set, lopt);
        if (!levelsets.empty())
          out.write("levelsets.vdb", rvegen::vdb_bytes(levelsets, result.set));
        levelsets.data.reset();  // the report keeps the grid summaries only
      });
    rvegen::VoxelImage image;
    if (want.image() || scene.homogenization.any()) {
      timed("voxels", [&] {
        rvegen::VoxelOptions vopt;
        vopt.partial_volume = scene.partial_volume;
        vopt.subsamples = scene.subsamples;
        image = rvegen::voxelize(result.set, scene.resolution, vopt);
      });
    }
    if (want.voxels) {
      timed("write voxels.vti", [&] {
        out.write_with("voxels.vti", [&](std::FILE* f) { rvegen::write_vti(image, f); });
      });
    }
    if (want.amitex) {
      timed("write material.vtk", [&] {
        out.write_with("material.vtk", [&](std::FILE* f) { rvegen::write_material_vtk(image, f); });
        out.write_with("zoneID.vtk", [&](std::FILE* f) { rvegen::write_zone_vtk(image, f); });
        out.write("amitex_materials.xml", rvegen::amitex_materials_xml(scene, result.set, image));
        out.write("amitex_loading.xml", rvegen::amitex_loading_xml());
        out.write("amitex_algorithm.xml", rvegen::amitex_algorithm_xml());
        if (rvegen::amitex_conductivity_wanted(scene)) {
          out.write("amitex_conductivity_materials.xml",
                    rvegen::amitex_conductivity_materials_xml(scene, image));
          out.write("amitex_conductivity_loading.xml", rvegen::amitex_conductivity_loading_xml());
          out.write("amitex_conductivity_algorithm.xml",
                    rvegen::amitex_conductivity_algorithm_xml());
        }
        out.write("amitex_run.sh", rvegen::amitex_run_sh(scene));
      });
    }
    if (want.mesh_voxel) {
      timed("write mesh_voxel.inp, .msh, .vtu", [&] {
        write_mesh_files(
            out, "mesh_voxel", [&](std::FILE* f) { rvegen::write_abaqus_voxel_mesh(image, f); },
            [&](std::FILE* f) { rvegen::write_gmsh_voxel_mesh(image, f); },
            [&](std::FILE* f) { rvegen::write_voxel_mesh_vtu(image, f); });
        for (const bool elastic : {false, true}) {
          const std::string deck = rvegen::abaqus_voxel_deck(scene, result.set, image, elastic);
          if (!deck.empty()) {
            out.write(elastic ? "run_voxel_elasticity.inp" : "run_voxel_conductivity.inp", deck);
          }
        }
      });
    }
    nlohmann::ordered_json tet_report;
    if (want.mesh_tet) {
      rvegen::TetMesh tets;
      timed("tetrahedral mesh", [&] {
        rvegen::TetMeshOptions topt;
        static_cast<rvegen::TetMeshSpec&>(topt) = scene.tet_mesh;
        topt.threads = threads;
        tets = rvegen::tet_mesh(result.set, topt, [&](double, const std::string& line) {
          if (!line.empty() && progress) progress(line);
          return true;
        });
      });
      timed("write mesh_tet.inp, .msh, .vtu", [&] {
        write_mesh_files(
            out, "mesh_tet", [&](std::FILE* f) { rvegen::write_abaqus_tet_mesh(tets, f); },
            [&](std::FILE* f) { rvegen::write_gmsh_tet_mesh(tets, f); },
            [&](std::FILE* f) { rvegen::write_tet_mesh_vtu(tets, f); });
      });
      tet_report = tet_mesh_report(result.set, tets);
      // Inclusions moved off the cell's faces before anything was written (mesh_tet.nudge), and
      // those that graze it with no room to move.
      tet_report["nudged_inclusions"] = nudged.moved;
      tet_report["nudge_stuck"] = nudged.stuck;
      // The estimate the memory check used, beside the count it estimated.
      tet_report["estimated_tetrahedra"] = std::llround(mesh_need.elements);
      const auto& angles = tet_report["min_dihedral_degrees"];
      if (angles["below_5_degrees"].get<long long>() > 0) {
        // Written all the same (the mesh conforms and fills the box); the analyst decides.
        std::cerr << "rvegen: mesh_tet: " << angles["below_5_degrees"].get<long long>()
                  << " elements have a dihedral angle under 5 degrees (least "
                  << angles["min"].get<double>()
                  << "); report.json's mesh_tet gives their distribution. Thin gaps and "
                     "inclusions that barely cross a box face (a thin cap, whose edge angle "
                     "bounds its elements') make them: another min_gap or mesh_tet.min_size "
                     "may help.\n";
      }
      for (const bool elastic : {false, true}) {
        const std::string deck = rvegen::abaqus_tet_deck(scene, result.set, tets, elastic);
        const char* name = elastic ? "run_tet_elasticity.inp" : "run_tet_conductivity.inp";
        if (!deck.empty()) {
          out.write(name, deck);
          tet_report["files"].push_back(name);
        }
      }
    }
    nlohmann::ordered_json effective;
    rvegen::EffectiveProperties solved;
    std::string not_converged;  // what the solves left above their tolerance
    std::vector<rvegen::LocalField> fields;
    if (scene.homogenization.any()) {
      timed("homogenization", [&] {
        effective = rvegen::cli::effective_properties(scene, result.set, image, progress, &solved);
      });
      not_converged = rvegen::unconverged(solved, scene.homogenization.tolerance);
      // The local fields for rve.h5 (scene.homogenization.fields), per load case.
      auto add = [&](const char* physics, const char* what, const char* names, int count,
                     const std::vector<std::vector<float>>& per_load) {
        for (size_t l = 0; l < per_load.size(); ++l) {
          fields.push_back({std::string(physics) + "/load_" + std::to_string(l) + "/" + what, names,
                            count, &per_load[l]});
        }
      };
      add("conductivity", "gradient", "1 2 3", 3, solved.gradient);
      add("conductivity", "flux", "1 2 3", 3, solved.flux);
      add("elasticity", "strain", "11 22 33 23 13 12", 6, solved.strain);
      add("elasticity", "stress", "11 22 33 23 13 12", 6, solved.stress);
    }
    rvegen::ReportStatistics stats;
    if (want.statistics) {
      timed("statistics", [&] { stats = rvegen::report_statistics(scene, result); });
    }
    auto report_now = [&] {
      timings.total_seconds = seconds_since(t0);
      timings.peak_memory_mb = peak_memory_mb();
      std::string text =
          rvegen::report_json(scene, result, want.image() ? &image : nullptr, timings, &levelsets,
                              want.statistics ? &stats : nullptr);
      if (effective.is_null() && tet_report.is_null()) return text;
      nlohmann::ordered_json report = nlohmann::ordered_json::parse(text);
      if (!tet_report.is_null()) report["mesh_tet"] = tet_report;
      if (!effective.is_null()) report["effective"] = effective;
      return report.dump(2) + "\n";
    };
    // rve.h5 carries the report as it stood before rve.h5 itself was written.
    if (want.h5) {
      timed("write rve.h5", [&] {
        out.write("rve.xdmf", rvegen::xdmf_text(image, "rve.h5", fields));
        rvegen::write_hdf5(out.staged_path("rve.h5"), image, result.set,
                           rvegen::scene_to_json(scene), report_now(), fields);
      });
    }
    out.write("report.json", report_now());
    out.commit();
    if (!out.leftover().empty()) {
      std::cerr << "rvegen: the previous set in " << out_dir << " could not be removed (not ours "
                << "to delete); it stays at " << out.leftover() << "\n";
    }
    const auto vf =
        rvegen::family_volume_fractions(result.set, static_cast<int>(scene.families.size()));
    double total = 0.0;
    for (double v : vf) total += v;
    if (!quiet) {
      int files = 0;
      const uintmax_t bytes = directory_bytes(out_dir, &files);
      std::fprintf(stderr,
                   "rvegen: %zu inclusions, volume fraction %.4f, %.2f s -> %s (%s in %d files)\n",
                   result.set.inclusions.size(), total, seconds_since(t0), out_dir.c_str(),
                   human_bytes(bytes).c_str(), files);
    }
    if (result.status != rvegen::PackingStatus::kOk) {
      std::cerr << "rvegen: target volume fraction not reached (status "
                << rvegen::status_name(result.status) << ", "
                << rvegen::stop_reason_name(result.stop_reason)
                << "); the best valid configuration found was written\n";
      return kExitNotReached;
    }
    if (!not_converged.empty()) {
      std::cerr << kNotConverged << not_converged << "\n";
      return kExitNotConverged;
    }
    return kExitOk;
  } catch (const rvegen::AuditFailure& e) {
    std::cerr << "rvegen: " << e.what() << "; nothing was written\n";
    return kExitAudit;
  } catch (const rvegen::NothingPlaced& e) {
    std::cerr << "rvegen: " << e.what() << "; nothing was written, " << out_dir
              << " is unchanged\n";
    return kExitNotReached;
  } catch (const rvegen::InputError& e) {
    // Found during the work (an unlucky draw past the inclusion limit, say).
    std::cerr << "rvegen: invalid scene: " << e.what() << "; nothing was written\n";
    return kExitInvalid;
  } catch (const rvegen::OutputError& e) {
    std::cerr << "rvegen: " << e.what() << "; " << out_dir << " is unchanged\n";
    return kExitOutput;
  } catch (const std::bad_alloc&) {
    std::cerr << "rvegen: out of memory (the estimate was " << rvegen::describe(need)
              << "); nothing was written\n";
    return kExitInvalid;
  } catch (const std::exception& e) {
    std::cerr << "rvegen: " << e.what() << "; nothing was written\n";
    return kExitOutput;
  }
}

int cmd_homogenize(const std::vector<std::string>& args) {
  if (wants_help(args)) {
    std::cout << kHomogenizeUsage;
    return kExitOk;
  }
  std::vector<std::string> files;
  bool quiet = false;
  int threads = 0;  // the process's share of the cores
  double max_memory = 0.0;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--quiet" || a == "-q") {
      quiet = true;
    } else if (a == "--max-memory") {
      if (i + 1 >= args.size()) return usage_error("--max-memory needs a size", "homogenize");
      max_memory = parse_size(args[++i]);
      if (max_memory <= 0.0) {
        return usage_error("--max-memory: not a size: " + args[i], "homogenize");
      }
    } else if (a == "--threads") {
      if (!read_threads(args, &i, &threads)) return usage_error(kThreadsNeed, "homogenize");
    } else if (!a.empty() && a[0] == '-') {
      return unknown_option(a, "homogenize", {"--quiet", "--threads", "--max-memory", "--help"});
    } else {
      files.push_back(a);
    }
  }
  if (files.size() != 2)
    return usage_error("homogenize needs an RVE directory and a scene file", "homogenize");
  const rvegen::cli::Ranks ranks;  // z slabs of the grid under an MPI launcher
  std::ostream& say = rvegen::cli::say_once(ranks);
  rvegen::Scene scene;
  rvegen::InclusionSet set;
  try {
    scene = rvegen::parse_scene(rvegen::read_file(files[1], kMaxSceneBytes));
    if (!scene.homogenization.any()) {
      throw rvegen::InputError("homogenization.physics: give conductivity, elasticity or both");
    }
    const std::string path = files[0] + "/inclusions.json";
    set = rvegen::read_inclusions_json(rvegen::read_file(path, kMaxInclusionFileBytes));
    std::vector<std::string> names;
    for (const rvegen::Family& f : scene.families) names.push_back(f.name);
    if (set.family_names != names) {
      std::string have, want;
      for (const auto& n : set.family_names) have += (have.empty() ? "" : ", ") + n;
      for (const auto& n : names) want += (want.empty() ? "" : ", ") + n;
      throw rvegen::InputError("families: the scene's (" + want + ") are not the RVE's (" + have +
                               ")");
    }
    // What is handed in is audited like what is packed: the scene's families and box, no
    // overlap, nothing outside a closed box.
    rvegen::check_rve_for_scene(set, scene, path);
  } catch (const std::exception& e) {
    say << "rvegen: invalid input: " << e.what() << "\n";
    return kExitInvalid;
  }
  {
    // Memory before any large allocation, as generate checks it: the image and the solver's
    // fields, of which this machine's ranks hold their slabs.
    rvegen::Scene sized = scene;
    sized.outputs =
        rvegen::Outputs{false, true, false, false, false, false, false, false, false, false};
    const rvegen::ResourceEstimate need = rvegen::estimate_resources(sized);
    const double here = (need.voxel_bytes + need.homogenization_bytes) * ranks.local_size() /
                        std::max(1, ranks.size());
    const double limit = max_memory > 0.0 ? max_memory : rvegen::available_memory_bytes();
    if (limit > 0.0 && here > limit) {
      say << "rvegen: the solve needs about " << rvegen::format_bytes(here)
          << " on this machine (voxels " << rvegen::format_bytes(need.voxel_bytes)
          << ", FFT solver " << rvegen::format_bytes(need.homogenization_bytes) << "), above the "
          << (max_memory > 0.0 ? "--max-memory limit of " : "memory available, ")
          << rvegen::format_bytes(limit)
          << ": lower voxels.resolution, or run on more machines (mpirun)\n";
      return kExitInvalid;
    }
  }
  try {
    // This rank's planes of z (all of them in one process), on its share of the machine's
    // cores (the processes a launcher put on it), and on at most --threads of them.
    const rvegen::Communicator comm = ranks.communicator();
    const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    int allowed = std::max(1, cores / ranks.local_size());
    if (threads > 0) allowed = std::min(allowed, threads);
    tbb::global_control share(tbb::global_control::max_allowed_parallelism,
                              static_cast<size_t>(allowed));
    const std::array<int, 3>& res = scene.resolution;
    const std::array<int, 2> z = rvegen::spectral::fft_slab(res, comm);
    rvegen::VoxelOptions vopt;
    vopt.partial_volume = false;
    vopt.extent = {0, res[0], 0, res[1], z[0], z[1]};
    const rvegen::VoxelImage image = rvegen::voxelize(set, res, vopt);
    const auto progress = [&](const std::string& line) {
      if (!quiet) say << line << "\n";
    };
    rvegen::EffectiveProperties solved;
    const auto out = rvegen::cli::effective_properties(scene, set, image, progress, &solved, comm);
    if (ranks.root()) std::cout << out.dump(2) << "\n";
    const std::string not_converged = rvegen::unconverged(solved, scene.homogenization.tolerance);
    if (!not_converged.empty()) {
      say << kNotConverged << not_converged << "\n";
      return kExitNotConverged;
    }
    return kExitOk;
  } catch (const rvegen::InputError& e) {
    say << "rvegen: invalid input: " << e.what() << "\n";
    return kExitInvalid;
  }
}

int cmd_check(const std::vector<std::string>& args) {
  if (wants_help(args)) {
    std::cout << kCheckUsage;
    return kExitOk;
  }
  std::string path;
  bool as_json = false;
  size_t max_pairs = 10000;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--json") {
      as_json = true;
    } else if (a == "--max-pairs") {
      if (i + 1 >= args.size()) return usage_error("--max-pairs needs a number", "check");
      const double n = parse_size(args[++i]);
      if (!(n >= 1.0 && n <= 1e9) || n != std::floor(n))
        return usage_error("--max-pairs: not a count in [1, 1e9]: " + args[i], "check");
      max_pairs = static_cast<size_t>(n);
    } else if (!a.empty() && a[0] == '-') {
      return unknown_option(a, "check", {"--json", "--max-pairs", "--help"});
    } else if (path.empty()) {
      path = a;
    } else {
      return usage_error("more than one file given", "check");
    }
  }
  if (path.empty()) return usage_error("check needs an inclusion file", "check");
  rvegen::InclusionSet set;
  try {
    set = rvegen::read_inclusions_json(rvegen::read_file(path, kMaxInclusionFileBytes));
  } catch (const std::exception& e) {
    std::cerr << "rvegen: invalid inclusion file " << path << ": " << e.what() << "\n";
    return kExitInvalid;
  }
  const rvegen::AuditReport report = rvegen::audit(set, max_pairs);
  const auto& overlaps = report.overlaps;
  const auto& outside = report.outside;
  const auto& inc = set.inclusions;
  if (as_json) {
    nlohmann::ordered_json j;
    j["n"] = inc.size();
    j["count"] = overlaps.size();
    j["truncated"] = report.truncated;
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
    std::printf("%zu inclusions, %s%zu overlapping pairs, %zu outside the box\n", inc.size(),
                report.truncated ? "at least " : "", overlaps.size(), outside.size());
  }
  return overlaps.empty() && outside.empty() ? kExitOk : kExitOverlap;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "-h" || args[0] == "--help" || args[0] == "help") {
    std::cout << usage();
    return args.empty() ? kExitInvalid : kExitOk;
  }
  if (args[0] == "--version" || args[0] == "-V" || args[0] == "version") {
    std::cout << "rvegen " RVEGEN_VERSION "\n";
    return kExitOk;
  }
  const std::string cmd = args[0];
  args.erase(args.begin());
  if (cmd == "generate") return cmd_generate(args);
  if (cmd == "check") return cmd_check(args);
  if (cmd == "study") return rvegen::cli::cmd_study(args);
  if (cmd == "homogenize") return cmd_homogenize(args);
  if (cmd == "default-scene") {
    if (wants_help(args)) {
      std::cout << kDefaultSceneUsage;
      return kExitOk;
    }
    if (!args.empty()) {
      return usage_error("default-scene takes no argument (got " + args[0] + ")", "default-scene");
    }
    std::cout << rvegen::scene_to_json(rvegen::default_scene());
    return kExitOk;
  }
  return usage_error("unknown command \"" + cmd + "\"" +
                     rvegen::cli::did_you_mean(
                         cmd, {"generate", "check", "homogenize", "study", "default-scene"}) +
                     " (generate, check, homogenize, study, default-scene)");
}
