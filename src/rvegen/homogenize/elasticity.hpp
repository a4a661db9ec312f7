// Effective stiffness of a periodic voxel image of isotropic elastic phases: the same
// Galerkin-form Lippmann-Schwinger solver as the conductivity (conductivity.hpp), on strain
// fields projected onto compatible ones (symmetrized discrete gradients of a periodic
// displacement), six load cases. Tensors in Mandel notation: (11, 22, 33, 23, 13, 12) with
// shear components times sqrt 2, so that the 6x6 matrix is the tensor in an orthonormal basis.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <functional>
#include <string>
#include <vector>

#include "rvegen/geometry/shapes.hpp"
#include "rvegen/homogenize/medium.hpp"
#include "rvegen/homogenize/spectral.hpp"

namespace rvegen {

struct ElasticityOptions {
  GradientScheme scheme = GradientScheme::kRotated;
  /// Relative residual of the equilibrium at which a load case stops.
  double tolerance = 1e-8;
  int max_iterations = 5000;
  int threads = 0;  // FFTW threads (0: all cores)
  /// Ranks that share the grid in z slabs (unset: this process alone); the medium is then this
  /// rank's slab, spectral::fft_slab(dims, comm), and every rank calls the solver.
  Communicator comm;
  /// Called after each iteration with the load case (0-5), the iteration and the relative
  /// residual; returning false stops the solve (Cancelled is thrown).
  std::function<bool(int, int, double)> progress;
  /// Called after each load case with the load case and its local strain field (the unit mean
  /// strain plus the fluctuation; 6 Mandel blocks of one value per voxel, x fastest).
  std::function<void(int, const std::vector<double>&)> field;
};

/// Young's moduli, shear moduli and Poisson's ratios of a stiffness (nu_ij = -S_ij / S_ii for
/// the compliance S: the contraction along j under a stress along i).
struct EngineeringConstants {
  double e1 = 0, e2 = 0, e3 = 0, g23 = 0, g13 = 0, g12 = 0;
  double nu12 = 0, nu13 = 0, nu23 = 0, nu21 = 0, nu31 = 0, nu32 = 0;
};
EngineeringConstants engineering_constants(const Mat6& mandel_stiffness);
/// Isotropic stiffness in Mandel notation from Young's modulus and Poisson's ratio.
Mat6 isotropic_stiffness(double young, double poisson);

struct ElasticityResult {
  Mat6 stiffness = Mat6::Zero();  // Mandel; column j: mean stress for a unit mean strain j
  std::array<int, 6> iterations = {0, 0, 0, 0, 0, 0};
  std::array<double, 6> residual = {0, 0, 0, 0, 0, 0};
  /// How each load case's iteration broke down ("" when it did not; spectral::CgOutcome).
  std::array<std::string, 6> breakdown;
  bool converged = true;
  double seconds = 0.0;
};

/// Effective stiffness of the image with `dims` voxels over a box of `box_size`; `young` and
/// `poisson` hold one value per voxel, x fastest (Young's modulus >= 0, Poisson's ratio in
/// (-1, 0.5)). Throws InputError on bad input.
ElasticityResult effective_stiffness(const std::array<int, 3>& dims, const Vec3& box_size,
                                     const std::vector<double>& young,
                                     const std::vector<double>& poisson,
                                     const ElasticityOptions& options = {});
/// The same for a medium of stiffness tensors (Mandel; anisotropic phases, composite voxels).
ElasticityResult effective_stiffness(const std::array<int, 3>& dims, const Vec3& box_size,
                                     const StiffnessMedium& medium,
                                     const ElasticityOptions& options = {});

}  // namespace rvegen
