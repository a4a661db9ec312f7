// An RVE written earlier, handed in with its scene (`rvegen homogenize DIR SCENE`): read,
// audited and checked against the scene as a packed set is, then solved on this rank's slab.
#pragma once

#include <string>

#include "rvegen/homogenize/effective.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/pipeline/run.hpp"

namespace rvegen {

/// The largest inclusion list read (inclusions.json of a few million inclusions).
constexpr size_t kMaxInclusionFileBytes = size_t(2) << 30;

/// DIR/inclusions.json for `scene`: the scene's families (the same names in the same order),
/// then check_rve_for_scene (box, shapes, coatings, continuous fibres, the exact audit).
/// Throws InputError naming the file and what is wrong.
InclusionSet read_rve_for_scene(const std::string& dir, const Scene& scene);

/// The solve's memory before any large allocation: the image and the solver's fields, of
/// which this machine holds `share` (its ranks' slabs: local ranks over ranks). Throws
/// InputError naming the need and the limit.
void check_solve_fits(const Scene& scene, const MemoryLimit& limit, double share);

/// This rank's planes of z of the scene's image (all of them in one process), voxelized and
/// solved as scene.homogenization asks.
EffectiveProperties homogenize_rve(const Scene& scene, const InclusionSet& set,
                                   const ProgressFn& progress, const Communicator& comm);

}  // namespace rvegen
