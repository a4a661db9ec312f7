#include "rvegen/pipeline/rve_input.hpp"

#include <algorithm>

#include "rvegen/homogenize/spectral.hpp"
#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/writers.hpp"
#include "rvegen/model/resources.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen {

InclusionSet read_rve_for_scene(const std::string& dir, const Scene& scene) {
  const std::string path = dir + "/inclusions.json";
  InclusionSet set = read_inclusions_json(read_file(path, kMaxInclusionFileBytes));
  std::vector<std::string> names;
  for (const Family& f : scene.families) names.push_back(f.name);
  if (set.family_names != names) {
    std::string have, want;
    for (const auto& n : set.family_names) have += (have.empty() ? "" : ", ") + n;
    for (const auto& n : names) want += (want.empty() ? "" : ", ") + n;
    throw InputError("families: the scene's (" + want + ") are not the RVE's (" + have + ")");
  }
  // What is handed in is audited like what is packed: the scene's families and box, no
  // overlap, nothing outside a closed box.
  check_rve_for_scene(set, scene, path);
  return set;
}

void check_solve_fits(const Scene& scene, const MemoryLimit& limit, double share) {
  Scene sized = scene;
  sized.outputs = Outputs{};
  sized.outputs.inclusions = sized.outputs.levelsets = sized.outputs.statistics = false;
  const ResourceEstimate need = estimate_resources(sized);
  const double here = (need.voxel_bytes + need.homogenization_bytes) * share;
  if (!limit.exceeded_by(here)) return;
  throw InputError("the solve needs about " + format_bytes(here) + " on this machine (voxels " +
                   format_bytes(need.voxel_bytes) + ", FFT solver " +
                   format_bytes(need.homogenization_bytes) + ")" + limit.above() +
                   ": lower voxels.resolution, or run on more machines (mpirun)");
}

EffectiveProperties homogenize_rve(const Scene& scene, const InclusionSet& set,
                                   const ProgressFn& progress, const Communicator& comm) {
  const std::array<int, 3>& res = scene.resolution;
  const std::array<int, 2> z = spectral::fft_slab(res, comm);
  VoxelOptions vopt;
  vopt.partial_volume = false;
  vopt.extent = {0, res[0], 0, res[1], z[0], z[1]};
  const VoxelImage image = voxelize(set, res, vopt);
  return solve_effective(scene, set, image, progress, comm);
}

}  // namespace rvegen
