#include "rvegen/model/elastic_constants.hpp"

#include <cmath>

#include "rvegen/model/errors.hpp"

namespace rvegen {

Eigen::Matrix<double, 6, 6> transverse_voigt_stiffness(double e_l, double e_t, double g_lt,
                                                       double nu_lt, double nu_tt, int axis) {
  if (!(e_l > 0.0) || !(e_t > 0.0) || !(g_lt > 0.0) || !std::isfinite(e_l + e_t + g_lt) ||
      !(nu_tt > -1.0 && nu_tt < 1.0) || !std::isfinite(nu_lt) || axis < 0 || axis > 2) {
    throw InputError(
        "transversely isotropic stiffness: moduli must be positive and finite, the transverse "
        "Poisson's ratio in (-1, 1)");
  }
  // Normal compliances: 1 / E on the diagonal, -nu / E off it.
  Eigen::Matrix3d s;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (i == j) {
        s(i, j) = 1.0 / (i == axis ? e_l : e_t);
      } else if (i == axis || j == axis) {
        s(i, j) = -nu_lt / e_l;
      } else {
        s(i, j) = -nu_tt / e_t;
      }
    }
  }
  Eigen::LLT<Eigen::Matrix3d> llt(s);
  if (llt.info() != Eigen::Success) {
    throw InputError(
        "transversely isotropic stiffness: the constants give no positive-definite tensor "
        "(check 1 - nu_TT - 2 nu_LT^2 E_T / E_L > 0)");
  }
  Eigen::Matrix<double, 6, 6> c = Eigen::Matrix<double, 6, 6>::Zero();
  c.topLeftCorner<3, 3>() = s.inverse();
  // Shear: the plane normal to the axis has G_TT, the two planes holding it G_LT (Voigt row
  // 3 + k is the shear of the plane normal to direction k).
  const double g_tt = e_t / (2.0 * (1.0 + nu_tt));
  for (int k = 0; k < 3; ++k) c(3 + k, 3 + k) = k == axis ? g_tt : g_lt;
  return c;
}

}  // namespace rvegen
