#include "rvegen/homogenize/spectral.hpp"

// MPI's C interface only (Open MPI and MPICH would otherwise pull in their C++ bindings).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <fftw3-mpi.h>
#include <fftw3.h>
#include <mpi.h>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "rvegen/model/errors.hpp"

namespace rvegen {

namespace {

MPI_Comm mpi_comm(const Communicator& comm) {
  return MPI_Comm_f2c(comm.handle);
}

}  // namespace

int rank_of(const Communicator& comm) {
  int r = 0;
  if (comm.set) MPI_Comm_rank(mpi_comm(comm), &r);
  return r;
}

int ranks_of(const Communicator& comm) {
  int n = 1;
  if (comm.set) MPI_Comm_size(mpi_comm(comm), &n);
  return n;
}

void sum_over_ranks(double* values, int count, const Communicator& comm) {
  if (comm.set && count > 0) {
    MPI_Allreduce(MPI_IN_PLACE, values, count, MPI_DOUBLE, MPI_SUM, mpi_comm(comm));
  }
}

double max_over_ranks(double value, const Communicator& comm) {
  if (comm.set) MPI_Allreduce(MPI_IN_PLACE, &value, 1, MPI_DOUBLE, MPI_MAX, mpi_comm(comm));
  return value;
}

namespace spectral {

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

// FFTW's threads, once per process, and its MPI interface when asked (after the threads, as
// FFTW requires); the caller holds the planner's lock.
void prepare_fftw(int threads, bool mpi) {
  static const bool threads_ready = fftw_init_threads() != 0;
  if (threads_ready) {
    // All cores, or as many as a tbb::global_control allows (rvegen --threads, ranks sharing
    // a machine).
    const size_t all = std::max<size_t>(
        1, tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    fftw_plan_with_nthreads(threads > 0 ? threads : static_cast<int>(all));
  }
  if (mpi) {
    static const bool mpi_ready = (fftw_mpi_init(), true);
    (void)mpi_ready;
  }
}

// A communicator of one rank needs no MPI transform.
Communicator distributed(const Communicator& comm) {
  return ranks_of(comm) > 1 ? comm : Communicator();
}

// FFTW's slabs of a grid of dims: real planes along z, then spectra along y (transposed);
// returns the complex values a spectrum's buffer needs.
size_t mpi_layout(const std::array<int, 3>& dims, const Communicator& comm, ptrdiff_t* n0,
                  ptrdiff_t* z0, ptrdiff_t* n1, ptrdiff_t* y0) {
  const ptrdiff_t alloc = fftw_mpi_local_size_3d_transposed(dims[2], dims[1], dims[0] / 2 + 1,
                                                            mpi_comm(comm), n0, z0, n1, y0);
  return static_cast<size_t>(std::max<ptrdiff_t>(alloc, 1));
}

}  // namespace

std::array<int, 2> fft_slab(const std::array<int, 3>& dims, const Communicator& comm) {
  const Communicator c = distributed(comm);
  if (!c.set) return {0, dims[2]};
  ptrdiff_t n0 = 0, z0 = 0, n1 = 0, y0 = 0;
  {
    std::lock_guard<std::mutex> lock(planner_mutex());
    prepare_fftw(0, true);
    mpi_layout(dims, c, &n0, &z0, &n1, &y0);
  }
  return {static_cast<int>(z0), static_cast<int>(z0 + n0)};
}

size_t slab_voxels(const std::array<int, 3>& dims, const Communicator& comm) {
  const std::array<int, 2> z = fft_slab(dims, comm);
  return static_cast<size_t>(dims[0]) * dims[1] * (z[1] - z[0]);
}

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

Grid::Grid(const std::array<int, 3>& dims, const Vec3& box, GradientScheme scheme, int threads,
           const Communicator& comm)
    : total_(static_cast<size_t>(dims[0]) * dims[1] * dims[2]), comm_(distributed(comm)) {
  const int hx = dims[0] / 2 + 1;
  std::lock_guard<std::mutex> lock(planner_mutex());
  prepare_fftw(threads, comm_.set);
  // x fastest: FFTW's last (fastest) dimension is x. FFTW_ESTIMATE: the same plan, hence the
  // same bytes, on every run. The spectrum is for planning only (FFTW_ESTIMATE does not touch
  // the arrays): the transforms run on the callers' spectra.
  if (!comm_.set) {
    n_ = total_;
    nc_ = alloc_ = static_cast<size_t>(hx) * dims[1] * dims[2];
    slab_ = {0, dims[2]};
    real_ = field_ = fftw_alloc_real(n_);
    auto* spec = fftw_alloc_complex(alloc_);
    forward_ = fftw_plan_dft_r2c_3d(dims[2], dims[1], dims[0], real_, spec, FFTW_ESTIMATE);
    inverse_ = fftw_plan_dft_c2r_3d(dims[2], dims[1], dims[0], spec, real_, FFTW_ESTIMATE);
    fftw_free(spec);
  } else {
    // Planes of z here; after the forward transform, planes of y (FFTW_MPI_TRANSPOSED_OUT
    // saves the transpose back; the inverse takes that layout in).
    ptrdiff_t n0 = 0, z0 = 0, n1 = 0, y0 = 0;
    alloc_ = mpi_layout(dims, comm_, &n0, &z0, &n1, &y0);
    n_ = static_cast<size_t>(n0) * dims[1] * dims[0];
    nc_ = static_cast<size_t>(n1) * dims[2] * hx;
    slab_ = {static_cast<int>(z0), static_cast<int>(z0 + n0)};
    mid_ = 2;
    slow_ = 1;
    slow_start_ = static_cast<size_t>(y0);
    real_ = fftw_alloc_real(2 * alloc_);
    field_ = fftw_alloc_real(std::max<size_t>(n_, 1));
    auto* spec = fftw_alloc_complex(alloc_);
    const MPI_Comm c = mpi_comm(comm_);
    forward_ = fftw_mpi_plan_dft_r2c_3d(dims[2], dims[1], dims[0], real_, spec, c,
                                        FFTW_ESTIMATE | FFTW_MPI_TRANSPOSED_OUT);
    inverse_ = fftw_mpi_plan_dft_c2r_3d(dims[2], dims[1], dims[0], spec, real_, c,
                                        FFTW_ESTIMATE | FFTW_MPI_TRANSPOSED_IN);
    fftw_free(spec);
  }
  if (!forward_ || !inverse_) throw std::runtime_error("homogenization: FFTW made no plan");
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
  // |k|^2 per stored frequency (in the stored layout); the largest over the whole grid sets the
  // floor below which none is kept.
  inv_norm_.assign(nc_, 0.0);
  double largest = 0.0;
  const size_t slow_count = nc_ / (static_cast<size_t>(hx) * dims[mid_]);
  size_t at = 0;
  size_t q[3];
  for (size_t s = 0; s < slow_count; ++s) {
    q[slow_] = s + slow_start_;
    for (q[mid_] = 0; q[mid_] < static_cast<size_t>(dims[mid_]); ++q[mid_]) {
      for (q[0] = 0; q[0] < static_cast<size_t>(hx); ++q[0], ++at) {
        const cplx k[3] = {diff_[0][q[0]] * (avg_[1][q[1]] * avg_[2][q[2]]),
                           diff_[1][q[1]] * (avg_[0][q[0]] * avg_[2][q[2]]),
                           diff_[2][q[2]] * (avg_[0][q[0]] * avg_[1][q[1]])};
        inv_norm_[at] = std::norm(k[0]) + std::norm(k[1]) + std::norm(k[2]);
        largest = std::max(largest, inv_norm_[at]);
      }
    }
  }
  if (comm_.set) {
    MPI_Allreduce(MPI_IN_PLACE, &largest, 1, MPI_DOUBLE, MPI_MAX, mpi_comm(comm_));
  }
  for (double& v : inv_norm_) v = v > kNoGradient * largest ? 1.0 / std::sqrt(v) : 0.0;
}

Grid::~Grid() {
  {
    std::lock_guard<std::mutex> lock(planner_mutex());
    fftw_destroy_plan(static_cast<fftw_plan>(forward_));
    fftw_destroy_plan(static_cast<fftw_plan>(inverse_));
  }
  if (field_ != real_) fftw_free(field_);
  fftw_free(real_);
}

double Grid::sum(double local) const {
  sum_over_ranks(&local, 1, comm_);
  return local;
}

double Grid::dot(const std::vector<double>& a, const std::vector<double>& b) const {
  return sum(spectral::dot(a, b));
}

void Grid::pad_from(const double* field) {
  const size_t nx = static_cast<size_t>(dims_[0]), row = 2 * (nx / 2 + 1);
  for (size_t r = 0, rows = n_ / std::max<size_t>(nx, 1); r < rows; ++r) {
    std::copy(field + r * nx, field + (r + 1) * nx, real_ + r * row);
  }
}

void Grid::unpad_to(double* field, double scale) const {
  const size_t nx = static_cast<size_t>(dims_[0]), row = 2 * (nx / 2 + 1);
  for (size_t r = 0, rows = n_ / std::max<size_t>(nx, 1); r < rows; ++r) {
    for (size_t i = 0; i < nx; ++i) field[r * nx + i] = real_[r * row + i] * scale;
  }
}

namespace {

void execute_forward(void* plan, double* in, cplx* out, bool mpi) {
  auto* o = reinterpret_cast<fftw_complex*>(out);
  if (mpi) {
    fftw_mpi_execute_dft_r2c(static_cast<fftw_plan>(plan), in, o);
  } else {
    fftw_execute_dft_r2c(static_cast<fftw_plan>(plan), in, o);
  }
}

void execute_inverse(void* plan, cplx* in, double* out, bool mpi) {
  auto* i = reinterpret_cast<fftw_complex*>(in);
  if (mpi) {
    fftw_mpi_execute_dft_c2r(static_cast<fftw_plan>(plan), i, out);
  } else {
    fftw_execute_dft_c2r(static_cast<fftw_plan>(plan), i, out);
  }
}

}  // namespace

void Grid::forward(const double* field, cplx* out) {
  if (comm_.set) {
    pad_from(field);
  } else {
    std::copy(field, field + n_, real_);
  }
  execute_forward(forward_, real_, out, comm_.set);
}

void Grid::forward_scratch(cplx* out) {
  if (comm_.set) pad_from(field_);
  execute_forward(forward_, real_, out, comm_.set);
}

void Grid::inverse_to_scratch(cplx* in) {
  execute_inverse(inverse_, in, real_, comm_.set);
  if (comm_.set) unpad_to(field_, 1.0);
}

void Grid::inverse(cplx* in, double* field) {
  execute_inverse(inverse_, in, real_, comm_.set);
  const double inv_n = 1.0 / static_cast<double>(total_);
  if (comm_.set) {
    unpad_to(field, inv_n);
  } else {
    for (size_t i = 0; i < n_; ++i) field[i] = real_[i] * inv_n;
  }
}

CgOutcome conjugate_gradients_galerkin(Grid& grid, std::vector<std::vector<cplx>>& spectra,
                                       const GalerkinOperator& op, std::vector<double> b,
                                       std::vector<double>* x, double tolerance, int max_iterations,
                                       const std::function<bool(int, double)>& progress) {
  CgOutcome out;
  std::fill(x->begin(), x->end(), 0.0);
  const double bnorm = std::sqrt(grid.dot(b, b));
  if (!(bnorm > 0.0)) return out;
  const size_t n = grid.size(), blocks = (n + kBlock - 1) / kBlock;
  const int d = op.components;
  std::vector<double> r = std::move(b), p = r;
  std::vector<double> part(blocks);
  double* scratch = grid.scratch();
  const double inv_n = 1.0 / static_cast<double>(grid.voxels());
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
    pap = grid.sum(pap);
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
    rr_new = grid.sum(rr_new);
    out.iterations = it;
    out.residual = std::sqrt(rr_new) / bnorm;
    // A stop asked on any rank stops them all (they would wait on each other otherwise).
    if (grid.sum(progress && !progress(it, out.residual) ? 1.0 : 0.0) > 0.0) {
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

}  // namespace spectral
}  // namespace rvegen
