// What the FFT solvers share: the periodic voxel grid in Fourier space (FFTW plans, the
// gradient multiplier of the chosen discretization) and the conjugate-gradient solver of the
// Galerkin form (Zeman et al. 2010; Vondrejc, Zeman, Marek 2014). The grid may be whole in this
// process or split in z slabs over the ranks of an MPI communicator (FFTW's MPI interface); the
// solvers are the same code either way, with their sums taken over the ranks.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstring>
#include <functional>
#include <string>
#include <type_traits>
#include <vector>

#include "rvegen/geometry/shapes.hpp"

namespace rvegen {

enum class GradientScheme { kRotated, kMoulinecSuquet };

/// An MPI communicator handed through interfaces that do not include mpi.h: the handle
/// MPI_Comm_c2f gives (MPI_Comm_f2c turns it back). Unset: this process alone, no MPI call.
struct Communicator {
  bool set = false;
  int handle = 0;
  static Communicator from_fortran(int handle) { return {true, handle}; }
};
/// This process's rank in the communicator and the number of ranks (0 and 1 when unset).
int rank_of(const Communicator& comm);
int ranks_of(const Communicator& comm);
/// Sums `count` values over the ranks, in place (nothing when unset); the largest of a value
/// over the ranks.
void sum_over_ranks(double* values, int count, const Communicator& comm);
double max_over_ranks(double value, const Communicator& comm);

namespace spectral {

using cplx = std::complex<double>;

/// A frequency's real and imaginary parts as one SIMD value: the projections' coefficients are
/// real, so both parts go through the same arithmetic, lane by lane (GCC and Clang vectors).
using Pair = double __attribute__((vector_size(16)));
inline Pair load_pair(const double* p) {
  Pair v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store_pair(double* p, Pair v) {
  std::memcpy(p, &v, sizeof v);
}
/// Two neighbouring frequencies' real and imaginary parts as one value (four lanes), for the
/// passes built for AVX2 (chosen at run time, see wide_passes). The helpers below and the
/// kernels are always inlined, so that the four-lane code is only ever made inside functions
/// built for it.
using Quad = double __attribute__((vector_size(32)));
// For the functions (and lambdas) that take Pairs or Quads.
#define RVEGEN_LANES inline __attribute__((always_inline))
#define RVEGEN_LANES_LAMBDA __attribute__((always_inline))
/// A Pair or a Quad at p (one frequency, or two side by side), and back.
template <class V>
RVEGEN_LANES V load_lanes(const double* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V>
RVEGEN_LANES void store_lanes(double* p, V v) {
  std::memcpy(p, &v, sizeof v);
}
/// One complex value of one frequency (Pair), or of two whose values lie `apart` doubles apart
/// (Quad), and back.
template <class V>
RVEGEN_LANES V load_apart(const double* p, size_t apart) {
  if constexpr (sizeof(V) == sizeof(Pair)) {
    (void)apart;
    return load_pair(p);
  } else {
    return __builtin_shufflevector(load_pair(p), load_pair(p + apart), 0, 1, 2, 3);
  }
}
template <class V>
RVEGEN_LANES void store_apart(double* p, size_t apart, V v) {
  if constexpr (sizeof(V) == sizeof(Pair)) {
    (void)apart;
    store_pair(p, v);
  } else {
    store_pair(p, __builtin_shufflevector(v, v, 0, 1));
    store_pair(p + apart, __builtin_shufflevector(v, v, 2, 3));
  }
}
/// Whether the solver's passes over the frequencies take two at a time and its fluxes four
/// voxels at a time, in four-lane vectors (AVX2 and FMA, when this processor has them and they
/// are allowed); allow_wide_passes(false) keeps them to one frequency and two voxels (the same
/// solve to rounding; for tests and comparisons) and returns what was allowed before.
bool wide_passes();
bool allow_wide_passes(bool allowed);

/// The planes [lo, hi) along z that FFTW's MPI transforms give this rank of `comm` for a grid of
/// dims voxels (the whole [0, dims[2]) when the communicator is unset). A rank may get none.
std::array<int, 2> fft_slab(const std::array<int, 3>& dims, const Communicator& comm);
/// Voxels of that slab.
size_t slab_voxels(const std::array<int, 3>& dims, const Communicator& comm);

/// Memory aligned as FFTW's planner wants it (the transforms run on the callers' buffers).
void* aligned_bytes(size_t bytes);
void free_aligned(void* p);
template <class T>
struct AlignedAllocator {
  using value_type = T;
  AlignedAllocator() = default;
  template <class U>
  AlignedAllocator(const AlignedAllocator<U>&) {}
  T* allocate(size_t n) { return static_cast<T*>(aligned_bytes(n * sizeof(T))); }
  void deallocate(T* p, size_t) { free_aligned(p); }
  bool operator==(const AlignedAllocator&) const { return true; }
  bool operator!=(const AlignedAllocator&) const { return false; }
};
/// A field's buffer: its spectrum after a transform, and before one its real values in padded
/// rows (see Grid::padded).
using Spectrum = std::vector<cplx, AlignedAllocator<cplx>>;

/// The grid of dims voxels over a box, with in-place r2c/c2r FFTs of one field at a time and,
/// per stored frequency, the direction of the scheme's gradient multiplier (zero where k
/// vanishes: the mean, and the rotated scheme's checkerboard modes). Real fields are x
/// fastest; in a Spectrum buffer (spectrum_size() values) the real values lie in padded rows
/// of row_stride() doubles, voxel i at padded(i), which FFTW transforms where they lie.
///
/// With a communicator, this process holds the z planes fft_slab() gives it (real fields of
/// size() values, x fastest) and, after a transform, the spectra of a slab of y frequencies
/// (FFTW's transposed layout: kx fastest, then kz, then ky); sums and means are over the ranks.
class Grid {
 public:
  Grid(const std::array<int, 3>& dims, const Vec3& box, GradientScheme scheme, int threads,
       const Communicator& comm = {});
  ~Grid();
  Grid(const Grid&) = delete;
  Grid& operator=(const Grid&) = delete;

  /// Real values per field held here, and the frequencies held here (complex values per
  /// transformed field); spectrum_size() is what a spectrum's buffer needs (FFTW's MPI
  /// transforms may need more room than the frequencies).
  size_t size() const { return n_; }
  size_t frequencies() const { return nc_; }
  size_t spectrum_size() const { return alloc_; }
  /// Voxels of the whole grid (over every rank).
  size_t voxels() const { return total_; }
  const Communicator& communicator() const { return comm_; }
  /// A sum of per-rank values over the ranks, and sum_i a[i] b[i] over the whole grid (the
  /// same bits whatever the number of threads).
  double sum(double local) const;
  double dot(const std::vector<double>& a, const std::vector<double>& b) const;
  /// f(at, xi) for the stored frequencies at in [lo, hi), xi the real unit direction there (3
  /// values), given `inv_norm`, the frequencies' 1 / |k| in that order (a Projector's). Both
  /// schemes' multipliers are k = c xi with |c| = 1 and c the same for the three components (i for
  /// Moulinec-Suquet; i exp(i (t_x + t_y + t_z) / 2), t the phase of a frequency along each axis,
  /// for the rotated scheme), so the projections k k^H / |k|^2 and their elastic counterpart, in
  /// which c meets its conjugate, take xi alone: real multipliers of the complex spectra. xi is
  /// formed from per-axis factors and the stored 1 / |k| as it is needed (a stored table would cost
  /// 24 bytes a frequency).
  template <class F>
  void for_each_unit_direction(size_t lo, size_t hi, const double* inv_norm, F&& f) const {
    // Indices along x, then the middle and the slowest axis of the stored layout.
    const size_t hx = static_cast<size_t>(dims_[0] / 2 + 1);
    const size_t nm = static_cast<size_t>(dims_[mid_]);
    size_t q[3];
    q[0] = lo % hx;
    q[mid_] = (lo / hx) % nm;
    q[slow_] = lo / hx / nm + slow_start_;
    size_t &kx = q[0], &km = q[mid_], &ks = q[slow_];
    // Along a row of kx the factors of y and z are fixed: xi = (diff_x a, avg_x b, avg_x c).
    double a = avg_[1][q[1]] * avg_[2][q[2]], b = diff_[1][q[1]] * avg_[2][q[2]],
           c = diff_[2][q[2]] * avg_[1][q[1]];
    for (size_t at = lo; at < hi; ++at) {
      const double s = inv_norm[at - lo];
      const double xi[3] = {diff_[0][kx] * a * s, avg_[0][kx] * b * s, avg_[0][kx] * c * s};
      f(at, xi);
      if (++kx == hx) {
        kx = 0;
        if (++km == nm) km = 0, ++ks;
        if (at + 1 < hi && ks < static_cast<size_t>(dims_[slow_])) {
          a = avg_[1][q[1]] * avg_[2][q[2]];
          b = diff_[1][q[1]] * avg_[2][q[2]];
          c = diff_[2][q[2]] * avg_[1][q[1]];
        }
      }
    }
  }
  /// Voxels per row (along x), rows held here, and doubles per padded row.
  size_t row() const { return static_cast<size_t>(dims_[0]); }
  size_t rows() const { return n_ / row(); }
  size_t row_stride() const { return 2 * (row() / 2 + 1); }
  /// Where voxel i's value lies in a buffer's padded rows.
  size_t padded(size_t i) const { return i + (i / row()) * (row_stride() - row()); }
  /// The spectrum of the real values in `buffer`'s padded rows, in place.
  void forward_in_place(Spectrum& buffer);
  /// voxels() times the real field of the spectrum in `buffer`, in padded rows, in place.
  void inverse_in_place(Spectrum& buffer);
  /// Component-major fields (spectra.size() blocks of size() values) into the buffers' padded
  /// rows, and back out divided by voxels() (so unload after load, convolve with the identity
  /// gives the fields back).
  void load(const double* fields, std::vector<Spectrum>& spectra) const;
  void unload(const std::vector<Spectrum>& spectra, double* fields) const;
  /// A projection at the frequencies [lo, hi) held here, whose values lie at v[c] for component
  /// c (frequency lo's real and imaginary parts at v[c][0] and v[c][1], then the next's), and
  /// their 1 / |k| at inv_norm (0 where k carries no gradient), in the same order.
  using Projector =
      std::function<void(size_t lo, size_t hi, double* const* v, const double* inv_norm)>;
  /// A pass over the rows [first, last) held here, adding to `sums` (slots of its own; no
  /// slot, and a null `sums`, when the sweep asks for none).
  using RowPass = std::function<void(size_t first, size_t last, double* sums)>;
  /// The transforms of the fields in the buffers (one each, at most six) split in two halves
  /// around the projection, so that the passes over the voxels meet the values in cache. On
  /// one process the first half is the 2D transforms of the z planes, the middle the transforms
  /// along z with the projection between them, done a few columns of frequencies at a time
  /// while they are in cache, and the second half the planes' inverse 2D transforms. With a
  /// communicator FFTW's 3D transforms are the halves and the middle is the projection alone.
  /// The same bits whatever the number of threads.
  ///
  /// sweep(): over blocks of whole z planes (fixed by the grid), plane by plane: when `finish`,
  /// the second half of the transforms before it (the buffers' padded rows then hold voxels()
  /// times the projected fields); `pass` over the plane's rows (when given); when `start`, the
  /// first half of the next transforms of what the buffers' padded rows hold. Returns the
  /// slots' totals, added in block order and then over the ranks.
  std::vector<double> sweep(std::vector<Spectrum>& spectra, bool finish, bool start, int slots,
                            const RowPass& pass);
  /// A pass over the frequencies held here, a run of neighbouring ones at a time:
  /// f(at, width, seq, v, inv_norm, sums) for the frequencies [at, at + width), whose values lie
  /// at v[c] (component c; frequency at's real and imaginary parts at v[c][0] and v[c][1], then
  /// the next's), their 1 / |k| at inv_norm, adding to `sums` (slots of its own; null when the
  /// pass asks for none). seq is the
  /// place of frequency at in the order the pass visits them (the same for every pass over the
  /// grid): arrays kept in that order are read in sequence. On one process, with `forward` the
  /// transforms along z before f and with `inverse` those after it, a block of columns at a
  /// time while in cache; with a communicator the sweeps make the whole transforms and the two
  /// flags change nothing. Returns the slots' totals, added in block order and then over the
  /// ranks (the same bits whatever the number of threads).
  using FrequencyPass = std::function<void(size_t at, size_t width, size_t seq, double* const* v,
                                           const double* inv_norm, double* sums)>;
  std::vector<double> frequency_pass(std::vector<Spectrum>& spectra, bool forward, bool inverse,
                                     int slots, const FrequencyPass& f);
  /// The middle: `project` at every frequency held here, between the transforms along z.
  void middle(std::vector<Spectrum>& spectra, const Projector& project);
  /// All of it: voxels() times the projected fields, in the buffers' padded rows.
  void convolve(std::vector<Spectrum>& spectra, const Projector& project);

 private:
  /// The slots' totals of per-block sums (`slots` a block, in block order), then over the
  /// ranks.
  std::vector<double> totals(const std::vector<double>& part, size_t slots) const;

  size_t n_, nc_, alloc_, total_;
  Communicator comm_;
  // The stored layout's middle and slowest axes, and the first index along the slowest.
  int mid_ = 1, slow_ = 2;
  size_t slow_start_ = 0;
  void* forward_;
  void* inverse_;
  // One process: the 2D transforms of one z plane, and the z transforms of a block of
  // columns_ columns where they lie (and of the last, narrower block).
  void* plane_forward_ = nullptr;
  void* plane_inverse_ = nullptr;
  size_t columns_ = 0;
  void* column_plan_[2][2] = {{nullptr, nullptr}, {nullptr, nullptr}};
  std::array<int, 3> dims_;
  // Per axis and index along it, the real parts of the multiplier k = c xi (see
  // for_each_unit_direction): the scheme's difference factor, and the average that the other
  // axes' components take (rotated scheme; 1 for Moulinec-Suquet); per frequency 1 / |k| (0
  // where k carries no gradient), on one process in the order middle() visits the frequencies
  // (block by block of columns, z by z: read in sequence, where the stored order would jump a
  // plane between runs of a few values).
  std::array<std::vector<double>, 3> diff_, avg_;
  std::vector<double> inv_norm_;
};

/// What the conjugate-gradient solver keeps, in Fourier space. A field in the range of the
/// projection P is, at each stored frequency, Kernel::expand of Kernel::kPotentials complex
/// values (the displacement of a compatible strain, the potential of a gradient), fewer than
/// its components: the residual r, s = P C p (p the direction), and the direction and the
/// solution x when x is asked for (each kPotentials values a frequency, in the order
/// Grid::frequency_pass visits them).
struct GalerkinFields {
  Spectrum r, p, s, x;
};
/// One pass of the solver over the frequencies (Projection::galerkin_step): with the spectra
/// of C times a field in the buffers, kStart sets r = -P C E (the right-hand side; p, s and x to
/// 0) and kIterate makes, with w = P C r, s = w + beta s, r -= alpha s and, when with_x,
/// p = r + beta p and x += alpha p; both write scale times r's components into the buffers and add
/// Parseval's sum of |r|^2 (voxels() times the sum over the grid) to the pass's slot. kField
/// writes scale times x's components.
struct GalerkinStep {
  enum Mode { kStart, kIterate, kField };
  Mode mode = kStart;
  double alpha = 0.0, beta = 0.0, scale = 1.0;
  bool with_x = false;
  GalerkinFields* fields = nullptr;
};

/// A grid with one buffer per component and the projection made of Kernel::project(v, i, xi):
/// P on one frequency whose real and imaginary parts lie at v[c] + i and v[c] + i + 1 (c <
/// Kernel::kComponents), xi its real unit direction (Grid::for_each_unit_direction). Applied to
/// component-major fields (apply), or handed to the solver (projector()); the kernel is inlined
/// into the loop over the frequencies.
template <class Kernel>
class Projection {
 public:
  Projection(const std::array<int, 3>& dims, const Vec3& box, GradientScheme scheme, int threads,
             const Communicator& comm)
      : grid_(dims, box, scheme, threads, comm), spectra_(Kernel::kComponents) {
    for (auto& s : spectra_) s.resize(grid_.spectrum_size());
  }
  /// P on component-major fields (Kernel::kComponents blocks of size() values; in and out may
  /// be the same).
  void apply(const double* in, double* out) {
    grid_.load(in, spectra_);
    grid_.convolve(spectra_, projector());
    grid_.unload(spectra_, out);
  }
  Grid::Projector projector() const {
    return [this](size_t lo, size_t hi, double* const* v, const double* inv_norm) {
      grid_.for_each_unit_direction(lo, hi, inv_norm, [&](size_t at, const double* xi) {
        Kernel::project(v, 2 * (at - lo), xi);
      });
    };
  }
  /// The solver's pass at the frequencies for `step` (read when the pass runs): Kernel::reduce
  /// gives the potentials of P v, Kernel::expand a field's components from its potentials, and
  /// Kernel::norm the squares of those components (lane by lane). Each takes one frequency in a
  /// Pair, or two neighbouring ones in a Quad (wide_passes()).
  Grid::FrequencyPass galerkin_step(const GalerkinStep& step) const {
    return [this, &step](size_t lo, size_t width, size_t seq, double* const* v,
                         const double* inv_norm, double* sums) {
      const GalerkinStep st = step;
      // The mode, whether x is kept and the width, fixed for the loop.
      auto go = [&](auto mode, auto with_x) {
        if (wide_passes()) {
          run_wide<decltype(mode)::value, decltype(with_x)::value>(st, lo, width, seq, v, inv_norm,
                                                                   sums);
        } else {
          run<decltype(mode)::value, decltype(with_x)::value>(st, lo, width, seq, v, inv_norm,
                                                              sums);
        }
      };
      using Mode = GalerkinStep::Mode;
      using Field = std::integral_constant<Mode, GalerkinStep::kField>;
      using Start = std::integral_constant<Mode, GalerkinStep::kStart>;
      using Iterate = std::integral_constant<Mode, GalerkinStep::kIterate>;
      if (st.mode == GalerkinStep::kField) {
        go(Field{}, std::false_type{});
      } else if (st.mode == GalerkinStep::kStart) {
        if (st.with_x) {
          go(Start{}, std::true_type{});
        } else {
          go(Start{}, std::false_type{});
        }
      } else if (st.with_x) {
        go(Iterate{}, std::true_type{});
      } else {
        go(Iterate{}, std::false_type{});
      }
    };
  }
  Grid& grid() { return grid_; }
  std::vector<Spectrum>& spectra() { return spectra_; }

 private:
  // Where a pass's values lie: the buffers' components and the solver's fields.
  struct Fields {
    double* comp[Kernel::kComponents];
    double *r = nullptr, *p = nullptr, *s = nullptr, *x = nullptr;
  };
  template <GalerkinStep::Mode kMode, bool kWithX>
  Fields fields_of(const GalerkinStep& st, size_t seq, double* const* v) const {
    constexpr int kp = Kernel::kPotentials;
    auto base = [&](Spectrum& f) { return reinterpret_cast<double*>(f.data()) + 2 * kp * seq; };
    Fields f;
    f.r = base(st.fields->r);
    // The direction only for x: the mean flux follows it through scalars.
    f.p = kWithX && kMode != GalerkinStep::kField ? base(st.fields->p) : nullptr;
    f.s = kMode == GalerkinStep::kField ? nullptr : base(st.fields->s);
    f.x = kWithX || kMode == GalerkinStep::kField ? base(st.fields->x) : nullptr;
    // The components' pointers in registers: the stores could alias v's array as far as the
    // compiler knows.
    for (int c = 0; c < Kernel::kComponents; ++c) f.comp[c] = v[c];
    return f;
  }

  // The pass at frequency j of the block (and j + 1 for a Quad), whose unit directions are xi
  // (lane by lane); the squares of r's components there into squares (0 for kField). (Quads
  // pass by reference: clang refuses a four-lane value returned from a function built without
  // AVX to one built with it, inlined or not.)
  template <class V, GalerkinStep::Mode kMode, bool kWithX, class S>
  RVEGEN_LANES static void step(const GalerkinStep& st, const Fields& f, size_t j, const S* xi,
                                V& squares) {
    constexpr int kp = Kernel::kPotentials;
    constexpr size_t apart = 2 * kp;  // a field's next frequency
    const size_t i = 2 * j, at = apart * j;
    V w[kp];
    if (kMode == GalerkinStep::kField) {
      for (int a = 0; a < kp; ++a) w[a] = load_apart<V>(f.x + at + 2 * a, apart);
      Kernel::expand(w, xi, st.scale, f.comp, i);
      squares = V{};
      return;
    }
    Kernel::reduce(f.comp, i, xi, w);
    // Every value read before any is written (the arrays may alias as far as the compiler
    // knows).
    V ra[kp], pa[kp], sa[kp], xa[kp];
    if (kMode == GalerkinStep::kStart) {
      for (int a = 0; a < kp; ++a) {
        ra[a] = -w[a];
        pa[a] = sa[a] = xa[a] = V{};
      }
    } else {
      const double alpha = st.alpha, beta = st.beta;
      for (int a = 0; a < kp; ++a) {
        ra[a] = load_apart<V>(f.r + at + 2 * a, apart);
        if (kWithX) pa[a] = load_apart<V>(f.p + at + 2 * a, apart);
        sa[a] = load_apart<V>(f.s + at + 2 * a, apart);
        if (kWithX) xa[a] = load_apart<V>(f.x + at + 2 * a, apart);
      }
      for (int a = 0; a < kp; ++a) {
        if (kWithX) pa[a] = ra[a] + beta * pa[a];
        sa[a] = w[a] + beta * sa[a];
        if (kWithX) xa[a] += alpha * pa[a];
        ra[a] -= alpha * sa[a];
      }
    }
    for (int a = 0; a < kp; ++a) {
      store_apart(f.r + at + 2 * a, apart, ra[a]);
      if (kWithX) store_apart(f.p + at + 2 * a, apart, pa[a]);
      store_apart(f.s + at + 2 * a, apart, sa[a]);
      if (kWithX) store_apart(f.x + at + 2 * a, apart, xa[a]);
      w[a] = ra[a];
    }
    Kernel::norm(w, xi, squares);
    Kernel::expand(w, xi, st.scale, f.comp, i);
  }

  // One frequency at a time, in two-lane vectors.
  template <GalerkinStep::Mode kMode, bool kWithX>
  void run(const GalerkinStep& st, size_t lo, size_t width, size_t seq, double* const* v,
           const double* inv_norm, double* sums) const {
    const Fields f = fields_of<kMode, kWithX>(st, seq, v);
    // Each stored frequency stands for itself and its conjugate, except on the kx = 0 plane
    // and (even rows) the kx = N / 2 plane, whose conjugates are themselves or also stored.
    const size_t hx = grid_.row() / 2 + 1, nyquist = grid_.row() % 2 == 0 ? hx - 1 : 0;
    size_t kx = lo % hx;
    Pair twice = {0.0, 0.0}, once = {0.0, 0.0};
    grid_.for_each_unit_direction(lo, lo + width, inv_norm, [&](size_t at, const double* xi) {
      Pair squares;
      step<Pair, kMode, kWithX>(st, f, at - lo, xi, squares);
      if (kx == 0 || kx == nyquist) {
        once += squares;
      } else {
        twice += squares;
      }
      if (++kx == hx) kx = 0;
    });
    sums[0] += 2.0 * (twice[0] + twice[1]) + (once[0] + once[1]);
  }

  // Two frequencies at a time, in four-lane vectors (built for AVX2 and FMA; called only
  // where wide_passes()): the directions and weights of up to 64 frequencies first, then the
  // frequencies in pairs, a last odd one alone.
  template <GalerkinStep::Mode kMode, bool kWithX>
  __attribute__((target("avx2,fma"))) void run_wide(const GalerkinStep& st, size_t lo, size_t width,
                                                    size_t seq, double* const* v,
                                                    const double* inv_norm, double* sums) const {
    const Fields f = fields_of<kMode, kWithX>(st, seq, v);
    const size_t hx = grid_.row() / 2 + 1, nyquist = grid_.row() % 2 == 0 ? hx - 1 : 0;
    size_t kx = lo % hx;
    constexpr size_t kRun = 64;
    double xs[3][kRun], weight[kRun];
    Quad sum2 = {0.0, 0.0, 0.0, 0.0};
    Pair sum1 = {0.0, 0.0};
    for (size_t first = 0; first < width; first += kRun) {
      const size_t run_width = std::min(kRun, width - first);
      size_t j = 0;
      grid_.for_each_unit_direction(lo + first, lo + first + run_width, inv_norm + first,
                                    [&](size_t, const double* xi) {
                                      for (int a = 0; a < 3; ++a) xs[a][j] = xi[a];
                                      weight[j] = kx == 0 || kx == nyquist ? 1.0 : 2.0;
                                      if (++kx == hx) kx = 0;
                                      ++j;
                                    });
      size_t k = 0;
      for (; k + 1 < run_width; k += 2) {
        Quad xi[3];
        for (int a = 0; a < 3; ++a) xi[a] = Quad{xs[a][k], xs[a][k], xs[a][k + 1], xs[a][k + 1]};
        const Quad w = {weight[k], weight[k], weight[k + 1], weight[k + 1]};
        Quad squares;
        step<Quad, kMode, kWithX>(st, f, first + k, xi, squares);
        sum2 += w * squares;
      }
      if (k < run_width) {
        const double xi[3] = {xs[0][k], xs[1][k], xs[2][k]};
        Pair squares;
        step<Pair, kMode, kWithX>(st, f, first + k, xi, squares);
        sum1 += weight[k] * squares;
      }
    }
    sums[0] += (sum2[0] + sum2[1]) + (sum2[2] + sum2[3]) + (sum1[0] + sum1[1]);
  }

  Grid grid_;
  std::vector<Spectrum> spectra_;
};

/// Voxels of a grid of `dims` voxels over a box of `box`; throws InputError when an axis has
/// no voxel or the box no positive size.
size_t checked_voxels(const std::array<int, 3>& dims, const Vec3& box);

/// Runs f(begin, end) over [0, n) in fixed blocks on all cores.
void parallel_blocks(size_t n, const std::function<void(size_t, size_t)>& f);
/// Sum of a[i] b[i] over this process's values, added in fixed blocks and then in block order:
/// the same bits whatever the number of threads.
double dot(const std::vector<double>& a, const std::vector<double>& b);

/// What a conjugate-gradient solve ended with: the iterations and the last relative residual
/// |r| / |b|; `stopped` when `progress(iteration, relative residual)` returned false (the caller
/// decides what that means).
struct CgOutcome {
  int iterations = 0;
  double residual = 0.0;
  bool stopped = false;
  /// How the iteration broke down, "" when it did not: a curvature r . A r that is not positive
  /// while the residual is above the tolerance (the operator is not positive definite in
  /// floating point), or a residual that is not finite. A breakdown is no slow convergence.
  std::string breakdown;
  /// The times the direction was reset to the residual, where the recurrence's curvature came
  /// out not positive while the residual's own was (round-off in the recurrence).
  int restarts = 0;
};
/// The Galerkin operator A = P C of the Lippmann-Schwinger solvers, by parts.
/// `flux(v, lo, hi, sums)` replaces the field at the voxels [lo, hi) of one row (component c of
/// voxel i at v[c][i - lo]) by C times it, in place, and adds v . C v over them to sums[0] and
/// the sum of component c of C v to sums[1 + c], voxel by voxel in order, while the values are
/// in registers. `step` is the physics' pass at the frequencies (Projection::galerkin_step),
/// `potentials` its complex values a frequency.
struct GalerkinOperator {
  int components = 0;
  int potentials = 0;
  std::function<void(double* const*, size_t, size_t, double*)> flux;
  std::function<Grid::FrequencyPass(const GalerkinStep&)> step;
};
namespace detail {

// `simple` on the V's lanes of voxels from j of a run whose row values start at o: t = C e
// written in place, e . t added to vdot and t to vm, lane by lane. e . t is summed as a tree:
// one long chain of additions into vdot would hold each group.
template <class V, int kC, int kNumbers, size_t kRun, class Simple>
RVEGEN_LANES void simple_group(double* const* row, size_t o, size_t j,
                               const double (&num)[kNumbers][kRun], const Simple& simple, V& vdot,
                               V* vm) {
  V e[kC], t[kC], n[kNumbers], et[kC];
  for (int c = 0; c < kC; ++c) e[c] = load_lanes<V>(row[c] + o + j);
  for (int k = 0; k < kNumbers; ++k) n[k] = load_lanes<V>(num[k] + j);
  simple(n, e, t);
  for (int c = 0; c < kC; ++c) {
    store_lanes(row[c] + o + j, t[c]);
    et[c] = e[c] * t[c];
    vm[c] += t[c];
  }
  for (int width_left = kC; width_left > 1; width_left = (width_left + 1) / 2) {
    for (int c = 0; c + (width_left + 1) / 2 < width_left; ++c)
      et[c] += et[c + (width_left + 1) / 2];
  }
  vdot += et[0];
}

// The lanes of vdot and vm added to dot and m.
template <class V, int kC>
RVEGEN_LANES void add_lanes(const V& vdot, const V* vm, double& dot, double* m) {
  for (size_t l = 0; l < sizeof(V) / sizeof(double); l += 2) {
    dot += vdot[l] + vdot[l + 1];
    for (int c = 0; c < kC; ++c) m[c] += vm[c][l] + vm[c][l + 1];
  }
}

// `simple` on the voxels [0, width) of a run from o (width a multiple of 2), V's lanes at a
// time (a last pair of a Quad run as a Pair), the sums added to dot and m.
template <class V, int kC, int kNumbers, size_t kRun, class Simple>
RVEGEN_LANES void simple_run(double* const* row, size_t o, size_t width,
                             const double (&num)[kNumbers][kRun], const Simple& simple, double& dot,
                             double* m) {
  constexpr size_t kLanes = sizeof(V) / sizeof(double);
  V vdot{}, vm[kC];
  for (V& q : vm) q = V{};
  size_t j = 0;
  for (; j + kLanes <= width; j += kLanes) simple_group<V, kC>(row, o, j, num, simple, vdot, vm);
  add_lanes<V, kC>(vdot, vm, dot, m);
  if (j < width) {  // the last two voxels of a Quad run (widths are even)
    Pair pdot{}, pm[kC];
    for (Pair& q : pm) q = Pair{};
    simple_group<Pair, kC>(row, o, j, num, simple, pdot, pm);
    add_lanes<Pair, kC>(pdot, pm, dot, m);
  }
}

// flux_in_runs's runs, V's lanes at a time where the numbers allow.
template <class V, int kC, int kNumbers, class Numbers, class Simple, class General>
RVEGEN_LANES void flux_runs(double* const* v, size_t lo, size_t hi, double* sums,
                            const Numbers& numbers, const Simple& simple, const General& general) {
  constexpr size_t kRun = 64;
  double num[kNumbers][kRun];
  double dot = 0.0, m[kC] = {};
  // The rows' pointers in registers: the stores below could alias v's array as far as the
  // compiler knows.
  double* row[kC];
  for (int c = 0; c < kC; ++c) row[c] = v[c];
  for (size_t first = lo; first < hi; first += kRun) {
    const size_t width = std::min(kRun, hi - first), o = first - lo;
    bool fast = width % 2 == 0;
    for (size_t j = 0; j < width && fast; ++j) {
      double n[kNumbers];
      fast = numbers(first + j, n);
      for (int k = 0; k < kNumbers; ++k) num[k][j] = n[k];
    }
    if (fast) {
      simple_run<V, kC, kNumbers>(row, o, width, num, simple, dot, m);
      continue;
    }
    for (size_t i = first, j = o; i < first + width; ++i, ++j) {
      double e[kC], t[kC];
      for (int c = 0; c < kC; ++c) e[c] = row[c][j];
      general(i, e, t);
      double et = 0.0;
      for (int c = 0; c < kC; ++c) {
        row[c][j] = t[c];
        et += e[c] * t[c];
        m[c] += t[c];
      }
      dot += et;
    }
  }
  sums[0] += dot;
  for (int c = 0; c < kC; ++c) sums[1 + c] += m[c];
}

// The same built for AVX2 and FMA, four voxels at a time.
template <int kC, int kNumbers, class Numbers, class Simple, class General>
__attribute__((target("avx2,fma"))) void flux_runs_wide(double* const* v, size_t lo, size_t hi,
                                                        double* sums, const Numbers& numbers,
                                                        const Simple& simple,
                                                        const General& general) {
  flux_runs<Quad, kC, kNumbers>(v, lo, hi, sums, numbers, simple, general);
}

}  // namespace detail

/// A GalerkinOperator::flux for media whose voxels mostly have tensors of a few numbers each
/// (kNumbers; an isotropic phase's): C times the field at the voxels [lo, hi) of one row
/// (component c of voxel i at v[c][i - lo], kC components), in place, adding v . C v to sums[0]
/// and the sum of component c of C v to sums[1 + c]. Runs of up to 64 voxels: where
/// numbers(i, n) gives true for every voxel of a run of an even width (and writes its numbers
/// at n[0 .. kNumbers)), several voxels at a time by simple(n, e, t) (t = C e, lane by lane;
/// n[k] the voxels' k-th numbers; simple takes Pairs, two voxels, and, where wide_passes(),
/// Quads, four, so it is a generic lambda, always inlined); otherwise voxel by voxel by
/// general(i, e, t). The sums go in lanes, added at the end of each run.
template <int kC, int kNumbers, class Numbers, class Simple, class General>
void flux_in_runs(double* const* v, size_t lo, size_t hi, double* sums, const Numbers& numbers,
                  const Simple& simple, const General& general) {
  if (wide_passes()) {
    detail::flux_runs_wide<kC, kNumbers>(v, lo, hi, sums, numbers, simple, general);
  } else {
    detail::flux_runs<Pair, kC, kNumbers>(v, lo, hi, sums, numbers, simple, general);
  }
}

/// Conjugate gradients for P C x = -P C E (E the uniform field `load`, `components` values; x
/// the fluctuation, in the range of P, from 0), in the variant of Chronopoulos and Gear (1989):
/// the two sums an iteration needs, r . A r and |r|^2, come from one sweep each, so an
/// iteration is one sweep over the voxels (r's field from its transforms, C r in place, r . C r
/// and the sums of C r, the transforms of C r started) and one pass over the frequencies (the
/// transforms along z, then A r = P C r and the updates of r, p, s = A p and x there, |r|^2 by
/// Parseval, r's field formed for the next sweep). r, p, s and x are kept in Fourier space as
/// their potentials (`fields`, sized here; a caller that solves again passes the same and their
/// pages are not mapped again); the voxels hold only the buffers. `mean_flux` (components
/// values) gets the mean of C x, summed from the sweeps' means of C r as they pass; the field x
/// (component-major, `components` blocks of size() values) is formed only when `x` is given.
/// Stops when |r| / |b| < tolerance, after max_iterations, or when progress returns false.
CgOutcome conjugate_gradients_galerkin(Grid& grid, std::vector<Spectrum>& spectra,
                                       const GalerkinOperator& op, const double* load,
                                       GalerkinFields& fields, std::vector<double>* x,
                                       std::vector<double>* mean_flux, double tolerance,
                                       int max_iterations,
                                       const std::function<bool(int, double)>& progress);

}  // namespace spectral
}  // namespace rvegen
