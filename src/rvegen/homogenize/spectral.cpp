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
#include <atomic>
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

// sum_i a[i] b[i] over [lo, hi) in four interleaved partial sums (a fixed order; four chains of
// additions instead of one, which would wait on each addition's latency).
inline double lane_dot(const double* a, const double* b, size_t lo, size_t hi) {
  double l[4] = {0.0, 0.0, 0.0, 0.0};
  size_t i = lo;
  for (; i + 4 <= hi; i += 4) {
    for (int k = 0; k < 4; ++k) l[k] += a[i + k] * b[i + k];
  }
  for (; i < hi; ++i) l[0] += a[i] * b[i];
  return (l[0] + l[1]) + (l[2] + l[3]);
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

namespace {

std::atomic<bool> wide_allowed{true};

}  // namespace

bool wide_passes() {
#if defined(__x86_64__) || defined(__i386__)
  static const bool supported = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return supported && wide_allowed.load(std::memory_order_relaxed);
#else
  return false;
#endif
}

bool allow_wide_passes(bool allowed) {
  return wide_allowed.exchange(allowed);
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
  parallel_blocks(
      n, [&](size_t lo, size_t hi) { part[lo / kBlock] = lane_dot(a.data(), b.data(), lo, hi); });
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
  // same bytes, on every run. In place: the real values in padded rows of the callers'
  // buffers, transformed where they lie. The buffer here is for planning only (FFTW_ESTIMATE
  // does not touch it).
  if (!comm_.set) {
    n_ = total_;
    nc_ = alloc_ = static_cast<size_t>(hx) * dims[1] * dims[2];
    auto* spec = fftw_alloc_complex(alloc_);
    auto* real = reinterpret_cast<double*>(spec);
    forward_ = fftw_plan_dft_r2c_3d(dims[2], dims[1], dims[0], real, spec, FFTW_ESTIMATE);
    inverse_ = fftw_plan_dft_c2r_3d(dims[2], dims[1], dims[0], spec, real, FFTW_ESTIMATE);
    // The same transforms split in halves (Grid::sweep, Grid::middle): the 2D transforms of
    // one z plane, run on the workers a plane at a time, and those along z of a block of
    // neighbouring columns of frequencies, where they lie.
    const int plane[2] = {dims[1], dims[0]}, complex_rows[2] = {dims[1], hx},
              real_rows[2] = {dims[1], 2 * hx};
    const int plane_values = dims[1] * hx;
    const size_t nz = static_cast<size_t>(dims[2]), per_plane = static_cast<size_t>(plane_values);
    // The workers run these plans one thread each. Planes start 64-byte aligned, as the first
    // one that is planned, only when a plane's bytes are a multiple of 64.
    fftw_plan_with_nthreads(1);
    const unsigned align = per_plane % 4 == 0 ? 0u : static_cast<unsigned>(FFTW_UNALIGNED);
    plane_forward_ = fftw_plan_many_dft_r2c(2, plane, 1, real, real_rows, 1, 2 * plane_values, spec,
                                            complex_rows, 1, plane_values, FFTW_ESTIMATE | align);
    plane_inverse_ = fftw_plan_many_dft_c2r(2, plane, 1, spec, complex_rows, 1, plane_values, real,
                                            real_rows, 1, 2 * plane_values, FFTW_ESTIMATE | align);
    // Columns per block: a block of six components stays within about 512 KiB (in L2), a
    // power of two from 4 to 64 fixed by the grid alone. The z transforms run where the
    // columns lie (a plane apart).
    columns_ = 4;
    while (columns_ < 64 && 2 * columns_ * nz * 6 * sizeof(cplx) <= (size_t(512) << 10)) {
      columns_ *= 2;
    }
    columns_ = std::min(columns_, per_plane);
    const size_t widths[2] = {columns_, per_plane % columns_};
    // Blocks start 64-byte aligned, as the first one that is planned, when columns_ is a
    // multiple of four.
    const unsigned column_align = columns_ % 4 == 0 ? 0u : static_cast<unsigned>(FFTW_UNALIGNED);
    bool planned = plane_forward_ && plane_inverse_;
    for (int w = 0; w < 2; ++w) {
      if (widths[w] == 0) continue;
      const int howmany = static_cast<int>(widths[w]), n = dims[2];
      const int step = static_cast<int>(per_plane);
      for (int sign : {0, 1}) {
        column_plan_[w][sign] = fftw_plan_many_dft(
            1, &n, howmany, spec, nullptr, step, 1, spec, nullptr, step, 1,
            sign == 0 ? FFTW_FORWARD : FFTW_BACKWARD, FFTW_ESTIMATE | column_align);
        planned = planned && column_plan_[w][sign];
      }
    }
    fftw_free(spec);
    prepare_fftw(threads, false);
    if (!planned) throw std::runtime_error("homogenization: FFTW made no plan");
  } else {
    // Planes of z here; after the forward transform, planes of y (FFTW_MPI_TRANSPOSED_OUT
    // saves the transpose back; the inverse takes that layout in).
    ptrdiff_t n0 = 0, z0 = 0, n1 = 0, y0 = 0;
    alloc_ = mpi_layout(dims, comm_, &n0, &z0, &n1, &y0);
    n_ = static_cast<size_t>(n0) * dims[1] * dims[0];
    nc_ = static_cast<size_t>(n1) * dims[2] * hx;
    mid_ = 2;
    slow_ = 1;
    slow_start_ = static_cast<size_t>(y0);
    auto* spec = fftw_alloc_complex(alloc_);
    auto* real = reinterpret_cast<double*>(spec);
    const MPI_Comm c = mpi_comm(comm_);
    forward_ = fftw_mpi_plan_dft_r2c_3d(dims[2], dims[1], dims[0], real, spec, c,
                                        FFTW_ESTIMATE | FFTW_MPI_TRANSPOSED_OUT);
    inverse_ = fftw_mpi_plan_dft_c2r_3d(dims[2], dims[1], dims[0], spec, real, c,
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
      if (scheme == GradientScheme::kMoulinecSuquet) {
        // The continuous gradient i 2 pi xi / L; Nyquist frequencies (even N) carry none.
        const bool nyquist = na % 2 == 0 && 2 * std::abs(xi) == na;
        diff_[a][idx] = nyquist ? 0.0 : 2.0 * M_PI * xi / box[a];
        avg_[a][idx] = 1.0;
      } else {
        // Willot's rotated scheme: the difference (exp(i t) - 1) N / L along a, the averages
        // (1 + exp(i t)) / 2 along the other axes, t = 2 pi xi / N; that is
        // 2 i sin(t / 2) exp(i t / 2) N / L and cos(t / 2) exp(i t / 2). The phases
        // exp(i t / 2) of the three axes make the common factor of the three components.
        const double half = M_PI * xi / na;
        diff_[a][idx] = 2.0 * std::sin(half) * (na / box[a]);
        avg_[a][idx] = std::cos(half);
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
        const double k[3] = {diff_[0][q[0]] * (avg_[1][q[1]] * avg_[2][q[2]]),
                             diff_[1][q[1]] * (avg_[0][q[0]] * avg_[2][q[2]]),
                             diff_[2][q[2]] * (avg_[0][q[0]] * avg_[1][q[1]])};
        inv_norm_[at] = k[0] * k[0] + k[1] * k[1] + k[2] * k[2];
        largest = std::max(largest, inv_norm_[at]);
      }
    }
  }
  if (comm_.set) {
    MPI_Allreduce(MPI_IN_PLACE, &largest, 1, MPI_DOUBLE, MPI_MAX, mpi_comm(comm_));
  }
  for (double& v : inv_norm_) v = v > kNoGradient * largest ? 1.0 / std::sqrt(v) : 0.0;
  if (!comm_.set) {
    std::vector<double> visited(nc_);
    const size_t nz = static_cast<size_t>(dims[2]), per_plane = nc_ / nz;
    size_t to = 0;
    for (size_t first = 0; first < per_plane; first += columns_) {
      const size_t width = std::min(columns_, per_plane - first);
      for (size_t z = 0; z < nz; ++z) {
        const double* from = inv_norm_.data() + z * per_plane + first;
        std::copy(from, from + width, visited.data() + to);
        to += width;
      }
    }
    inv_norm_.swap(visited);
  }
}

Grid::~Grid() {
  {
    std::lock_guard<std::mutex> lock(planner_mutex());
    fftw_destroy_plan(static_cast<fftw_plan>(forward_));
    fftw_destroy_plan(static_cast<fftw_plan>(inverse_));
    for (void* p : {plane_forward_, plane_inverse_, column_plan_[0][0], column_plan_[0][1],
                    column_plan_[1][0], column_plan_[1][1]}) {
      if (p) fftw_destroy_plan(static_cast<fftw_plan>(p));
    }
  }
}

double Grid::sum(double local) const {
  sum_over_ranks(&local, 1, comm_);
  return local;
}

double Grid::dot(const std::vector<double>& a, const std::vector<double>& b) const {
  return sum(spectral::dot(a, b));
}

void Grid::forward_in_place(Spectrum& buffer) {
  auto* b = reinterpret_cast<fftw_complex*>(buffer.data());
  auto* real = reinterpret_cast<double*>(buffer.data());
  if (comm_.set) {
    fftw_mpi_execute_dft_r2c(static_cast<fftw_plan>(forward_), real, b);
  } else {
    fftw_execute_dft_r2c(static_cast<fftw_plan>(forward_), real, b);
  }
}

void Grid::inverse_in_place(Spectrum& buffer) {
  auto* b = reinterpret_cast<fftw_complex*>(buffer.data());
  auto* real = reinterpret_cast<double*>(buffer.data());
  if (comm_.set) {
    fftw_mpi_execute_dft_c2r(static_cast<fftw_plan>(inverse_), b, real);
  } else {
    fftw_execute_dft_c2r(static_cast<fftw_plan>(inverse_), b, real);
  }
}

void Grid::load(const double* fields, std::vector<Spectrum>& spectra) const {
  const size_t nx = row(), stride = row_stride();
  for (size_t c = 0; c < spectra.size(); ++c) {
    const double* field = fields + c * n_;
    double* real = reinterpret_cast<double*>(spectra[c].data());
    for (size_t r = 0; r < rows(); ++r) {
      std::copy(field + r * nx, field + (r + 1) * nx, real + r * stride);
    }
  }
}

void Grid::unload(const std::vector<Spectrum>& spectra, double* fields) const {
  const double inv_n = 1.0 / static_cast<double>(total_);
  const size_t nx = row(), stride = row_stride();
  for (size_t c = 0; c < spectra.size(); ++c) {
    double* field = fields + c * n_;
    const double* real = reinterpret_cast<const double*>(spectra[c].data());
    for (size_t r = 0; r < rows(); ++r) {
      for (size_t i = 0; i < nx; ++i) field[r * nx + i] = real[r * stride + i] * inv_n;
    }
  }
}

std::vector<double> Grid::sweep(std::vector<Spectrum>& spectra, bool finish, bool start, int slots,
                                const RowPass& pass) {
  if (spectra.size() > 6) throw std::logic_error("homogenization: at most six fields");
  const size_t ny = static_cast<size_t>(dims_[1]), planes = rows() / ny;
  const size_t per = std::max<size_t>(1, kBlock / (row() * ny));
  const size_t blocks = (planes + per - 1) / per, k = static_cast<size_t>(std::max(slots, 0));
  const size_t plane_values = ny * (row() / 2 + 1);
  if (comm_.set && finish) {
    for (auto& s : spectra) inverse_in_place(s);
  }
  std::vector<double> part(blocks * k, 0.0);
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, blocks, 1),
      [&](const tbb::blocked_range<size_t>& r) {
        for (size_t b = r.begin(); b != r.end(); ++b) {
          for (size_t z = b * per; z < std::min(planes, (b + 1) * per); ++z) {
            if (!comm_.set && finish) {
              for (auto& s : spectra) {
                auto* at = reinterpret_cast<fftw_complex*>(s.data() + z * plane_values);
                fftw_execute_dft_c2r(static_cast<fftw_plan>(plane_inverse_), at,
                                     reinterpret_cast<double*>(at));
              }
            }
            if (pass) pass(z * ny, (z + 1) * ny, part.data() + b * k);
            if (!comm_.set && start) {
              for (auto& s : spectra) {
                auto* at = reinterpret_cast<fftw_complex*>(s.data() + z * plane_values);
                fftw_execute_dft_r2c(static_cast<fftw_plan>(plane_forward_),
                                     reinterpret_cast<double*>(at), at);
              }
            }
          }
        }
      },
      tbb::simple_partitioner());
  if (comm_.set && start) {
    for (auto& s : spectra) forward_in_place(s);
  }
  return totals(part, k);
}

std::vector<double> Grid::frequency_pass(std::vector<Spectrum>& spectra, bool forward, bool inverse,
                                         int slots, const FrequencyPass& f) {
  const size_t d = spectra.size(), k = static_cast<size_t>(std::max(slots, 0));
  if (d > 6) throw std::logic_error("homogenization: at most six fields");
  std::vector<double> part;
  if (comm_.set) {
    part.assign(((nc_ + kBlock - 1) / kBlock) * k, 0.0);
    parallel_blocks(nc_, [&](size_t lo, size_t hi) {
      double* v[6];
      for (size_t c = 0; c < d; ++c) v[c] = reinterpret_cast<double*>(spectra[c].data() + lo);
      f(lo, hi - lo, lo, v, inv_norm_.data() + lo, part.data() + (lo / kBlock) * k);
    });
  } else {
    const size_t nz = static_cast<size_t>(dims_[2]), per_plane = nc_ / nz;
    const size_t blocks = (per_plane + columns_ - 1) / columns_;
    part.assign(blocks * k, 0.0);
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, blocks, 1),
        [&](const tbb::blocked_range<size_t>& r) {
          for (size_t b = r.begin(); b != r.end(); ++b) {
            const size_t first = b * columns_, width = std::min(columns_, per_plane - first);
            const int w = width == columns_ ? 0 : 1;
            if (forward) {
              for (size_t c = 0; c < d; ++c) {
                auto* col = reinterpret_cast<fftw_complex*>(spectra[c].data() + first);
                fftw_execute_dft(static_cast<fftw_plan>(column_plan_[w][0]), col, col);
              }
            }
            double* v[6];
            const double* inv_norm = inv_norm_.data() + first * nz;  // the blocks before are full
            for (size_t z = 0; z < nz; ++z) {
              const size_t at = z * per_plane + first;
              for (size_t c = 0; c < d; ++c) {
                v[c] = reinterpret_cast<double*>(spectra[c].data() + at);
              }
              f(at, width, first * nz + z * width, v, inv_norm + z * width, part.data() + b * k);
            }
            if (inverse) {
              for (size_t c = 0; c < d; ++c) {
                auto* col = reinterpret_cast<fftw_complex*>(spectra[c].data() + first);
                fftw_execute_dft(static_cast<fftw_plan>(column_plan_[w][1]), col, col);
              }
            }
          }
        },
        tbb::simple_partitioner());
  }
  return totals(part, k);
}

std::vector<double> Grid::totals(const std::vector<double>& part, size_t slots) const {
  std::vector<double> total(slots, 0.0);
  for (size_t b = 0; slots > 0 && b < part.size() / slots; ++b) {
    for (size_t j = 0; j < slots; ++j) total[j] += part[b * slots + j];
  }
  sum_over_ranks(total.data(), static_cast<int>(slots), comm_);
  return total;
}

void Grid::middle(std::vector<Spectrum>& spectra, const Projector& project) {
  frequency_pass(spectra, true, true, 0,
                 [&](size_t at, size_t width, size_t, double* const* v, const double* inv_norm,
                     double*) { project(at, at + width, v, inv_norm); });
}

void Grid::convolve(std::vector<Spectrum>& spectra, const Projector& project) {
  sweep(spectra, false, true, 0, nullptr);
  middle(spectra, project);
  sweep(spectra, true, false, 0, nullptr);
}

void* aligned_bytes(size_t bytes) {
  void* p = fftw_malloc(std::max<size_t>(bytes, 1));
  if (!p) throw std::bad_alloc();
  return p;
}

void free_aligned(void* p) {
  fftw_free(p);
}

// A relative residual above this is no step of a positive definite solve (it can grow by at
// most the square root of the operator's condition, and well before that CG's has gone down):
// the iteration has broken down.
constexpr double kResidualGrowth = 1e4;

CgOutcome conjugate_gradients_galerkin(Grid& grid, std::vector<Spectrum>& spectra,
                                       const GalerkinOperator& op, const double* load,
                                       GalerkinFields& fields, std::vector<double>* x,
                                       std::vector<double>* mean_flux, double tolerance,
                                       int max_iterations,
                                       const std::function<bool(int, double)>& progress) {
  CgOutcome out;
  const int d = op.components;
  const size_t dd = static_cast<size_t>(d);
  const size_t n = grid.size(), nx = grid.row(), stride = grid.row_stride();
  const size_t potentials = static_cast<size_t>(op.potentials) * grid.frequencies();
  for (Spectrum* f : {&fields.r, &fields.s}) f->resize(potentials);
  if (x) fields.p.resize(potentials), fields.x.resize(potentials);
  mean_flux->assign(d, 0.0);
  std::vector<double*> buffer(d);
  for (int c = 0; c < d; ++c) buffer[c] = reinterpret_cast<double*>(spectra[c].data());
  const double inv_n = 1.0 / static_cast<double>(grid.voxels());
  // The sweeps' pass: C times the field in the buffers' rows, in place (after writing E there
  // when `fill`).
  auto flux = [&](bool fill) -> Grid::RowPass {
    return [&, fill](size_t first, size_t last, double* sums) {
      double* v[6];
      for (size_t row = first; row < last; ++row) {
        for (size_t c = 0; c < dd; ++c) {
          v[c] = buffer[c] + row * stride;
          if (fill) std::fill(v[c], v[c] + nx, load[c]);
        }
        op.flux(v, row * nx, (row + 1) * nx, sums);
      }
    };
  };
  GalerkinStep step;
  step.scale = inv_n;  // the buffers then hold the fields themselves after the inverse transforms
  step.with_x = x != nullptr;
  step.fields = &fields;
  const Grid::FrequencyPass at_frequencies = op.step(step);
  // The right-hand side b = -P C E is the first residual.
  grid.sweep(spectra, false, true, d + 1, flux(true));
  double gamma = grid.frequency_pass(spectra, true, true, 1, at_frequencies)[0] * inv_n;
  const double bnorm = std::sqrt(gamma);
  std::vector<double> mean_direction(dd, 0.0);  // the mean of C p
  if (bnorm > 0.0) {
    double gamma_before = 0.0, alpha_before = 0.0;
    out.residual = 1.0;
    for (int it = 1; it <= max_iterations; ++it) {
      // r . A r = r . C r (r lies in the range of the orthogonal projection), and the sums of
      // C r; the transforms of C r start behind the sweep.
      const std::vector<double> sums = grid.sweep(spectra, true, true, d + 1, flux(false));
      if (!(sums[0] > 0.0)) {
        // r . A r not positive: round-off once the residual is below the tolerance (nothing
        // left to reduce), otherwise the operator is not positive definite in floating point.
        if (!std::isfinite(sums[0])) {
          out.breakdown = "the curvature r . A r was not finite at iteration " + std::to_string(it);
        } else if (out.residual >= tolerance) {
          char what[160];
          std::snprintf(what, sizeof what,
                        "the curvature r . A r was not positive (%.2e) at iteration %d, with the "
                        "relative residual at %.2e",
                        sums[0], it, out.residual);
          out.breakdown = what;
        }
        break;
      }
      double beta = it > 1 ? gamma / gamma_before : 0.0;
      double denominator = it > 1 ? sums[0] - beta * gamma / alpha_before : sums[0];
      if (!(denominator > 0.0)) {
        // The recurrence's p . A p lost to round-off where r . A r is positive: the direction
        // starts again from the residual (a steepest-descent step).
        beta = 0.0;
        denominator = sums[0];
        ++out.restarts;
      }
      const double alpha = gamma / denominator;
      for (size_t c = 0; c < dd; ++c) {
        mean_direction[c] = sums[1 + c] * inv_n + beta * mean_direction[c];
        (*mean_flux)[c] += alpha * mean_direction[c];
      }
      step.mode = GalerkinStep::kIterate;
      step.alpha = alpha;
      step.beta = beta;
      const double gamma_next =
          grid.frequency_pass(spectra, true, true, 1, at_frequencies)[0] * inv_n;
      out.iterations = it;
      out.residual = std::sqrt(gamma_next) / bnorm;
      if (!std::isfinite(out.residual) || out.residual > kResidualGrowth) {
        char what[160];
        std::snprintf(what, sizeof what,
                      "the residual grew to %.2e times its start at iteration %d", out.residual,
                      it);
        out.breakdown = std::isfinite(out.residual)
                            ? std::string(what)
                            : "the residual was not finite at iteration " + std::to_string(it);
        break;
      }
      // A stop asked on any rank stops them all (they would wait on each other otherwise).
      if (grid.sum(progress && !progress(it, out.residual) ? 1.0 : 0.0) > 0.0) {
        out.stopped = true;
        return out;
      }
      if (out.residual < tolerance) break;
      gamma_before = gamma;
      alpha_before = alpha;
      gamma = gamma_next;
    }
  }
  if (out.breakdown.empty() && out.iterations >= max_iterations && out.residual > 1.0) {
    // Positive definite in exact arithmetic, the energy of the error never grows; a residual
    // that ends above its start after every iteration allowed is round-off's.
    char what[160];
    std::snprintf(what, sizeof what,
                  "the residual ended at %.2e times its start after %d iterations", out.residual,
                  out.iterations);
    out.breakdown = what;
  }
  if (x) {
    x->resize(dd * n);
    if (bnorm > 0.0) {
      // x's spectrum into the buffers and back to voxels (unload divides by voxels()).
      step.mode = GalerkinStep::kField;
      step.scale = 1.0;
      grid.frequency_pass(spectra, false, true, 1, at_frequencies);
      grid.sweep(spectra, true, false, 0, nullptr);
      grid.unload(spectra, x->data());
    } else {
      std::fill(x->begin(), x->end(), 0.0);
    }
  }
  return out;
}

}  // namespace spectral
}  // namespace rvegen
