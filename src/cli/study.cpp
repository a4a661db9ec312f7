#include "study.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <thread>

#include "args.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/io/writers.hpp"
#include "rvegen/model/errors.hpp"
#include "rvegen/pipeline/ranks.hpp"
#include "rvegen/study/study.hpp"

namespace rvegen::cli {

namespace fs = std::filesystem;

namespace {

constexpr int kExitOk = 0, kExitOutput = 1, kExitInvalid = 2, kExitNotReached = 3,
              kExitNotConverged = 5;

const char* kStudyUsage =
    "usage: rvegen study SCENE.json [-o DIR] [--sizes LIST] [--realizations N]\n"
    "                    [--target-error E] [--jobs N] [--max-memory SIZE] [--quiet]\n"
    "  How big must the RVE be? Generates N realizations (default 10) of the scene at each\n"
    "  size of LIST (box edge multiples of the scene's box, default 1,1.5,2; families given by\n"
    "  count scale their count with the volume, the voxel size stays), computes on each the\n"
    "  volume fractions (exact and voxel), the orientation tensor of fibre families, the mean\n"
    "  nearest-neighbour distance and, when the scene has \"homogenization\", the effective\n"
    "  conductivity and stiffness, then per size and property the mean, standard deviation and\n"
    "  95 % confidence interval of the mean, the variance law D^2(V) = K V^-alpha fitted over\n"
    "  the sizes, and the volume at which N realizations give the mean to the relative error E\n"
    "  (default 0.01). Writes DIR/study.json and DIR/study.csv (default DIR ./study).\n"
    "  Each realization is written once, in DIR/realizations/, with its seed: a rerun with\n"
    "  more realizations or sizes computes only the missing ones. --jobs: realizations run at\n"
    "  once (default: every core). Under an MPI launcher (mpirun -np N rvegen study ...) the\n"
    "  ranks share the realizations out, each machine's cores shared by its ranks; only the\n"
    "  realization records travel to rank 0, which writes the statistics (the same as one\n"
    "  process gives). Before any work, each realization's peak memory is estimated: a study\n"
    "  whose largest size does not fit in the memory available (or --max-memory SIZE, bytes\n"
    "  or with K, M, G) is refused, and fewer realizations run at once where all would not fit.\n"
    "  Each record it resumes from is checked (its seed, size, status, values and digest).\n"
    "  Exit 0; 2 on invalid input (or DIR holding a study of another scene); 1 when DIR\n"
    "  cannot be written; 3 when some realization did not reach its target, 5 when some\n"
    "  realization's homogenization did not converge (either way they are left out of the\n"
    "  statistics, and counted: study.json's not_reached and not_converged).\n";

// Rank 0's statistics, said as the exit code.
int statistics(const StudyPlan& plan, const std::vector<double>& peaks, bool quiet) {
  StudyOutcome outcome;
  try {
    outcome = write_study_statistics(plan, peaks);
  } catch (const InputError& e) {
    std::cerr << "rvegen: " << e.what() << "\n";
    return kExitInvalid;
  } catch (const std::exception& e) {
    std::cerr << "rvegen: " << e.what() << "\n";
    return kExitOutput;
  }
  if (!quiet)
    std::cerr << "study: written " << (plan.dir / "study.json").string() << " and study.csv\n";
  if (outcome.not_reached > 0) {
    std::cerr << "rvegen: " << outcome.not_reached << " realization(s) did not reach the "
              << "target; they are left out of the statistics\n";
    return kExitNotReached;
  }
  if (outcome.not_converged > 0) {
    std::cerr << "rvegen: the homogenization of " << outcome.not_converged
              << " realization(s) did not converge (their records say which load cases); they "
              << "are left out of the statistics\n";
    return kExitNotConverged;
  }
  return kExitOk;
}

}  // namespace

const char* study_usage() {
  return kStudyUsage;
}

int cmd_study(const std::vector<std::string>& args) {
  const auto t0 = std::chrono::steady_clock::now();
  const Ranks ranks;  // several processes when started by an MPI launcher
  std::ostream& err = say_once(ranks);
  auto usage_error = [&err](const std::string& msg) {
    err << "rvegen: " << msg << "\n(rvegen study --help shows the usage)\n";
    return kExitInvalid;
  };
  std::string scene_path, out_dir = "study", sizes_text = "1,1.5,2";
  int realizations = 10, jobs = 0;
  double target_error = 0.01, max_memory = 0.0;
  bool quiet = false;
  for (const std::string& a : args) {
    if (a != "-h" && a != "--help") continue;
    if (ranks.root()) std::cout << kStudyUsage;
    return kExitOk;
  }
  try {
    const auto files = read_args(
        args, "study",
        {{{"-o", "--output"}, "a directory", [&](const std::string& v) { out_dir = v; }},
         {{"--sizes"}, "a list such as 1,1.5,2", [&](const std::string& v) { sizes_text = v; }},
         {{"--realizations"},
          "a whole number in [1, 100000]",
          [&](const std::string& v) {
            realizations = static_cast<int>(
                number_in(v, 1, 1e5, true, "--realizations", "a whole number in [1, 100000]"));
          }},
         {{"--target-error"},
          "a relative error such as 0.01",
          [&](const std::string& v) {
            target_error = number_in(v, 1e-9, 1.0, false, "--target-error",
                                     "a relative error in [1e-9, 1] such as 0.01");
          }},
         {{"--jobs"},
          "a whole number in [1, 4096]",
          [&](const std::string& v) {
            jobs = static_cast<int>(
                number_in(v, 1, 4096, true, "--jobs", "a whole number in [1, 4096]"));
          }},
         {{"--max-memory"},
          "a size",
          [&](const std::string& v) { max_memory = size_in_bytes(v, "--max-memory"); }},
         {{"-q", "--quiet"}, "", [&](const std::string&) { quiet = true; }}});
    if (files.size() > 1) throw UsageError("more than one scene file given");
    if (!files.empty()) scene_path = files[0];
  } catch (const UsageError& e) {
    return usage_error(e.what());
  }
  if (scene_path.empty()) return usage_error("study needs a scene file");
  StudyPlan plan;
  std::string note;
  int at_once = 0;
  try {
    const Scene base = parse_scene(read_file(scene_path, kMaxSceneBytes));
    plan = plan_study(base, scene_path, out_dir, parse_study_sizes(sizes_text), realizations,
                      target_error);
    plan.start = t0;
    plan.ranks = ranks.size();
  } catch (const std::exception& e) {
    err << "rvegen: invalid study of " << scene_path << ": " << e.what() << "\n";
    return kExitInvalid;
  }
  try {
    // Memory before any work; each rank takes its share of the machine's cores (the processes
    // a launcher put on it), and no more realizations at once than its memory holds.
    const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    const int share = std::max(1, cores / std::max(1, ranks.local_size()));
    at_once = study_jobs_that_fit(plan, memory_limit(max_memory), jobs > 0 ? jobs : share,
                                  ranks.local_size(), &note);
  } catch (const std::exception& e) {
    err << "rvegen: " << e.what() << "\n";
    return kExitInvalid;
  }
  if (!note.empty() && !quiet) err << "study: " << note << "\n";
  // The directory (new, or a study of the same scene) and the records kept, checked before
  // any work: rank 0 decides, the other ranks follow its answer.
  int ready = kExitOk;
  std::vector<int> missing;
  if (ranks.root()) {
    try {
      prepare_study_directory(plan);
      missing = missing_realizations(plan);
    } catch (const InputError& e) {
      err << "rvegen: " << e.what() << "\n";
      ready = kExitInvalid;
    } catch (const std::exception& e) {
      err << "rvegen: " << e.what() << "\n";
      ready = kExitOutput;
    }
  }
  ready = ranks.broadcast(ready);
  if (ready != kExitOk) return ready;
  missing = ranks.broadcast(missing);
  const size_t total = plan.sizes.size() * static_cast<size_t>(realizations);
  if (ranks.root() && !quiet) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "%zu sizes x %d realizations, %zu to compute (%zu kept)",
                  plan.sizes.size(), realizations, missing.size(), total - missing.size());
    std::cerr << "study: " << buf << "\n";
  }
  std::vector<double> peaks;  // on rank 0: every rank's peak memory, in rank order
  ProgressFn progress;
  if (!quiet) progress = [](const std::string& line) { std::cerr << "study: " << line << "\n"; };
  const std::string first = run_study_share(plan, missing, ranks, at_once, progress, &peaks);
  int stopped = kExitOk;
  if (ranks.root() && !first.empty()) {
    err << "rvegen: study stopped: " << first << "\n";
    stopped = kExitOutput;
  }
  stopped = ranks.broadcast(stopped);
  if (stopped != kExitOk) return stopped;
  // The statistics are rank 0's; every rank ends with its exit code.
  return ranks.broadcast(ranks.root() ? statistics(plan, peaks, quiet) : kExitOk);
}

}  // namespace rvegen::cli
