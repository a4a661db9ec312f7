// Effective conductivity of a periodic voxel image: the Lippmann-Schwinger equation on the
// voxel grid, posed in the space of discrete gradient fields (the Galerkin form of Vondrejc,
// Zeman and Marek 2014) and solved by conjugate gradients (Zeman et al. 2010), or by the basic
// fixed-point scheme of Moulinec and Suquet (1998) as a reference. FFTs by FFTW3.
//
// Discretizations of the gradient (the Fourier multiplier k(xi) of each voxel-centre field):
//  * kRotated (default): Willot's rotated scheme (2015), the gradient of a field at the voxel
//    corners taken at the voxel centres, k_j = (e^{i t_j} - 1) / h_j prod_{l != j}
//    (1 + e^{i t_l}) / 2 with t = 2 pi xi / N. It is the trilinear hexahedral element with one
//    integration point (Schneider, Merkert, Kabel 2016) and does not ring at high contrast;
//    laminates with interfaces on voxel faces are exact.
//  * kMoulinecSuquet: the continuous gradient i 2 pi xi / L (Nyquist frequencies dropped), the
//    original scheme; it rings at interfaces.
// The projection onto gradient fields is k k^H / |k|^2 at each frequency (zero where k = 0).
#pragma once

#include <array>
#include <functional>
#include <string>
#include <vector>

#include "rvegen/geometry/shapes.hpp"
#include "rvegen/homogenize/medium.hpp"
#include "rvegen/homogenize/spectral.hpp"

namespace rvegen {

enum class LinearSolver { kConjugateGradient, kFixedPoint };

struct ConductivityOptions {
  GradientScheme scheme = GradientScheme::kRotated;
  LinearSolver solver = LinearSolver::kConjugateGradient;
  /// Stop when the residual of the equilibrium (the gradient part of the flux) over its value
  /// for the first iterate falls below this.
  double tolerance = 1e-8;
  int max_iterations = 5000;
  /// FFTW threads (0: all cores).
  int threads = 0;
  /// Ranks that share the grid in z slabs (unset: this process alone); the medium is then this
  /// rank's slab, spectral::fft_slab(dims, comm), and every rank calls the solver.
  Communicator comm;
  /// Called after each iteration with the load case (0-2), the iteration and the relative
  /// residual; returning false stops the solve (Cancelled is thrown).
  std::function<bool(int, int, double)> progress;
  /// Called after each load case with the load case and its local gradient field (the unit
  /// mean gradient plus the fluctuation; 3 blocks of one value per voxel, x fastest; this
  /// rank's slab with comm).
  std::function<void(int, const std::vector<double>&)> field;
};

struct ConductivityResult {
  /// Effective conductivity: column j is the mean flux for a unit mean gradient along axis j.
  Mat3 tensor = Mat3::Zero();
  std::array<int, 3> iterations = {0, 0, 0};
  std::array<double, 3> residual = {0.0, 0.0, 0.0};
  /// How each load case's iteration broke down ("" when it did not; spectral::CgOutcome).
  std::array<std::string, 3> breakdown;
  /// True when every load case reached the tolerance.
  bool converged = true;
  double seconds = 0.0;
};

/// Effective conductivity of the periodic image with `dims` voxels over a box of `box_size`;
/// `conductivity` holds one non-negative value per voxel, x fastest (dims[0] * dims[1] *
/// dims[2] values, or the slab's with options.comm). Throws InputError on a size mismatch or a
/// negative or non-finite value.
ConductivityResult effective_conductivity(const std::array<int, 3>& dims, const Vec3& box_size,
                                          const std::vector<double>& conductivity,
                                          const ConductivityOptions& options = {});
/// The same for a medium of conductivity tensors (anisotropic phases, composite voxels).
ConductivityResult effective_conductivity(const std::array<int, 3>& dims, const Vec3& box_size,
                                          const ConductivityMedium& medium,
                                          const ConductivityOptions& options = {});

}  // namespace rvegen
