#include "study.hpp"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "process.hpp"
#include "ranks.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/io/writers.hpp"
#include "rvegen/model/errors.hpp"
#include "rvegen/study/study.hpp"

namespace rvegen::cli {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

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

// The records this rank computes: its share of the missing realizations, on its cores, with
// a progress line each. Returns the first failure (empty: none) and the records by file name.
std::string compute_share(const StudyPlan& plan, const std::vector<int>& missing,
                          const Ranks& ranks, int at_once, bool quiet, json* records) {
  struct Task {
    size_t size;
    int k;
  };
  std::vector<Task> todo;
  for (size_t t = static_cast<size_t>(ranks.rank()); t < missing.size();
       t += static_cast<size_t>(ranks.size()))
    todo.push_back(
        {static_cast<size_t>(missing[t] / plan.realizations), missing[t] % plan.realizations});
  std::error_code ec;
  if (!ranks.root()) fs::create_directories(plan.rdir, ec);  // rank 0 gets a copy of each
  const std::string who = ranks.size() > 1 ? "rank " + std::to_string(ranks.rank()) + ": " : "";
  std::mutex say;
  std::atomic<size_t> done{0};
  std::string failure;
  std::vector<std::string> written(todo.size());
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                            static_cast<size_t>(at_once));
  tbb::parallel_for(size_t(0), todo.size(), size_t(1), [&](size_t t) {
    {
      std::lock_guard<std::mutex> lock(say);
      if (!failure.empty()) return;
    }
    const Task& task = todo[t];
    const std::string file = study_record_file(plan.sizes[task.size], task.k);
    std::string status, error;
    double seconds = 0.0;
    try {
      written[t] = run_realization(plan, task.size, task.k, ranks.size() > 1 ? ranks.rank() : -1,
                                   &status, &seconds);
      write_whole(plan.rdir / file, written[t]);
    } catch (const std::bad_alloc&) {
      error = "out of memory in realization " + std::to_string(task.k) + " at size " +
              study_size_name(plan.sizes[task.size]) +
              " (run fewer at once: --jobs, or --max-memory)";
    } catch (const std::exception& e) {
      error = e.what();
    }
    std::lock_guard<std::mutex> lock(say);
    if (!error.empty()) {
      if (failure.empty()) failure = error;
      written[t].clear();
      return;
    }
    if (!quiet) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "%zu/%zu done (size %s, realization %d, %s, %.1f s)", ++done,
                    todo.size(), study_size_name(plan.sizes[task.size]).c_str(), task.k,
                    status.c_str(), seconds);
      std::cerr << "study: " << who << buf << "\n";
    }
  });
  *records = json::object();
  for (size_t t = 0; t < todo.size(); ++t) {
    if (!written[t].empty())
      (*records)[study_record_file(plan.sizes[todo[t].size], todo[t].k)] = written[t];
  }
  return failure;
}

// Only the records and each rank's peak memory travel to rank 0 (a record is a few hundred
// bytes: no image, no inclusion list). Rank 0 keeps a copy of any record it does not see on
// its own disk, and returns the first rank's failure (empty: none); `peaks` gets every rank's
// peak memory on rank 0.
std::string gather_records(const StudyPlan& plan, const Ranks& ranks, const std::string& failure,
                           const json& records, std::vector<double>* peaks) {
  json mine = json::object();
  mine["failure"] = failure;
  mine["records"] = records;
  mine["peak_memory_mb"] = peak_memory_mb();
  if (!ranks.root()) {
    ranks.gather(mine.dump());
    return "";
  }
  std::string first;
  std::error_code ec;
  for (const std::string& text : ranks.gather(mine.dump())) {
    const json theirs = json::parse(text);
    peaks->push_back(theirs["peak_memory_mb"].get<double>());
    const std::string f = theirs["failure"].get<std::string>();
    if (first.empty()) first = f;
    for (auto it = theirs["records"].begin(); it != theirs["records"].end(); ++it) {
      if (fs::exists(plan.rdir / it.key(), ec)) continue;
      try {
        write_whole(plan.rdir / it.key(), it.value().get<std::string>());
      } catch (const std::exception& e) {
        if (first.empty()) first = e.what();
      }
    }
  }
  return first;
}

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
  auto number = [&](size_t& i, const char* what, double lo, double hi, double* v) {
    if (i + 1 >= args.size()) return false;
    char* end = nullptr;
    *v = std::strtod(args[++i].c_str(), &end);
    if (*end != '\0' || !(*v >= lo && *v <= hi)) {
      throw InputError(std::string(what) + ": \"" + args[i] + "\" is not a number in [" +
                       study_size_name(lo) + ", " + study_size_name(hi) + "]");
    }
    return true;
  };
  try {
    for (size_t i = 0; i < args.size(); ++i) {
      const std::string& a = args[i];
      double v = 0.0;
      if (a == "-h" || a == "--help") {
        if (ranks.root()) std::cout << kStudyUsage;
        return kExitOk;
      } else if (a == "-o" || a == "--output") {
        if (i + 1 >= args.size()) return usage_error("-o needs a directory");
        out_dir = args[++i];
      } else if (a == "--sizes") {
        if (i + 1 >= args.size()) return usage_error("--sizes needs a list such as 1,1.5,2");
        sizes_text = args[++i];
      } else if (a == "--realizations") {
        if (!number(i, "--realizations", 1, 100000, &v) || v != std::floor(v))
          return usage_error("--realizations needs a whole number in [1, 100000]");
        realizations = static_cast<int>(v);
      } else if (a == "--target-error") {
        if (!number(i, "--target-error", 1e-9, 1.0, &v))
          return usage_error("--target-error needs a relative error such as 0.01");
        target_error = v;
      } else if (a == "--jobs") {
        if (!number(i, "--jobs", 1, 4096, &v) || v != std::floor(v))
          return usage_error("--jobs needs a whole number in [1, 4096]");
        jobs = static_cast<int>(v);
      } else if (a == "--max-memory") {
        if (i + 1 >= args.size() || (max_memory = parse_size(args[++i])) <= 0.0)
          return usage_error("--max-memory needs a size such as 8G, 512M or 1000000 (bytes)");
      } else if (a == "--quiet" || a == "-q") {
        quiet = true;
      } else if (!a.empty() && a[0] == '-') {
        return usage_error(
            "unknown option " + a + " of study" +
            did_you_mean(a, {"-o", "--output", "--sizes", "--realizations", "--target-error",
                             "--jobs", "--max-memory", "--quiet", "--help"}));
      } else if (scene_path.empty()) {
        scene_path = a;
      } else {
        return usage_error("more than one scene file given");
      }
    }
  } catch (const InputError& e) {
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
  json records;
  const std::string failure = compute_share(plan, missing, ranks, at_once, quiet, &records);
  std::vector<double> peaks;  // on rank 0: every rank's peak memory, in rank order
  const std::string first = gather_records(plan, ranks, failure, records, &peaks);
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
