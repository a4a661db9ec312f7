#include "rvegen/homogenize/spectral.hpp"

#include <fftw3.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <thread>

#include "rvegen/model/errors.hpp"

namespace rvegen::spectral {

namespace {

// A frequency whose |k|^2 is below this (relative to the largest) has no gradient.
constexpr double kNoGradient = 1e-14;

// FFTW's planner is not thread-safe, and its threads are set up once per process.
std::mutex& planner_mutex() {
  static std::mutex m;
  return m;
}

// Block of the parallel loops and of the fixed-order sums.
constexpr size_t kBlock = size_t(1) << 14;

}  // namespace

size_t checked_voxels(const std::array<int, 3>& dims, const Vec3& box) {
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 1) throw InputError("homogenization: voxels per axis must be >= 1");
    if (!(box[a] > 0.0)) throw InputError("homogenization: box size must be positive");
  }
  return static_cast<size_t>(dims[0]) * dims[1] * dims[2];
}

void parallel_blocks(size_t n, const std::function<void(size_t, size_t)>& f) {
  const size_t blocks = (n + kBlock - 1) / kBlock;
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, blocks, 1),
      [&](const tbb::blocked_range<size_t>& r) {
        for (size_t b = r.begin(); b != r.end(); ++b) {
          f(b * kBlock, std::min(n, (b + 1) * kBlock));
        }
      },
      tbb::simple_partitioner());
}

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  const size_t n = a.size(), blocks = (n + kBlock - 1) / kBlock;
  std::vector<double> part(blocks, 0.0);
  parallel_blocks(n, [&](size_t lo, size_t hi) {
    double s = 0.0;
    for (size_t i = lo; i < hi; ++i) s += a[i] * b[i];
    part[lo / kBlock] = s;
  });
  double s = 0.0;
  for (double v : part) s += v;
  return s;
}

Grid::Grid(const std::array<int, 3>& dims, const Vec3& box, GradientScheme scheme, int threads)
    : n_(static_cast<size_t>(dims[0]) * dims[1] * dims[2]),
      nc_(static_cast<size_t>(dims[0] / 2 + 1) * dims[1] * dims[2]) {
  real_ = fftw_alloc_real(n_);
  // A spectrum to plan with only (FFTW_ESTIMATE does not touch the arrays): the transforms run
  // on the callers' spectra.
  cplx* spectrum = reinterpret_cast<cplx*>(fftw_alloc_complex(nc_));
  {
    std::lock_guard<std::mutex> lock(planner_mutex());
    static const bool threads_ready = fftw_init_threads() != 0;
    if (threads_ready) {
      const unsigned all = std::max(1u, std::thread::hardware_concurrency());
      fftw_plan_with_nthreads(threads > 0 ? threads : static_cast<int>(all));
    }
    // x fastest: FFTW's last (fastest) dimension is x. FFTW_ESTIMATE: the same plan, hence the
    // same bytes, on every run.
    auto* spec = reinterpret_cast<fftw_complex*>(spectrum);
    forward_ = fftw_plan_dft_r2c_3d(dims[2], dims[1], dims[0], real_, spec, FFTW_ESTIMATE);
    inverse_ = fftw_plan_dft_c2r_3d(dims[2], dims[1], dims[0], spec, real_, FFTW_ESTIMATE);
  }
  fftw_free(spectrum);
  dims_ = dims;
  for (int a = 0; a < 3; ++a) {
    const int na = dims[a];
    diff_[a].resize(na);
    avg_[a].resize(na);
    for (int idx = 0; idx < na; ++idx) {
      const int xi = idx <= na / 2 ? idx : idx - na;
      const double t = 2.0 * M_PI * xi / na;
      if (scheme == GradientScheme::kMoulinecSuquet) {
        // The continuous gradient; Nyquist frequencies (even N) carry no gradient.
        const bool nyquist = na % 2 == 0 && 2 * std::abs(xi) == na;
        diff_[a][idx] = nyquist ? cplx(0.0) : cplx(0.0, 2.0 * M_PI * xi / box[a]);
        avg_[a][idx] = 1.0;
      } else {
        // Willot's rotated scheme: a difference along a, averages along the other axes.
        diff_[a][idx] = (std::polar(1.0, t) - 1.0) * (na / box[a]);
        avg_[a][idx] = 0.5 * (1.0 + std::polar(1.0, t));
      }
    }
  }
  // |k|^2 per stored frequency; the largest sets the floor below which none is kept.
  inv_norm_.resize(nc_);
  double largest = 0.0;
  const int hx = dims[0] / 2 + 1;
  size_t at = 0;
  for (int kz = 0; kz < dims[2]; ++kz) {
    for (int ky = 0; ky < dims[1]; ++ky) {
      for (int kx = 0; kx < hx; ++kx, ++at) {
        const cplx k[3] = {diff_[0][kx] * (avg_[1][ky] * avg_[2][kz]),
                           diff_[1][ky] * (avg_[0][kx] * avg_[2][kz]),
                           diff_[2][kz] * (avg_[0][kx] * avg_[1][ky])};
        inv_norm_[at] = std::norm(k[0]) + std::norm(k[1]) + std::norm(k[2]);
        largest = std::max(largest, inv_norm_[at]);
      }
    }
  }
  for (double& v : inv_norm_) v = v > kNoGradient * largest ? 1.0 / std::sqrt(v) : 0.0;
}

Grid::~Grid() {
  {
    std::lock_guard<std::mutex> lock(planner_mutex());
    fftw_destroy_plan(static_cast<fftw_plan>(forward_));
    fftw_destroy_plan(static_cast<fftw_plan>(inverse_));
  }
  fftw_free(real_);
}

void Grid::forward(const double* field, cplx* out) {
  std::copy(field, field + n_, real_);
  fftw_execute_dft_r2c(static_cast<fftw_plan>(forward_), real_,
                       reinterpret_cast<fftw_complex*>(out));
}

void Grid::forward_scratch(cplx* out) {
  fftw_execute_dft_r2c(static_cast<fftw_plan>(forward_), real_,
                       reinterpret_cast<fftw_complex*>(out));
}

void Grid::inverse_to_scratch(cplx* in) {
  fftw_execute_dft_c2r(static_cast<fftw_plan>(inverse_), reinterpret_cast<fftw_complex*>(in),
                       real_);
}

void Grid::inverse(cplx* in, double* field) {
  fftw_execute_dft_c2r(static_cast<fftw_plan>(inverse_), reinterpret_cast<fftw_complex*>(in),
                       real_);
  const double inv_n = 1.0 / static_cast<double>(n_);
  for (size_t i = 0; i < n_; ++i) field[i] = real_[i] * inv_n;
}

CgOutcome conjugate_gradients_galerkin(Grid& grid, std::vector<std::vector<cplx>>& spectra,
                                       const GalerkinOperator& op, std::vector<double> b,
                                       std::vector<double>* x, double tolerance, int max_iterations,
                                       const std::function<bool(int, double)>& progress) {
  CgOutcome out;
  std::fill(x->begin(), x->end(), 0.0);
  const double bnorm = std::sqrt(dot(b, b));
  if (!(bnorm > 0.0)) return out;
  const size_t n = grid.size(), blocks = (n + kBlock - 1) / kBlock;
  const int d = op.components;
  std::vector<double> r = std::move(b), p = r;
  std::vector<double> part(blocks);
  double* scratch = grid.scratch();
  const double inv_n = 1.0 / static_cast<double>(n);
  // Sums of per-block parts in block order: the same bits whatever the number of threads.
  auto total = [&] {
    double s = 0.0;
    for (double v : part) s += v;
    return s;
  };
  double rr = bnorm * bnorm;
  out.residual = 1.0;
  for (int it = 1; it <= max_iterations; ++it) {
    // p . C p while the flux is formed, component by component, each transformed in place.
    double pap = 0.0;
    for (int c = 0; c < d; ++c) {
      const double* pc = p.data() + c * n;
      parallel_blocks(n, [&](size_t lo, size_t hi) {
        op.flux(c, p.data(), scratch, lo, hi);
        double s = 0.0;
        for (size_t i = lo; i < hi; ++i) s += pc[i] * scratch[i];
        part[lo / kBlock] = s;
      });
      pap += total();
      grid.forward_scratch(spectra[c].data());
    }
    if (!(pap > 0.0)) break;  // nothing left to reduce (round-off)
    parallel_blocks(grid.frequencies(), op.project);
    const double alpha = rr / pap;
    double rr_new = 0.0;
    for (int c = 0; c < d; ++c) {
      grid.inverse_to_scratch(spectra[c].data());
      double* xc = x->data() + c * n;
      double* rc = r.data() + c * n;
      const double* pc = p.data() + c * n;
      const double a = alpha * inv_n;
      parallel_blocks(n, [&](size_t lo, size_t hi) {
        double s = 0.0;
        for (size_t i = lo; i < hi; ++i) {
          xc[i] += alpha * pc[i];
          rc[i] -= a * scratch[i];
          s += rc[i] * rc[i];
        }
        part[lo / kBlock] = s;
      });
      rr_new += total();
    }
    out.iterations = it;
    out.residual = std::sqrt(rr_new) / bnorm;
    if (progress && !progress(it, out.residual)) {
      out.stopped = true;
      return out;
    }
    if (out.residual < tolerance) break;
    const double beta = rr_new / rr;
    rr = rr_new;
    parallel_blocks(d * n, [&](size_t lo, size_t hi) {
      for (size_t i = lo; i < hi; ++i) p[i] = r[i] + beta * p[i];
    });
  }
  return out;
}

}  // namespace rvegen::spectral
