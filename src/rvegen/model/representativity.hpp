// How big must an RVE be? The statistical answer of Kanit, Forest, Galliet, Mounoury and Jeulin
// (2003): a property Z is computed on n realizations at several volumes V; its variance follows
// D_Z^2(V) = K V^-alpha (alpha = 1 for a finite integral range; Jeulin notes smaller exponents
// for fibre systems, so alpha is fitted too); the relative error of the mean of n realizations
// is 2 D_Z(V) / (|Z| sqrt n), and the volume (or the number of realizations) that brings it
// under a target follows. Pure arithmetic, no I/O.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

namespace rvegen {

/// n values: their mean, standard deviation (divisor n - 1) and the 95 % confidence interval of
/// the mean (Student's t with n - 1 degrees of freedom). With one value: sd 0, the interval is
/// the value.
struct SampleSummary {
  size_t n = 0;
  double mean = 0.0, sd = 0.0, ci_low = 0.0, ci_high = 0.0;
};
SampleSummary summarize(const std::vector<double>& values);

/// The 0.975 quantile of Student's t with `dof` (>= 1) degrees of freedom.
double student_t975(int dof);

/// D^2(V) = K V^-alpha, fitted by least squares on log D^2 against log V over the volumes with at
/// least two realizations. `exact`: every variance is zero to rounding (the property does not
/// vary from one realization to the next: any size is representative for it). `fitted`: two
/// volumes or more with a positive variance gave K and alpha; with one such volume, alpha is
/// taken as 1 and `fitted` stays false.
struct VarianceLaw {
  bool exact = false, fitted = false;
  double K = 0.0, alpha = 1.0;
  int points = 0;  // volumes used
  double variance_at(double volume) const;
  /// The integral range A3 of D^2(V) = D2 (A3 / V)^alpha, given the point variance D2 (for a
  /// phase indicator, phi (1 - phi)).
  double integral_range(double point_variance) const;
};
/// `mean_scale` is a typical |mean| of the property (zero variances are judged against it).
VarianceLaw fit_variance_law(const std::vector<double>& volumes,
                             const std::vector<SampleSummary>& samples, double mean_scale);

/// The smallest volume at which the mean of n realizations of a property of mean `mean` has a
/// relative error (2 D(V) / (|mean| sqrt n)) of at most `rel_error`; 0 when the law is exact, and
/// infinity when it has no usable decay (alpha <= 0).
double recommended_volume(const VarianceLaw& law, double mean, double rel_error, int n);

/// The realizations needed at one volume, of variance D2, for the same relative error (at least
/// 1).
long long realizations_needed(double variance, double mean, double rel_error);

/// The window method of Kanit et al. (2003): one periodic image of a phase's share per voxel
/// (`field`, dims[0] x dims[1] x dims[2], x fastest) cut into k x k x k equal windows. For each
/// k the window volume (voxel_volume * voxels per window), the number of windows and the
/// variance of the window means about the image mean, with divisor windows - 1. That divisor is
/// the one that estimates the variance of a window in an unbounded medium: the windows of one
/// periodic image add up to its fixed total, which lowers their spread by (1 - 1/windows).
struct WindowVariance {
  int k = 0;
  double volume = 0.0;
  size_t windows = 0;
  double variance = 0.0;
  double mean = 0.0;  // the image's mean share (the windows' mean)
};
/// Throws std::invalid_argument when a k is below 2 or does not divide every dimension, or when
/// the field's size is not the product of dims.
std::vector<WindowVariance> window_variances(const std::vector<float>& field,
                                             const std::array<int, 3>& dims, double voxel_volume,
                                             const std::vector<int>& ks);

/// Several realizations' window variances (the same ks each) as one: per k the mean variance
/// and the windows of all.
std::vector<WindowVariance> pool_window_variances(
    const std::vector<std::vector<WindowVariance>>& realizations);

/// The integral range A3 of a phase of volume fraction phi from window variances (several
/// realizations pooled beforehand). For a cubic window of edge L in a medium whose covariance
/// C(h) vanishes beyond a range below L, the variance of the window's share is exactly
/// (1/L^6) Int prod_i (L - |h_i|) C(h) dh, so that
///   V D^2(V) = phi (1 - phi) A3 - b / L + O(1 / L^2),
/// the surface term b taking away from the windows' corners and faces what an unbounded
/// medium's law phi (1 - phi) A3 / V gives. The fit is weighted least squares of V D^2 against
/// 1 / L (weights: the number of windows, to which the precision of a variance is
/// proportional); A3 is its intercept over phi (1 - phi). `fitted` needs two window sizes.
struct WindowIntegralRange {
  bool fitted = false;
  double integral_range = 0.0;
  double surface_term = 0.0;  // b / (phi (1 - phi)), a length times A3's unit
  int sizes = 0;
};
WindowIntegralRange window_integral_range(const std::vector<WindowVariance>& windows, double phi);

}  // namespace rvegen
