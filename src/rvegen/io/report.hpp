// report.json: what a run produced, per family and in total.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "rvegen/model/shell_overlaps.hpp"
#include "rvegen/model/stats.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/levelset_info.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen {

/// Exact (analytic) volume fraction of each family, from the inclusion volumes.
std::vector<double> family_volume_fractions(const InclusionSet& set, int n_families);

/// Exact volume fraction of each phase (phase_table order; the matrix gets the rest). Where
/// shells that may touch overlap, the lens counts once, in the earlier inclusion's shell (as in
/// the voxel image and the tetrahedral mesh) when shell_overlaps is exact (spheres, no point in
/// three shells); otherwise each shell counts whole and their phase is an upper bound.
std::vector<double> phase_volume_fractions(const InclusionSet& set,
                                           const std::vector<Phase>& phases);
/// The same with the set's shell_overlaps already computed.
std::vector<double> phase_volume_fractions(const InclusionSet& set,
                                           const std::vector<Phase>& phases,
                                           const ShellOverlaps& overlaps);

/// Wall-clock seconds of a whole run: each phase in the order it ran (packing, audit, voxels,
/// each writer, ...), the total, and the peak resident memory of the process.
struct RunTimings {
  std::vector<std::pair<std::string, double>> phases;
  double total_seconds = 0.0;
  double peak_memory_mb = 0.0;  // 0: not measured
};

/// The statistics of a packed set the report gives (the costly part of a report): g(r) of each
/// sphere family's centres over five mean diameters (empty for other families) and the nearest-
/// neighbour distances.
struct ReportStatistics {
  std::vector<RadialDistribution> radial;  // per family
  Summary nearest;
};
ReportStatistics report_statistics(const Scene& scene, const PackingResult& result);

/// A section of report.json after the packing's: its key and its JSON object text
/// (report_sections.hpp builds "mesh_tet" and "effective").
using ReportSection = std::pair<std::string, std::string>;

/// report.json text. `image` may be null (then no voxel statistics), `levelsets` too (then no
/// level-set section), `stats` too (then no g(r) and no nearest-neighbour section: the
/// "statistics" output left out); `sections` follow in their order.
std::string report_json(const Scene& scene, const PackingResult& result, const VoxelImage* image,
                        const RunTimings& timings, const LevelSets* levelsets = nullptr,
                        const ReportStatistics* stats = nullptr,
                        const std::vector<ReportSection>& sections = {});

}  // namespace rvegen
