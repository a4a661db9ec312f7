// Effective properties of a voxelized RVE from a scene's "materials" and "homogenization": the
// media (phase tensors, transversely isotropic cores turned to their inclusion's axis, voxels
// cut by one core surface mixed by the voxel rule), the FFT solves, and the bounds of isotropic
// phases beside the results. What the command line reports and the VTK filter tabulates.
#pragma once

#include <array>
#include <functional>
#include <string>
#include <vector>

#include "rvegen/homogenize/conductivity.hpp"
#include "rvegen/homogenize/elasticity.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen {

/// Voigt, Reuss and Hashin-Shtrikman(-Walpole) bounds from the image's phase shares; `stated`
/// is false when a phase is anisotropic (these bounds do not apply).
struct Bounds {
  bool stated = false;
  double voigt = 0.0, reuss = 0.0, hs_lower = 0.0, hs_upper = 0.0;
};

struct EffectiveProperties {
  std::string voxel_rule;
  size_t cut_voxels = 0;     // voxels mixed by the rule
  size_t shared_voxels = 0;  // voxels cut by two cores (left plain)
  std::array<int, 3> resolution = {0, 0, 0};
  std::vector<double> phase_shares;  // by phase label (centre labels)
  bool has_conductivity = false, has_stiffness = false;
  ConductivityResult conductivity;
  Bounds conductivity_bounds;
  ElasticityResult stiffness;
  EngineeringConstants constants;
  /// The isotropic projection of the stiffness: bulk modulus (3K = sum of C_ij, i, j < 3, over
  /// 3) and shear modulus (2G = (trace - 3K) / 5).
  double bulk = 0.0, shear = 0.0;
  Bounds bulk_bounds, shear_bounds;
  /// With scene.homogenization.fields, the local fields of each load case (float, blocks of
  /// one value per voxel, x fastest): gradient and flux (3 blocks), strain and stress (6
  /// blocks, tensor components 11, 22, 33, 23, 13, 12, not Mandel-scaled).
  std::vector<std::vector<float>> gradient, flux, strain, stress;
  /// The phase whose tensor's eigenvalues lie furthest apart, and how far (the ratio of the
  /// largest to the least), among all phases' conductivities and stiffnesses: what a breakdown
  /// names ("phase \"matrix\": stiffness eigenvalues 8.3e+15 apart").
  std::string conductivity_spread, stiffness_spread;
};

/// Called with the physics ("conductivity", "elasticity"), the load case, the number of load
/// cases, the iteration and the relative residual; false stops the solve (Cancelled is thrown).
using SolveProgress = std::function<bool(const char*, int, int, int, double)>;

/// Solves what scene.homogenization asks for on `image` (labels at voxel centres and inclusion
/// ids) of the inclusions `set`. The scene's materials must have been validated
/// (validate_homogenization). The image is the whole one, or with `comm` this rank's z slab,
/// spectral::fft_slab(image.dims, comm): every rank calls, the image is never gathered, and
/// every rank gets the whole image's results (the local fields are of its slab).
EffectiveProperties effective_properties(const Scene& scene, const InclusionSet& set,
                                         const VoxelImage& image,
                                         const SolveProgress& progress = nullptr,
                                         const Communicator& comm = {});

/// What did not converge, in one sentence ("conductivity: load cases 1, 2 and 3 stopped at 1000
/// iterations with relative residuals up to 3.7e-04, above the tolerance 1e-06"; a breakdown
/// as one: "elasticity: load case 4 broke down (...): round-off, not slow convergence; ...",
/// naming the phase of the widest spread; the physics joined by "; "), or "" when every load
/// case reached the tolerance. A tensor that did not
/// converge is not the RVE's effective property: the command line says so and exits 5, the VTK
/// filter warns.
std::string unconverged(const EffectiveProperties& e, double tolerance);

}  // namespace rvegen
