// What the FFT solvers share: the periodic voxel grid in Fourier space (FFTW plans, the
// gradient multiplier of the chosen discretization) and the conjugate-gradient solver of the
// Galerkin form (Zeman et al. 2010; Vondrejc, Zeman, Marek 2014).
#pragma once

#include <array>
#include <cmath>
#include <complex>
#include <functional>
#include <vector>

#include "rvegen/geometry/shapes.hpp"

namespace rvegen {

enum class GradientScheme { kRotated, kMoulinecSuquet };

namespace spectral {

using cplx = std::complex<double>;

/// The grid of dims voxels over a box, with r2c/c2r FFTs of one real field at a time (x
/// fastest) and, per stored frequency, the unit gradient multiplier k(xi) / |k(xi)| of the
/// scheme (zero where k vanishes: the mean, and the rotated scheme's checkerboard modes).
class Grid {
 public:
  Grid(const std::array<int, 3>& dims, const Vec3& box, GradientScheme scheme, int threads);
  ~Grid();
  Grid(const Grid&) = delete;
  Grid& operator=(const Grid&) = delete;

  /// Real values per field, and complex values per transformed field.
  size_t size() const { return n_; }
  size_t frequencies() const { return nc_; }
  /// f(at, k) for the stored frequencies at in [lo, hi), k the unit multiplier there (3
  /// values), formed from per-axis factors and the stored 1 / |k| as it is needed (a stored
  /// table of k would cost 48 bytes a frequency, a sixth of the elasticity solver's memory).
  template <class F>
  void for_each_unit_k(size_t lo, size_t hi, F&& f) const {
    const size_t hx = static_cast<size_t>(dims_[0] / 2 + 1), ny = static_cast<size_t>(dims_[1]);
    size_t kx = lo % hx, ky = (lo / hx) % ny, kz = lo / hx / ny;
    for (size_t at = lo; at < hi; ++at) {
      cplx k[3] = {diff_[0][kx] * (avg_[1][ky] * avg_[2][kz]),
                   diff_[1][ky] * (avg_[0][kx] * avg_[2][kz]),
                   diff_[2][kz] * (avg_[0][kx] * avg_[1][ky])};
      const double s = inv_norm_[at];
      for (cplx& v : k) v *= s;
      f(at, k);
      if (++kx == hx) {
        kx = 0;
        if (++ky == ny) ky = 0, ++kz;
      }
    }
  }
  /// Spectrum of a real field (n values) into `out` (frequencies() values).
  void forward(const double* field, cplx* out);
  /// Real field of a spectrum, divided by n (so inverse(forward(f)) = f); `in` is destroyed.
  void inverse(cplx* in, double* field);
  /// The grid's own real field (size() values): forward_scratch transforms it where it is,
  /// inverse_to_scratch leaves n times the field of a spectrum in it (no copies).
  double* scratch() { return real_; }
  void forward_scratch(cplx* out);
  void inverse_to_scratch(cplx* in);

 private:
  size_t n_, nc_;
  double* real_;
  void* forward_;
  void* inverse_;
  std::array<int, 3> dims_;
  // Per axis and index along it: the scheme's difference factor and the averages of the other
  // axes' (rotated scheme; 1 for Moulinec-Suquet); per frequency 1 / |k| (0 where k carries no
  // gradient).
  std::array<std::vector<cplx>, 3> diff_, avg_;
  std::vector<double> inv_norm_;
};

/// Voxels of a grid of `dims` voxels over a box of `box`; throws InputError when an axis has
/// no voxel or the box no positive size.
size_t checked_voxels(const std::array<int, 3>& dims, const Vec3& box);

/// Runs f(begin, end) over [0, n) in fixed blocks on all cores.
void parallel_blocks(size_t n, const std::function<void(size_t, size_t)>& f);
/// Sum of a[i] b[i], added in fixed blocks and then in block order: the same bits whatever the
/// number of threads.
double dot(const std::vector<double>& a, const std::vector<double>& b);

/// What a conjugate-gradient solve ended with: the iterations and the last relative residual
/// |r| / |b|; `stopped` when `progress(iteration, relative residual)` returned false (the caller
/// decides what that means).
struct CgOutcome {
  int iterations = 0;
  double residual = 0.0;
  bool stopped = false;
};
/// The Galerkin operator A = P C of the Lippmann-Schwinger solvers, given by parts so that
/// conjugate_gradients_galerkin can keep three fields: `components` fields of n values
/// (component-major); `flux(c, p, out, lo, hi)` writes component c of C p at voxels [lo, hi)
/// into out[lo, hi); `project(lo, hi)` applies P to the spectra at frequencies [lo, hi).
struct GalerkinOperator {
  int components = 0;
  std::function<void(int, const double*, double*, size_t, size_t)> flux;
  std::function<void(size_t, size_t)> project;
};
/// Conjugate gradients for P C x = b with x, the residual and the direction only (x starts at
/// 0; `spectra` holds one spectrum per component). The direction stays in the range of the
/// orthogonal projection P, so p . P C p = p . C p, summed before the transforms; the product's
/// spectra are then turned back one component at a time straight into the updates of x and the
/// residual, never stored as a field. Stops when |r| / |b| < tolerance, after max_iterations, or
/// when progress returns false. `b` is taken by value: it becomes the residual.
CgOutcome conjugate_gradients_galerkin(Grid& grid, std::vector<std::vector<cplx>>& spectra,
                                       const GalerkinOperator& op, std::vector<double> b,
                                       std::vector<double>* x, double tolerance, int max_iterations,
                                       const std::function<bool(int, double)>& progress);

}  // namespace spectral
}  // namespace rvegen
