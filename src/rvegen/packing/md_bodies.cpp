#include "rvegen/packing/md_bodies.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>

#include "rvegen/geometry/tolerances.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/parallel.hpp"

namespace rvegen::md {

namespace {

// A volume fraction floor for the start scale (a scene of no volume starts at scale 1).
constexpr double kMinFraction = 1e-12;
// Just below 1: a centre on the box's far face goes in the last Morton cell.
constexpr double kBelowOne = 1.0 - 1e-12;
constexpr double kStartFraction = 0.25;  // volume fraction of the initial force scale
// Chains get at least kChainPatience times md.patience: a chain pair caught across another's
// wave blocks every certificate until it parts, so a stall is not yet a jam (tuned on the
// Figure 5 scene, samples/bench_deformed.py).
constexpr double kChainPatience = 6.0;
}  // namespace

Shape Body::at_scale(double s) const {
  if (!radial) return shape.scaled(s + pad);
  Shape out = shape;
  out.radius = shape.radius * s + add_radius;
  if (add_half > 0.0) out.half_axis = shape.half_axis * (1.0 + add_half / cap_half);
  return out;
}

Inclusion Body::chain_at(double scale) const {
  Inclusion inc = place_like(*chain, shape, scale);
  inc.mod.wave_angle = wave_angle;
  inc.mod.bend_angle = bend_angle;
  return inc;
}

namespace {
// The angle of direction R v about the frame of axis u1, v at `angle` about the frame of u0 (the
// frame of CentreLine: e1 = any_orthogonal(u), e2 = u x e1).
double turned_angle(const Vec3& u0, const Vec3& u1, const Mat3& R, double angle) {
  const Vec3 a1 = any_orthogonal(u0), a2 = u0.cross(a1);
  const Vec3 v = R * (std::cos(angle) * a1 + std::sin(angle) * a2);
  const Vec3 b1 = any_orthogonal(u1), b2 = u1.cross(b1);
  return std::atan2(v.dot(b2), v.dot(b1));
}
}  // namespace

void Body::turn_by(const Mat3& R) {
  if (shape.kind == ShapeKind::Cylinder) {
    const double len = shape.half_axis.norm();
    const Vec3 u0 = shape.half_axis / len;
    const Vec3 u1 = (R * shape.half_axis).normalized();
    shape.half_axis = u1 * len;
    if (chain) {
      wave_angle = turned_angle(u0, u1, R, wave_angle);
      bend_angle = turned_angle(u0, u1, R, bend_angle);
    }
    return;
  }
  const Mat3 Q = R * shape.rotation;
  // Re-orthonormalise (Gram-Schmidt) so rounding does not accumulate.
  const Vec3 c0 = Q.col(0).normalized();
  const Vec3 c1 = (Q.col(1) - c0.dot(Q.col(1)) * c0).normalized();
  shape.rotation.col(0) = c0;
  shape.rotation.col(1) = c1;
  shape.rotation.col(2) = c0.cross(c1);
}

void Body::support_line(const Vec3& n, double* alpha, double* beta) const {
  if (radial) {
    // Cylinder: half length |n.u| + radius sqrt(1 - (n.u)^2), radius s r + add_radius.
    const double c = std::min(1.0, std::abs(n.dot(shape.half_axis)) / cap_half);
    const double sn = std::sqrt(std::max(0.0, 1.0 - c * c));
    *alpha = (cap_half + add_half) * c + add_radius * sn;
    *beta = shape.radius * sn;
    return;
  }
  // Scaled about the centre: h_s(n) = (s + pad) h_1(n).
  const double h = shape.support_value(n) - n.dot(shape.center);
  *alpha = pad * h;
  *beta = h;
}

BodyMobility Body::mobility(const Shape& scaled) const {
  switch (turn) {
    case Turn::kNone:
      return body_mobility(scaled, false, Vec3::Zero());
    case Turn::kFree:
      return body_mobility(scaled, true, Vec3::Zero());
    case Turn::kAboutAxis:
      return body_mobility(scaled, true, turn_axis);
  }
  return body_mobility(scaled, false, Vec3::Zero());
}

double separating_scale(const Body& a, const Body& b, const Vec3& shift, const Vec3& n) {
  double alpha_a, beta_a, alpha_b, beta_b;
  a.support_line(n, &alpha_a, &beta_a);
  b.support_line(-n, &alpha_b, &beta_b);
  const double room = n.dot(b.shape.center + shift - a.shape.center) - alpha_a - alpha_b;
  if (beta_a + beta_b <= kNoDirection) return room >= 0.0 ? 1e300 : 0.0;  // holds at every scale
  return room / (beta_a + beta_b);
}

Turn turn_mode(const OrientationLaw& law, MdSettings::Rotation rotation, Vec3* axis) {
  switch (rotation) {
    case MdSettings::Rotation::kFixed:
      return Turn::kNone;
    case MdSettings::Rotation::kFree:
      if (law.kind == OrientationLaw::Kind::kAligned) return Turn::kNone;
      if (law.kind == OrientationLaw::Kind::kPlanar) {
        *axis = law.axis;
        return Turn::kAboutAxis;
      }
      return Turn::kFree;
    case MdSettings::Rotation::kKeepTensor:
      break;
  }
  // Directions the law never takes (eigenvalue 0 of its tensor) stay out of reach: turning is
  // free, about the one null direction (planar), or none (aligned).
  const OrientationLaw::NullSpace null = law.null_space();
  if (null.count >= 2) return Turn::kNone;
  if (null.count == 1) {
    *axis = null.normal;
    return Turn::kAboutAxis;
  }
  return Turn::kFree;
}

void wrap(const Box& box, Body* b) {
  b->shape.center = box.wrapped(b->shape.center);
}

Bodies make_bodies(const PackingSpec& spec, const std::vector<Inclusion>& pop, Random& rng) {
  Bodies out;
  std::vector<Body>& bodies = out.all;
  const Box& box = spec.box;
  bodies.resize(pop.size());
  double total = 0.0, crowding = 0.0, radial = 0.0;
  for (size_t i = 0; i < pop.size(); ++i) {
    Body& b = bodies[i];
    b.shape = envelope(pop[i]);    // modified inclusions are packed by their envelopes ...
    if (packs_as_chain(pop[i])) {  // ... wavy fibres by their chains of sheared pieces
      b.shape = chain_bound(pop[i]);
      b.chain = std::make_shared<const Inclusion>(pop[i]);
      b.wave_angle = pop[i].mod.wave_angle;
      b.bend_angle = pop[i].mod.bend_angle;
      out.chains = true;
    }
    b.family = pop[i].family;
    b.volume = b.shape.volume();
    b.bound = b.shape.bounding_radius();
    b.pad = spec.min_gap / (2.0 * b.shape.min_size());
    total += b.volume;
    // crowding: elongated bodies cross about 2 a phi others at volume fraction phi (a: half
    // length over radius), spheres touch about 6 phi: the start is weighed by it.
    const OrientationLaw& law = spec.families[b.family].orientation;
    switch (b.shape.kind) {
      case ShapeKind::Sphere:
        b.cap_radius = b.shape.radius;
        break;
      case ShapeKind::Cylinder:
        b.cap_half = b.shape.half_axis.norm();
        b.cap_radius = b.shape.radius;
        break;
      case ShapeKind::Ellipsoid: {
        // Capsule around the longest axis with the middle semi-axis as radius.
        Vec3 s = b.shape.semi_axes;
        std::sort(s.data(), s.data() + 3);
        b.cap_half = s[2];
        b.cap_radius = s[1];
        break;
      }
    }
    if (b.shape.kind != ShapeKind::Sphere) {
      out.oriented.push_back(static_cast<int>(i));
      b.turn = turn_mode(law, spec.md.rotation, &b.turn_axis);
      if (b.turn != Turn::kNone && spec.md.rotation == MdSettings::Rotation::kKeepTensor) {
        out.held[b.family].push_back(static_cast<int>(i));
      }
      const Modifiers& m = pop[i].mod;
      const Shape& core = pop[i].shape;
      // What the envelope adds to the core (body.hpp: envelope), and half the gap.
      const double add =
          (m.shells_may_touch ? 0.0 : m.coating) + m.packing_pad + 0.5 * spec.min_gap;
      const double add_half = m.through ? 0.0 : add;
      if (b.turn == Turn::kNone && core.kind == ShapeKind::Cylinder && !m.curved() &&
          law.null_space().count >= 2 &&
          (m.through ||
           (core.half_axis.norm() >= 2.0 * core.radius &&
            (!box.periodic || 2.0 * (core.half_axis.norm() + add_half) < box.size.minCoeff())))) {
        // (a fibre at least as long as the periodic box could meet its own image end to end
        // at every radius: it grows in length too, unless it is continuous)
        b.radial = true;
        b.shape = Shape::cylinder(b.shape.center, core.radius, core.half_axis);
        b.cap_half = core.half_axis.norm();
        b.cap_radius = core.radius;
        b.add_radius = add;
        b.add_half = add_half;
        b.through_axis = through_axis(pop[i]);
        b.pad = 0.0;
      }
    }
    // Start where few bodies touch: volume fraction kStartFraction for bodies growing in every
    // direction, weighed by crossings (see crowding) ...
    if (b.radial) {
      radial += b.volume;  // ... and for aligned fibres, whose volume grows as s^2
    } else {
      crowding += b.volume * std::max(1.0, b.bound / b.shape.min_size() / 3.0);
    }
    // Random centre: anywhere in a periodic box, inside (as far as the scale allows) otherwise.
    for (int a = 0; a < 3; ++a) b.shape.center[a] = box.origin[a] + box.size[a] * rng.uniform();
  }
  // Deformed spheres are kept apart by their support functions (tables built in parallel).
  rvegen::parallel_for(size_t(0), pop.size(), [&](size_t i) {
    if (auto table = support_table(pop[i])) {
      const Modifiers& m = pop[i].mod;
      Body& b = bodies[i];
      b.support = std::move(table);
      b.core_radius = pop[i].shape.radius;
      b.extra = (m.shells_may_touch ? 0.0 : m.coating) + m.packing_pad;
    }
  });
  double elongation = 0.0;
  for (const Body& b : bodies) elongation += b.volume * b.bound / b.shape.min_size();
  elongation /= std::max(total, kNoDirection);
  out.patience = std::llround(spec.md.patience *
                              std::max(out.chains ? kChainPatience : 1.0,
                                       std::clamp(1.0 + (elongation - 3.5) / 1.3, 1.0, 6.0)));
  const double vf = crowding / box.volume();
  out.start_scale = std::min(1.0, std::cbrt(kStartFraction / std::max(vf, kMinFraction)));
  if (radial > 0.0)
    out.start_scale = std::min(out.start_scale, std::sqrt(kStartFraction * box.volume() / radial));
  return out;
}

namespace {
// Spreads the 10 low bits of v to every third bit.
uint32_t spread_bits(uint32_t v) {
  v &= 0x3ffu;
  v = (v | (v << 16)) & 0x030000ffu;
  v = (v | (v << 8)) & 0x0300f00fu;
  v = (v | (v << 4)) & 0x030c30c3u;
  v = (v | (v << 2)) & 0x09249249u;
  return v;
}
}  // namespace

std::vector<int> order_in_space(const Box& box, Bodies* bodies) {
  std::vector<Body>& all = bodies->all;
  const size_t n = all.size();
  std::vector<std::pair<uint32_t, int>> keyed(n);
  for (size_t i = 0; i < n; ++i) {
    uint32_t cell[3];
    for (int a = 0; a < 3; ++a) {
      const double t = (all[i].shape.center[a] - box.origin[a]) / box.size[a];
      cell[a] = static_cast<uint32_t>(std::clamp(t, 0.0, kBelowOne) * 1024.0);
    }
    keyed[i] = {spread_bits(cell[0]) | spread_bits(cell[1]) << 1 | spread_bits(cell[2]) << 2,
                static_cast<int>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<int> drawn(n), place(n);
  std::vector<Body> sorted;
  sorted.reserve(n);
  for (size_t k = 0; k < n; ++k) {
    drawn[k] = keyed[k].second;
    place[drawn[k]] = static_cast<int>(k);
    sorted.push_back(all[drawn[k]]);
  }
  all.swap(sorted);
  auto renumber = [&](std::vector<int>* list) {
    for (int& i : *list) i = place[i];
    std::sort(list->begin(), list->end());
  };
  renumber(&bodies->oriented);
  for (auto& entry : bodies->held) renumber(&entry.second);
  return drawn;
}

}  // namespace rvegen::md
