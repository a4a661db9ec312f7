// One pipeline from a scene to its outputs, for every front end: plan the memory, pack,
// audit, nudge the inclusions off the mesh cell's faces where a tetrahedral mesh is asked
// for, check the mesh's memory, build each representation asked for, solve, write, report.
// The command line runs it whole (run_to_directory); the VTK source and filters call the same
// steps (pack_scene, prepare_tet_mesh), so that a scene gives the same inclusions, mesh and
// numbers from each.
#pragma once

#include <chrono>
#include <functional>
#include <string>

#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/homogenize/effective.hpp"
#include "rvegen/io/writers.hpp"
#include "rvegen/model/resources.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {

/// The memory a run may take: `--max-memory` when given, else what the machine has left
/// (available_memory_bytes; 0 when unknown: no limit).
struct MemoryLimit {
  double bytes = 0.0;
  bool given = false;
  /// ", above the --max-memory limit of 8.6 GB" or ", above the memory available, 3.1 GB".
  std::string above() const;
  bool exceeded_by(double need) const { return bytes > 0.0 && need > bytes; }
};
MemoryLimit memory_limit(double max_memory);

/// The scene's estimated peak against the limit, before any large allocation. A scene that
/// asks for a tetrahedral mesh and fits without it is let through even when the guess of its
/// mesh does not fit: the mesh's need is known only once the gaps are (prepare_tet_mesh).
struct RunPlan {
  ResourceEstimate need;
  MemoryLimit limit;
  bool mesh_guess_over = false;  // the guess of the mesh is over the limit; packing decides
};
/// Throws InputError ("the scene needs about ...") when the scene cannot fit.
RunPlan plan_run(const Scene& scene, const MemoryLimit& limit);

/// The packed set made ready for the tetrahedral mesh (mesh_tet): refused when tet_mesh
/// cannot mesh it; with shift_cell and nudge, its inclusions moved off the chosen cell's faces
/// where there is room, audited like the packed set (when the moved set fails the audit, the
/// packed set is kept and its movers count as stuck).
Nudged nudge_for_tet_mesh(InclusionSet* set, const TetMeshSpec& spec, double min_gap);

/// The tetrahedral mesh's need on this set against the limit, `others` the rest of the run's
/// estimate (the mesh's share replaced by the one found). Throws InputError naming the need,
/// the limit and the first coarser mesh that would fit (its settings named as `names` says).
TetMeshNeed check_tet_mesh_fits(const InclusionSet& set, const TetMeshSpec& spec,
                                const MemoryLimit& limit, const ResourceEstimate& others,
                                SettingNames names = SettingNames::kScene);

/// generate(), then, when the scene asks for a tetrahedral mesh, nudge_for_tet_mesh: the
/// inclusions every output of the run is made of.
struct Packed {
  PackingResult result;
  Nudged nudged;
};
Packed pack_scene(const Scene& scene, const Monitor& monitor,
                  const std::function<void(InclusionSet&)>& before_audit = nullptr);

/// The FFT solves scene.homogenization asks for on `image`, with a progress line at most once a
/// second ("<physics>: load L/N, iteration I, residual R"). With `comm`, `image` is this
/// rank's slab and every rank calls.
EffectiveProperties solve_effective(const Scene& scene, const InclusionSet& set,
                                    const VoxelImage& image, const ProgressFn& progress,
                                    const Communicator& comm = {});

struct RunOptions {
  ProgressFn progress;  // one line at a time; may be empty
  int threads = 0;      // the tetrahedral mesher's threads (0: all)
  /// When the run started (report.json's total time is the whole command's).
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  /// Test hook: alters the packed set before its audit (fault injection).
  std::function<void(InclusionSet&)> before_audit;
};

/// What a whole run gave, for the caller's messages and exit code.
struct RunOutcome {
  PackingResult result;
  std::string not_converged;    // what the solves left above their tolerance (empty: none)
  long long slivers = 0;        // tetrahedra with a dihedral angle under 5 degrees
  double least_dihedral = 0.0;  // of the mesh, degrees
};

/// Runs the scene to its outputs in `out` (staged; the caller commits): pack, nudge, mesh
/// check, each representation asked for, the solves, the report. Throws what the steps throw
/// (InputError, AuditFailure, NothingPlaced, OutputError, Cancelled, std::bad_alloc).
RunOutcome run_to_directory(const Scene& scene, const RunPlan& plan, const RunOptions& options,
                            OutputSet& out);

}  // namespace rvegen
