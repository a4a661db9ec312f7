// report.json: what a run produced, per family and in total.
#pragma once

#include <string>

#include "rvegen/levelset.hpp"
#include "rvegen/packing.hpp"
#include "rvegen/voxelize.hpp"

namespace rvegen {

/// Exact (analytic) volume fraction of each family, from the inclusion volumes.
std::vector<double> family_volume_fractions(const InclusionSet& set, int n_families);

/// Exact volume fraction of each phase (phase_table order; the matrix gets the rest). Shells
/// that merge (shells_may_touch) are counted each, so their phase is an upper bound.
std::vector<double> phase_volume_fractions(const InclusionSet& set,
                                           const std::vector<Phase>& phases);

/// report.json text. `image` may be null (then no voxel statistics), `levelsets` too (then no
/// level-set section).
std::string report_json(const Scene& scene, const PackingResult& result, const VoxelImage* image,
                        double total_seconds, const LevelSets* levelsets = nullptr);

}  // namespace rvegen
