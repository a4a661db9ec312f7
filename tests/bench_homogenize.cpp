// Homogenization benchmark: cost of the FFT solvers against the FFTs alone, iterations against
// contrast, and the whole elasticity solve. Prints a table (tab-separated):
//   physics res contrast threads seconds iterations s_per_iteration fft_s ratio peak_MiB fft3d_s
//   split_s iteration_s iteration_ratio passes
// fft_s is the time of the transforms one iteration needs (3 or 6 forward and as many inverse)
// on the same grid in the same run, the faster of FFTW's 3D transforms (fft3d_s) and the same
// transforms split as the solver runs them (split_s), each the median of sets timed before and
// after the solves; ratio = s_per_iteration / fft_s (the FFTs are the floor). peak_MiB is the
// process's peak resident memory after the row (it only grows: run one size per process to read
// bytes per voxel). iteration_s is an iteration alone (between the solver's reports of two
// consecutive iterations: no set-up, no right-hand side), iteration_ratio = iteration_s / fft_s.
// passes: "wide" when the passes over the frequencies take two at a time (AVX2), else "narrow".
// The image: spheres packed at 0.3 (radius 0.12 of a unit box, seed 7), labels at
// voxel centres. usage: rvegen_bench_homogenize RES [conductivity|elasticity] [THREADS] [CONTRAST
// ...] [narrow]
#include <sys/resource.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "rvegen/homogenize/conductivity.hpp"
#include "rvegen/homogenize/elasticity.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace {

double peak_mib() {
  struct rusage ru {};
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss / 1024.0;
}

double seconds_of(const std::function<void()>& f) {
  const auto t = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s RES [conductivity|elasticity] [THREADS] [CONTRAST ...]\n",
                 argv[0]);
    return 2;
  }
  const int res = std::atoi(argv[1]);
  const std::string physics = argc > 2 ? argv[2] : "conductivity";
  const int threads = argc > 3 ? std::atoi(argv[3]) : 0;
  // "narrow" among the contrasts keeps the passes over the frequencies to one frequency at a
  // time (spectral::allow_wide_passes), to compare with the four-lane passes in the same build.
  std::vector<double> contrasts;
  for (int i = 4; i < argc; ++i) {
    if (std::string(argv[i]) == "narrow") {
      rvegen::spectral::allow_wide_passes(false);
    } else {
      contrasts.push_back(std::atof(argv[i]));
    }
  }
  if (contrasts.empty()) contrasts = {10.0, 100.0, 1000.0};
  // THREADS limits every parallel loop (TBB's passes over the voxels as well as FFTW's threads),
  // as `rvegen --threads` does.
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<size_t>(threads));
  }

  rvegen::Scene s;
  s.box.size = rvegen::Vec3(1, 1, 1);
  s.seed = 7;
  rvegen::Family sph;
  sph.name = "spheres";
  sph.shape = rvegen::ShapeKind::Sphere;
  sph.radius = 0.12;
  sph.volume_fraction = 0.3;
  s.families = {sph};
  const rvegen::PackingResult packed = rvegen::generate(s);
  rvegen::VoxelOptions vopt;
  vopt.partial_volume = false;
  const rvegen::VoxelImage img = rvegen::voxelize(packed.set, {res, res, res}, vopt);
  const std::array<int, 3> dims = {res, res, res};
  const size_t n = img.phase.size();

  // The transforms of one iteration, alone, the floor an iteration cannot go below: FFTW's 3D
  // transforms in place (no copies, no scaling), and the same transforms split as the solver
  // runs them (Grid::convolve with a projection that does nothing); the floor is the faster
  // of the two. Timed one set at a time, before and after the solves (the machine's speed
  // drifts), and the median of each taken.
  const int fields = physics == "elasticity" ? 6 : 3;
  std::vector<double> fft_times, split_times;
  auto time_ffts = [&] {
    rvegen::spectral::Grid grid(dims, s.box.size, rvegen::GradientScheme::kRotated, threads);
    std::vector<rvegen::spectral::Spectrum> spec(fields);
    for (auto& b : spec) b.assign(grid.spectrum_size(), 1.0);
    const rvegen::spectral::Grid::Projector nothing = [](size_t, size_t, double* const*,
                                                         const double*) {};
    for (int r = 0; r < 5; ++r) {
      fft_times.push_back(seconds_of([&] {
        for (auto& b : spec) grid.forward_in_place(b);
        for (auto& b : spec) grid.inverse_in_place(b);
      }));
      split_times.push_back(seconds_of([&] { grid.convolve(spec, nothing); }));
    }
  };
  auto median = [](std::vector<double> t) {
    std::sort(t.begin(), t.end());
    return t[t.size() / 2];
  };
  time_ffts();
  std::printf(
      "physics\tres\tcontrast\tthreads\tseconds\titerations\ts_per_iteration\tfft_s\tratio\tpeak_"
      "MiB\tfft3d_s\tsplit_s\titeration_s\titeration_ratio\tpasses\n");
  // The iterations alone: the intervals between the solver's reports of consecutive
  // iterations (each one sweep and one pass over the frequencies), summed; the set-up and each
  // load case's right-hand side and first iteration left out (seconds / iterations counts them
  // all).
  using Clock = std::chrono::steady_clock;
  Clock::time_point previous;
  double between = 0.0;
  int between_count = 0, last_it = 0;
  const auto watch = [&](int, int it, double) {
    const Clock::time_point now = Clock::now();
    if (it == last_it + 1 && it > 1) {
      between += std::chrono::duration<double>(now - previous).count();
      ++between_count;
    }
    previous = now;
    last_it = it;
    return true;
  };
  for (double contrast : contrasts) {
    int iterations = 0;
    double seconds = 0.0;
    between = 0.0;
    between_count = 0;
    if (physics == "elasticity") {
      std::vector<double> young(n), poisson(n, 0.3);
      for (size_t i = 0; i < n; ++i) young[i] = img.phase[i] == 0 ? 1.0 : contrast;
      rvegen::ElasticityOptions opt;
      opt.tolerance = 1e-6;
      opt.threads = threads;
      opt.progress = watch;
      const rvegen::ElasticityResult r =
          rvegen::effective_stiffness(dims, s.box.size, young, poisson, opt);
      for (int it : r.iterations) iterations += it;
      seconds = r.seconds;
    } else {
      std::vector<double> k(n);
      for (size_t i = 0; i < n; ++i) k[i] = img.phase[i] == 0 ? 1.0 : contrast;
      rvegen::ConductivityOptions opt;
      opt.tolerance = 1e-6;
      opt.threads = threads;
      opt.progress = watch;
      const rvegen::ConductivityResult r = rvegen::effective_conductivity(dims, s.box.size, k, opt);
      for (int it : r.iterations) iterations += it;
      seconds = r.seconds;
    }
    const double per = seconds / std::max(1, iterations);
    const double per_alone = between / std::max(1, between_count);
    time_ffts();
    const double fft3d_s = median(fft_times), split_s = median(split_times);
    const double fft_s = std::min(fft3d_s, split_s);
    std::printf("%s\t%d\t%g\t%d\t%.3f\t%d\t%.4f\t%.4f\t%.2f\t%.0f\t%.4f\t%.4f\t%.4f\t%.2f\t%s\n",
                physics.c_str(), res, contrast, threads, seconds, iterations, per, fft_s,
                per / fft_s, peak_mib(), fft3d_s, split_s, per_alone, per_alone / fft_s,
                rvegen::spectral::wide_passes() ? "wide" : "narrow");
  }
  return 0;
}
