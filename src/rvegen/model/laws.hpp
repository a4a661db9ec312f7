// The laws a family draws from: sizes (fixed, uniform, normal, lognormal, weibull) and
// orientations (isotropic, aligned, von Mises-Fisher, planar, tensor), with their exact moments.
#pragma once

#include "rvegen/geometry/random.hpp"
#include "rvegen/geometry/shapes.hpp"

namespace rvegen {

struct AcgLaw;

/// Distribution of one size (radius, aspect ratio, semi-axis).
/// normal and lognormal take the mean and standard deviation of the size itself and are
/// truncated to [max(lo, tiny), hi] with lo/hi at mean -/+ 6 std (normal) or exp(mu -/+ 6 sigma)
/// (lognormal): draws outside are redrawn, so sizes are always positive and bounded. weibull
/// (shape k, scale lambda) is truncated to its quantiles 1e-9 and 1 - 1e-9.
struct SizeLaw {
  enum class Kind { kFixed, kUniform, kNormal, kLognormal, kWeibull };
  Kind kind = Kind::kFixed;
  double p1 = 0.0;  // fixed: value; uniform: min; normal, lognormal: mean; weibull: shape k
  double p2 = 0.0;  // uniform: max; normal, lognormal: std; weibull: scale lambda

  SizeLaw() = default;
  SizeLaw(double value) : p1(value) {}  // NOLINT(google-explicit-constructor): a fixed size
  bool fixed() const { return kind == Kind::kFixed; }
  double sample(Random& rng) const;
  /// Smallest and largest size the law can draw.
  double lower() const;
  double upper() const;
  /// E[X^k] of the (truncated) law.
  double moment(int k) const;
  double mean() const { return moment(1); }
};

/// Law of the directions of a family's axes (cylinder axis, ellipsoid first semi-axis).
/// `tensor` draws from the angular central Gaussian (ACG) whose second-order orientation tensor
/// is `a2`: p = x / |x| with x ~ N(0, B), B fitted to a2 (see orientation.hpp).
struct OrientationLaw {
  enum class Kind { kIsotropic, kAligned, kVonMisesFisher, kPlanar, kTensor };
  Kind kind = Kind::kIsotropic;
  Vec3 axis = Vec3::UnitZ();         // unit: aligned and von Mises-Fisher axis, planar normal
  double kappa = 0.0;                // von Mises-Fisher concentration
  Mat3 a2 = Mat3::Identity() / 3.0;  // tensor: the target <p p^T>
  /// A unit direction drawn from the law (the tensor law fits its ACG on every call: draw many
  /// through an AcgSampler instead).
  Vec3 sample(Random& rng) const;
  /// The law's second-order orientation tensor <p p^T> (exact).
  Mat3 tensor() const;
  /// What the law forbids: the directions it never takes, the null space of its tensor
  /// (eigenvalues at most kNullEigenvalue). `count` 0: every direction is taken; 1: the axes
  /// stay in the plane normal to `normal` (planar laws, and tensors of that kind); 2 or more:
  /// one direction only (aligned).
  struct NullSpace {
    int count = 0;
    Vec3 normal = Vec3::Zero();
  };
  NullSpace null_space() const;
  static constexpr double kNullEigenvalue = 1e-12;
  /// Tensors typed by users are symmetric and of trace 1 to this (the validation says so).
  static constexpr double kTypedTolerance = 1e-6;
  /// A tensor as typed, as the law takes it: within kTypedTolerance of symmetric and of trace
  /// 1, its symmetric part over its trace (the law then reaches what the user meant, not a
  /// tensor 5e-7 off trace 1); any other unchanged, for the validation to name.
  static Mat3 as_typed(const Mat3& a);
};

}  // namespace rvegen
