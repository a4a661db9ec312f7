// Voxelization benchmark: accuracy against time. Prints one table row per (scene, resolution,
// method) as tab-separated values:
//   scene  resolution  method  seconds  volume_fraction  analytic  abs_error  threads
// method "centre" = labels at voxel centres only; "partial" = labels + partial volumes.
// usage: rvegen_bench_voxels [SCENE.json|default|spheres10k] RES [RES ...] [--threads N]
//        rvegen_bench_voxels --levelsets SCENE.json N [N ...]
//   level sets with voxel size = box / N: one row per N,
//   N  seconds  grids  sparse_bytes  dense_bytes  ratio  volume_error
//   volume_error: |(volume inside the grids) - (exact volume of the regions they describe)| as a
//   fraction of the box (the inside volume counted on the grids' own voxels).
#include <tbb/global_control.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "rvegen/io/scene_json.hpp"
#include "rvegen/io/writers.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/levelset.hpp"
#include "rvegen/raster/voxelize.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s SCENE|default|spheres10k RES [RES ...] [--threads N]\n",
                 argv[0]);
    return 2;
  }
  if (std::string(argv[1]) == "--levelsets") {
    const rvegen::Scene scene = rvegen::parse_scene(rvegen::read_file(argv[2]));
    const rvegen::PackingResult r = rvegen::generate(scene);
    double exact = 0.0;  // volume of what the grids describe: wavy/deformed cores, shells
    for (const auto& inc : r.set.inclusions) {
      const rvegen::RegionVolumes v = rvegen::region_volumes(inc);
      if (inc.mod.curved() || inc.mod.deformed()) exact += v.core;
      if (inc.mod.coated()) exact += v.shell;
    }
    exact /= r.set.box.volume();
    for (int i = 3; i < argc; ++i) {
      const int n = std::atoi(argv[i]);
      rvegen::LevelSetOptions o;
      o.voxel_size = r.set.box.size.minCoeff() / n;
      const auto t0 = std::chrono::steady_clock::now();
      const rvegen::LevelSets ls = rvegen::build_level_sets(r.set, o);
      const double sec =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      // Inside volume: sample the grids at the voxel centres of a dense grid over the box.
      long long inside = 0, total = 0;
      const double h = o.voxel_size;
      for (double z = 0.5 * h; z < r.set.box.size[2]; z += h) {
        for (double y = 0.5 * h; y < r.set.box.size[1]; y += h) {
          for (double x = 0.5 * h; x < r.set.box.size[0]; x += h) {
            ++total;
            for (size_t g = 0; g < ls.grids.size(); ++g) {
              if (rvegen::level_set_value(ls, g, rvegen::Vec3(x, y, z)) < 0.0) {
                ++inside;
                break;
              }
            }
          }
        }
      }
      const double vf = static_cast<double>(inside) / static_cast<double>(total);
      std::printf("%d\t%.3f\t%zu\t%lld\t%lld\t%.3f\t%.2e\n", n, sec, ls.grids.size(),
                  ls.memory_bytes, ls.dense_bytes,
                  static_cast<double>(ls.memory_bytes) / static_cast<double>(ls.dense_bytes),
                  std::abs(vf - exact));
      std::fflush(stdout);
    }
    return 0;
  }
  const std::string which = argv[1];
  std::vector<int> res;
  int threads = 0;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--threads" && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else {
      res.push_back(std::atoi(argv[i]));
    }
  }
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  threads);
  }
  rvegen::Scene scene = rvegen::default_scene();
  if (which == "spheres10k") {
    // 10,000 inclusions in the default mix (spheres, fibres, ellipsoids at 35 %).
    for (auto& f : scene.families) f.volume_fraction *= 1.0;
    const double n = scene.expected_count(0) + scene.expected_count(1) + scene.expected_count(2);
    scene.box.size *= std::cbrt(10000.0 / n);
  } else if (which != "default") {
    scene = rvegen::parse_scene(rvegen::read_file(which));
  }
  const rvegen::PackingResult r = rvegen::generate(scene);
  double analytic = 0.0;
  for (const auto& inc : r.set.inclusions) analytic += inc.shape.volume();
  analytic /= r.set.box.volume();
  for (int n : res) {
    for (int partial = 0; partial < 2; ++partial) {
      rvegen::VoxelOptions o;
      o.partial_volume = partial == 1;
      const auto t0 = std::chrono::steady_clock::now();
      const rvegen::VoxelImage im = rvegen::voxelize(r.set, {n, n, n}, o);
      const double sec =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      double vf = 0.0;
      if (partial) {
        vf = rvegen::partial_volume_fraction(im);
      } else {
        const auto lf = rvegen::label_fractions(im);
        for (size_t l = 0; l < im.phases.size(); ++l) {
          if (im.phases[l].kind == rvegen::PhaseKind::kCore) vf += lf[l];
        }
      }
      std::printf("%s\t%zu\t%d\t%s\t%.4f\t%.6f\t%.6f\t%.2e\t%d\n", which.c_str(),
                  r.set.inclusions.size(), n, partial ? "partial" : "centre", sec, vf, analytic,
                  std::abs(vf - analytic), threads);
      std::fflush(stdout);
    }
  }
  return 0;
}
