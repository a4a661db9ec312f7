// The tetrahedral mesher's tolerances, named by what they protect (the geometry's own, such as
// kNoDirection, are in geometry/tolerances.hpp). Lengths are relative to what each names.
#pragma once

#include "rvegen/geometry/tolerances.hpp"

namespace rvegen::mesh_parts {

/// A node within this of the box's least side from a box face lies on it: the tolerance of
/// the periodic pairs (and of a unit normal along an axis).
constexpr double kOnFace = 1e-9;
/// How far from its image's translate, in the box's least side, a node on an upper face is
/// snapped onto it (Gmsh places the nodes of copied faces to about this).
constexpr double kSnapReach = 1e-6;
/// The reach, in the box's least side, of the search for a node's periodic image once the
/// nodes are snapped (three times kOnFace: the rounded keys that found them before).
constexpr double kImageReach = 3e-9;
/// A box face's patch and its image match when their centres of mass lie within this of the
/// box's least side, and their keys (areas and bounds) agree within kPatchKeyMatch.
constexpr double kPatchTolerance = 1e-6;
constexpr double kPatchKeyMatch = 1e-3;
/// Element volumes that must add up (a flip, a fill of the box) agree to this, relatively.
constexpr double kVolumeRoundoff = 1e-9;
/// A point within this of a flat end's plane (over the cylinder's size) is on its rim or disk.
constexpr double kOnEndPlane = 1e-6;
/// A point whose angle from a debonded sphere's axis has a cosine within this of the cap's lies
/// on the void's cone.
constexpr double kOnVoidCone = 1e-7;
/// A debonding cap whose cosine is within this of -1 is the whole sphere.
constexpr double kWholeCap = 1e-9;
/// Directions (unit vectors' components, cross products) shorter than this turn too sharply to
/// follow: a face nearly tangent to a surface, a normal nearly along the face's axis.
constexpr double kShallowTangent = 1e-3;
constexpr double kShortDirection = 1e-6;
/// A fibre axis's component along a face normal at most this is parallel to the face (its
/// squared cross product with the normal, kParallel2).
constexpr double kParallelComponent = 1e-9;
constexpr double kParallel2 = 1e-18;
/// Newton's steps onto a surface stop at kRoundoff-like 1e-12 of the step and succeed at
/// kNewtonReach of it.
constexpr double kNewtonStop = 1e-12;
constexpr double kNewtonReach = 1e-9;
/// A node's step search shrinks its step down to this fraction of the shortest edge.
constexpr double kLeastStep = 1e-3;
/// A nudge moves an inclusion past a contact's depth by this share of min_gap, and of its own
/// size (the depth is an upper bound or exact).
constexpr double kPastGap = 1e-3;
constexpr double kPastSize = 1e-9;
/// Gmsh's integration of the size field along curves stops at this precision in elements
/// (its own default, 1e-9, costs far more time for the same nodes).
constexpr double kSizeIntegrationPrecision = 1e-5;
/// A sliver's remake may move an interface: by flipping its edge where the two lines (the edge
/// and the new diagonal) lie within kFlipReach of the shorter's length apart, and by
/// collapsing an edge where the kept node lies within kCollapseReach of the mean edge length
/// from the plane of each of the other node's interface triangles. At most kRemakeRounds
/// rounds of remakes.
constexpr double kFlipReach = 0.1;
constexpr double kCollapseReach = 0.1;
constexpr int kRemakeRounds = 4;
/// At most kLiftRounds rounds of node moves lift slivers (a move can help an element next to it).
constexpr int kLiftRounds = 4;
/// The element estimate counts its running sum in thousandths of an element.
constexpr double kEstimateUnit = 1e-3;

}  // namespace rvegen::mesh_parts
