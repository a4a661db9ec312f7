#include "rvegen/homogenize/conductivity.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <unordered_map>

#include "rvegen/model/errors.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {

namespace {

// Conductivity tensors are positive semi-definite to this share of their size.
constexpr double kTensorRounding = 1e-12;

// The orthogonal projection onto discrete gradient fields, k k^H / |k|^2 = xi xi^T at each
// frequency (xi the real unit direction of k), on 3-component fields.
// The projection onto gradients at one frequency, xi (xi . v): a gradient's potential is the
// one complex value xi . v. Real coefficients: the real and the imaginary parts as one pair.
struct GradientKernel {
  static constexpr int kComponents = 3;
  static constexpr int kPotentials = 1;
  using Pair = spectral::Pair;
  // xi . v on one frequency (V a Pair), or on two neighbouring ones (a Quad, xi's lanes each
  // frequency's).
  template <class V, class S>
  RVEGEN_LANES static void reduce(double* const* v, size_t i, const S* xi, V* w) {
    using spectral::load_lanes;
    w[0] = xi[0] * load_lanes<V>(v[0] + i) + xi[1] * load_lanes<V>(v[1] + i) +
           xi[2] * load_lanes<V>(v[2] + i);
  }
  template <class V, class S>
  RVEGEN_LANES static void expand(const V* w, const S* xi, double scale, double* const* v,
                                  size_t i) {
    const V s = scale * w[0];
    for (int a = 0; a < 3; ++a) spectral::store_lanes(v[a] + i, xi[a] * s);
  }
  // |xi w|^2 for |xi| = 1 (w is 0 where xi is), into squares.
  template <class V, class S>
  RVEGEN_LANES static void norm(const V* w, const S*, V& squares) {
    squares = w[0] * w[0];
  }
  static void project(double* const* v, size_t i, const double* xi) {
    Pair w[1];
    reduce(v, i, xi, w);
    expand(w, xi, 1.0, v, i);
  }
};
using GradientProjection = spectral::Projection<GradientKernel>;

}  // namespace

ConductivityResult effective_conductivity(const std::array<int, 3>& dims, const Vec3& box_size,
                                          const std::vector<double>& conductivity,
                                          const ConductivityOptions& opt) {
  spectral::checked_voxels(dims, box_size);
  const size_t n = spectral::slab_voxels(dims, opt.comm);
  if (conductivity.size() != n) {
    throw InputError("homogenization: " + std::to_string(conductivity.size()) +
                     " conductivities for " + std::to_string(n) + " voxels");
  }
  // One isotropic tensor per distinct value.
  ConductivityMedium m;
  m.index.resize(n);
  std::unordered_map<double, uint32_t> row;
  for (size_t i = 0; i < n; ++i) {
    const double k = conductivity[i];
    if (!(k >= 0.0) || !std::isfinite(k)) {
      throw InputError("homogenization: conductivities must be finite and >= 0");
    }
    auto [it, fresh] = row.try_emplace(k, static_cast<uint32_t>(m.tensors.size()));
    if (fresh) m.tensors.push_back(k * Mat3::Identity());
    m.index[i] = it->second;
  }
  return effective_conductivity(dims, box_size, m, opt);
}

namespace {

// Checks the medium (finite, positive semi-definite tensors; an index for every voxel) and
// gives the extreme eigenvalues over the tensors in use (the fixed-point reference; every
// rank's).
void checked_extremes(const ConductivityMedium& medium, const ConductivityOptions& opt,
                      double* kmin, double* kmax) {
  *kmin = INFINITY;
  *kmax = 0.0;
  for (const Mat3& t : medium.tensors) {
    if (!t.allFinite()) throw InputError("homogenization: conductivities must be finite");
    const Vec3 ev = Eigen::SelfAdjointEigenSolver<Mat3>(t).eigenvalues();
    if (ev.minCoeff() < -kTensorRounding * std::max(1.0, ev.maxCoeff())) {
      throw InputError("homogenization: conductivities must be positive semi-definite");
    }
    *kmin = std::min(*kmin, ev.minCoeff());
    *kmax = std::max(*kmax, ev.maxCoeff());
  }
  for (uint32_t i : medium.index) {
    if (i >= medium.tensors.size()) throw InputError("homogenization: a voxel has no tensor");
  }
  if (opt.solver == LinearSolver::kFixedPoint && opt.comm.set) {
    *kmin = -max_over_ranks(-*kmin, opt.comm);
    *kmax = max_over_ranks(*kmax, opt.comm);
  }
}

}  // namespace

ConductivityResult effective_conductivity(const std::array<int, 3>& dims, const Vec3& box_size,
                                          const ConductivityMedium& medium,
                                          const ConductivityOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  const size_t whole = spectral::checked_voxels(dims, box_size),
               n = spectral::slab_voxels(dims, opt.comm);
  if (medium.index.size() != n) {
    throw InputError("homogenization: a medium of " + std::to_string(medium.index.size()) +
                     " voxels for " + std::to_string(n));
  }
  double kmin = 0.0, kmax = 0.0;
  checked_extremes(medium, opt, &kmin, &kmax);
  GradientProjection project(dims, box_size, opt.scheme, opt.threads, opt.comm);
  const spectral::Grid& grid = project.grid();
  ConductivityResult res;
  // For conjugate gradients, the solver's r and s as potentials, one complex value a frequency
  // (spectral::GalerkinFields; p and x too for the local fields, and x's field); for the
  // fixed-point scheme x, tmp, e and r.
  const bool fixed_point = opt.solver == LinearSolver::kFixedPoint;
  std::vector<double> x(fixed_point || opt.field ? 3 * n : 0), tmp, e, r;
  if (fixed_point) tmp.resize(3 * n), e.resize(3 * n), r.resize(3 * n);
  // The mean of the tensors: the mean flux of a uniform gradient.
  Mat3 mean_tensor = medium.sum();
  sum_over_ranks(mean_tensor.data(), 9, opt.comm);
  mean_tensor /= static_cast<double>(whole);
  // k times a 3-component field, and (k - k0) times one.
  auto times = [&](const std::vector<double>& f, std::vector<double>* out, double shift) {
    spectral::parallel_blocks(n, [&](size_t lo, size_t hi) {
      for (size_t i = lo; i < hi; ++i) {
        const Vec3 g(f[i], f[n + i], f[2 * n + i]);
        const Vec3 q = medium.at(i) * g - shift * g;
        for (int a = 0; a < 3; ++a) (*out)[a * n + i] = q[a];
      }
    });
  };
  auto times_k = [&](const std::vector<double>& f, std::vector<double>* out) {
    times(f, out, 0.0);
  };
  std::vector<double> b;            // the fixed-point scheme's right-hand side
  spectral::GalerkinFields fields;  // the solver's (kept over the loads)
  spectral::GalerkinOperator op;
  op.components = 3;
  op.potentials = GradientKernel::kPotentials;
  // Isotropic tensors (the phases; composite voxels have general ones) by their one number.
  std::vector<double> scalar(medium.tensors.size(), -1.0);  // -1: not isotropic
  for (size_t t = 0; t < medium.tensors.size(); ++t) {
    const Mat3& k = medium.tensors[t];
    if (k == k(0, 0) * Mat3::Identity()) scalar[t] = k(0, 0);
  }
  op.flux = [&](double* const* v, size_t lo, size_t hi, double* sums) {
    spectral::flux_in_runs<3, 1>(
        v, lo, hi, sums,
        [&](size_t i, double* n) {
          n[0] = scalar[medium.index[i]];
          return n[0] >= 0.0;
        },
        [](const auto* n, const auto* g, auto* q) RVEGEN_LANES_LAMBDA {
          for (int c = 0; c < 3; ++c) q[c] = n[0] * g[c];
        },
        [&](size_t i, const double* g, double* q) {
          Eigen::Map<Vec3> out(q);
          out = medium.at(i) * Eigen::Map<const Vec3>(g);
        });
  };
  op.step = [&](const spectral::GalerkinStep& st) { return project.galerkin_step(st); };
  for (int load = 0; load < 3; ++load) {
    // Mean gradient E = unit vector along `load`; unknown: the fluctuation x (a gradient field
    // with zero mean); equilibrium: P[k (E + x)] = 0, i.e. P[k x] = -P[k E].
    auto progress = [&](int it, double rel) {
      return !opt.progress || opt.progress(load, it, rel);
    };
    spectral::CgOutcome out;
    bool solved = false;  // a right-hand side of 0 asks for nothing
    if (opt.solver == LinearSolver::kConjugateGradient) {
      double e[3] = {0.0, 0.0, 0.0};
      e[load] = 1.0;
      std::vector<double> flux;
      out = spectral::conjugate_gradients_galerkin(project.grid(), project.spectra(), op, e, fields,
                                                   opt.field ? &x : nullptr, &flux, opt.tolerance,
                                                   opt.max_iterations, progress);
      solved = out.iterations > 0;
      // The mean flux: that of E plus the mean of k x, summed as the solver went.
      res.tensor.col(load) = mean_tensor.col(load) + Vec3(flux[0], flux[1], flux[2]);
    } else {
      b.assign(3 * n, 0.0);
      std::fill(b.begin() + load * n, b.begin() + (load + 1) * n, 1.0);
      const std::vector<double> mean = b;
      times_k(b, &b);
      project.apply(b.data(), b.data());
      const double bnorm = std::sqrt(grid.dot(b, b));
      solved = bnorm > 0.0;
      if (solved) {
        // Basic scheme with the reference k0 = (kmin + kmax) / 2: x <- -P[(k - k0)(E + x)] / k0;
        // the residual is the gradient part of the flux of the new iterate.
        const double k0 = 0.5 * (kmin + kmax);
        std::fill(x.begin(), x.end(), 0.0);
        for (int it = 1; it <= opt.max_iterations; ++it) {
          for (size_t i = 0; i < 3 * n; ++i) e[i] = mean[i] + x[i];
          times(e, &tmp, k0);
          project.apply(tmp.data(), x.data());
          for (double& v : x) v /= -k0;
          for (size_t i = 0; i < 3 * n; ++i) e[i] = mean[i] + x[i];
          times_k(e, &tmp);
          project.apply(tmp.data(), r.data());
          out.iterations = it;
          out.residual = std::sqrt(grid.dot(r, r)) / bnorm;
          if (grid.sum(progress(it, out.residual) ? 0.0 : 1.0) > 0.0) {  // on any rank
            out.stopped = true;
            break;
          }
          if (out.residual < opt.tolerance) break;
        }
      } else {
        std::fill(x.begin(), x.end(), 0.0);
        res.tensor.col(load) = mean_tensor.col(load);
      }
    }
    if (out.stopped) throw Cancelled();
    res.iterations[load] = out.iterations;
    res.residual[load] = out.residual;
    res.breakdown[load] = out.breakdown;
    if (solved && !(out.residual < opt.tolerance)) res.converged = false;
    if (!out.breakdown.empty()) res.converged = false;
    // The local gradient E + x (x is reset by the next solve).
    if (!x.empty()) {
      for (size_t i = 0; i < n; ++i) x[load * n + i] += 1.0;
    }
    if (fixed_point && solved) {
      // The fixed-point scheme's mean flux, voxel by voxel in order.
      Vec3 sum = Vec3::Zero();
      for (size_t i = 0; i < n; ++i) sum += medium.at(i) * Vec3(x[i], x[n + i], x[2 * n + i]);
      sum_over_ranks(sum.data(), 3, opt.comm);
      res.tensor.col(load) = sum / static_cast<double>(whole);
    }
    if (opt.field) opt.field(load, x);
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace rvegen
