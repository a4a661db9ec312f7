// Elastic constants of a transversely isotropic material (a fibre about its axis), shared by
// the FFT solver (turned to each fibre's axis) and the AMITEX_FFTP writer (in the fibre frame).
#pragma once

#include <Eigen/Dense>

namespace rvegen {

/// Stiffness in Voigt notation (rows and columns 11, 22, 33, 23, 13, 12; engineering shear
/// strains, so C44 is a shear modulus) of a transversely isotropic material in its own frame,
/// its axis along direction `axis` (0, 1 or 2), from the axial modulus E_L, the transverse
/// modulus E_T, the axial shear modulus G_LT, the axial Poisson's ratio nu_LT (transverse
/// contraction under axial stress) and the transverse one nu_TT (G_TT = E_T / (2 (1 + nu_TT))).
/// Throws InputError when the constants give no positive-definite tensor.
Eigen::Matrix<double, 6, 6> transverse_voigt_stiffness(double e_l, double e_t, double g_lt,
                                                       double nu_lt, double nu_tt, int axis);

}  // namespace rvegen
