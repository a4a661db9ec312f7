#include "rvegen/packing/contacts.hpp"

namespace rvegen {

BodyMobility body_mobility(const Shape& s, bool turns, const Vec3& axis) {
  BodyMobility m;
  const double volume = s.volume();
  m.inv_volume = 1.0 / volume;
  if (!turns || s.kind == ShapeKind::Sphere) return m;
  // Inertia tensor = volume x gyration tensor I / m of the uniform solid.
  Mat3 K;
  if (s.kind == ShapeKind::Cylinder) {
    const Vec3 u = s.half_axis.normalized();
    const double L2 = s.half_axis.squaredNorm(), r2 = s.radius * s.radius;
    const double k_ax = 0.5 * r2, k_tr = 0.25 * r2 + L2 / 3.0;
    K = k_tr * Mat3::Identity() + (k_ax - k_tr) * u * u.transpose();
  } else {
    const Vec3& a = s.semi_axes;
    const Vec3 k(a[1] * a[1] + a[2] * a[2], a[0] * a[0] + a[2] * a[2], a[0] * a[0] + a[1] * a[1]);
    K = s.rotation * (k / 5.0).asDiagonal() * s.rotation.transpose();
  }
  K *= volume;
  if (axis.squaredNorm() > 0.0) {
    const Vec3 e = axis.normalized();
    m.inv_inertia = e * e.transpose() / e.dot(K * e);
  } else {
    m.inv_inertia = K.inverse();
  }
  return m;
}

ContactResponse contact_response(const Vec3& ca, const BodyMobility& ma, const Vec3& cb,
                                 const BodyMobility& mb, const Contact& c, double gain) {
  ContactResponse r;
  const Vec3 ra = c.point - ca, rb = c.point - cb;
  const Vec3 ta = ra.cross(c.normal), tb = rb.cross(c.normal);
  const double mob =
      ma.inv_volume + ta.dot(ma.inv_inertia * ta) + mb.inv_volume + tb.dot(mb.inv_inertia * tb);
  if (!(mob > 0.0) || !c.overlap) return r;
  r.impulse = (gain * c.depth / mob) * c.normal;
  r.move_a = -ma.inv_volume * r.impulse;
  r.move_b = mb.inv_volume * r.impulse;
  r.turn_a = ma.inv_inertia * ra.cross(-r.impulse);
  r.turn_b = mb.inv_inertia * rb.cross(r.impulse);
  return r;
}

}  // namespace rvegen
