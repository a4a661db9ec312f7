// How the molecular-dynamics packer answers one contact (the paper's Table 1 turned into a
// displacement): the mobilities of a body and the impulse that separates a pair.
#pragma once

#include "rvegen/geometry/pair.hpp"
#include "rvegen/geometry/shapes.hpp"

namespace rvegen {

/// Inverse translational and rotational inertia of a uniform solid inclusion (mass = volume).
/// inv_inertia is zero when the body does not turn, and projects on `axis` when it may only
/// turn about that axis (a zero axis: free).
struct BodyMobility {
  double inv_volume = 0.0;
  Mat3 inv_inertia = Mat3::Zero();
};
BodyMobility body_mobility(const Shape& s, bool turns, const Vec3& axis);

/// What the MD packer does with one contact between a (centre ca) and b (centre cb): a
/// repulsive impulse along the contact normal (from a to b), proportional to the overlap depth,
/// acting at the contact point, of the size that would separate the two bodies along the normal
/// if it acted alone (gain 1) given both mobilities. a receives -impulse, b +impulse; the
/// moves and turns are the resulting displacements and rotation vectors.
struct ContactResponse {
  Vec3 impulse = Vec3::Zero();
  Vec3 move_a = Vec3::Zero(), move_b = Vec3::Zero();
  Vec3 turn_a = Vec3::Zero(), turn_b = Vec3::Zero();
};
ContactResponse contact_response(const Vec3& ca, const BodyMobility& ma, const Vec3& cb,
                                 const BodyMobility& mb, const Contact& c, double gain);

}  // namespace rvegen
