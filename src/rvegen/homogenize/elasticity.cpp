#include "rvegen/homogenize/elasticity.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <string>

#include "rvegen/model/errors.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
const double kInvSqrt2 = 1.0 / std::sqrt(2.0);

// The orthogonal projection onto compatible strains at each frequency: for the multiplier
// k = c xi (xi the real unit direction, |c| = 1), the strains sym(k (x) u); the projection of T
// is sym(xi (x) u) with u = 2 T xi - xi (xi . T xi) (the normal equations (I + xi xi^T) / 2,
// inverted by Sherman-Morrison with |xi| = 1; c meets its conjugate and drops out).
struct StrainKernel {
  static constexpr int kComponents = 6;
  // A compatible strain's potential: the displacement u, three complex values.
  static constexpr int kPotentials = 3;
  using Pair = spectral::Pair;
  // u of P on one frequency of each component's spectrum (its real and imaginary parts at
  // v[c][i] and v[c][i + 1], as one pair: the coefficients are real), or on two neighbouring
  // ones (V a Quad, xi's lanes each frequency's).
  template <class V, class S>
  RVEGEN_LANES static void reduce(double* const* v, size_t i, const S* xi, V* u) {
    using spectral::load_lanes;
    // The tensor from its Mandel components, T xi, and xi . T xi.
    const V t00 = load_lanes<V>(v[0] + i), t11 = load_lanes<V>(v[1] + i),
            t22 = load_lanes<V>(v[2] + i);
    const V t12 = load_lanes<V>(v[3] + i) * kInvSqrt2, t02 = load_lanes<V>(v[4] + i) * kInvSqrt2,
            t01 = load_lanes<V>(v[5] + i) * kInvSqrt2;
    const V d0 = t00 * xi[0] + t01 * xi[1] + t02 * xi[2];
    const V d1 = t01 * xi[0] + t11 * xi[1] + t12 * xi[2];
    const V d2 = t02 * xi[0] + t12 * xi[1] + t22 * xi[2];
    const V kd = xi[0] * d0 + xi[1] * d1 + xi[2] * d2;
    u[0] = 2.0 * d0 - xi[0] * kd;
    u[1] = 2.0 * d1 - xi[1] * kd;
    u[2] = 2.0 * d2 - xi[2] * kd;
  }
  // scale sym(xi (x) u) in Mandel components (shear: sqrt 2 (xi_i u_j + xi_j u_i) / 2).
  template <class V, class S>
  RVEGEN_LANES static void expand(const V* w, const S* xi, double scale, double* const* v,
                                  size_t i) {
    using spectral::store_lanes;
    const V u0 = scale * w[0], u1 = scale * w[1], u2 = scale * w[2];
    store_lanes(v[0] + i, xi[0] * u0);
    store_lanes(v[1] + i, xi[1] * u1);
    store_lanes(v[2] + i, xi[2] * u2);
    store_lanes(v[3] + i, (xi[1] * u2 + xi[2] * u1) * kInvSqrt2);
    store_lanes(v[4] + i, (xi[0] * u2 + xi[2] * u0) * kInvSqrt2);
    store_lanes(v[5] + i, (xi[0] * u1 + xi[1] * u0) * kInvSqrt2);
  }
  // |sym(xi (x) u)|^2 = (|u|^2 + (xi . u)^2) / 2 for |xi| = 1, lane by lane (u is 0 where xi
  // is: there reduce gives 0), into squares.
  template <class V, class S>
  RVEGEN_LANES static void norm(const V* u, const S* xi, V& squares) {
    const V xu = xi[0] * u[0] + xi[1] * u[1] + xi[2] * u[2];
    const V uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    squares = 0.5 * (uu + xu * xu);
  }
  // P on one frequency.
  static void project(double* const* v, size_t i, const double* xi) {
    Pair u[3];
    reduce(v, i, xi, u);
    expand(u, xi, 1.0, v, i);
  }
};
using StrainProjection = spectral::Projection<StrainKernel>;

struct IsotropicPart {
  bool isotropic = false;
  // C v = (c11 - lambda) v_i + lambda tr(v) for the normal components i, 2 mu v_i for the
  // shear ones.
  double lambda = 0.0, normal = 0.0, two_mu = 0.0;
};

// Which stiffnesses have the isotropic pattern (c11 on the normal diagonal, lambda beside it,
// 2 mu on the shear diagonal, zero elsewhere), and their numbers.
std::vector<IsotropicPart> isotropic_parts(const std::vector<Mat6>& tensors) {
  std::vector<IsotropicPart> out(tensors.size());
  for (size_t t = 0; t < tensors.size(); ++t) {
    const Mat6& c = tensors[t];
    const double lambda = c(0, 1), two_mu = c(3, 3);
    Mat6 iso = two_mu * Mat6::Identity();
    iso.topLeftCorner<3, 3>().array() += lambda;
    for (int i = 0; i < 3; ++i) iso(i, i) = c(0, 0);
    out[t].isotropic = iso == c;
    out[t].lambda = lambda;
    out[t].normal = c(0, 0) - lambda;
    out[t].two_mu = two_mu;
  }
  return out;
}

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
  StrainProjection project(dims, box_size, opt.scheme, opt.threads, opt.comm);
  ElasticityResult res;
  // At peak: the six buffers the transforms run in, and the solver's r and s (p and x too for
  // the local fields, and x's field) as displacements, three complex values a frequency.
  std::vector<double> x;
  // The mean of the stiffnesses: the mean stress of a uniform strain.
  Mat6 mean_tensor = medium.sum();
  sum_over_ranks(mean_tensor.data(), 36, opt.comm);
  mean_tensor /= static_cast<double>(whole);
  spectral::GalerkinOperator op;
  op.components = 6;
  op.potentials = StrainKernel::kPotentials;
  // Isotropic stiffnesses (the phases; composite voxels have general ones) by their three
  // numbers: 7 products instead of 36.
  const std::vector<IsotropicPart> iso = isotropic_parts(medium.tensors);
  op.flux = [&](double* const* v, size_t lo, size_t hi, double* sums) {
    spectral::flux_in_runs<6, 3>(
        v, lo, hi, sums,
        [&](size_t i, double* n) {
          const IsotropicPart& ip = iso[medium.index[i]];
          n[0] = ip.normal;
          n[1] = ip.lambda;
          n[2] = ip.two_mu;
          return ip.isotropic;
        },
        [](const auto* n, const auto* e, auto* t) RVEGEN_LANES_LAMBDA {
          const auto l = n[1] * (e[0] + e[1] + e[2]);
          for (int c = 0; c < 3; ++c) t[c] = n[0] * e[c] + l;
          for (int c = 3; c < 6; ++c) t[c] = n[2] * e[c];
        },
        [&](size_t i, const double* e, double* t) {
          const uint32_t id = medium.index[i];
          const IsotropicPart& ip = iso[id];
          if (ip.isotropic) {
            const double l = ip.lambda * (e[0] + e[1] + e[2]);
            for (int c = 0; c < 3; ++c) t[c] = ip.normal * e[c] + l;
            for (int c = 3; c < 6; ++c) t[c] = ip.two_mu * e[c];
          } else {
            Eigen::Map<Vec6> out(t);
            out = medium.tensors[id] * Eigen::Map<const Vec6>(e);
          }
        });
  };
  op.step = [&](const spectral::GalerkinStep& st) { return project.galerkin_step(st); };
  spectral::GalerkinFields fields;  // the solver's (kept over the loads)
  for (int load = 0; load < 6; ++load) {
    // The uniform unit strain `load`; the solver finds the fluctuation x with P C (E + x) = 0.
    double e[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    e[load] = 1.0;
    std::vector<double> flux;
    const spectral::CgOutcome out = spectral::conjugate_gradients_galerkin(
        project.grid(), project.spectra(), op, e, fields, opt.field ? &x : nullptr, &flux,
        opt.tolerance, opt.max_iterations,
        [&](int it, double rel) { return !opt.progress || opt.progress(load, it, rel); });
    if (out.stopped) throw Cancelled();
    res.iterations[load] = out.iterations;
    res.residual[load] = out.residual;
    res.breakdown[load] = out.breakdown;
    if (out.iterations > 0 && !(out.residual < opt.tolerance)) res.converged = false;
    if (!out.breakdown.empty()) res.converged = false;
    // The mean stress: that of the unit strain plus the mean of C x, summed as the solver went.
    res.stiffness.col(load) = mean_tensor.col(load) + Eigen::Map<const Vec6>(flux.data());
    if (opt.field) {
      // The local strain: the unit strain plus the fluctuation.
      for (size_t i = 0; i < n; ++i) x[load * n + i] += 1.0;
      opt.field(load, x);
    }
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace rvegen
