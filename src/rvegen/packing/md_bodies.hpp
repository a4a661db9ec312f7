// Molecular-dynamics packing, part 1: the bodies. How each drawn inclusion is packed (its
// envelope, growth, bounding capsule, how it may turn) and its shape at a growth scale s.
// md.cpp describes the scheme.
#pragma once

#include <map>
#include <memory>
#include <vector>

#include "rvegen/model/deformed_support.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/packing/contacts.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen::md {

enum class Turn { kNone, kFree, kAboutAxis };

struct Body {
  Shape shape;  // current centre and orientation, sizes at scale 1
  int family = 0;
  double pad = 0.0;       // gap / (2 min_size)
  double volume = 0.0;    // at scale 1
  double bound = 0.0;     // bounding radius at scale 1
  double cap_half = 0.0;  // bounding capsule at scale 1: half length along `axis`, radius
  double cap_radius = 0.0;
  // Aligned fibres (straight cylinders, plain or coated, at least twice as long as wide, that
  // never turn) grow in radius only, at full length: growing in length, they would butt end to
  // end in columns that wrap around a periodic box and jam at any density. `shape` is then the
  // core, and the force shape has radius s r + add_radius and half length h + add_half: the
  // shell (unless shells may touch), the packing pad and half the gap are added at every scale,
  // so the coating keeps its thickness while the core grows. `pad` is 0.
  bool radial = false;
  double add_radius = 0.0, add_half = 0.0;
  // Continuous fibres (Modifiers::through): radial bodies as long as the periodic box along
  // this axis (add_half 0). An image along it is the same fibre continued, not a neighbour.
  int through_axis = -1;
  Turn turn = Turn::kNone;
  Vec3 turn_axis = Vec3::UnitZ();
  // Deformed spheres (deformed_support.hpp): `shape` is their bounding ball; pairs are kept
  // apart along the line of centres by the support function core_radius table(u) + extra, at
  // most the ball's radius (at scale 1; it scales with the body).
  std::shared_ptr<const DeformedSupport> support;
  double core_radius = 0.0, extra = 0.0;
  // Wavy fibres (body.hpp, chain_pieces): `shape` is the straight cylinder holding their chain of
  // pieces, and the drawn fibre they are cut from, placed like `shape` at each contact.
  std::shared_ptr<const Inclusion> chain;
  // A chain's wave and bend directions (Modifiers::wave_angle, bend_angle, about the frame of
  // its axis): they turn with the body, so a chain also spins about its own axis.
  double wave_angle = 0.0, bend_angle = 0.0;

  /// The drawn chain placed like the body (centre, axis, wave and bend directions), scaled by
  /// `scale` about its centre.
  Inclusion chain_at(double scale) const;
  /// Turns the body by the rotation R (its axis, and a chain's wave and bend directions).
  void turn_by(const Mat3& R);

  /// Support value at scale 1 along unit u: the table's, or the ball's radius.
  double support_along(const Vec3& u) const {
    return support ? bounded_support(*support, core_radius, extra, shape.radius, u) : shape.radius;
  }

  /// The scale the forces act at when the packer's outer scale is s_out.
  double force_scale(double s_out) const { return s_out + pad; }
  /// The shape the body is tested with at growth s (at its current centre and orientation).
  Shape at_scale(double s) const;
  /// Its bounding capsule at growth s: half length and radius.
  double cap_half_at(double s) const { return radial ? cap_half + add_half : cap_half * (s + pad); }
  double cap_radius_at(double s) const {
    return radial ? cap_radius * s + add_radius : cap_radius * (s + pad);
  }
  /// True when the image of `other` shifted by `shift` is this continuous fibre's own
  /// continuation, or another continuous fibre along the same axis met again along it: such a
  /// pair is no contact (the image without that shift is the one that counts).
  bool continued_by(const Body& other, const Vec3& shift) const {
    return through_axis >= 0 && through_axis == other.through_axis && shift[through_axis] != 0.0;
  }
  /// Support value of the body at growth s along unit n, about its centre: alpha + s beta.
  void support_line(const Vec3& n, double* alpha, double* beta) const;
  /// Translational and rotational mobility of the body's shape `scaled` (how it may turn).
  BodyMobility mobility(const Shape& scaled) const;
};

/// Largest scale s at which the plane through the contact with normal n separates a
/// (scale s + pad_a) from b (scale s + pad_b, at its centre + shift).
double separating_scale(const Body& a, const Body& b, const Vec3& shift, const Vec3& n);

/// How bodies of a family with law `law` may turn under md.rotation (`axis`: the one axis
/// they may turn about, for kAboutAxis).
Turn turn_mode(const OrientationLaw& law, MdSettings::Rotation rotation, Vec3* axis);

/// Moves the centre into a periodic box (no-op otherwise).
void wrap(const Box& box, Body* b);

/// The bodies of a drawn population, at random centres, and what the packer starts from.
struct Bodies {
  std::vector<Body> all;
  std::vector<int> oriented;             // bodies that are not spheres
  std::map<int, std::vector<int>> held;  // md.rotation keep_tensor: family -> bodies that turn
  bool chains = false;                   // some bodies are chains (wavy, bent fibres)
  double start_scale = 1.0;              // where few bodies touch (see make_bodies)
  // Steps over which a stalled valid scale halves the pressure: md.patience times
  // 1 + (e - 3.5) / 1.3, between 1 and 6, e the mean elongation of the bodies (bounding radius
  // over smallest size, weighted by volume), as long bodies rearrange more slowly: halving the
  // pressure too soon jams long fibres short of targets they reach with more patience, too late
  // wastes steps on compact bodies (so up to e = 3.5 they keep md.patience). Chains: at least
  // kChainPatience. The fibre table of docs/benchmarks.md is what the constants were tuned on.
  long long patience = 100;
};
/// (Planar and aligned fibres are then placed in layers and slots: md_layers.hpp.)
Bodies make_bodies(const PackingSpec& spec, const std::vector<Inclusion>& pop, Random& rng);

/// Bodies from this many on are put in space order (order_in_space): below, they fit in the
/// caches and the order makes no difference (and the packing stays as it always was).
constexpr size_t kSpaceOrderFrom = size_t(1) << 15;

/// Reorders the bodies along a Morton (Z-order) curve of their centres, so that bodies near in
/// space are near in memory (a large packing otherwise misses the cache at every neighbour it
/// visits). Returns `drawn`: body k is the drawn inclusion drawn[k]. The lists of body indices
/// (oriented, held) follow. The curve has 2^10 cells per axis of the box.
std::vector<int> order_in_space(const Box& box, Bodies* bodies);

}  // namespace rvegen::md
