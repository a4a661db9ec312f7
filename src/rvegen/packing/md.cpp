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
// configuration is returned shrunk to its scale. A jam near the target is first compressed again
// up to kRecompressions times, each time from the best configuration shaken (md.shake).
//
// min_gap: inclusion i is tested at scale s + gap / (2 min_size_i); scaled so, it contains the
// inclusion at scale s grown by gap / 2 in every direction, so valid pairs are >= gap apart.
//
// The parts: md_bodies (what is packed and how it grows and turns), md_neighbours (the Verlet
// list: pairs whose bounding capsules, inflated by a skin, intersect; rebuilt when some body could
// have moved by more than half its skin), md_contacts (step 1 and 2), md_integrator (step 3 and
// md.rotation keep_tensor). This file is the driver: scale control, best configuration, budgets.
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <tuple>
#include <utility>

#include "rvegen/geometry/random.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/orientation.hpp"
#include "rvegen/packing/md_integrator.hpp"
#include "rvegen/packing/md_layers.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {

namespace {

using md::Body;

constexpr double kMinPressure = 1e-6;
// Compressions started again after a jam below the target, before the run reports it jammed:
// each at kRecompressPressure times md.pressure and twice as patient as the last, when the jam
// left at least kRecompressFrom of the drawn volume: a jam just below the target is a schedule
// that compressed too fast, which a slower one gets past, while a jam far below is the shapes'
// limit. The harder restart pressure shakes the jammed configuration loose first (restarting at
// md.pressure alone crept up far more slowly). Seeds and times: docs/benchmarks.md.
constexpr int kRecompressions = 4;
constexpr double kRecompressPressure = 4.0;
constexpr double kRecompressFrom = 0.95;
// With md.shake > 0 a stall counts as a jam to compress again from once m is below kShakeBelow
// (not kMinPressure), and each compression starts from the best configuration shaken: every body
// moved by up to md.shake of its capsule's radius, uniformly in a ball, and turned about a random
// axis by up to the angle that moves its ends as far. The damped contacts alone settle back into
// the jam they left; the shake lets the packing leave it: on a mixture of coated wavy fibres
// and deformed grains, shaken runs packed denser than unshaken ones and than the earlier
// restarts alone, and shakes smaller or larger than kChainShake did less well. Not for convex
// bodies by default: a dense sphere packing reaches its target sooner unshaken (their jams
// creep up at low pressure). docs/benchmarks.md.
constexpr double kShakeBelow = 1e-3;
// Chains (see run()): s_out drops by at most kChainDrop m a step; the contacts act on pieces
// grown by a relative skin min(kChainSkin, kChainSkinPerPressure m); after kChainHold steps
// without a valid scale, s_out drops by kChainUnjam. The skin lets the contacts part pieces a
// little beyond touching, so the pass can certify the force scale itself; a thick skin pushes
// chains apart that would fit, and early or large drops undo the compression (the values were
// tuned on the Figure 5 scene, samples/bench_deformed.py).
constexpr double kChainDrop = 2.0;
constexpr double kChainSkin = 0.002, kChainSkinPerPressure = 0.1;
constexpr int kChainHold = 50;
constexpr double kChainUnjam = 0.003;
constexpr double kStall = 0.1;  // m halves when the valid scale grew by less than kStall m
// Chains held kChainDeepHolds times running (kChainHold steps each, no valid scale) with an
// overlap deeper than kChainDeep of a size at each are intertwined at that scale beyond what the
// contacts undo: the bodies go back to the best configuration, at rest, and m halves. (4-wave
// coated fibres alone stayed held for long with many pairs deeply overlapping; going back, they
// packed denser soon after. The 4-wave mixture's holds, whose deep overlaps come and go, never
// meet the rule: its runs are unchanged. docs/benchmarks.md.)
constexpr double kChainDeep = 0.3;
constexpr int kChainDeepHolds = 3;

class MdPacker {
 public:
  MdPacker(const PackingSpec& scene, const Monitor& monitor)
      : scene_(scene), box_(scene.box), monitor_(monitor), progress_(monitor.line) {}

  PackingResult run();

 private:
  void init();
  void snapshot(double scale);
  /// Puts every body back where the best configuration had it, at rest.
  void restore_best();
  void report_progress(bool force);
  void next_scale(double s_in);
  /// The best configuration, each body moved and turned at random by up to md.shake of its size.
  void shake();
  void report_fraction() const;
  /// Volume at the best valid scale over the drawn volume.
  double reached_share() const;

  const PackingSpec& scene_;
  const Box& box_;
  const Monitor& monitor_;
  const ProgressFn& progress_;
  // Drawn volume of the bodies that grow in radius only (aligned fibres) and of the others.
  double radial_volume_ = 0.0, other_volume_ = 0.0;
  std::vector<Inclusion> pop_;  // drawn cores and modifiers
  md::Bodies bodies_;
  std::vector<int> drawn_;  // body k packs the drawn inclusion pop_[drawn_[k]]
  md::VerletList list_;
  md::ContactSums sums_;
  std::unique_ptr<md::Integrator> integrator_;
  // Scale control: contacts act at s_out = max(s_start, s_in (1 + m)).
  double s_out_ = 0.0, s_start_ = 0.0, m_ = 0.0;
  long long steps_ = 0;
  int hold_ = 0;
  int deep_holds_ = 0;      // holds running with an overlap deeper than kChainDeep
  int recompressions_ = 0;  // compressions started again after a jam
  double shake_ = 0.0;      // md.shake, or its default for the scene
  // Best valid configuration.
  double best_scale_ = -1.0;
  std::vector<Vec3> best_center_;
  std::vector<Shape> best_oriented_;
  std::vector<std::pair<double, double>> best_angles_;  // chains' wave and bend angles
  std::chrono::steady_clock::time_point t0_, last_progress_;
  // The time budget holds inside a step too (a pair-list build of a crowded scene can take
  // longer than the budget): long loops call tick_, which throws OutOfTime, or Cancelled when
  // the caller cancels (the first pass, which runs whatever the clock says, calls cancel_tick_).
  struct OutOfTime {};
  std::chrono::steady_clock::time_point deadline_;
  bool cancelled() const { return monitor_.cancelled && monitor_.cancelled(); }
  const std::function<void()> tick_ = [this] {
    if (cancelled()) throw Cancelled();
    if (std::chrono::steady_clock::now() > deadline_) throw OutOfTime{};
  };
  const std::function<void()> cancel_tick_ = [this] {
    if (cancelled()) throw Cancelled();
  };
};

void MdPacker::init() {
  Random rng(scene_.seed);
  pop_ = draw_population(scene_, rng);
  bodies_ = md::make_bodies(scene_, pop_, rng);
  // Planar fibres start at heights in layers, aligned ones in slots (md_layers.hpp).
  md::layer_planar_fibres(scene_, rng, &bodies_, progress_);
  md::slot_aligned_fibres(scene_, rng, &bodies_);
  drawn_.resize(bodies_.all.size());
  for (size_t i = 0; i < drawn_.size(); ++i) drawn_[i] = static_cast<int>(i);
  if (bodies_.all.size() >= md::kSpaceOrderFrom) drawn_ = md::order_in_space(box_, &bodies_);
  s_start_ = s_out_ = bodies_.start_scale;
  shake_ = scene_.md.shake.value_or(bodies_.chains ? MdSettings::kChainShake : 0.0);
  m_ = scene_.md.pressure;
  integrator_ = std::make_unique<md::Integrator>(bodies_.all.size());
  for (size_t k = 0; k < bodies_.all.size(); ++k) {
    (bodies_.all[k].radial ? radial_volume_ : other_volume_) += pop_[drawn_[k]].shape.volume();
  }
}

void MdPacker::snapshot(double scale) {
  // Centres of all bodies, orientations of the others (spheres have none worth keeping).
  best_scale_ = scale;
  best_center_.resize(bodies_.all.size());
  for (size_t i = 0; i < bodies_.all.size(); ++i) best_center_[i] = bodies_.all[i].shape.center;
  const std::vector<int>& oriented = bodies_.oriented;
  best_oriented_.resize(oriented.size());
  best_angles_.resize(oriented.size());
  for (size_t k = 0; k < oriented.size(); ++k) {
    const Body& b = bodies_.all[oriented[k]];
    best_oriented_[k] = b.shape;
    best_angles_[k] = {b.wave_angle, b.bend_angle};
  }
}

void MdPacker::restore_best() {
  std::vector<Body>& bodies = bodies_.all;
  for (size_t i = 0; i < bodies.size(); ++i) bodies[i].shape.center = best_center_[i];
  const std::vector<int>& oriented = bodies_.oriented;
  for (size_t k = 0; k < oriented.size(); ++k) {
    Body& b = bodies[oriented[k]];
    const Vec3 c = b.shape.center;
    const double turn =
        std::acos(std::clamp(law_axis(b.shape).dot(law_axis(best_oriented_[k])), -1.0, 1.0));
    b.shape = best_oriented_[k];
    b.shape.center = c;
    b.wave_angle = best_angles_[k].first;
    b.bend_angle = best_angles_[k].second;
    list_.turned(oriented[k], turn);
  }
  // The moves are the list's to see (it compares the centres with those of its last build); the
  // motion carried over from the last steps is dropped.
  integrator_ = std::make_unique<md::Integrator>(bodies.size());
}

void MdPacker::shake() {
  restore_best();
  // Its own stream, one per restart, drawn in body order: the same on any number of threads.
  Random rng(scene_.seed ^ (0x5eedULL * static_cast<uint64_t>(recompressions_ + 1)));
  std::vector<Body>& bodies = bodies_.all;
  const double s = best_scale_;
  for (size_t i = 0; i < bodies.size(); ++i) {
    Body& b = bodies[i];
    const double reach = shake_ * b.cap_radius_at(s);
    const Vec3 move = rng.unit_vector() * (reach * std::cbrt(rng.uniform()));
    // (Drawn for every body, so that the stream does not depend on how each may turn.) A body
    // that may turn only about one axis (planar laws) turns about it.
    const Vec3 drawn_axis = rng.unit_vector();
    const Vec3 axis = b.turn == md::Turn::kAboutAxis ? b.turn_axis : drawn_axis;
    const double turn = reach / std::max(b.bound * s, reach) * rng.uniform();
    b.shape.center += move;
    if (b.turn != md::Turn::kNone && turn > 0.0) {
      b.turn_by(Eigen::AngleAxisd(turn, axis).toRotationMatrix());
      list_.turned(static_cast<int>(i), turn);
    }
  }
  // The held orientation tensors stay exact (the turns are random, the hold maps them back).
  hold_tensors(scene_, bodies_.held, &bodies, &list_);
  s_out_ = s;
}

double MdPacker::reached_share() const {
  const double s = std::clamp(best_scale_, 0.0, 1.0);
  const double total = radial_volume_ + other_volume_;
  return total > 0.0 ? (radial_volume_ * s * s + other_volume_ * s * s * s) / total : 1.0;
}

void MdPacker::report_fraction() const {
  if (monitor_.fraction) monitor_.fraction(reached_share());
}

void MdPacker::report_progress(bool force) {
  if (!progress_) return;
  const auto now = std::chrono::steady_clock::now();
  if (!force && std::chrono::duration<double>(now - last_progress_).count() < 1.0) return;
  last_progress_ = now;
  double vol = 0.0;
  double valid = 0.0;
  const double s = std::clamp(best_scale_, 0.0, 1.0);
  // In the volumes of the inclusions' cores (what the target counts), not of the envelopes.
  for (size_t k = 0; k < bodies_.all.size(); ++k) {
    const double v = pop_[drawn_[k]].shape.volume();
    vol += v;
    valid += v * (bodies_.all[k].radial ? s * s : s * s * s);
  }
  char buf[200];
  std::snprintf(
      buf, sizeof buf,
      "md: %.1f s, step %lld, volume fraction %.4f valid / %.4f target, largest overlap %.2e, "
      "pressure %.1e, %zu pairs, %lld rebuilds",
      std::chrono::duration<double>(now - t0_).count(), steps_, valid / box_.volume(),
      vol / box_.volume(), sums_.max_overlap, m_, list_.pairs().size(), list_.rebuilds());
  progress_(buf);
}

// The scale the contacts act at next, from this step's valid scale s_in (0: none).
void MdPacker::next_scale(double s_in) {
  if (bodies_.chains) {
    // Chains: the contacts act at a scale never above 1, where the chains are placed (a chain
    // is not convex, and valid at a scale above 1 need not mean valid at 1). It follows the
    // valid scale, but drops by at most kChainDrop m a step: a chain pair's certificate may
    // lie far below s_out (shrunk, its pieces move across each other's waves), and following
    // it dragged the scale of all down and undid the compression (the Figure 5 scene jammed far
    // below its target). With no valid scale, it is held: the contacts part the overlaps at that
    // scale until one is certified there (the skin makes them part the pieces a little more
    // than needed, so the pass certifies the force scale itself); held kChainHold steps (a
    // pair caught across another's wave), it drops by kChainUnjam.
    if (s_in > 0.0) {
      hold_ = 0;
      deep_holds_ = 0;
      const double s = std::max(s_in, s_out_ * (1.0 - kChainDrop * m_));
      s_out_ = std::min(1.0, std::max(s_start_, s * (1.0 + m_)));
    } else if (++hold_ >= kChainHold) {
      hold_ = 0;
      deep_holds_ = sums_.max_overlap > kChainDeep ? deep_holds_ + 1 : 0;
      if (deep_holds_ >= kChainDeepHolds && best_scale_ > 0.0) {
        // Intertwined beyond what the contacts undo: from the best configuration again, more
        // gently.
        deep_holds_ = 0;
        restore_best();
        m_ *= 0.5;
        s_out_ = std::min(1.0, best_scale_ * (1.0 + m_));
      } else {
        s_out_ *= 1.0 - kChainUnjam;
      }
    }
  } else if (s_in > 0.0) {
    // (No valid scale this step: the contacts keep acting at the same scale, never at 0.)
    s_out_ = std::max(s_start_, s_in * (1.0 + m_));
  }
}

PackingResult MdPacker::run() {
  t0_ = last_progress_ = std::chrono::steady_clock::now();
  deadline_ = t0_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                        std::chrono::duration<double>(scene_.md.max_seconds));
  init();
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
  std::vector<Body>& bodies = bodies_.all;
  if (bodies.empty()) best_scale_ = 1.0;
  double mark = 0.0;  // best scale at the last pressure check
  while (!bodies.empty()) {
    double s_in = 0.0;
    try {
      // The first pass runs whatever the clock says (placing planar fibres in layers may have
      // taken the budget): its configuration, at the start scale, is the least a run returns.
      const std::function<void()>& tick = steps_ == 0 ? cancel_tick_ : tick_;
      const double skin = bodies_.chains ? std::min(kChainSkin, kChainSkinPerPressure * m_) : 0.0;
      list_.update(&bodies, box_, s_out_, tick);
      s_in = contact_pass(bodies, bodies_.oriented, list_.pairs(), box_, s_out_, best_scale_, skin,
                          &sums_, tick);
    } catch (const OutOfTime&) {
      why = StopReason::kTimeBudget;
      break;
    }
    // A scale of 0 is no configuration (inclusions of size 0): nothing is kept until one is
    // valid at a positive scale.
    s_in = md::round_to_target(s_in);
    if (s_in > best_scale_ && s_in > 0.0) snapshot(s_in);
    if (best_scale_ >= 1.0) break;
    integrator_->step(sums_, &bodies, &list_);
    hold_tensors(scene_, bodies_.held, &bodies, &list_);
    ++steps_;
    if (steps_ % bodies_.patience == 0) {
      // Pressure control: halve m when the valid scale has stalled.
      if (best_scale_ < mark * (1.0 + kStall * m_)) {
        m_ *= 0.5;
        // Stalled: the starting scale may itself be jammed (long fibres), so the outer scale
        // may now drop below it.
        s_start_ = 0.0;
      }
      mark = best_scale_;
      // Jammed just below the target: compress again from here (shaken, with md.shake),
      // harder at first and twice as patiently (slower compression near jamming packs denser),
      // up to kRecompressions times within the budget. A jam far below the target (an
      // unreachable one) ends the run at once.
      const bool shaking = shake_ > 0.0;
      const bool near = reached_share() >= kRecompressFrom;
      if (m_ < (shaking ? kShakeBelow : kMinPressure) && near &&
          recompressions_ < kRecompressions) {
        ++recompressions_;
        bodies_.patience *= 2;
        m_ = kRecompressPressure * scene_.md.pressure;
        if (shaking) {
          shake();
          if (progress_) {
            char buf[160];
            std::snprintf(buf, sizeof buf,
                          "md: jammed at volume fraction %.4f; shaken and compressed again (%d of "
                          "%d)",
                          reached_share() * (radial_volume_ + other_volume_) / box_.volume(),
                          recompressions_, kRecompressions);
            progress_(buf);
          }
        }
      } else if (m_ < kMinPressure) {
        why = StopReason::kJammed;
        break;
      }
    }
    next_scale(s_in);
    if (steps_ >= scene_.md.max_steps) {
      why = StopReason::kStepBudget;
      break;
    }
    if (cancelled()) throw Cancelled();
    // The clock every step (a step of long chains can be slow), the progress
    // every 16 steps (at most once a second).
    const auto now = std::chrono::steady_clock::now();
    if (now > deadline_) {
      why = StopReason::kTimeBudget;
      break;
    }
    if ((steps_ & 15) == 0 || now - last_progress_ > std::chrono::seconds(1)) {
      report_fraction();
      report_progress(false);
    }
  }
  res.status = best_scale_ >= 1.0 ? PackingStatus::kOk : PackingStatus::kTargetNotReached;
  // Out of time before any valid configuration: nothing is placed (best_center_ is empty).
  res.scale = std::clamp(best_scale_, 0.0, 1.0);
  res.steps = steps_;
  res.stop_reason = why;
  res.placed_count.assign(nf, 0);
  const std::vector<int>& oriented = bodies_.oriented;
  if (best_oriented_.size() == oriented.size()) {
    for (size_t k = 0; k < oriented.size(); ++k) {
      Body& b = bodies[oriented[k]];
      b.shape = best_oriented_[k];
      std::tie(b.wave_angle, b.bend_angle) = best_angles_[k];
    }
  }
  // Written in the order drawn, whatever order the bodies were packed in.
  std::vector<int> body_of(drawn_.size());
  for (size_t k = 0; k < drawn_.size(); ++k) body_of[drawn_[k]] = static_cast<int>(k);
  for (size_t j = 0; j < best_center_.size(); ++j) {
    const int i = body_of[j];
    Body b = bodies[i];
    b.shape.center = best_center_[i];
    wrap(box_, &b);
    // Aligned fibres (radial) keep their length: only the radius is scaled.
    Inclusion inc =
        b.chain ? b.chain_at(res.scale) : place_like(pop_[j], b.shape, b.radial ? 1.0 : res.scale);
    if (b.radial) inc.shape.radius *= res.scale;
    inc.id = static_cast<int>(res.set.inclusions.size());
    res.set.inclusions.push_back(inc);
    ++res.placed_count[inc.family];
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  report_progress(true);
  report_fraction();
  return res;
}

}  // namespace

PackingResult pack_md(const PackingSpec& scene, const Monitor& monitor) {
  MdPacker packer(scene, monitor);
  return packer.run();
}

}  // namespace rvegen
