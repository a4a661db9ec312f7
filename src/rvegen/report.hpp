// report.json: what a run produced, per family and in total.
#pragma once

#include <string>

#include "rvegen/packing.hpp"
#include "rvegen/voxelize.hpp"

namespace rvegen {

/// Exact (analytic) volume fraction of each family, from the inclusion volumes.
std::vector<double> family_volume_fractions(const InclusionSet& set, int n_families);

/// report.json text. `image` may be null (then no voxel statistics).
std::string report_json(const Scene& scene, const PackingResult& result, const VoxelImage* image,
                        double total_seconds);

}  // namespace rvegen
