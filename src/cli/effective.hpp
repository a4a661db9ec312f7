// The command line's homogenization step: per-voxel phase properties from the scene's
// "materials", the FFT solves asked for in "homogenization", and the report's "effective"
// object with the bounds beside the results.
#pragma once

#include <nlohmann/json.hpp>

#include "rvegen/homogenize/effective.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen::cli {

/// Solves what scene.homogenization asks for on `image` (labels at voxel centres, inclusion ids)
/// of the inclusions `set`, and returns the report's "effective" object. Each voxel takes its
/// phase's properties (transversely isotropic cores turned to their inclusion's axis); voxels
/// cut by one core surface take the scene's voxel rule. Progress lines go to `progress` (about
/// once a second).
/// With scene.homogenization.fields, `fields` receives the local fields (owned by `*keep`).
/// With `comm`, `image` is this rank's slab (spectral::fft_slab) and every rank calls.
nlohmann::ordered_json effective_properties(const Scene& scene, const InclusionSet& set,
                                            const VoxelImage& image, const ProgressFn& progress,
                                            EffectiveProperties* keep = nullptr,
                                            const Communicator& comm = {});

}  // namespace rvegen::cli
