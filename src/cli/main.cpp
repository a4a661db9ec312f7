// rvegen: command-line generator and auditor of Representative Volume Elements.
#include <tbb/global_control.h>

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

#include "args.hpp"
#include "rvegen/femesh/lsan_suppressions.hpp"  // in sanitizer builds
#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/report.hpp"
#include "rvegen/io/report_sections.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/io/writers.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/resources.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/pipeline/ranks.hpp"
#include "rvegen/pipeline/run.hpp"
#include "rvegen/pipeline/rve_input.hpp"
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

using rvegen::kMaxInclusionFileBytes;
using rvegen::cli::kMaxSceneBytes;
using rvegen::cli::number_in;
using rvegen::cli::peak_memory_mb;
using rvegen::cli::read_args;
using rvegen::cli::size_in_bytes;
using rvegen::cli::split_commas;
using rvegen::cli::UsageError;

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

const char* kThreadsNeed = "a whole number in [1, 4096]";
int read_threads(const std::string& v) {
  return static_cast<int>(number_in(v, 1, 4096, true, "--threads", kThreadsNeed));
}

// The summary line of a run written, and its exit code: 3 when the target was not reached
// (the best valid configuration was written), 5 when a solve did not converge.
int finish_generate(const rvegen::RunOutcome& run, const rvegen::Scene& scene,
                    const std::string& out_dir, bool quiet,
                    std::chrono::steady_clock::time_point t0) {
  if (!quiet) {
    const auto vf =
        rvegen::family_volume_fractions(run.result.set, static_cast<int>(scene.families.size()));
    double total = 0.0;
    for (double v : vf) total += v;
    std::fprintf(stderr, "rvegen: %zu inclusions, volume fraction %.4f, %.2f s -> %s (%s)\n",
                 run.result.set.inclusions.size(), total, seconds_since(t0), out_dir.c_str(),
                 rvegen::describe_directory(out_dir).c_str());
  }
  if (run.result.status != rvegen::PackingStatus::kOk) {
    std::cerr << "rvegen: target volume fraction not reached (status "
              << rvegen::status_name(run.result.status) << ", "
              << rvegen::stop_reason_name(run.result.stop_reason)
              << "); the best valid configuration found was written\n";
    return kExitNotReached;
  }
  if (!run.not_converged.empty()) {
    std::cerr << kNotConverged << run.not_converged << "\n";
    return kExitNotConverged;
  }
  return kExitOk;
}

int cmd_generate(const std::vector<std::string>& args) {
  if (wants_help(args)) {
    std::cout << kGenerateUsage;
    return kExitOk;
  }
  std::string scene_path, out_dir = "rve";
  std::vector<std::string> outputs;  // --outputs
  bool quiet = false, outputs_given = false;
  double max_memory = 0.0;
  int threads = 0;  // all cores
  try {
    const auto files = read_args(
        args, "generate",
        {{{"-o", "--output"}, "a directory", [&](const std::string& v) { out_dir = v; }},
         {{"--outputs"},
          "a list such as inclusions,voxels,h5",
          [&](const std::string& v) { outputs = split_commas(v), outputs_given = true; }},
         {{"-q", "--quiet"}, "", [&](const std::string&) { quiet = true; }},
         {{"--threads"}, kThreadsNeed, [&](const std::string& v) { threads = read_threads(v); }},
         {{"--max-memory"}, "a size", [&](const std::string& v) {
            max_memory = size_in_bytes(v, "--max-memory");
          }}});
    if (files.size() > 1) throw UsageError("more than one scene file given");
    if (!files.empty()) scene_path = files[0];
  } catch (const UsageError& e) {
    return usage_error(e.what(), "generate");
  }
  const auto t0 = std::chrono::steady_clock::now();
  rvegen::Scene scene;
  try {
    scene = scene_path.empty() ? rvegen::default_scene()
                               : rvegen::parse_scene(rvegen::read_file(scene_path, kMaxSceneBytes));
    if (outputs_given)
      scene.outputs = rvegen::outputs_from_names(outputs, scene.outputs.mesh, "--outputs");
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
  // scene fits without it, the inclusions are packed and the mesher's own size field decides,
  // and offers settings that fit this RVE, so that one run reaches them.
  rvegen::RunPlan plan;
  try {
    plan = rvegen::plan_run(scene, rvegen::memory_limit(max_memory));
  } catch (const rvegen::InputError& e) {
    std::cerr << "rvegen: " << e.what() << "\n";
    return kExitInvalid;
  }
  // --threads: every parallel phase (packing, voxels, FFT) on at most that many cores; the same
  // scene gives the same RVE with any number.
  std::unique_ptr<tbb::global_control> thread_limit;
  if (threads > 0) {
    thread_limit = std::make_unique<tbb::global_control>(
        tbb::global_control::max_allowed_parallelism, static_cast<size_t>(threads));
  }
  rvegen::RunOptions options;
  if (!quiet) options.progress = [](const std::string& line) { std::cerr << line << "\n"; };
  options.threads = threads;
  options.start = t0;
  options.before_audit = fault_hook();
  try {
    // The output place is checked (and a private staging directory made) before the work.
    rvegen::OutputSet out(out_dir);
    const rvegen::RunOutcome run = rvegen::run_to_directory(scene, plan, options, out);
    if (run.slivers > 0) {
      // Written all the same (the mesh conforms and fills the box); the analyst decides.
      std::cerr << "rvegen: mesh_tet: " << run.slivers
                << " elements have a dihedral angle under 5 degrees (least " << run.least_dihedral
                << "); report.json's mesh_tet gives their distribution. Thin gaps and "
                   "inclusions that barely cross a box face (a thin cap, whose edge angle "
                   "bounds its elements') make them: another min_gap or mesh_tet.min_size "
                   "may help.\n";
    }
    out.commit();
    if (!out.leftover().empty()) {
      std::cerr << "rvegen: the previous set in " << out_dir << " could not be removed (not ours "
                << "to delete); it stays at " << out.leftover() << "\n";
    }
    return finish_generate(run, scene, out_dir, quiet, t0);
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
    std::cerr << "rvegen: out of memory (the estimate was " << rvegen::describe(plan.need)
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
  try {
    files = read_args(
        args, "homogenize",
        {{{"-q", "--quiet"}, "", [&](const std::string&) { quiet = true; }},
         {{"--threads"}, kThreadsNeed, [&](const std::string& v) { threads = read_threads(v); }},
         {{"--max-memory"}, "a size", [&](const std::string& v) {
            max_memory = size_in_bytes(v, "--max-memory");
          }}});
  } catch (const UsageError& e) {
    return usage_error(e.what(), "homogenize");
  }
  if (files.size() != 2)
    return usage_error("homogenize needs an RVE directory and a scene file", "homogenize");
  const rvegen::Ranks ranks;  // z slabs of the grid under an MPI launcher
  std::ostream& say = rvegen::say_once(ranks);
  rvegen::Scene scene;
  rvegen::InclusionSet set;
  try {
    scene = rvegen::parse_scene(rvegen::read_file(files[1], kMaxSceneBytes));
    if (!scene.homogenization.any()) {
      throw rvegen::InputError("homogenization.physics: give conductivity, elasticity or both");
    }
    set = rvegen::read_rve_for_scene(files[0], scene);
    // Memory before any large allocation, as generate checks it.
    rvegen::check_solve_fits(scene, rvegen::memory_limit(max_memory),
                             static_cast<double>(ranks.local_size()) / std::max(1, ranks.size()));
  } catch (const std::exception& e) {
    say << "rvegen: invalid input: " << e.what() << "\n";
    return kExitInvalid;
  }
  try {
    // This rank's planes of z, on its share of the machine's cores (the processes a launcher
    // put on it), and on at most --threads of them.
    const rvegen::Communicator comm = ranks.communicator();
    const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    int allowed = std::max(1, cores / ranks.local_size());
    if (threads > 0) allowed = std::min(allowed, threads);
    tbb::global_control share(tbb::global_control::max_allowed_parallelism,
                              static_cast<size_t>(allowed));
    const auto progress = [&](const std::string& line) {
      if (!quiet) say << line << "\n";
    };
    const rvegen::EffectiveProperties solved = rvegen::homogenize_rve(scene, set, progress, comm);
    if (ranks.root()) {
      const std::string section =
          rvegen::effective_section(scene.homogenization, solved, rvegen::ranks_of(comm));
      std::cout << nlohmann::ordered_json::parse(section).dump(2) << "\n";
    }
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
  try {
    const auto files =
        read_args(args, "check",
                  {{{"--json"}, "", [&](const std::string&) { as_json = true; }},
                   {{"--max-pairs"}, "a count in [1, 1e9]", [&](const std::string& v) {
                      max_pairs = static_cast<size_t>(
                          number_in(v, 1, 1e9, true, "--max-pairs", "a count in [1, 1e9]"));
                    }}});
    if (files.size() > 1) throw UsageError("more than one file given");
    if (!files.empty()) path = files[0];
  } catch (const UsageError& e) {
    return usage_error(e.what(), "check");
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
  std::cout << (as_json ? rvegen::audit_json(set, report) : rvegen::audit_text(set, report));
  const auto& overlaps = report.overlaps;
  const auto& outside = report.outside;
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
                     rvegen::json_util::did_you_mean(
                         cmd, {"generate", "check", "homogenize", "study", "default-scene"}) +
                     " (generate, check, homogenize, study, default-scene)");
}
