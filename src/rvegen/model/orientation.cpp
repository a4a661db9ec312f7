#include "rvegen/model/orientation.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>

#include "rvegen/geometry/tolerances.hpp"
#include "rvegen/model/parallel.hpp"

namespace rvegen {

namespace {
// Carlson's duplication for R_D stops when its arguments agree to this (relative): the
// fifth-order series that follows is then accurate to about 1e-18.
constexpr double kCarlsonStop = 1e-3;
// The Newton solve for a law's parameters stops at this residual (entries of an orientation
// tensor, at most 1); its Jacobian is taken by forward differences of this step.
constexpr double kNewtonResidual = 1e-14, kDifferenceStep = 1e-6;
// Eigenvalues of a target tensor at most kAbsentEigenvalue are directions it does not want; a
// sample whose tensor has one below kLackingEigenvalue where the target wants it cannot be
// turned to match.
constexpr double kAbsentEigenvalue = 1e-12, kLackingEigenvalue = 1e-6;
}  // namespace

Vec3 AcgLaw::sample(Random& rng) const {
  for (;;) {
    const Vec3 z(rng.normal(), rng.normal(), rng.normal());
    const Vec3 x = frame * scale.cwiseProduct(z);
    const double n = x.norm();
    if (n > kNoDirection) return x / n;
  }
}

double carlson_rd(double x, double y, double z) {
  // Carlson (1995), duplication to |1 - x/mu| < kCarlsonStop, then the fifth-order series (error
  // about 1e-18 relative).
  constexpr double c1 = 3.0 / 14.0, c2 = 1.0 / 6.0, c3 = 9.0 / 22.0, c4 = 3.0 / 26.0,
                   c5 = 0.25 * c3, c6 = 1.5 * c4;
  double sum = 0.0, fac = 1.0, ave = 0.0, dx = 0.0, dy = 0.0, dz = 0.0;
  for (int it = 0; it < 200; ++it) {
    const double sx = std::sqrt(x), sy = std::sqrt(y), sz = std::sqrt(z);
    const double lambda = sx * (sy + sz) + sy * sz;
    sum += fac / (sz * (z + lambda));
    fac *= 0.25;
    x = 0.25 * (x + lambda);
    y = 0.25 * (y + lambda);
    z = 0.25 * (z + lambda);
    ave = 0.2 * (x + y + 3.0 * z);
    dx = (ave - x) / ave;
    dy = (ave - y) / ave;
    dz = (ave - z) / ave;
    if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) < kCarlsonStop) break;
  }
  const double ea = dx * dy, eb = dz * dz, ec = ea - eb, ed = ea - 6.0 * eb, ee = ed + ec + ec;
  return 3.0 * sum + fac *
                         (1.0 + ed * (-c1 + c5 * ed - c6 * dz * ee) +
                          dz * (c2 * ee + dz * (-c3 * ec + dz * c4 * ea))) /
                         (ave * std::sqrt(ave));
}

Vec3 acg_second_moments(const Vec3& b) {
  const double g = 3.0 * std::sqrt(b[0] * b[1] * b[2]);
  return Vec3(carlson_rd(1.0 / b[1], 1.0 / b[2], 1.0 / b[0]) / g,
              carlson_rd(1.0 / b[0], 1.0 / b[2], 1.0 / b[1]) / g,
              carlson_rd(1.0 / b[0], 1.0 / b[1], 1.0 / b[2]) / g);
}

Mat3 acg_fourth_moments(const Vec3& b) {
  // t = u / (1 - u) maps [0, 1) onto [0, inf); composite Gauss-Legendre (4 points, 400 panels).
  static const double xg[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                               0.8611363115940526};
  static const double wg[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                               0.3478548451374538};
  Mat3 m = Mat3::Zero();
  const int panels = 400;
  for (int p = 0; p < panels; ++p) {
    for (int q = 0; q < 4; ++q) {
      const double u = (p + 0.5 + 0.5 * xg[q]) / panels, w = 0.5 * wg[q] / panels;
      const double t = u / (1.0 - u), dt = 1.0 / ((1.0 - u) * (1.0 - u));
      double common = t * dt * w;
      for (int k = 0; k < 3; ++k) common /= std::sqrt(1.0 + 2.0 * b[k] * t);
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          m(i, j) += (i == j ? 3.0 : 1.0) * common * b[i] * b[j] /
                     ((1.0 + 2.0 * b[i] * t) * (1.0 + 2.0 * b[j] * t));
        }
      }
    }
  }
  return m;
}

namespace {
// b with second moments e (all > 0, sum 1): Newton on log b with b_0 fixed to 1.
Vec3 solve_acg(const Vec3& e) {
  Vec3 lb(0.0, 2.0 * std::log(e[1] / e[0]), 2.0 * std::log(e[2] / e[0]));  // exact in 2D
  auto residual = [&](const Vec3& l) {
    const Vec3 m = acg_second_moments(Vec3(std::exp(l[0]), std::exp(l[1]), std::exp(l[2])));
    return Eigen::Vector2d(std::log(m[1] / e[1]), std::log(m[2] / e[2]));
  };
  Eigen::Vector2d r = residual(lb);
  for (int it = 0; it < 100 && r.cwiseAbs().maxCoeff() > kNewtonResidual; ++it) {
    Eigen::Matrix2d J;
    for (int k = 0; k < 2; ++k) {
      Vec3 l = lb;
      l[k + 1] += kDifferenceStep;
      J.col(k) = (residual(l) - r) / kDifferenceStep;
    }
    const Eigen::Vector2d step = J.colPivHouseholderQr().solve(-r);
    double alpha = 1.0;
    for (int h = 0; h < 30; ++h, alpha *= 0.5) {
      Vec3 l = lb;
      l[1] += alpha * step[0];
      l[2] += alpha * step[1];
      const Eigen::Vector2d rn = residual(l);
      if (rn.norm() < r.norm() || h == 29) {
        lb = l;
        r = rn;
        break;
      }
    }
  }
  return Vec3(1.0, std::exp(lb[1]), std::exp(lb[2]));
}
}  // namespace

AcgLaw fit_acg(const Mat3& a2) {
  const Eigen::SelfAdjointEigenSolver<Mat3> es(0.5 * (a2 + a2.transpose()));
  // Eigenvalues ascending; order them descending so column 0 is the main direction.
  AcgLaw law;
  Vec3 e;
  for (int k = 0; k < 3; ++k) {
    law.frame.col(k) = es.eigenvectors().col(2 - k);
    e[k] = std::max(0.0, es.eigenvalues()[2 - k]);
  }
  e /= e.sum();
  constexpr double kZero = 1e-12;
  if (e[1] <= kZero) {
    law.scale = Vec3(1.0, 0.0, 0.0);
  } else if (e[2] <= kZero) {
    law.scale = Vec3(e[0], e[1], 0.0);  // circle: E[p_1^2] = s_1 / (s_1 + s_2)
  } else {
    law.scale = solve_acg(e).cwiseSqrt();
  }
  return law;
}

bool match_orientation_tensor(std::vector<Vec3>* dirs, const Mat3& target, double tol) {
  std::vector<Vec3>& p = *dirs;
  if (p.size() < 2) return false;
  const Eigen::SelfAdjointEigenSolver<Mat3> et(target);
  Mat3 half = Mat3::Zero();  // target^(1/2)
  for (int k = 0; k < 3; ++k) {
    const double l = std::max(0.0, et.eigenvalues()[k]);
    half += std::sqrt(l) * et.eigenvectors().col(k) * et.eigenvectors().col(k).transpose();
  }
  // The directions in fixed blocks, each block's sum of v v^T kept and the blocks' sums added
  // in block order: the same bits on any number of threads, and the sum (every iteration's
  // serial part before) runs on all cores, fused with the map of the directions.
  constexpr size_t kBlock = 1024;
  const size_t blocks = (p.size() + kBlock - 1) / kBlock;
  std::vector<Mat3> partial(blocks);
  std::vector<Vec3> q = p;
  std::atomic<bool> lost{false};
  // Maps block b's directions by t (unless t is null) and keeps their sum of v v^T.
  const auto map_and_sum = [&](const Mat3* t) {
    rvegen::parallel_for(size_t(0), blocks, [&](size_t b) {
      Mat3 sum = Mat3::Zero();
      const size_t end = std::min(q.size(), (b + 1) * kBlock);
      for (size_t i = b * kBlock; i < end; ++i) {
        if (t) {
          const Vec3 w = *t * q[i];
          const double n = w.norm();
          if (!(n > kNoDirection)) {
            lost = true;
            return;
          }
          q[i] = w / n;
        }
        sum += q[i] * q[i].transpose();
      }
      partial[b] = sum;
    });
  };
  map_and_sum(nullptr);
  for (int it = 0; it < 200; ++it) {
    Mat3 s = Mat3::Zero();
    for (const Mat3& m : partial) s += m;
    s /= static_cast<double>(q.size());
    if ((s - target).cwiseAbs().maxCoeff() <= tol) {
      p = q;
      return true;
    }
    const Eigen::SelfAdjointEigenSolver<Mat3> es(s);
    Mat3 inv_half = Mat3::Zero();  // pseudo-inverse of s^(1/2) on target's support
    for (int k = 0; k < 3; ++k) {
      const double l = es.eigenvalues()[k];
      if (l <= kAbsentEigenvalue) continue;
      if (l < kLackingEigenvalue)
        return false;  // a direction the target wants but the sample lacks
      inv_half += es.eigenvectors().col(k) * es.eigenvectors().col(k).transpose() / std::sqrt(l);
    }
    const Mat3 t = half * inv_half;
    map_and_sum(&t);
    if (lost) return false;
  }
  return false;
}

Vec3 law_axis(const Shape& s) {
  switch (s.kind) {
    case ShapeKind::Sphere:
      return Vec3::Zero();
    case ShapeKind::Cylinder:
      return s.half_axis.normalized();
    case ShapeKind::Ellipsoid:
      return s.rotation.col(0);
  }
  return Vec3::Zero();
}

double set_law_axis(Shape* s, const Vec3& p) {
  const Vec3 old = law_axis(*s);
  const double angle = std::atan2(old.cross(p).norm(), old.dot(p));
  if (s->kind == ShapeKind::Cylinder) {
    s->half_axis = p * s->half_axis.norm();
  } else if (s->kind == ShapeKind::Ellipsoid) {
    const Mat3 r = Eigen::Quaterniond::FromTwoVectors(old, p).toRotationMatrix() * s->rotation;
    // Re-orthonormalised about p so rounding does not accumulate.
    s->rotation.col(0) = p;
    s->rotation.col(1) = (r.col(1) - p.dot(r.col(1)) * p).normalized();
    s->rotation.col(2) = p.cross(s->rotation.col(1));
  }
  return angle;
}

}  // namespace rvegen
