// Orientation laws given by their second-order tensor: the angular central Gaussian (ACG) fitted
// to a prescribed A2, and the correction that gives a finite sample of directions its law's A2.
//
// ACG: p = x / |x| with x ~ N(0, B). With B = V diag(b) V^T, p has A2 = V diag(e) V^T where
//   e_i = E[p_i^2] = integral_0^inf b_i (1 + 2 b_i t)^-1 prod_k (1 + 2 b_k t)^-1/2 dt
//       = R_D(1/b_j, 1/b_k, 1/b_i) / (3 sqrt(b_1 b_2 b_3))   (Carlson's R_D),
// and its fourth-order tensor (the closure it implies) has, in the same frame, the only non-zero
// components (and their index permutations)
//   A4_iijj = integral_0^inf t b_i b_j (1 + 2 b_i t)^-1 (1 + 2 b_j t)^-1
//             prod_k (1 + 2 b_k t)^-1/2 dt  (i != j),   A4_iiii = 3 x the same with j = i.
#pragma once

#include <vector>

#include "rvegen/geometry/random.hpp"
#include "rvegen/geometry/shapes.hpp"

namespace rvegen {

/// An ACG law: p = normalise(frame * (scale .* z)), z standard normal in 3D. A zero scale
/// component keeps p out of that direction (A2 eigenvalue 0).
struct AcgLaw {
  Mat3 frame = Mat3::Identity();
  Vec3 scale = Vec3::Ones();  // sqrt of B's eigenvalues
  Vec3 sample(Random& rng) const;
};

/// Carlson's symmetric elliptic integral R_D(x, y, z), x, y >= 0 (not both 0), z > 0.
double carlson_rd(double x, double y, double z);
/// E[p_i^2] of the ACG with B = diag(b), b > 0.
Vec3 acg_second_moments(const Vec3& b);
/// A4_iijj of the ACG with B = diag(b), b > 0 (the fourth moments E[p_i^2 p_j^2]).
Mat3 acg_fourth_moments(const Vec3& b);
/// The ACG whose A2 is `a2` (symmetric, trace 1, positive semi-definite), to 1e-12.
AcgLaw fit_acg(const Mat3& a2);

/// Turns the directions (the whole sample, by one linear map and renormalisation, repeated) so
/// their mean <p p^T> equals `target` to within `tol` in every component. Directions must lie in
/// the span of target's eigenvectors of non-zero eigenvalue (as draws of the law do). Returns
/// false, leaving the sample unchanged, if the sample is too degenerate to be corrected.
bool match_orientation_tensor(std::vector<Vec3>* dirs, const Mat3& target, double tol = 1e-13);

/// The axis an orientation law governs: a cylinder's axis, an ellipsoid's first semi-axis
/// (column 0 of its rotation); zero for spheres.
Vec3 law_axis(const Shape& s);
/// Turns `s` so its law_axis is the unit vector `p` (an ellipsoid's frame by the least rotation
/// that takes its first axis to p); returns the angle turned.
double set_law_axis(Shape* s, const Vec3& p);

}  // namespace rvegen
