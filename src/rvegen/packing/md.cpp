// Molecular-dynamics packing (the paper's section 3) with growth, in the spirit of the
// force-biased algorithm.
//
// All inclusions are drawn and placed at once at random positions. Every inclusion i is
// scaled about its centre by a common factor: s_out + pad_i for the forces (the "outer" size)
// while the configuration is certified non-overlapping at a smaller "inner" scale s_in. Each
// step:
//   1. every pair that overlaps at the outer scale (exact pair test) gets a repulsive contact
//      proportional to the overlap depth, along the test's separating normal and applied at its
//      point of application (paper, Table 1), so cylinders and ellipsoids also turn;
//      non-periodic boxes add the same kind of contact with each wall;
//   2. s_in is the largest scale at which every such pair is still separated by the plane of
//      its contact normal (support functions, exact for spheres, a certified lower bound
//      otherwise); pairs that do not overlap at the outer scale are valid below it, since a
//      convex body scaled down about an inner point stays inside itself. The best s_in so far
//      and its configuration are recorded;
//   3. bodies move in the strongly damped limit of the paper's equations of motion: each
//      contact's impulse is the one that would just separate the pair if it acted alone (with
//      the translational and rotational mobilities of both bodies), plus a fraction kMomentum
//      of the previous step's motion (damping 1 - kMomentum).
// The outer scale follows the inner one: s_out = s_in (1 + m), with the "pressure" m halved
// whenever s_in has stalled over md.patience steps (md.pressure is its initial value). The run ends
// when s_in >= 1 (status "ok": the inclusions have their drawn sizes), when m < kMinPressure
// (jammed), or on the step/time budget; then the status is "target_not_reached" and the best valid
// configuration is returned shrunk to its scale.
//
// min_gap: inclusion i is tested at scale s + gap / (2 min_size_i); scaled so, it contains the
// inclusion at scale s grown by gap / 2 in every direction, so valid pairs are >= gap apart.
//
// Broad phase: a Verlet list of pairs (with periodic shift) whose bounding capsules, inflated
// by a skin, intersect; it is rebuilt when some body could have moved (translation, rotation
// times its radius, growth) by more than half the skin. It is built on a cell grid of spheres
// strung along each capsule's axis, so long fibres do not force huge cells.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <tuple>

#include "rvegen/model/body.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/model/orientation.hpp"
#include "rvegen/packing/contacts.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {

namespace {

constexpr double kMomentum = 0.9;    // fraction of the last step's motion kept (damping 0.1)
constexpr double kRelaxation = 1.0;  // scale of the summed contact impulses
constexpr double kMinPressure = 1e-6;
constexpr double kStall = 0.1;           // m halves when the valid scale grew by less than kStall m
constexpr double kSkin = 0.5;            // Verlet skin, in capsule radii of each body
constexpr double kSkinLength = 0.5;      // or in half lengths of each body if more
constexpr double kStartFraction = 0.25;  // volume fraction of the initial force scale
constexpr double kMaxTurn = 0.2;         // radians per step

enum class Turn { kNone, kFree, kAboutAxis };

struct Body {
  Shape shape;  // current centre and orientation, sizes at scale 1
  int family = 0;
  double pad = 0.0;       // gap / (2 min_size)
  double volume = 0.0;    // at scale 1
  double bound = 0.0;     // bounding radius at scale 1
  double cap_half = 0.0;  // bounding capsule at scale 1: half length along `axis`, radius
  double cap_radius = 0.0;
  // Aligned fibres (plain cylinders at least twice as long as wide that never turn) grow in
  // radius only, at full length: growing in length, they would butt end to end in columns that
  // wrap around a periodic box and jam at any density. Their force shape is radius
  // s r + half_gap and half length h + half_gap, and `pad` is 0.
  bool radial = false;
  double half_gap = 0.0;
  Turn turn = Turn::kNone;
  Vec3 turn_axis = Vec3::UnitZ();
};

// Squared distance between segments [p1, q1] and [p2, q2] (Ericson, Real-Time Collision
// Detection, 5.1.9).
double segment_distance2(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2) {
  const Vec3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0.0, t = 0.0;
  if (a <= 1e-300 && e <= 1e-300) return r.squaredNorm();
  if (a <= 1e-300) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 1e-300) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), den = a * e - b * b;
      s = den > 1e-14 * a * e ? std::clamp((b * f - c * e) / den, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return (p1 + d1 * s - (p2 + d2 * t)).squaredNorm();
}

struct PairEntry {
  int a, b;
  Vec3 shift;  // b is taken at its centre + shift
};

class MdPacker {
 public:
  MdPacker(const PackingSpec& scene, const ProgressFn& progress)
      : scene_(scene), box_(scene.box), progress_(progress) {}

  PackingResult run();

 private:
  void init_bodies();
  double force_scale(const Body& b) const { return s_out_ + b.pad; }
  // The shape a body is tested with at growth s (at its current centre and orientation).
  static Shape at_scale(const Body& b, double s);
  // Its bounding capsule at growth s: half length and radius.
  static double cap_half_at(const Body& b, double s) {
    return b.radial ? b.cap_half + b.half_gap : b.cap_half * (s + b.pad);
  }
  static double cap_radius_at(const Body& b, double s) {
    return b.radial ? b.cap_radius * s + b.half_gap : b.cap_radius * (s + b.pad);
  }
  // Support value of the body at growth s along unit n, about its centre: alpha + s beta.
  static void support_line(const Body& b, const Vec3& n, double* alpha, double* beta);
  void build_pairs();
  bool pairs_stale() const;
  // Contacts of the current configuration at the force scale: accumulates their motion and
  // returns a scale at which the current configuration is valid.
  double contacts();
  void move();  // damped motion from the accumulated contacts
  // md.rotation keep_tensor: one linear map per family restores the law's A2 after turning.
  void hold_tensors();
  Turn turn_mode(const OrientationLaw& law, Vec3* axis) const;
  std::map<int, std::vector<int>> held_;  // family -> bodies that turn
  void wrap(Body& b) const;
  void snapshot(double scale);
  void report_progress(bool force);
  // Largest scale s <= s_out at which the plane through the contact with normal n separates
  // a (scale s + pad_a) from b (scale s + pad_b, at its centre + shift).
  double separating_scale(const Body& a, const Body& b, const Vec3& shift, const Vec3& n) const;

  BodyMobility mobility_of(const Body& b, const Shape& scaled) const;
  struct Key {
    int a, b, kx, ky, kz;
    bool operator<(const Key& o) const {
      return std::tie(a, b, kx, ky, kz) < std::tie(o.a, o.b, o.kx, o.ky, o.kz);
    }
    bool operator==(const Key& o) const {
      return a == o.a && b == o.b && kx == o.kx && ky == o.ky && kz == o.kz;
    }
  };
  static Key make_key(int a, int b, int kx, int ky, int kz);
  // Spheres covering every body (centre, radius, body) at the last pair-list build.
  std::vector<Vec3> sub_c_;
  std::vector<double> sub_r_;
  std::vector<int> sub_body_;
  std::vector<Key> keys_;
  std::vector<double> half_skin_;
  void add(int i, const Vec3& move, const Vec3& turn) {
    move_[i] += move;
    turn_[i] += turn;
  }

  const PackingSpec& scene_;
  const Box& box_;
  const ProgressFn& progress_;
  std::vector<Body> bodies_;
  std::vector<Vec3> move_, turn_, vel_, omega_;
  std::vector<Vec3> axis_;  // principal axis of every body this step
  // Steps over which a stalled valid scale halves the pressure: md.patience, times the mean
  // elongation / 6.7 (at most 6) of the bodies, as long bodies rearrange more slowly.
  long long patience_ = 100;
  // Verlet list and the state it was built for. Centres are wrapped into a periodic box only
  // when the list is rebuilt, so the stored shifts stay right between rebuilds.
  std::vector<PairEntry> pairs_;
  std::vector<Vec3> built_center_;
  std::vector<double> turned_since_build_;
  double built_scale_ = -1.0;
  long long rebuilds_ = 0;
  // Scale control: contacts act at s_out = max(s_start, s_in (1 + m)).
  double s_out_ = 0.0, s_start_ = 0.0, m_ = 0.0;
  long long steps_ = 0;
  double max_overlap_ = 0.0;  // largest relative overlap depth of the last step
  // Best valid configuration.
  double best_scale_ = -1.0;
  std::vector<Vec3> best_center_;
  std::vector<int> oriented_;  // bodies that are not spheres
  std::vector<Shape> best_oriented_;
  std::vector<Inclusion> pop_;  // drawn cores and modifiers
  std::chrono::steady_clock::time_point t0_, last_progress_;
  // The time budget holds inside a step too (a pair-list build of a crowded scene can take
  // longer than the budget): long loops call check_time(), which throws OutOfTime.
  struct OutOfTime {};
  std::chrono::steady_clock::time_point deadline_;
  void check_time() const {
    if (std::chrono::steady_clock::now() > deadline_) throw OutOfTime{};
  }
};

void MdPacker::init_bodies() {
  Random rng(scene_.seed);
  pop_ = draw_population(scene_, rng);
  const std::vector<Inclusion>& pop = pop_;
  bodies_.resize(pop.size());
  double total = 0.0, crowding = 0.0, radial = 0.0;
  for (size_t i = 0; i < pop.size(); ++i) {
    Body& b = bodies_[i];
    b.shape = envelope(pop[i]);  // modified inclusions are packed by their envelopes
    b.family = pop[i].family;
    b.volume = b.shape.volume();
    b.bound = b.shape.bounding_radius();
    b.pad = scene_.min_gap / (2.0 * b.shape.min_size());
    total += b.volume;
    // crowding: elongated bodies cross about 2 a phi others at volume fraction phi (a: half
    // length over radius), spheres touch about 6 phi: the start is weighed by it.
    const OrientationLaw& law = scene_.families[b.family].orientation;
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
      oriented_.push_back(static_cast<int>(i));
      b.turn = turn_mode(law, &b.turn_axis);
      if (b.turn != Turn::kNone && scene_.md.rotation == MdSettings::Rotation::kKeepTensor) {
        held_[b.family].push_back(static_cast<int>(i));
      }
      const Eigen::SelfAdjointEigenSolver<Mat3> es(law.tensor());
      if (b.turn == Turn::kNone && b.shape.kind == ShapeKind::Cylinder && !pop[i].mod.any() &&
          es.eigenvalues()[1] <= 1e-12 && b.shape.half_axis.norm() >= 2.0 * b.shape.radius &&
          (!box_.periodic ||
           2.0 * (b.shape.half_axis.norm() + 0.5 * scene_.min_gap) < box_.size.minCoeff())) {
        // (a fibre at least as long as the periodic box could meet its own image end to end
        // at every radius: it grows in length too)
        b.radial = true;
        b.half_gap = 0.5 * scene_.min_gap;
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
    for (int a = 0; a < 3; ++a) b.shape.center[a] = box_.origin[a] + box_.size[a] * rng.uniform();
  }
  double elongation = 0.0;
  for (const Body& b : bodies_) elongation += b.volume * b.bound / b.shape.min_size();
  elongation /= std::max(total, 1e-300);
  patience_ = std::llround(scene_.md.patience * std::clamp(elongation / 6.7, 1.0, 6.0));
  const double vf = crowding / box_.volume();
  s_start_ = std::min(1.0, std::cbrt(kStartFraction / std::max(vf, 1e-12)));
  if (radial > 0.0)
    s_start_ = std::min(s_start_, std::sqrt(kStartFraction * box_.volume() / radial));
  s_out_ = s_start_;
  m_ = scene_.md.pressure;
  const size_t n = bodies_.size();
  move_.assign(n, Vec3::Zero());
  turn_.assign(n, Vec3::Zero());
  vel_.assign(n, Vec3::Zero());
  omega_.assign(n, Vec3::Zero());
}

// How bodies of a family with law `law` may turn under md.rotation.
Turn MdPacker::turn_mode(const OrientationLaw& law, Vec3* axis) const {
  switch (scene_.md.rotation) {
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
  const Eigen::SelfAdjointEigenSolver<Mat3> es(law.tensor());
  int zeros = 0;
  for (int k = 0; k < 3; ++k) zeros += es.eigenvalues()[k] <= 1e-12 ? 1 : 0;
  if (zeros >= 2) return Turn::kNone;
  if (zeros == 1) {
    *axis = es.eigenvectors().col(0);
    return Turn::kAboutAxis;
  }
  return Turn::kFree;
}

void MdPacker::hold_tensors() {
  for (const auto& [family, members] : held_) {
    std::vector<Vec3> dirs(members.size());
    for (size_t k = 0; k < members.size(); ++k) dirs[k] = law_axis(bodies_[members[k]].shape);
    if (!match_orientation_tensor(&dirs, scene_.families[family].orientation.tensor(), 1e-10)) {
      continue;
    }
    for (size_t k = 0; k < members.size(); ++k) {
      turned_since_build_[members[k]] += set_law_axis(&bodies_[members[k]].shape, dirs[k]);
    }
  }
}

void MdPacker::wrap(Body& b) const {
  if (!box_.periodic) return;
  for (int a = 0; a < 3; ++a) {
    const double t = (b.shape.center[a] - box_.origin[a]) / box_.size[a];
    b.shape.center[a] -= std::floor(t) * box_.size[a];
  }
}

bool MdPacker::pairs_stale() const {
  if (built_scale_ < 0.0) return true;
  for (size_t i = 0; i < bodies_.size(); ++i) {
    const Body& b = bodies_[i];
    const double d = (b.shape.center - built_center_[i]).norm();
    const double grow = (b.radial ? b.cap_radius : b.bound) * std::max(0.0, s_out_ - built_scale_);
    const double r = cap_half_at(b, s_out_) + cap_radius_at(b, s_out_);
    if (d + turned_since_build_[i] * r + grow > half_skin_[i]) return true;
  }
  return false;
}

// Canonical key of a candidate pair: a <= b, b taken at its centre + k * box (k in box sizes);
// for a == b one of k and -k.
MdPacker::Key MdPacker::make_key(int a, int b, int kx, int ky, int kz) {
  if (a > b) {
    std::swap(a, b);
    kx = -kx;
    ky = -ky;
    kz = -kz;
  }
  if (a == b && (kx < 0 || (kx == 0 && (ky < 0 || (ky == 0 && kz < 0))))) {
    kx = -kx;
    ky = -ky;
    kz = -kz;
  }
  return {a, b, kx, ky, kz};
}

void MdPacker::build_pairs() {
  const size_t n = bodies_.size();
  built_center_.resize(n);
  half_skin_.resize(n);
  turned_since_build_.assign(n, 0.0);
  built_scale_ = s_out_;
  ++rebuilds_;
  pairs_.clear();
  for (Body& b : bodies_) wrap(b);
  // Strings of spheres covering each capsule inflated by the body's half skin (relative to its
  // size, so large bodies do not force frequent rebuilds).
  sub_c_.clear();
  sub_r_.clear();
  sub_body_.clear();
  std::vector<Vec3> seg_p(n), seg_q(n);
  std::vector<double> cap_r(n);
  for (size_t i = 0; i < n; ++i) {
    const Body& b = bodies_[i];
    built_center_[i] = b.shape.center;
    // Long bodies get a skin of a fraction of their length too: their ends sweep far when
    // they grow or turn, and the capsule test in contacts() keeps the extra pairs cheap.
    // Aligned fibres (radial) neither turn nor grow in length: the skin of a half-grown fibre.
    half_skin_[i] =
        b.radial ? 0.5 * kSkin * b.cap_radius * std::max(s_out_, 0.5)
                 : 0.5 * kSkin * std::max(b.cap_radius, kSkinLength * b.cap_half) * force_scale(b);
    const Vec3 e = principal_axis(b.shape) * cap_half_at(b, s_out_);
    const double rho = cap_radius_at(b, s_out_) + half_skin_[i];
    seg_p[i] = b.shape.center - e;
    seg_q[i] = b.shape.center + e;
    cap_r[i] = rho;
    const int k = b.cap_half > 0.0 ? static_cast<int>(std::ceil(2.0 * e.norm() / rho)) + 1 : 1;
    const double spacing = k > 1 ? 2.0 * e.norm() / (k - 1) : 0.0;
    const double rs = std::sqrt(rho * rho + 0.25 * spacing * spacing);
    for (int t = 0; t < k; ++t) {
      const double u = k > 1 ? -1.0 + 2.0 * t / (k - 1) : 0.0;
      sub_c_.push_back(b.shape.center + u * e);
      sub_r_.push_back(rs);
      sub_body_.push_back(static_cast<int>(i));
    }
  }
  // Every pair of covering spheres that meet (the broad phase the audit and RSA use too).
  keys_.clear();
  for (const SpherePair& sp : sphere_pairs(box_, sub_c_, sub_r_, [this] { check_time(); })) {
    const int a = sub_body_[sp.i], b = sub_body_[sp.j];
    if (a == b && sp.k[0] == 0 && sp.k[1] == 0 && sp.k[2] == 0) continue;
    keys_.push_back(make_key(a, b, sp.k[0], sp.k[1], sp.k[2]));
  }
  check_time();
  std::sort(keys_.begin(), keys_.end());
  keys_.erase(std::unique(keys_.begin(), keys_.end()), keys_.end());
  check_time();
  pairs_.reserve(keys_.size());
  for (const Key& k : keys_) {
    const Vec3 shift(k.kx * box_.size[0], k.ky * box_.size[1], k.kz * box_.size[2]);
    const double rr = cap_r[k.a] + cap_r[k.b];
    if (segment_distance2(seg_p[k.a], seg_q[k.a], seg_p[k.b] + shift, seg_q[k.b] + shift) >
        rr * rr) {
      continue;
    }
    pairs_.push_back({k.a, k.b, shift});
  }
}

BodyMobility MdPacker::mobility_of(const Body& b, const Shape& scaled) const {
  switch (b.turn) {
    case Turn::kNone:
      return body_mobility(scaled, false, Vec3::Zero());
    case Turn::kFree:
      return body_mobility(scaled, true, Vec3::Zero());
    case Turn::kAboutAxis:
      return body_mobility(scaled, true, b.turn_axis);
  }
  return body_mobility(scaled, false, Vec3::Zero());
}

Shape MdPacker::at_scale(const Body& b, double s) {
  if (!b.radial) return b.shape.scaled(s + b.pad);
  Shape out = b.shape;
  out.radius = b.shape.radius * s + b.half_gap;
  if (b.half_gap > 0.0) out.half_axis = b.shape.half_axis * (1.0 + b.half_gap / b.cap_half);
  return out;
}

void MdPacker::support_line(const Body& b, const Vec3& n, double* alpha, double* beta) {
  if (b.radial) {
    // Cylinder: half length |n.u| + radius sqrt(1 - (n.u)^2), radius s r + half_gap.
    const double c = std::min(1.0, std::abs(n.dot(b.shape.half_axis)) / b.cap_half);
    const double sn = std::sqrt(std::max(0.0, 1.0 - c * c));
    *alpha = (b.cap_half + b.half_gap) * c + b.half_gap * sn;
    *beta = b.shape.radius * sn;
    return;
  }
  // Scaled about the centre: h_s(n) = (s + pad) h_1(n).
  const double h = b.shape.support_value(n) - n.dot(b.shape.center);
  *alpha = b.pad * h;
  *beta = h;
}

double MdPacker::separating_scale(const Body& a, const Body& b, const Vec3& shift,
                                  const Vec3& n) const {
  double alpha_a, beta_a, alpha_b, beta_b;
  support_line(a, n, &alpha_a, &beta_a);
  support_line(b, -n, &alpha_b, &beta_b);
  const double room = n.dot(b.shape.center + shift - a.shape.center) - alpha_a - alpha_b;
  if (beta_a + beta_b <= 1e-300) return room >= 0.0 ? 1e300 : 0.0;  // holds at every scale
  return room / (beta_a + beta_b);
}

double MdPacker::contacts() {
  const size_t n = bodies_.size();
  if (pairs_stale()) build_pairs();
  for (size_t i = 0; i < n; ++i) {
    move_[i].setZero();
    turn_[i].setZero();
  }
  axis_.resize(n);
  for (int i : oriented_) axis_[i] = principal_axis(bodies_[i].shape);  // spheres have none
  double s_in = s_out_;
  max_overlap_ = 0.0;
  size_t visited = 0;
  for (const PairEntry& e : pairs_) {
    if ((++visited & 4095) == 0) check_time();
    const Body &ba = bodies_[e.a], &bb = bodies_[e.b];
    const double fa = force_scale(ba), fb = force_scale(bb);
    if (ba.shape.kind == ShapeKind::Sphere && bb.shape.kind == ShapeKind::Sphere) {
      // Sphere pairs in closed form (the same test as intersect_sphere_sphere).
      const double ra = ba.shape.radius, rb = bb.shape.radius;
      const Vec3 d = bb.shape.center + e.shift - ba.shape.center;
      const double rr = fa * ra + fb * rb, d2 = d.squaredNorm();
      if (d2 >= rr * rr) continue;
      const double dist = std::sqrt(d2), depth = rr - dist;
      const Vec3 nrm = dist > 0.0 ? Vec3(d / dist) : Vec3::UnitX();
      max_overlap_ = std::max(max_overlap_, depth / std::min(fa * ra, fb * rb));
      s_in = std::min(s_in, (dist - ba.pad * ra - bb.pad * rb) / (ra + rb));
      const Vec3 J = (kRelaxation * depth / (1.0 / ba.volume + 1.0 / bb.volume)) * nrm;
      move_[e.a] -= J / ba.volume;
      move_[e.b] += J / bb.volume;
      continue;
    }
    if (ba.radial && bb.radial && std::abs(axis_[e.a].dot(axis_[e.b])) >= 1.0 - 1e-12) {
      // Parallel fibres in closed form: they overlap exactly when their axial ranges do and
      // their axes are nearer than the sum of the radii; the push is sideways only, so aligned
      // fibres never butt end to end in columns.
      const Vec3& u = axis_[e.a];
      const Vec3 d = bb.shape.center + e.shift - ba.shape.center;
      const double along = std::abs(d.dot(u));
      if (along >= cap_half_at(ba, s_out_) + cap_half_at(bb, s_out_)) continue;
      const Vec3 side = d - d.dot(u) * u;
      const double dist = side.norm(), ra = ba.shape.radius, rb = bb.shape.radius;
      const double reach = cap_radius_at(ba, s_out_) + cap_radius_at(bb, s_out_);
      if (dist >= reach) continue;
      const double depth = reach - dist;
      const Vec3 nrm = dist > 0.0 ? Vec3(side / dist) : any_orthogonal(u);
      max_overlap_ = std::max(max_overlap_, depth / (s_out_ * std::min(ra, rb)));
      s_in = std::min(s_in, (dist - ba.half_gap - bb.half_gap) / (ra + rb));
      const Vec3 J = (kRelaxation * depth / (1.0 / ba.volume + 1.0 / bb.volume)) * nrm;
      move_[e.a] -= J / ba.volume;
      move_[e.b] += J / bb.volume;
      continue;
    }
    {
      // Bounding spheres, then capsules: most listed pairs of long bodies are apart.
      const Vec3 cb = bb.shape.center + e.shift;
      const double rr = cap_radius_at(ba, s_out_) + cap_radius_at(bb, s_out_);
      const double ha = cap_half_at(ba, s_out_), hb = cap_half_at(bb, s_out_);
      const double reach = rr + ha + hb;
      if ((cb - ba.shape.center).squaredNorm() >= reach * reach) continue;
      const Vec3 ea = axis_[e.a] * ha, eb = axis_[e.b] * hb;
      if (segment_distance2(ba.shape.center - ea, ba.shape.center + ea, cb - eb, cb + eb) >=
          rr * rr) {
        continue;
      }
    }
    const Shape A = at_scale(ba, s_out_);
    const Shape B = at_scale(bb, s_out_).translated(e.shift);
    const Contact c = intersect(A, B);
    if (!c.overlap) continue;
    max_overlap_ = std::max(max_overlap_, c.depth / std::min(A.min_size(), B.min_size()));
    s_in = std::min(s_in, separating_scale(ba, bb, e.shift, c.normal));
    // An inclusion against its own periodic image (e.a == e.b) only turns: the two moves
    // cancel.
    const ContactResponse r = contact_response(A.center, mobility_of(ba, A), B.center,
                                               mobility_of(bb, B), c, kRelaxation);
    add(e.a, r.move_a, r.turn_a);
    add(e.b, r.move_b, r.turn_b);
  }
  if (!box_.periodic) {
    // Walls: contacts push the shape at the force scale back inside; the valid scale is the
    // largest at which the (unpadded) shape is inside.
    for (size_t i = 0; i < n; ++i) {
      const Body& b = bodies_[i];
      Vec3 half, lo, hi;
      b.shape.scaled(1.0).translated(-b.shape.center).aabb(&lo, &half);  // half extents
      const Shape cur = at_scale(b, s_out_);
      cur.aabb(&lo, &hi);
      for (int a = 0; a < 3; ++a) {
        const double c = b.shape.center[a], w0 = box_.origin[a], w1 = w0 + box_.size[a];
        // Half extent along axis a at growth s: al + s be (unpadded).
        double al = 0.0, be = half[a];
        if (b.radial) {
          const double u = std::min(1.0, std::abs(b.shape.half_axis[a]) / b.cap_half);
          al = b.cap_half * u;
          be = b.shape.radius * std::sqrt(std::max(0.0, 1.0 - u * u));
        }
        const double room = std::min(c - w0, w1 - c) - al;
        s_in = std::min(s_in, be > 0.0 ? room / be : (room >= 0.0 ? 1e300 : 0.0));
        const double below = w0 - lo[a], above = hi[a] - w1;
        for (int side = 0; side < 2; ++side) {
          const double depth = side == 0 ? below : above;
          if (!(depth > 0.0)) continue;
          Vec3 nrm = Vec3::Zero();
          nrm[a] = side == 0 ? 1.0 : -1.0;  // into the box
          const Vec3 p = cur.support(-nrm);
          max_overlap_ = std::max(max_overlap_, depth / cur.min_size());
          // The wall is an immovable body beyond the face (normal from the inclusion to it).
          Contact c;
          c.overlap = true;
          c.depth = depth;
          c.normal = -nrm;
          c.point = p;
          const ContactResponse r =
              contact_response(cur.center, mobility_of(b, cur), p, BodyMobility{}, c, 1.0);
          add(static_cast<int>(i), r.move_a, r.turn_a);
        }
      }
    }
  }
  return std::max(0.0, s_in);
}

void MdPacker::move() {
  for (size_t i = 0; i < bodies_.size(); ++i) {
    Body& b = bodies_[i];
    vel_[i] = kMomentum * vel_[i] + move_[i];
    b.shape.center += vel_[i];
    if (b.turn != Turn::kNone) {
      omega_[i] = kMomentum * omega_[i] + turn_[i];
      double ang = omega_[i].norm();
      if (ang > kMaxTurn) {
        omega_[i] *= kMaxTurn / ang;
        ang = kMaxTurn;
      }
      if (ang > 0.0) {
        const Mat3 R = Eigen::AngleAxisd(ang, omega_[i] / ang).toRotationMatrix();
        if (b.shape.kind == ShapeKind::Cylinder) {
          const double len = b.shape.half_axis.norm();
          b.shape.half_axis = (R * b.shape.half_axis).normalized() * len;
        } else {
          const Mat3 Q = R * b.shape.rotation;
          // Re-orthonormalise (Gram-Schmidt) so rounding does not accumulate.
          const Vec3 c0 = Q.col(0).normalized();
          const Vec3 c1 = (Q.col(1) - c0.dot(Q.col(1)) * c0).normalized();
          b.shape.rotation.col(0) = c0;
          b.shape.rotation.col(1) = c1;
          b.shape.rotation.col(2) = c0.cross(c1);
        }
        turned_since_build_[i] += ang;
      }
    }
  }
  hold_tensors();
}

void MdPacker::snapshot(double scale) {
  // Centres of all bodies, orientations of the others (spheres have none worth keeping).
  best_scale_ = scale;
  best_center_.resize(bodies_.size());
  for (size_t i = 0; i < bodies_.size(); ++i) best_center_[i] = bodies_[i].shape.center;
  best_oriented_.resize(oriented_.size());
  for (size_t k = 0; k < oriented_.size(); ++k) best_oriented_[k] = bodies_[oriented_[k]].shape;
}

void MdPacker::report_progress(bool force) {
  if (!progress_) return;
  const auto now = std::chrono::steady_clock::now();
  if (!force && std::chrono::duration<double>(now - last_progress_).count() < 1.0) return;
  last_progress_ = now;
  double vol = 0.0;
  double valid = 0.0;
  const double s = std::clamp(best_scale_, 0.0, 1.0);
  for (const Body& b : bodies_) {
    vol += b.volume;
    valid += b.volume * (b.radial ? s * s : s * s * s);
  }
  char buf[200];
  std::snprintf(
      buf, sizeof buf,
      "md: %.1f s, step %lld, volume fraction %.4f valid / %.4f target, largest overlap %.2e, "
      "pressure %.1e, %zu pairs, %lld rebuilds",
      std::chrono::duration<double>(now - t0_).count(), steps_, valid / box_.volume(),
      vol / box_.volume(), max_overlap_, m_, pairs_.size(), rebuilds_);
  progress_(buf);
}

PackingResult MdPacker::run() {
  t0_ = last_progress_ = std::chrono::steady_clock::now();
  deadline_ = t0_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                        std::chrono::duration<double>(scene_.md.max_seconds));
  init_bodies();
  PackingResult res;
  res.method = Method::kMd;
  res.set.box = box_;
  const int nf = static_cast<int>(scene_.families.size());
  res.target_count.assign(nf, 0);
  res.target_volume_fraction.assign(nf, 0.0);
  for (const Inclusion& inc : pop_) {
    ++res.target_count[inc.family];
    res.target_volume_fraction[inc.family] += inc.shape.volume() / box_.volume();
  }
  StopReason why = StopReason::kTargetReached;
  if (bodies_.empty()) best_scale_ = 1.0;
  double mark = 0.0;  // best scale at the last pressure check
  while (!bodies_.empty()) {
    double s_in = 0.0;
    try {
      s_in = contacts();
    } catch (const OutOfTime&) {
      why = StopReason::kTimeBudget;
      break;
    }
    // A scale of 0 is no configuration (inclusions of size 0): nothing is kept until one is
    // valid at a positive scale.
    if (s_in > best_scale_ && s_in > 0.0) snapshot(s_in);
    if (best_scale_ >= 1.0) break;
    move();
    ++steps_;
    if (steps_ % patience_ == 0) {
      // Pressure control: halve m when the valid scale has stalled.
      if (best_scale_ < mark * (1.0 + kStall * m_)) {
        m_ *= 0.5;
        // Stalled: the starting scale may itself be jammed (long fibres), so the outer scale
        // may now drop below it.
        s_start_ = 0.0;
      }
      mark = best_scale_;
      if (m_ < kMinPressure) {
        why = StopReason::kJammed;
        break;
      }
    }
    s_out_ = std::max(s_start_, s_in * (1.0 + m_));
    if (steps_ >= scene_.md.max_steps) {
      why = StopReason::kStepBudget;
      break;
    }
    if ((steps_ & 15) == 0) {
      const double t =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
      if (t > scene_.md.max_seconds) {
        why = StopReason::kTimeBudget;
        break;
      }
      report_progress(false);
    }
  }
  res.status = best_scale_ >= 1.0 ? PackingStatus::kOk : PackingStatus::kTargetNotReached;
  // Out of time before any valid configuration: nothing is placed (best_center_ is empty).
  res.scale = std::clamp(best_scale_, 0.0, 1.0);
  res.steps = steps_;
  res.stop_reason = why;
  res.placed_count.assign(nf, 0);
  if (best_oriented_.size() == oriented_.size()) {
    for (size_t k = 0; k < oriented_.size(); ++k) bodies_[oriented_[k]].shape = best_oriented_[k];
  }
  for (size_t i = 0; i < best_center_.size(); ++i) {
    Body b = bodies_[i];
    b.shape.center = best_center_[i];
    wrap(b);
    // Aligned fibres (radial) keep their length: only the radius is scaled.
    Inclusion inc = place_like(pop_[i], b.shape, b.radial ? 1.0 : res.scale);
    if (b.radial) inc.shape.radius *= res.scale;
    inc.id = static_cast<int>(res.set.inclusions.size());
    res.set.inclusions.push_back(inc);
    ++res.placed_count[inc.family];
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  report_progress(true);
  return res;
}

}  // namespace

PackingResult pack_md(const PackingSpec& scene, const ProgressFn& progress) {
  MdPacker packer(scene, progress);
  return packer.run();
}

}  // namespace rvegen
