#include "rvegen/homogenize/conductivity.hpp"

#include <fftw3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <mutex>
#include <string>
#include <thread>

#include "rvegen/model/errors.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {

namespace {

using cplx = std::complex<double>;

// A frequency whose |k|^2 is below this (relative to the largest) has no gradient: the
// projection is zero there (the mean, and the rotated scheme's checkerboard modes).
constexpr double kNoGradient = 1e-14;

// FFTW's planner is not thread-safe, and its threads are set up once per process.
std::mutex& planner_mutex() {
  static std::mutex m;
  return m;
}

// One real buffer of n values, fftw-aligned.
struct RealField {
  explicit RealField(size_t n) : data(fftw_alloc_real(n)), size(n) {}
  ~RealField() { fftw_free(data); }
  RealField(const RealField&) = delete;
  RealField& operator=(const RealField&) = delete;
  double* data;
  size_t size;
};

// The projection onto discrete gradient fields, applied to 3-component voxel fields.
class GradientProjection {
 public:
  GradientProjection(const std::array<int, 3>& dims, const Vec3& box, GradientScheme scheme,
                     int threads)
      : nx_(dims[0]),
        ny_(dims[1]),
        nz_(dims[2]),
        n_(static_cast<size_t>(nx_) * ny_ * nz_),
        nc_(static_cast<size_t>(nx_ / 2 + 1) * ny_ * nz_) {
    for (int a = 0; a < 3; ++a) spectrum_[a] = fftw_alloc_complex(nc_);
    scratch_ = fftw_alloc_real(n_);
    {
      std::lock_guard<std::mutex> lock(planner_mutex());
      static const bool threads_ready = fftw_init_threads() != 0;
      if (threads_ready) {
        const unsigned all = std::max(1u, std::thread::hardware_concurrency());
        fftw_plan_with_nthreads(threads > 0 ? threads : static_cast<int>(all));
      }
      // x fastest: FFTW's last (fastest) dimension is x.
      forward_ = fftw_plan_dft_r2c_3d(nz_, ny_, nx_, scratch_, spectrum_[0], FFTW_ESTIMATE);
      inverse_ = fftw_plan_dft_c2r_3d(nz_, ny_, nx_, spectrum_[0], scratch_, FFTW_ESTIMATE);
    }
    multiplier_.resize(3 * nc_);
    double largest = 0.0;
    const double pi = M_PI;
    const int n[3] = {nx_, ny_, nz_};
    for (int kz = 0; kz < nz_; ++kz) {
      for (int ky = 0; ky < ny_; ++ky) {
        for (int kx = 0; kx <= nx_ / 2; ++kx) {
          const int idx[3] = {kx, ky, kz};
          cplx k[3];
          for (int a = 0; a < 3; ++a) {
            const int xi = idx[a] <= n[a] / 2 ? idx[a] : idx[a] - n[a];
            const double h = box[a] / n[a];
            if (scheme == GradientScheme::kMoulinecSuquet) {
              const bool nyquist = n[a] % 2 == 0 && 2 * std::abs(xi) == n[a];
              k[a] = nyquist ? cplx(0.0) : cplx(0.0, 2.0 * pi * xi / box[a]);
            } else {
              const double t = 2.0 * pi * xi / n[a];
              k[a] = (std::polar(1.0, t) - 1.0) / h;
            }
          }
          if (scheme == GradientScheme::kRotated) {
            cplx avg[3];
            for (int a = 0; a < 3; ++a) {
              const int xi = idx[a] <= n[a] / 2 ? idx[a] : idx[a] - n[a];
              avg[a] = 0.5 * (1.0 + std::polar(1.0, 2.0 * pi * xi / n[a]));
            }
            k[0] *= avg[1] * avg[2];
            k[1] *= avg[0] * avg[2];
            k[2] *= avg[0] * avg[1];
          }
          const size_t at = (static_cast<size_t>(kz) * ny_ + ky) * (nx_ / 2 + 1) + kx;
          for (int a = 0; a < 3; ++a) multiplier_[3 * at + a] = k[a];
          largest = std::max(largest, std::norm(k[0]) + std::norm(k[1]) + std::norm(k[2]));
        }
      }
    }
    // Normalize each multiplier so the projection is k k^H / |k|^2 (zero where k vanishes).
    for (size_t at = 0; at < nc_; ++at) {
      cplx* k = &multiplier_[3 * at];
      const double norm2 = std::norm(k[0]) + std::norm(k[1]) + std::norm(k[2]);
      const double s = norm2 > kNoGradient * largest ? 1.0 / std::sqrt(norm2) : 0.0;
      for (int a = 0; a < 3; ++a) k[a] *= s;
    }
  }
  ~GradientProjection() {
    {
      std::lock_guard<std::mutex> lock(planner_mutex());
      fftw_destroy_plan(forward_);
      fftw_destroy_plan(inverse_);
    }
    for (auto* s : spectrum_) fftw_free(s);
    fftw_free(scratch_);
  }
  GradientProjection(const GradientProjection&) = delete;
  GradientProjection& operator=(const GradientProjection&) = delete;

  size_t size() const { return n_; }

  /// out = P[in]; in and out hold 3 components of n values each (component-major); may alias.
  void apply(const double* in, double* out) {
    for (int a = 0; a < 3; ++a) {
      std::copy(in + a * n_, in + (a + 1) * n_, scratch_);
      fftw_execute_dft_r2c(forward_, scratch_, spectrum_[a]);
    }
    const double inv_n = 1.0 / static_cast<double>(n_);
    for (size_t at = 0; at < nc_; ++at) {
      const cplx* k = &multiplier_[3 * at];
      cplx f[3];
      for (int a = 0; a < 3; ++a) f[a] = cplx(spectrum_[a][at][0], spectrum_[a][at][1]);
      const cplx s =
          (std::conj(k[0]) * f[0] + std::conj(k[1]) * f[1] + std::conj(k[2]) * f[2]) * inv_n;
      for (int a = 0; a < 3; ++a) {
        const cplx v = k[a] * s;
        spectrum_[a][at][0] = v.real();
        spectrum_[a][at][1] = v.imag();
      }
    }
    for (int a = 0; a < 3; ++a) {
      fftw_execute_dft_c2r(inverse_, spectrum_[a], scratch_);
      std::copy(scratch_, scratch_ + n_, out + a * n_);
    }
  }

 private:
  int nx_, ny_, nz_;
  size_t n_, nc_;
  fftw_complex* spectrum_[3];
  double* scratch_;
  fftw_plan forward_, inverse_;
  std::vector<cplx> multiplier_;  // unit k(xi) / |k(xi)| per frequency, 3 per frequency
};

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0.0;
  for (size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}

}  // namespace

ConductivityResult effective_conductivity(const std::array<int, 3>& dims, const Vec3& box_size,
                                          const std::vector<double>& conductivity,
                                          const ConductivityOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 1) throw InputError("homogenization: voxels per axis must be >= 1");
    if (!(box_size[a] > 0.0)) throw InputError("homogenization: box size must be positive");
  }
  const size_t n = static_cast<size_t>(dims[0]) * dims[1] * dims[2];
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
  std::vector<double> e(3 * n), x(3 * n), r(3 * n), p(3 * n), ap(3 * n), tmp(3 * n);
  // k times a 3-component field.
  auto times_k = [&](const std::vector<double>& f, std::vector<double>* out) {
    for (int a = 0; a < 3; ++a) {
      for (size_t i = 0; i < n; ++i) (*out)[a * n + i] = conductivity[i] * f[a * n + i];
    }
  };
  auto report = [&](int load, int it, double rel) {
    if (opt.progress && !opt.progress(load, it, rel)) throw Cancelled();
  };
  for (int load = 0; load < 3; ++load) {
    // Mean gradient E = unit vector along `load`; unknown: the fluctuation x (a gradient field
    // with zero mean); equilibrium: P[k (E + x)] = 0.
    std::vector<double> mean(3 * n, 0.0);
    std::fill(mean.begin() + load * n, mean.begin() + (load + 1) * n, 1.0);
    std::fill(x.begin(), x.end(), 0.0);
    times_k(mean, &tmp);
    project.apply(tmp.data(), r.data());
    for (double& v : r) v = -v;  // b = -P[k E]
    const double bnorm = std::sqrt(dot(r, r));
    int it = 0;
    double rel = 0.0;
    if (bnorm > 0.0) {
      if (opt.solver == LinearSolver::kConjugateGradient) {
        p = r;
        double rr = dot(r, r);
        for (it = 1; it <= opt.max_iterations; ++it) {
          times_k(p, &tmp);
          project.apply(tmp.data(), ap.data());
          const double pap = dot(p, ap);
          if (!(pap > 0.0)) break;  // converged to round-off
          const double alpha = rr / pap;
          for (size_t i = 0; i < 3 * n; ++i) {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
          }
          const double rr_new = dot(r, r);
          rel = std::sqrt(rr_new) / bnorm;
          report(load, it, rel);
          if (rel < opt.tolerance) break;
          const double beta = rr_new / rr;
          rr = rr_new;
          for (size_t i = 0; i < 3 * n; ++i) p[i] = r[i] + beta * p[i];
        }
      } else {
        // Basic scheme with the reference k0 = (kmin + kmax) / 2: x <- -P[(k - k0)(E + x)] / k0.
        const double k0 = 0.5 * (kmin + kmax);
        for (it = 1; it <= opt.max_iterations; ++it) {
          for (size_t i = 0; i < 3 * n; ++i) e[i] = mean[i] + x[i];
          for (int a = 0; a < 3; ++a) {
            for (size_t i = 0; i < n; ++i) tmp[a * n + i] = (conductivity[i] - k0) * e[a * n + i];
          }
          project.apply(tmp.data(), x.data());
          for (double& v : x) v /= -k0;
          // Residual: the gradient part of the flux of the new iterate.
          for (size_t i = 0; i < 3 * n; ++i) e[i] = mean[i] + x[i];
          times_k(e, &tmp);
          project.apply(tmp.data(), r.data());
          rel = std::sqrt(dot(r, r)) / bnorm;
          report(load, it, rel);
          if (rel < opt.tolerance) break;
        }
      }
    }
    res.iterations[load] = std::min(it, opt.max_iterations);
    res.residual[load] = rel;
    if (bnorm > 0.0 && !(rel < opt.tolerance)) res.converged = false;
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
