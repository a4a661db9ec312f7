// The numerical tolerances of the geometry, named by what they protect. The pair tests' own
// tolerances (kContactRelTolerance, kDepthRelTolerance) are in pair.hpp, beside the tests they
// bound. The layers above use these where the same thing is protected, and name their own
// beside the code that owns them.
#pragma once

namespace rvegen {

/// A vector (or a squared length) at most this small has no usable direction: dividing by its
/// norm could overflow. Also the floor of a divisor that may be zero.
constexpr double kNoDirection = 1e-300;
/// The rounding noise of a length computed from a few others, relative to them (about 50 units
/// in the last place of a double): a length below it is zero, a point that near a plane is on it.
constexpr double kRoundoff = 1e-14;
/// kRoundoff squared, for squared lengths (its own literal, so that the value is exact).
constexpr double kRoundoff2 = 1e-28;
/// Two directions whose sine (the norm of the cross product of unit vectors) is at most this are
/// parallel: the point where their lines cross would lie 1e12 lengths away.
constexpr double kParallelSine = 1e-12;
/// Iterations stop when the next step would improve the answer by at most this fraction of it
/// (GJK's closest point): beyond it they chase rounding.
constexpr double kIterationStop = 1e-12;
/// One-dimensional root finders (Newton with bisection) stop at this relative width: double
/// precision, give or take a few units in the last place.
constexpr double kRootStop = 1e-15;
/// Relative margin added to computed bounds (bounding cylinders and balls, support bounds), so
/// that rounding never leaves a bound smaller than what it holds.
constexpr double kBoundMargin = 1e-12;

}  // namespace rvegen
