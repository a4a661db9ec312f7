#include "rvegen/homogenize/medium.hpp"

#include <cmath>

#include "rvegen/model/elastic_constants.hpp"
#include "rvegen/model/errors.hpp"

namespace rvegen {

namespace {

// The laminate mix of two tensors inverts their difference projected on the normal: this share
// of their size is added so that equal tensors (no jump) invert too.
constexpr double kMixRegularization = 1e-13;
// Material tensors are symmetric, and positive semi-definite, to this share of their size.
constexpr double kTensorRounding = 1e-12;
// A cut voxel's interface normal has norm 1 to this.
constexpr double kNormalTolerance = 1e-6;
// A laminate voxel whose inside or outside layer carries nothing (a pore, or a matrix that
// carries nothing) holding less material than this share is taken as empty (see pore_mix).
constexpr double kLeastSolidShare = 0.1;
// An inclusion's core whose largest coefficient is at most this share of the largest of the
// layers around it in a cut voxel is a pore there too (see pore_mix).
constexpr double kWeakCore = 1e-4;

const double kSqrt2 = std::sqrt(2.0);
constexpr int kPair[6][2] = {{0, 0}, {1, 1}, {2, 2}, {1, 2}, {0, 2}, {0, 1}};

// The jump map N of the laminate: conductivity N a = a n; elasticity N a = sym(a (x) n) in
// Mandel components (so that N^T sigma = sigma n).
Eigen::Matrix<double, 3, 1> jump_map3(const Vec3& n) {
  return n;
}
Eigen::Matrix<double, 6, 3> jump_map6(const Vec3& n) {
  Eigen::Matrix<double, 6, 3> m = Eigen::Matrix<double, 6, 3>::Zero();
  for (int c = 0; c < 6; ++c) {
    const int i = kPair[c][0], j = kPair[c][1];
    const double w = c < 3 ? 0.5 : 0.5 * kSqrt2;
    m(c, i) += w * n[j];
    m(c, j) += w * n[i];
  }
  return m;
}

template <int D>
bool carries_nothing(const Eigen::Matrix<double, D, D>& c) {
  return c.cwiseAbs().maxCoeff() == 0.0;
}

// (sum w_i C_i^-1)^-1, with a material that is singular in some direction (a void) giving
// zero there: every layer is shifted by a tiny multiple of their scale.
template <int D>
Eigen::Matrix<double, D, D> harmonic_mean(const std::vector<Eigen::Matrix<double, D, D>>& c,
                                          const std::vector<double>& w) {
  using M = Eigen::Matrix<double, D, D>;
  double scale = 0.0;
  for (const M& m : c) scale = std::max(scale, m.cwiseAbs().maxCoeff());
  if (scale == 0.0) return M::Zero();
  const M eps = kMixRegularization * scale * M::Identity();
  M s = M::Zero();
  for (size_t i = 0; i < c.size(); ++i) {
    if (w[i] > 0.0) s += w[i] * (c[i] + eps).inverse();
  }
  M r = s.inverse() - eps;
  return 0.5 * (r + r.transpose());
}

template <int D, int J>
Eigen::Matrix<double, D, D> laminate(const std::vector<Eigen::Matrix<double, D, D>>& c,
                                     const std::vector<double>& w,
                                     const Eigen::Matrix<double, D, J>& jump) {
  using M = Eigen::Matrix<double, D, D>;
  using K = Eigen::Matrix<double, J, J>;
  M mean = M::Zero(), second = M::Zero();
  Eigen::Matrix<double, D, J> ck = Eigen::Matrix<double, D, J>::Zero();
  K kinv = K::Zero();
  bool void_present = false;
  for (size_t s = 0; s < c.size(); ++s) {
    if (w[s] <= 0.0) continue;
    if (carries_nothing(c[s])) {
      void_present = true;
      continue;
    }
    const Eigen::Matrix<double, D, J> cn = c[s] * jump;
    const K ki = (jump.transpose() * cn).inverse();
    mean += w[s] * c[s];
    second += w[s] * cn * ki * cn.transpose();
    ck += w[s] * cn * ki;
    kinv += w[s] * ki;
  }
  M r = mean - second;
  if (!void_present && kinv.cwiseAbs().maxCoeff() > 0.0) r += ck * kinv.inverse() * ck.transpose();
  return 0.5 * (r + r.transpose());
}

// The laminate's tensor is singular across the interface wherever a layer carries nothing, so a
// pore's cut voxels carried nothing across its surface: on insulating spheres conjugate
// gradients stalled far above their tolerance, well below the converged conductivity and bulk
// modulus. Where the inside or the outside layer carries nothing, the layers that carry
// something are averaged (Voigt: the mix Lucarini et al. 2022 found best for empty phases), and
// a voxel with under kLeastSolidShare of material is empty (bounding the contrast conjugate
// gradients see at 10): the solves then converge in few iterations, close to the values plain
// voxels extrapolate to. Thin layers that carry nothing (debonding gaps, shells:
// compose_medium's `thin`) keep the laminate, which carries nothing across them, as a gap does:
// averaged, a debonded sphere's gap thinner than a voxel barely mattered. A core with at most
// kWeakCore of what surrounds it (the 1e-6 that finite-element users give voids) stalled the
// same way and is a pore too; a little above the bound the laminate converges but runs low on
// coarse grids, where the pore's mix would be close (docs/benchmarks.md). The bound
// is not higher because a flat laminate whose weaker layer is inside stays exact at contrast
// 1000 only with the laminate rule.
template <int D>
Eigen::Matrix<double, D, D> pore_mix(const std::vector<Eigen::Matrix<double, D, D>>& c,
                                     const std::vector<double>& w, const std::vector<bool>& pore) {
  using M = Eigen::Matrix<double, D, D>;
  M m = M::Zero();
  double solid = 0.0;
  for (size_t i = 0; i < c.size(); ++i) {
    if (w[i] <= 0.0 || pore[i] || carries_nothing(c[i])) continue;
    m += w[i] * c[i];
    solid += w[i];
  }
  return solid < kLeastSolidShare ? M::Zero() : m;
}

template <int D, int J>
Eigen::Matrix<double, D, D> mix(const std::vector<Eigen::Matrix<double, D, D>>& c,
                                const std::vector<double>& w, VoxelRule rule,
                                const Eigen::Matrix<double, D, J>& jump) {
  using M = Eigen::Matrix<double, D, D>;
  if (c.size() != w.size() || c.empty()) {
    throw InputError("homogenization: a composite voxel needs one share per layer");
  }
  // The layer with the largest share (the first of equal ones).
  size_t most = 0;
  for (size_t i = 1; i < w.size(); ++i) {
    if (w[i] > w[most]) most = i;
  }
  if (w[most] >= 1.0) return c[most];
  switch (rule) {
    case VoxelRule::kPlain:
      return c[most];
    case VoxelRule::kVoigt: {
      M m = M::Zero();
      for (size_t i = 0; i < c.size(); ++i) m += w[i] * c[i];
      return m;
    }
    case VoxelRule::kReuss:
      return harmonic_mean<D>(c, w);
    case VoxelRule::kLaminate:
      return laminate<D, J>(c, w, jump);
  }
  return c[most];
}

template <int D>
void check_material(const Eigen::Matrix<double, D, D>& c, size_t row) {
  const double scale = c.cwiseAbs().maxCoeff();
  const std::string which = "homogenization: material tensor " + std::to_string(row);
  if (!std::isfinite(scale)) throw InputError(which + " is not finite");
  if ((c - c.transpose()).cwiseAbs().maxCoeff() > kTensorRounding * scale) {
    throw InputError(which + " is not symmetric");
  }
  if (scale == 0.0) return;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, D, D>> eig(c);
  if (eig.eigenvalues().minCoeff() < -kTensorRounding * scale) {
    throw InputError(which + " is not positive semi-definite");
  }
}

}  // namespace

VoxelRule voxel_rule_from_name(const std::string& name) {
  if (name == "plain") return VoxelRule::kPlain;
  if (name == "voigt") return VoxelRule::kVoigt;
  if (name == "reuss") return VoxelRule::kReuss;
  if (name == "laminate") return VoxelRule::kLaminate;
  throw InputError("homogenization: unknown voxel rule \"" + name +
                   "\" (plain, voigt, reuss or laminate)");
}

const char* voxel_rule_name(VoxelRule rule) {
  switch (rule) {
    case VoxelRule::kPlain:
      return "plain";
    case VoxelRule::kVoigt:
      return "voigt";
    case VoxelRule::kReuss:
      return "reuss";
    case VoxelRule::kLaminate:
      return "laminate";
  }
  return "?";
}

Mat3 mix_conductivity(const std::vector<Mat3>& layers, const std::vector<double>& shares,
                      const Vec3& n, VoxelRule rule) {
  return mix<3, 1>(layers, shares, rule, jump_map3(n));
}

Mat6 mix_stiffness(const std::vector<Mat6>& layers, const std::vector<double>& shares,
                   const Vec3& n, VoxelRule rule) {
  return mix<6, 3>(layers, shares, rule, jump_map6(n));
}

Mat3 mix_conductivity(const Mat3& a, const Mat3& b, double f, const Vec3& n, VoxelRule rule) {
  return mix_conductivity({a, b}, {f, 1.0 - f}, n, rule);
}

Mat6 mix_stiffness(const Mat6& a, const Mat6& b, double f, const Vec3& n, VoxelRule rule) {
  return mix_stiffness({a, b}, {f, 1.0 - f}, n, rule);
}

template <int D>
TensorMedium<D> compose_medium(const std::vector<uint32_t>& material,
                               const std::vector<Eigen::Matrix<double, D, D>>& materials,
                               const std::vector<CompositeVoxel>& composites, VoxelRule rule,
                               const std::vector<bool>& thin) {
  for (size_t r = 0; r < materials.size(); ++r) check_material<D>(materials[r], r);
  auto is_thin = [&](uint32_t row) { return row < thin.size() && thin[row]; };
  auto size = [&](uint32_t row) { return materials[row].cwiseAbs().maxCoeff(); };
  TensorMedium<D> m;
  m.index = material;
  for (uint32_t i : m.index) {
    if (i >= materials.size()) {
      throw InputError("homogenization: a voxel's material " + std::to_string(i) +
                       " is not among " + std::to_string(materials.size()));
    }
  }
  m.tensors = materials;
  if (rule == VoxelRule::kPlain) return m;
  m.tensors.reserve(materials.size() + composites.size());
  for (const CompositeVoxel& c : composites) {
    if (c.voxel >= m.index.size() || c.inside >= materials.size() ||
        c.outside >= materials.size() || c.middle >= materials.size()) {
      throw InputError("homogenization: a composite voxel refers to no voxel or no material");
    }
    const double outer = 1.0 - c.fraction - c.middle_fraction;
    if (!(c.fraction >= 0.0 && c.middle_fraction >= 0.0 && outer >= -kNormalTolerance) ||
        !c.normal.allFinite() || std::abs(c.normal.norm() - 1.0) > kNormalTolerance) {
      throw InputError(
          "homogenization: a composite voxel's shares must lie in [0, 1] and add up to 1 at "
          "most, and its normal be a unit vector");
    }
    m.index[c.voxel] = static_cast<uint32_t>(m.tensors.size());
    // Layers along the normal: inside, middle (a coating's shell), outside.
    const std::vector<Eigen::Matrix<double, D, D>> layers = {
        materials[c.inside], materials[c.middle], materials[c.outside]};
    const std::vector<double> shares = {c.fraction, c.middle_fraction, std::max(0.0, outer)};
    // Pores: an inside layer (a core) that carries nothing or under kWeakCore of what is
    // around it, an outside layer (the matrix) that carries nothing; never a thin layer.
    const double around =
        std::max(shares[1] > 0.0 ? size(c.middle) : 0.0, shares[2] > 0.0 ? size(c.outside) : 0.0);
    const bool inner_pore =
        shares[0] > 0.0 && !is_thin(c.inside) && size(c.inside) <= kWeakCore * around;
    const bool outer_pore =
        shares[2] > 0.0 && !is_thin(c.outside) && carries_nothing<D>(materials[c.outside]);
    if (rule == VoxelRule::kLaminate && (inner_pore || outer_pore)) {
      m.tensors.push_back(pore_mix<D>(layers, shares, {inner_pore, false, outer_pore}));
    } else if constexpr (D == 3) {
      m.tensors.push_back(mix_conductivity(layers, shares, c.normal, rule));
    } else {
      m.tensors.push_back(mix_stiffness(layers, shares, c.normal, rule));
    }
  }
  return m;
}

template TensorMedium<3> compose_medium<3>(const std::vector<uint32_t>&, const std::vector<Mat3>&,
                                           const std::vector<CompositeVoxel>&, VoxelRule,
                                           const std::vector<bool>&);
template TensorMedium<6> compose_medium<6>(const std::vector<uint32_t>&, const std::vector<Mat6>&,
                                           const std::vector<CompositeVoxel>&, VoxelRule,
                                           const std::vector<bool>&);

Mat3 transverse_conductivity(double axial, double transverse, const Vec3& axis) {
  const Vec3 a = axis.normalized();
  return transverse * Mat3::Identity() + (axial - transverse) * a * a.transpose();
}

Mat6 mandel_rotation(const Mat3& r) {
  Mat6 m;
  for (int d = 0; d < 6; ++d) {
    Mat3 e = Mat3::Zero();
    const int k = kPair[d][0], l = kPair[d][1];
    if (d < 3) {
      e(k, l) = 1.0;
    } else {
      e(k, l) = e(l, k) = 1.0 / kSqrt2;
    }
    const Mat3 g = r * e * r.transpose();
    for (int c = 0; c < 6; ++c) {
      const int i = kPair[c][0], j = kPair[c][1];
      m(c, d) = c < 3 ? g(i, j) : kSqrt2 * g(i, j);
    }
  }
  return m;
}

Mat6 transverse_stiffness(double e_l, double e_t, double g_lt, double nu_lt, double nu_tt,
                          const Vec3& axis) {
  // In the fibre frame (axis = local 3), Voigt to Mandel: shear rows and columns times sqrt 2.
  Mat6 local = transverse_voigt_stiffness(e_l, e_t, g_lt, nu_lt, nu_tt, 2);
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) local(i, j) *= (i < 3 ? 1.0 : kSqrt2) * (j < 3 ? 1.0 : kSqrt2);
  }
  const Vec3 a = axis.normalized();
  const Vec3 t1 = a.unitOrthogonal(), t2 = a.cross(t1);
  Mat3 r;
  r.col(0) = t1;
  r.col(1) = t2;
  r.col(2) = a;
  const Mat6 m = mandel_rotation(r);
  Mat6 c = m * local * m.transpose();
  return 0.5 * (c + c.transpose());
}

}  // namespace rvegen
