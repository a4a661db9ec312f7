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

#include "process.hpp"
#include "ranks.hpp"
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
#include "rvegen/pipeline/run.hpp"
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
    int files = 0;
    const uintmax_t bytes = directory_bytes(out_dir, &files);
    std::fprintf(stderr,
                 "rvegen: %zu inclusions, volume fraction %.4f, %.2f s -> %s (%s in %d files)\n",
                 run.result.set.inclusions.size(), total, seconds_since(t0), out_dir.c_str(),
                 human_bytes(bytes).c_str(), files);
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
    const rvegen::EffectiveProperties solved =
        rvegen::solve_effective(scene, set, image, progress, comm);
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
