// The medium the FFT solvers see: per voxel an index into a table of material tensors (3x3
// conductivities or 6x6 stiffnesses in Mandel notation), so that each fibre can carry its own
// rotated tensor and each voxel cut by an interface its own mixed one.
//
// Composite voxels (Kabel, Merkert, Schneider 2015): a voxel cut by one interface holds two
// materials, a share f of the "inside" one and 1 - f of the "outside" one, and the interface
// normal n. The voxel rule gives it one tensor:
//  * kPlain: the material at the voxel centre (the composite voxel keeps its own material);
//  * kVoigt: the arithmetic mean f A + (1 - f) B;
//  * kReuss: the harmonic mean (f A^-1 + (1 - f) B^-1)^-1;
//  * kLaminate: the exact effective tensor of a laminate of A and B with normal n: strains
//    (gradients) continuous along the interface, tractions (normal fluxes) continuous across
//    it. With N the map from a jump vector a to the jump sym(a (x) n) (gradient: a n) and
//    K_i = N^T C_i N,
//      C = <C> - <C N K^-1 N^T C> + <C N K^-1> <K^-1>^-1 <K^-1 N^T C>  (<.>: mean by share);
//    where a material carries nothing (a void, C = 0) the last term drops (zero traction).
//    A laminate of layers normal to n is then exact whatever the voxel size.
// A voxel cut by a coated inclusion holds up to three layers, core, shell and matrix, along
// the same normal (the shell's surfaces are parallel); the means above run over the three.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <vector>

#include "rvegen/geometry/shapes.hpp"
#include "rvegen/raster/cut_voxels.hpp"

namespace rvegen {

using Mat6 = Eigen::Matrix<double, 6, 6>;

template <int D>
struct TensorMedium {
  using Tensor = Eigen::Matrix<double, D, D>;
  /// Row of `tensors` for each voxel (x fastest).
  std::vector<uint32_t> index;
  std::vector<Tensor> tensors;
  const Tensor& at(size_t voxel) const { return tensors[index[voxel]]; }
  /// The sum of the voxels' tensors (by how many voxels use each row: exact counts, so the
  /// same bits however the voxels are visited).
  Tensor sum() const {
    std::vector<double> count(tensors.size(), 0.0);
    for (uint32_t i : index) count[i] += 1.0;
    Tensor s = Tensor::Zero();
    for (size_t r = 0; r < tensors.size(); ++r) s += count[r] * tensors[r];
    return s;
  }
};
using ConductivityMedium = TensorMedium<3>;
using StiffnessMedium = TensorMedium<6>;

enum class VoxelRule { kPlain, kVoigt, kReuss, kLaminate };
/// "plain", "voigt", "reuss", "laminate"; InputError names the choices otherwise.
VoxelRule voxel_rule_from_name(const std::string& name);
const char* voxel_rule_name(VoxelRule rule);

/// A voxel cut by one interface, or by two parallel ones (a coating's shell between a core and
/// the matrix): layers inside, middle and outside along the normal.
struct CompositeVoxel {
  size_t voxel = 0;
  uint32_t inside = 0, outside = 0;  // materials (rows of the material table)
  uint32_t middle = 0;               // the middle layer's material (with middle_fraction > 0)
  double fraction = 0.0;             // share of the voxel on the inside
  double middle_fraction = 0.0;      // share in the middle layer; the outside has the rest
  Vec3 normal = Vec3::UnitX();       // unit normal of the interfaces
};

/// A cut voxel as a composite voxel whose materials are the cut voxel's phase labels (rows of
/// a table that starts with a row per phase label).
inline CompositeVoxel composite_of(const CutVoxel& c) {
  CompositeVoxel v;
  v.voxel = c.voxel;
  v.inside = c.inside;
  v.outside = c.outside;
  v.middle = c.middle;
  v.fraction = c.fraction;
  v.middle_fraction = c.middle_fraction;
  v.normal = c.normal;
  return v;
}

/// The medium of an image: voxel v has material `material[v]` (a row of `materials`), except
/// the composite voxels, which get the rule's tensor (each its own row). With the laminate
/// rule, a composite voxel whose inside or outside layer carries nothing (a zero tensor: a pore)
/// gets the mean of its layers that carry something, or nothing when they hold under a tenth
/// of it; rows marked in `thin` (debonding gaps, shells) that carry nothing keep the laminate,
/// which carries nothing across them. Throws InputError when a material is not symmetric
/// positive semi-definite, an index is out of range or a composite voxel's share is outside
/// [0, 1] or its normal not finite.
template <int D>
TensorMedium<D> compose_medium(const std::vector<uint32_t>& material,
                               const std::vector<Eigen::Matrix<double, D, D>>& materials,
                               const std::vector<CompositeVoxel>& composites, VoxelRule rule,
                               const std::vector<bool>& thin = {});

/// The rule's tensor for shares f of A and 1 - f of B with interface normal n.
Mat3 mix_conductivity(const Mat3& a, const Mat3& b, double f, const Vec3& n, VoxelRule rule);
Mat6 mix_stiffness(const Mat6& a, const Mat6& b, double f, const Vec3& n, VoxelRule rule);
/// The same for any number of layers normal to n with the given shares (adding up to 1); the
/// plain rule takes the layer with the largest share.
Mat3 mix_conductivity(const std::vector<Mat3>& layers, const std::vector<double>& shares,
                      const Vec3& n, VoxelRule rule);
Mat6 mix_stiffness(const std::vector<Mat6>& layers, const std::vector<double>& shares,
                   const Vec3& n, VoxelRule rule);

/// Transversely isotropic conductivity about the unit axis a: k_t I + (k_a - k_t) a a^T.
Mat3 transverse_conductivity(double axial, double transverse, const Vec3& axis);
/// Transversely isotropic stiffness (Mandel) about the unit axis a, from the axial modulus
/// E_L, the transverse modulus E_T, the axial shear modulus G_LT, the axial Poisson's ratio
/// nu_LT (transverse contraction under axial stress) and the transverse one nu_TT. Throws
/// InputError when the constants give no positive-definite tensor.
Mat6 transverse_stiffness(double e_l, double e_t, double g_lt, double nu_lt, double nu_tt,
                          const Vec3& axis);
/// The Mandel 6x6 matrix of the rotation R acting on symmetric tensors (R e R^T).
Mat6 mandel_rotation(const Mat3& r);

}  // namespace rvegen
