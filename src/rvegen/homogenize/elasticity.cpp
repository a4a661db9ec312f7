#include "rvegen/homogenize/elasticity.hpp"

#include <chrono>
#include <cmath>
#include <map>
#include <string>

#include "rvegen/model/errors.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {

namespace {

using spectral::cplx;
using Vec6 = Eigen::Matrix<double, 6, 1>;
const double kSqrt2 = std::sqrt(2.0), kInvSqrt2 = 1.0 / kSqrt2;
// Mandel index of the tensor component (i, j), and its pair.
constexpr int kMandel[3][3] = {{0, 5, 4}, {5, 1, 3}, {4, 3, 2}};
constexpr int kPair[6][2] = {{0, 0}, {1, 1}, {2, 2}, {1, 2}, {0, 2}, {0, 1}};

// The orthogonal projection onto compatible strains at each frequency: for the unit gradient
// multiplier k, the strains sym(k (x) u); the projection of T is sym(k (x) u) with
// u = 2 d - conj(k) (k . d), d = T^T conj(k) (the normal equations (|k|^2 I + conj(k) k^T) / 2,
// inverted by Sherman-Morrison with |k| = 1).
class StrainProjection {
 public:
  StrainProjection(const std::array<int, 3>& dims, const Vec3& box, GradientScheme scheme,
                   int threads, const Communicator& comm)
      : grid_(dims, box, scheme, threads, comm), spectrum_(6) {
    for (auto& s : spectrum_) s.resize(grid_.spectrum_size());
  }
  void apply(const double* in, double* out) {
    const size_t n = grid_.size();
    for (int c = 0; c < 6; ++c) grid_.forward(in + c * n, spectrum_[c]);
    spectral::parallel_blocks(grid_.frequencies(), [&](size_t lo, size_t hi) { project(lo, hi); });
    for (int c = 0; c < 6; ++c) grid_.inverse(spectrum_[c], out + c * n);
  }
  /// P on the spectra at frequencies [lo, hi).
  void project(size_t lo, size_t hi) {
    grid_.for_each_unit_k(lo, hi, [&](size_t at, const cplx* k) { project_at(at, k); });
  }
  spectral::Grid& grid() { return grid_; }
  std::vector<spectral::Spectrum>& spectra() { return spectrum_; }

 private:
  void project_at(size_t at, const cplx* k) {
    cplx t[3][3];
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        const int m = kMandel[i][j];
        t[i][j] = i == j ? spectrum_[m][at] : spectrum_[m][at] * kInvSqrt2;
      }
    }
    cplx d[3], kd = 0.0;
    for (int j = 0; j < 3; ++j) {
      d[j] = std::conj(k[0]) * t[0][j] + std::conj(k[1]) * t[1][j] + std::conj(k[2]) * t[2][j];
      kd += k[j] * d[j];
    }
    cplx u[3];
    for (int j = 0; j < 3; ++j) u[j] = 2.0 * d[j] - std::conj(k[j]) * kd;
    for (int c = 0; c < 6; ++c) {
      const int i = kPair[c][0], j = kPair[c][1];
      const cplx e = 0.5 * (k[i] * u[j] + k[j] * u[i]);
      spectrum_[c][at] = c < 3 ? e : e * kSqrt2;
    }
  }

  spectral::Grid grid_;
  std::vector<spectral::Spectrum> spectrum_;
};

}  // namespace

Mat6 isotropic_stiffness(double young, double poisson) {
  const double lambda = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
  const double mu = young / (2.0 * (1.0 + poisson));
  Mat6 c = 2.0 * mu * Mat6::Identity();
  c.topLeftCorner<3, 3>().array() += lambda;
  return c;
}

EngineeringConstants engineering_constants(const Mat6& c) {
  const Mat6 s = c.inverse();
  EngineeringConstants e;
  e.e1 = 1.0 / s(0, 0);
  e.e2 = 1.0 / s(1, 1);
  e.e3 = 1.0 / s(2, 2);
  // Mandel shear compliance is 1 / (2 G).
  e.g23 = 1.0 / (2.0 * s(3, 3));
  e.g13 = 1.0 / (2.0 * s(4, 4));
  e.g12 = 1.0 / (2.0 * s(5, 5));
  e.nu12 = -s(0, 1) / s(0, 0);
  e.nu13 = -s(0, 2) / s(0, 0);
  e.nu23 = -s(1, 2) / s(1, 1);
  e.nu21 = -s(1, 0) / s(1, 1);
  e.nu31 = -s(2, 0) / s(2, 2);
  e.nu32 = -s(2, 1) / s(2, 2);
  return e;
}

ElasticityResult effective_stiffness(const std::array<int, 3>& dims, const Vec3& box_size,
                                     const std::vector<double>& young,
                                     const std::vector<double>& poisson,
                                     const ElasticityOptions& opt) {
  spectral::checked_voxels(dims, box_size);
  const size_t n = spectral::slab_voxels(dims, opt.comm);
  if (young.size() != n || poisson.size() != n) {
    throw InputError("homogenization: " + std::to_string(young.size()) + " Young's moduli and " +
                     std::to_string(poisson.size()) + " Poisson's ratios for " + std::to_string(n) +
                     " voxels");
  }
  // One isotropic stiffness per distinct pair of constants.
  StiffnessMedium m;
  m.index.resize(n);
  std::map<std::pair<double, double>, uint32_t> row;
  for (size_t i = 0; i < n; ++i) {
    if (!(young[i] >= 0.0) || !std::isfinite(young[i])) {
      throw InputError("homogenization: Young's moduli must be finite and >= 0");
    }
    if (!(poisson[i] > -1.0 && poisson[i] < 0.5)) {
      throw InputError("homogenization: Poisson's ratios must lie in (-1, 0.5)");
    }
    auto [it, fresh] =
        row.try_emplace({young[i], poisson[i]}, static_cast<uint32_t>(m.tensors.size()));
    if (fresh) m.tensors.push_back(isotropic_stiffness(young[i], poisson[i]));
    m.index[i] = it->second;
  }
  return effective_stiffness(dims, box_size, m, opt);
}

ElasticityResult effective_stiffness(const std::array<int, 3>& dims, const Vec3& box_size,
                                     const StiffnessMedium& medium, const ElasticityOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  const size_t whole = spectral::checked_voxels(dims, box_size);
  const size_t n = spectral::slab_voxels(dims, opt.comm);
  if (medium.index.size() != n) {
    throw InputError("homogenization: a medium of " + std::to_string(medium.index.size()) +
                     " voxels for " + std::to_string(n));
  }
  for (const Mat6& t : medium.tensors) {
    if (!t.allFinite()) throw InputError("homogenization: stiffnesses must be finite");
  }
  for (uint32_t i : medium.index) {
    if (i >= medium.tensors.size()) throw InputError("homogenization: a voxel has no tensor");
  }
  // Stress of a strain field (6 Mandel components, component-major).
  auto stress = [&](const std::vector<double>& e, std::vector<double>* s) {
    spectral::parallel_blocks(n, [&](size_t lo, size_t hi) {
      Vec6 v;
      for (size_t i = lo; i < hi; ++i) {
        for (int c = 0; c < 6; ++c) v[c] = e[c * n + i];
        const Vec6 t = medium.at(i) * v;
        for (int c = 0; c < 6; ++c) (*s)[c * n + i] = t[c];
      }
    });
  };
  StrainProjection project(dims, box_size, opt.scheme, opt.threads, opt.comm);
  ElasticityResult res;
  // At peak: the solver's residual and direction (two 6-component fields, and x only for the
  // local fields) and the six spectra (the flux is formed in them and transformed in place);
  // the right-hand side's stress and its projection are computed in place (the projection
  // reads every component before it writes one).
  std::vector<double> x(opt.field ? 6 * n : 0);
  // The mean of the stiffnesses: the mean stress of a uniform strain.
  Mat6 mean_tensor = medium.sum();
  sum_over_ranks(mean_tensor.data(), 36, opt.comm);
  mean_tensor /= static_cast<double>(whole);
  spectral::GalerkinOperator op;
  op.components = 6;
  op.flux = [&](const double* p, double* const* out, size_t lo, size_t hi, size_t at) {
    Vec6 v;
    for (size_t i = lo, j = at; i < hi; ++i, ++j) {
      for (int k = 0; k < 6; ++k) v[k] = p[k * n + i];
      const Vec6 t = medium.at(i) * v;
      for (int c = 0; c < 6; ++c) out[c][j] = t[c];
    }
  };
  op.project = [&](size_t lo, size_t hi) { project.project(lo, hi); };
  for (int load = 0; load < 6; ++load) {
    // Right-hand side: minus the projected stress of the uniform unit strain `load`.
    std::vector<double> b(6 * n, 0.0);
    std::fill(b.begin() + load * n, b.begin() + (load + 1) * n, 1.0);
    stress(b, &b);
    project.apply(b.data(), b.data());
    for (double& v : b) v = -v;
    std::vector<double> flux;
    const spectral::CgOutcome out = spectral::conjugate_gradients_galerkin(
        project.grid(), project.spectra(), op, std::move(b), opt.field ? &x : nullptr, &flux,
        opt.tolerance, opt.max_iterations,
        [&](int it, double rel) { return !opt.progress || opt.progress(load, it, rel); });
    if (out.stopped) throw Cancelled();
    res.iterations[load] = out.iterations;
    res.residual[load] = out.residual;
    if (out.iterations > 0 && !(out.residual < opt.tolerance)) res.converged = false;
    // The mean stress: that of the unit strain plus the mean of C x, summed as the solver went.
    res.stiffness.col(load) = mean_tensor.col(load) + Eigen::Map<const Vec6>(flux.data());
    if (opt.field) {
      // The local strain: the unit strain plus the fluctuation (x is reset by the next solve).
      for (size_t i = 0; i < n; ++i) x[load * n + i] += 1.0;
      opt.field(load, x);
    }
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace rvegen
