// What the FFT solvers share: the periodic voxel grid in Fourier space (FFTW plans, the
// gradient multiplier of the chosen discretization) and the conjugate-gradient solver of the
// Galerkin form (Zeman et al. 2010; Vondrejc, Zeman, Marek 2014).
#pragma once

#include <array>
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
  /// The unit multiplier at stored frequency `at` (3 values).
  const cplx* unit_k(size_t at) const { return &unit_k_[3 * at]; }
  /// Spectrum of a real field (n values) into `out` (frequencies() values).
  void forward(const double* field, cplx* out);
  /// Real field of a spectrum, divided by n (so inverse(forward(f)) = f); `in` is destroyed.
  void inverse(cplx* in, double* field);

 private:
  size_t n_, nc_;
  double* real_;
  cplx* spectrum_;
  void* forward_;
  void* inverse_;
  std::vector<cplx> unit_k_;
};

/// Voxels of a grid of `dims` voxels over a box of `box`; throws InputError when an axis has
/// no voxel or the box no positive size.
size_t checked_voxels(const std::array<int, 3>& dims, const Vec3& box);

/// Runs f(begin, end) over [0, n) in fixed blocks on all cores.
void parallel_blocks(size_t n, const std::function<void(size_t, size_t)>& f);
/// Sum of a[i] b[i], added in fixed blocks and then in block order: the same bits whatever the
/// number of threads.
double dot(const std::vector<double>& a, const std::vector<double>& b);

/// Conjugate gradients for A x = b on the subspace the projection-based operator A keeps (x
/// starts at 0). `apply(p, out)` computes A p. Stops when |r| / |b| < tolerance or after
/// max_iterations; `progress(iteration, relative residual)` returning false stops it too
/// (the caller decides what that means). Returns the iterations and the last relative residual.
struct CgOutcome {
  int iterations = 0;
  double residual = 0.0;
  bool stopped = false;
};
/// `b` is taken by value: it becomes the residual (one field less at peak).
CgOutcome conjugate_gradients(
    const std::function<void(const std::vector<double>&, std::vector<double>*)>& apply,
    std::vector<double> b, std::vector<double>* x, double tolerance, int max_iterations,
    const std::function<bool(int, double)>& progress);

}  // namespace spectral
}  // namespace rvegen
