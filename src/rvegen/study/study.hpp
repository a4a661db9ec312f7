// The representativity study (`rvegen study`): how big must the RVE be? Realizations of a
// scene at several box sizes, each packed through the pipeline and measured (volume
// fractions, orientation tensors, nearest neighbours, g(r), effective properties), written once
// as a record with its seed and digest; then per size and property the statistics, the
// variance law D^2(V) = K V^-alpha, the window method's integral range and the size recommended
// for a target error. The command line reads the arguments, shares the realizations out among
// its threads and MPI ranks, and prints; everything else is here.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "rvegen/model/scene.hpp"
#include "rvegen/pipeline/ranks.hpp"
#include "rvegen/pipeline/run.hpp"

namespace rvegen {

/// "1,1.5,2": box edge multiples in (0, 100], sorted, none twice. Throws InputError naming
/// --sizes and the item.
std::vector<double> parse_study_sizes(const std::string& text);

/// "1.5": a size as the records' file names and messages give it.
std::string study_size_name(double m);

/// What a study's realizations and statistics depend on.
struct StudyPlan {
  std::string scene_path;
  std::filesystem::path dir, rdir;  // the study's directory and its realizations
  std::vector<double> sizes;        // box size factors
  std::vector<double> volumes;      // box volume of each size
  double base_volume = 0.0;         // the scene's own box volume
  int realizations = 0;
  double target_error = 0.0;
  int ranks = 1;          // processes of this run (the statistics do not depend on it)
  uint64_t seed = 0;      // the scene's, from which each realization's is drawn
  std::string signature;  // the scene as the study holds it (keys each record's digest)
  std::vector<std::vector<Scene>> scenes;  // [size][realization]
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
};

/// The plan of a study of `base` (read from `scene_path`) in `dir`: each realization's scene,
/// its box and counts scaled to the size and its seed drawn from the scene's, the size and its
/// number (the same realization always gets the same seed). Throws InputError naming what is
/// wrong (a count that scales out of range, a scene that keeps local fields).
StudyPlan plan_study(const Scene& base, const std::string& scene_path, const std::string& dir,
                     const std::vector<double>& sizes, int realizations, double target_error);

/// How many realizations may run at once on this machine (`local_ranks` processes sharing it,
/// each running that many): `wanted`, or fewer when the estimated peak of a realization at the
/// largest size times them does not fit in `limit` (then `note` says so). Throws InputError
/// naming the size and the figure when one realization cannot fit.
int study_jobs_that_fit(const StudyPlan& plan, const MemoryLimit& limit, int wanted,
                        int local_ranks, std::string* note);

/// Makes the study's directory: new, or one holding a study of the same scene. Throws
/// InputError when it holds a study of another scene, OutputError when it is not empty and
/// holds no study, or cannot be written.
void prepare_study_directory(const StudyPlan& plan);

/// The realizations without a record (size index * realizations + k), after checking every
/// record kept (its size, realization, seed, status, values and digest): throws InputError
/// naming the first record that cannot be trusted, before any work.
std::vector<int> missing_realizations(const StudyPlan& plan);

/// The file name of realization k's record at size m ("size_1.5_3.json").
std::string study_record_file(double m, int k);

/// Packs and measures realization k of size index i; returns its record (JSON text, with its
/// digest), `status` its status ("ok", "target_not_reached", "not_converged",
/// "nothing_placed"). `rank`: the MPI rank that computed it (-1: one process). Throws what the
/// pipeline throws, except NothingPlaced (a record of its own).
std::string run_realization(const StudyPlan& plan, size_t i, int k, int rank, std::string* status,
                            double* seconds);

/// Computes this rank's share of the `missing` realizations (every ranks()-th), `at_once` at a
/// time, each written as a record with a progress line; then only the records and each rank's
/// peak memory travel to rank 0 (a record is a few hundred bytes: no image, no inclusion
/// list), which keeps a copy of any record it does not see on its own disk and gets every
/// rank's peak in `peaks`. Every rank calls. Returns, on rank 0, the first rank's failure
/// (empty: none).
std::string run_study_share(const StudyPlan& plan, const std::vector<int>& missing,
                            const Ranks& ranks, int at_once, const ProgressFn& progress,
                            std::vector<double>* peaks);

/// Writes `text` to `path` through a temporary file and a rename: a killed run leaves the old
/// file or the new one, never half of one. Throws OutputError.
void write_whole(const std::filesystem::path& path, const std::string& text);

/// What the statistics left out.
struct StudyOutcome {
  int not_reached = 0;    // realizations that missed their target
  int not_converged = 0;  // realizations whose homogenization did not converge
};
/// Writes study.json and study.csv from the records (rank 0's work). `rank_peaks_mb`: every
/// rank's peak memory under MPI (empty for one process). Throws InputError naming a record
/// that cannot be read, OutputError when the files cannot be written.
StudyOutcome write_study_statistics(const StudyPlan& plan, std::vector<double> rank_peaks_mb);

}  // namespace rvegen
