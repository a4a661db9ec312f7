#include "rvegen/model/laws.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "rvegen/model/orientation.hpp"

namespace rvegen {

namespace {
// A truncated normal size law keeps at least this share of its mean as its smallest size.
constexpr double kMinSizeShare = 1e-6;
// Concentrations below kUniformKappa draw as the uniform law (the closed form's logarithm would
// lose every digit); below kSeriesKappa the second moment is taken from its series.
constexpr double kUniformKappa = 1e-8, kSeriesKappa = 1e-3;
}  // namespace

namespace {
// Parameters of the lognormal law with the given mean and std of the size itself.
void lognormal_params(double mean, double std, double* mu, double* sigma) {
  const double s2 = std::log(1.0 + (std * std) / (mean * mean));
  *sigma = std::sqrt(s2);
  *mu = std::log(mean) - 0.5 * s2;
}
constexpr double kTails = 6.0;         // truncation of normal and lognormal laws, in std / sigma
constexpr double kWeibullTail = 1e-9;  // truncation of weibull laws: quantiles q and 1 - q
double weibull_quantile(double k, double lambda, double q) {
  return lambda * std::pow(-std::log1p(-q), 1.0 / k);
}
}  // namespace

double SizeLaw::lower() const {
  switch (kind) {
    case Kind::kFixed:
      return p1;
    case Kind::kUniform:
      return p1;
    case Kind::kNormal:
      return std::max(p1 - kTails * p2, kMinSizeShare * p1);
    case Kind::kLognormal: {
      double mu, sigma;
      lognormal_params(p1, p2, &mu, &sigma);
      return std::exp(mu - kTails * sigma);
    }
    case Kind::kWeibull:
      return weibull_quantile(p1, p2, kWeibullTail);
  }
  return p1;
}

double SizeLaw::upper() const {
  switch (kind) {
    case Kind::kFixed:
      return p1;
    case Kind::kUniform:
      return p2;
    case Kind::kNormal:
      return p1 + kTails * p2;
    case Kind::kLognormal: {
      double mu, sigma;
      lognormal_params(p1, p2, &mu, &sigma);
      return std::exp(mu + kTails * sigma);
    }
    case Kind::kWeibull:
      return weibull_quantile(p1, p2, 1.0 - kWeibullTail);
  }
  return p1;
}

double SizeLaw::sample(Random& rng) const {
  const double lo = lower(), hi = upper();
  for (;;) {
    double x = p1;
    switch (kind) {
      case Kind::kFixed:
        return p1;
      case Kind::kUniform:
        return rng.uniform(p1, p2);
      case Kind::kNormal:
        x = p1 + p2 * rng.normal();
        break;
      case Kind::kLognormal: {
        double mu, sigma;
        lognormal_params(p1, p2, &mu, &sigma);
        x = std::exp(mu + sigma * rng.normal());
        break;
      }
      case Kind::kWeibull:
        // Inverse transform on the truncated range.
        return weibull_quantile(p1, p2, kWeibullTail + (1.0 - 2.0 * kWeibullTail) * rng.uniform());
    }
    if (x >= lo && x <= hi) return x;
  }
}

double SizeLaw::moment(int k) const {
  switch (kind) {
    case Kind::kFixed:
      return std::pow(p1, k);
    case Kind::kUniform:
      return p2 > p1 ? (std::pow(p2, k + 1) - std::pow(p1, k + 1)) / ((k + 1) * (p2 - p1))
                     : std::pow(p1, k);
    default:
      break;
  }
  // Truncated normal / lognormal / weibull: Simpson's rule on the density over [lower, upper].
  double mu = p1, sigma = p2;
  if (kind == Kind::kLognormal) lognormal_params(p1, p2, &mu, &sigma);
  auto density = [&](double x) {
    if (kind == Kind::kWeibull) {
      const double z = x / p2;
      return std::pow(z, p1 - 1.0) * std::exp(-std::pow(z, p1));
    }
    const double z = kind == Kind::kNormal ? (x - mu) / sigma : (std::log(x) - mu) / sigma;
    return std::exp(-0.5 * z * z) / (kind == Kind::kNormal ? 1.0 : x);
  };
  const int n = 4000;
  const double a = lower(), b = upper(), h = (b - a) / n;
  double mass = 0.0, mom = 0.0;
  for (int i = 0; i <= n; ++i) {
    const double x = a + i * h, w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
    mass += w * density(x);
    mom += w * density(x) * std::pow(x, k);
  }
  return mom / mass;
}

Vec3 OrientationLaw::sample(Random& rng) const {
  switch (kind) {
    case Kind::kIsotropic:
      return rng.unit_vector();
    case Kind::kAligned:
      return axis;
    case Kind::kVonMisesFisher: {
      // Wood (1994) in three dimensions: w = cos(angle to the axis) has density ~ exp(kappa w).
      const double u = rng.uniform();
      const double w = kappa > kUniformKappa
                           ? 1.0 + std::log(u + (1.0 - u) * std::exp(-2.0 * kappa)) / kappa
                           : 2.0 * u - 1.0;
      const double phi = 2.0 * M_PI * rng.uniform();
      const Vec3 e1 = any_orthogonal(axis), e2 = axis.cross(e1);
      const double s = std::sqrt(std::max(0.0, 1.0 - w * w));
      return (w * axis + s * (std::cos(phi) * e1 + std::sin(phi) * e2)).normalized();
    }
    case Kind::kPlanar: {
      const double phi = 2.0 * M_PI * rng.uniform();
      const Vec3 e1 = any_orthogonal(axis), e2 = axis.cross(e1);
      return std::cos(phi) * e1 + std::sin(phi) * e2;
    }
    case Kind::kTensor:
      return fit_acg(a2).sample(rng);
  }
  return axis;
}

OrientationLaw::NullSpace OrientationLaw::null_space() const {
  const Eigen::SelfAdjointEigenSolver<Mat3> es(tensor());
  NullSpace out;
  for (int k = 0; k < 3; ++k) out.count += es.eigenvalues()[k] <= kNullEigenvalue ? 1 : 0;
  if (out.count == 1) out.normal = es.eigenvectors().col(0);
  return out;
}

Mat3 OrientationLaw::tensor() const {
  switch (kind) {
    case Kind::kIsotropic:
      return Mat3::Identity() / 3.0;
    case Kind::kAligned:
      return axis * axis.transpose();
    case Kind::kVonMisesFisher: {
      // <(p.mu)^2> = 1 - 2 (coth k - 1/k) / k; series below k = 1e-3 (isotropic limit 1/3).
      const double k = kappa;
      const double c2 = k < kSeriesKappa ? 1.0 / 3.0 + 2.0 * k / 45.0 * k
                                         : 1.0 - 2.0 * (1.0 / std::tanh(k) - 1.0 / k) / k;
      return c2 * axis * axis.transpose() +
             0.5 * (1.0 - c2) * (Mat3::Identity() - axis * axis.transpose());
    }
    case Kind::kPlanar:
      return 0.5 * (Mat3::Identity() - axis * axis.transpose());
    case Kind::kTensor:
      return a2;
  }
  return Mat3::Identity() / 3.0;
}

Mat3 OrientationLaw::as_typed(const Mat3& a) {
  if ((a - a.transpose()).cwiseAbs().maxCoeff() > kTypedTolerance ||
      std::abs(a.trace() - 1.0) > kTypedTolerance)
    return a;
  Mat3 sym = 0.5 * (a + a.transpose());
  // Eigenvalues within the tolerance of 0 are 0: a tensor typed as diag(0.5, 0.5, 1e-12) means
  // the planar law, which the packing holds exactly (kept, a tiny third eigenvalue grew).
  // A tensor without such an eigenvalue keeps its typed values (over its trace).
  const Eigen::SelfAdjointEigenSolver<Mat3> es(sym);
  Vec3 ev = es.eigenvalues();
  bool snapped = false;
  for (int k = 0; k < 3; ++k) {
    if (ev[k] != 0.0 && std::abs(ev[k]) <= kTypedTolerance) ev[k] = 0.0, snapped = true;
  }
  if (snapped) sym = es.eigenvectors() * ev.asDiagonal() * es.eigenvectors().transpose();
  const double trace = sym.trace();
  return trace == 1.0 ? sym : Mat3(sym / trace);
}

}  // namespace rvegen
