// Voxelization benchmark: accuracy against time. Prints one table row per (scene, resolution,
// method) as tab-separated values:
//   scene  resolution  method  seconds  volume_fraction  analytic  abs_error  threads
// method "centre" = labels at voxel centres only; "partial" = labels + partial volumes.
// usage: rvegen_bench_voxels [SCENE.json|default|spheres10k] RES [RES ...] [--threads N]
#include <tbb/global_control.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "rvegen/packing.hpp"
#include "rvegen/scene.hpp"
#include "rvegen/voxelize.hpp"
#include "rvegen/writers.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s SCENE|default|spheres10k RES [RES ...] [--threads N]\n",
                 argv[0]);
    return 2;
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
          if (im.phases[l].kind == "core") vf += lf[l];
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
