#include "rvegen/homogenize/conductivity.hpp"

#include <chrono>
#include <cmath>
#include <string>

#include "rvegen/model/errors.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {

namespace {

using spectral::cplx;

// The orthogonal projection onto discrete gradient fields, k k^H / |k|^2 at each frequency,
// applied to 3-component voxel fields (component-major: 3 blocks of n values).
class GradientProjection {
 public:
  GradientProjection(const std::array<int, 3>& dims, const Vec3& box, GradientScheme scheme,
                     int threads)
      : grid_(dims, box, scheme, threads) {
    for (auto& s : spectrum_) s.resize(grid_.frequencies());
  }
  size_t size() const { return grid_.size(); }
  void apply(const double* in, double* out) {
    const size_t n = grid_.size();
    for (int a = 0; a < 3; ++a) grid_.forward(in + a * n, spectrum_[a].data());
    spectral::parallel_blocks(grid_.frequencies(), [&](size_t lo, size_t hi) {
      for (size_t at = lo; at < hi; ++at) {
        const cplx* k = grid_.unit_k(at);
        const cplx s = std::conj(k[0]) * spectrum_[0][at] + std::conj(k[1]) * spectrum_[1][at] +
                       std::conj(k[2]) * spectrum_[2][at];
        for (int a = 0; a < 3; ++a) spectrum_[a][at] = k[a] * s;
      }
    });
    for (int a = 0; a < 3; ++a) grid_.inverse(spectrum_[a].data(), out + a * n);
  }

 private:
  spectral::Grid grid_;
  std::vector<cplx> spectrum_[3];
};

using spectral::dot;

}  // namespace

ConductivityResult effective_conductivity(const std::array<int, 3>& dims, const Vec3& box_size,
                                          const std::vector<double>& conductivity,
                                          const ConductivityOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  const size_t n = spectral::checked_voxels(dims, box_size);
  if (conductivity.size() != n) {
    throw InputError("homogenization: " + std::to_string(conductivity.size()) +
                     " conductivities for " + std::to_string(n) + " voxels");
  }
  double kmin = INFINITY, kmax = 0.0;
  for (double k : conductivity) {
    if (!(k >= 0.0) || !std::isfinite(k)) {
      throw InputError("homogenization: conductivities must be finite and >= 0");
    }
    kmin = std::min(kmin, k);
    kmax = std::max(kmax, k);
  }
  GradientProjection project(dims, box_size, opt.scheme, opt.threads);
  ConductivityResult res;
  std::vector<double> x(3 * n), tmp(3 * n), e, r;  // e, r: the fixed-point scheme's
  if (opt.solver == LinearSolver::kFixedPoint) e.resize(3 * n), r.resize(3 * n);
  // k times a 3-component field.
  auto times_k = [&](const std::vector<double>& f, std::vector<double>* out) {
    spectral::parallel_blocks(n, [&](size_t lo, size_t hi) {
      for (int a = 0; a < 3; ++a) {
        for (size_t i = lo; i < hi; ++i) (*out)[a * n + i] = conductivity[i] * f[a * n + i];
      }
    });
  };
  for (int load = 0; load < 3; ++load) {
    // Mean gradient E = unit vector along `load`; unknown: the fluctuation x (a gradient field
    // with zero mean); equilibrium: P[k (E + x)] = 0, i.e. P[k x] = -P[k E].
    std::vector<double> mean(3 * n, 0.0);
    std::fill(mean.begin() + load * n, mean.begin() + (load + 1) * n, 1.0);
    times_k(mean, &tmp);
    std::vector<double> b(3 * n);
    project.apply(tmp.data(), b.data());
    for (double& v : b) v = -v;
    const double bnorm = std::sqrt(dot(b, b));
    auto progress = [&](int it, double rel) {
      return !opt.progress || opt.progress(load, it, rel);
    };
    spectral::CgOutcome out;
    if (opt.solver == LinearSolver::kConjugateGradient) {
      out = spectral::conjugate_gradients(
          [&](const std::vector<double>& p, std::vector<double>* ap) {
            times_k(p, &tmp);
            project.apply(tmp.data(), ap->data());
          },
          std::move(b), &x, opt.tolerance, opt.max_iterations, progress);
    } else if (bnorm > 0.0) {
      // Basic scheme with the reference k0 = (kmin + kmax) / 2: x <- -P[(k - k0)(E + x)] / k0;
      // the residual is the gradient part of the flux of the new iterate.
      const double k0 = 0.5 * (kmin + kmax);
      std::fill(x.begin(), x.end(), 0.0);
      for (int it = 1; it <= opt.max_iterations; ++it) {
        for (size_t i = 0; i < 3 * n; ++i) e[i] = mean[i] + x[i];
        for (int a = 0; a < 3; ++a) {
          for (size_t i = 0; i < n; ++i) tmp[a * n + i] = (conductivity[i] - k0) * e[a * n + i];
        }
        project.apply(tmp.data(), x.data());
        for (double& v : x) v /= -k0;
        for (size_t i = 0; i < 3 * n; ++i) e[i] = mean[i] + x[i];
        times_k(e, &tmp);
        project.apply(tmp.data(), r.data());
        out.iterations = it;
        out.residual = std::sqrt(dot(r, r)) / bnorm;
        if (!progress(it, out.residual)) {
          out.stopped = true;
          break;
        }
        if (out.residual < opt.tolerance) break;
      }
    } else {
      std::fill(x.begin(), x.end(), 0.0);
    }
    if (out.stopped) throw Cancelled();
    res.iterations[load] = out.iterations;
    res.residual[load] = out.residual;
    if (bnorm > 0.0 && !(out.residual < opt.tolerance)) res.converged = false;
    // Mean flux of k (E + x).
    for (int a = 0; a < 3; ++a) {
      double q = 0.0;
      for (size_t i = 0; i < n; ++i) q += conductivity[i] * (mean[a * n + i] + x[a * n + i]);
      res.tensor(a, load) = q / static_cast<double>(n);
    }
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace rvegen
