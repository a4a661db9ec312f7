#include "rvegen/packing/md_contacts.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>

#include "rvegen/geometry/convex.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/parallel.hpp"
#include "rvegen/packing/body_contacts.hpp"

namespace rvegen::md {

namespace {
// Aligned fibres whose axes' cosine is within this of 1 take the parallel closed form.
constexpr double kParallelCos = 1e-12;
constexpr double kRelaxation = 1.0;  // scale of the summed contact impulses
// Axes closer to parallel than this (squared sine) skip the line test: their lines' distance
// says little about their segments'.
constexpr double kLineTestMinSine2 = 1e-6;
// A chain pair whose contacts' pushes (depth times normal) add up to less than kCancelling of
// their depths is held in place by them (see visit_pair).
constexpr double kCancelling = 0.25;

// A ball holding a run of kRun consecutive pieces of a chain: a pair's pieces are culled run by
// run before piece by piece (4-wave fibres have many pieces, and most of a crossing pair's runs
// are far from the other body). It holds every piece's bounding ball, grown by a relative
// kRunMargin, so that a run it culls holds only pieces the piece test would cull too, whatever
// the rounding: the pieces found, and so the packing, are the same as without it.
constexpr size_t kRun = 8;
constexpr double kRunMargin = 1e-9;
struct RunBall {
  Vec3 c;
  double r;
};

// Pieces of every body at one scale, computed when first asked for (a body's chain costs a
// place_like and a sine per piece; it meets many others), grown by a relative `grow`: by
// grow r all round (r: a piece's radius; they hold the pieces as they are), with their runs'
// balls.
class PieceCache {
 public:
  explicit PieceCache(const std::vector<Body>& bodies) : bodies_(bodies) {}
  /// The balls of the runs of body i's pieces as last returned by at().
  const std::vector<RunBall>& runs(int i) const { return runs_[i]; }
  /// Pieces of body i at the force scale of growth s (its chain's, or its own shape).
  const std::vector<Piece>& at(int i, double s, double grow) {
    if (scale_.empty()) {  // sized when first asked: most passes meet no chain
      store_.resize(bodies_.size());
      runs_.resize(bodies_.size());
      scale_.assign(bodies_.size(), -1.0);
      grow_.assign(bodies_.size(), 0.0);
    }
    if (scale_[i] != s || grow_[i] != grow) {
      const Body& b = bodies_[i];
      std::vector<Piece>& out = store_[i];
      out.clear();
      if (b.chain) {
        parts_.clear();
        chain_pieces(b.chain_at(b.force_scale(s)), &parts_);
        out.reserve(parts_.size());
        for (ShearedPiece& p : parts_) {
          p.round += grow * p.radius;
          out.push_back(Piece::of(p));
        }
      } else {
        Shape p = b.at_scale(s);
        if (grow > 0.0) {
          const double dr = grow * p.radius;
          if (p.kind == ShapeKind::Cylinder) {
            const double h = p.half_axis.norm();
            p.half_axis *= (h + dr) / h;
          }
          p.radius += dr;
        }
        out.push_back(Piece::of(p));
      }
      std::vector<RunBall>& runs = runs_[i];
      runs.clear();
      for (size_t k0 = 0; k0 < out.size(); k0 += kRun) {
        const size_t k1 = std::min(out.size(), k0 + kRun);
        const Vec3 c = 0.5 * (out[k0].center() + out[k1 - 1].center());
        double r = 0.0;
        for (size_t k = k0; k < k1; ++k) {
          r = std::max(r, (out[k].center() - c).norm() + out[k].bounding_radius());
        }
        runs.push_back({c, r * (1.0 + kRunMargin)});
      }
      scale_[i] = s;
      grow_[i] = grow;
    }
    return store_[i];
  }

 private:
  const std::vector<Body>& bodies_;
  std::vector<std::vector<Piece>> store_;
  std::vector<std::vector<RunBall>> runs_;
  std::vector<ShearedPiece> parts_;
  std::vector<double> scale_, grow_;
};

// The overlapping pieces of the pair e at growth s (grown by `grow`, see PieceCache): the pieces
// of each body near the other's bounding capsule, then the exact tests between those. Appends
// the contacts to *found (only the first when first_only) and returns whether there is any.
struct NearPieces {
  std::vector<const Piece*> a;
  std::vector<Piece> b;  // shifted
};
bool chain_overlaps(const std::vector<Body>& bodies, const std::vector<Vec3>& axis,
                    PieceCache* pieces, const PairEntry& e, double s, double grow, bool first_only,
                    NearPieces* near, std::vector<Contact>* found) {
  const Body &ba = bodies[e.a], &bb = bodies[e.b];
  const Vec3 ca = ba.shape.center, cb = bb.shape.center + e.shift;
  const double ra = ba.cap_radius_at(s) * (1.0 + grow), rb = bb.cap_radius_at(s) * (1.0 + grow);
  const Vec3 ha = axis[e.a] * (ba.cap_half_at(s) + ra - ba.cap_radius_at(s));
  const Vec3 hb = axis[e.b] * (bb.cap_half_at(s) + rb - bb.cap_radius_at(s));
  const Capsule cap_a{ca - ha, ca + ha, ra};
  const Capsule cap_b{cb - hb, cb + hb, rb};
  near->a.clear();
  near->b.clear();
  // A ball (centre c, radius r) that misses the capsule (a point against a segment, cheaper than
  // the capsules' segments) holds nothing that meets it.
  auto ball_meets = [](const Vec3& c, double r, const Capsule& cap) {
    const Vec3 d = cap.q - cap.p;
    const double d2 = d.squaredNorm();
    const double t = d2 > 0.0 ? std::clamp((c - cap.p).dot(d) / d2, 0.0, 1.0) : 0.0;
    const double reach = r + cap.r;
    return (cap.p + t * d - c).squaredNorm() < reach * reach;
  };
  // A piece whose bounding ball misses the other's capsule is apart from it; a run of pieces
  // whose ball misses it holds no piece near it.
  auto near_capsule = [&](const Piece& p, const Capsule& cap) {
    return ball_meets(p.center(), p.bounding_radius(), cap) && capsules_meet(capsule_of(p), cap);
  };
  // visit(k) for every piece k of body i in a run whose ball (moved by shift) meets cap.
  auto in_near_runs = [&](int i, size_t count, const Vec3& shift, const Capsule& cap,
                          const auto& visit) {
    const std::vector<RunBall>& runs = pieces->runs(i);
    for (size_t g = 0; g < runs.size(); ++g) {
      if (!ball_meets(runs[g].c + shift, runs[g].r, cap)) continue;
      for (size_t k = g * kRun; k < std::min(count, (g + 1) * kRun); ++k) visit(k);
    }
  };
  const std::vector<Piece>& pa = pieces->at(e.a, s, grow);
  in_near_runs(e.a, pa.size(), Vec3::Zero(), cap_b, [&](size_t k) {
    if (near_capsule(pa[k], cap_b)) near->a.push_back(&pa[k]);
  });
  if (near->a.empty()) return false;
  const std::vector<Piece>& pb = pieces->at(e.b, s, grow);
  in_near_runs(e.b, pb.size(), e.shift, cap_a, [&](size_t k) {
    const Piece q = pb[k].translated(e.shift);
    if (near_capsule(q, cap_a)) near->b.push_back(q);
  });
  // A deformed grain's piece is its bounding ball (its support function at the force scale,
  // grown like the pieces, gives the plane test).
  auto grain_of = [&](const Body& g, const Vec3& gc) {
    return Grain{gc, [&g, s, grow](const Vec3& u) {
                   return g.force_scale(s) * (1.0 + grow) * g.support_along(u);
                 }};
  };
  const bool is_grain_a = ba.support && !ba.chain, is_grain_b = bb.support && !bb.chain;
  const Grain ga = is_grain_a ? grain_of(ba, ca) : Grain{},
              gb = is_grain_b ? grain_of(bb, cb) : Grain{};
  return piece_contacts(near->a, near->b, is_grain_a ? &ga : nullptr, is_grain_b ? &gb : nullptr,
                        first_only, found);
}
// The valid scale of the overlapping pairs `limits` (scale certified by the contact plane,
// pair): the plane of the contact normal is not the best separating plane of every pair (end
// disks, the normals of EPA), and the pairs with the lowest such scales hold the packing back.
// Those kRefined are bisected kBisections times between their plane's scale and s_out with the
// exact test (valid at one scale, a pair is valid below it: both shapes shrink about inner
// points); the scale is the least of theirs and the next pair's plane scale.
double refined_scale(const std::vector<Body>& bodies, double s_out,
                     std::vector<std::pair<double, const PairEntry*>>* limits) {
  constexpr size_t kRefined = 64;
  constexpr int kBisections = 12;
  std::vector<std::pair<double, const PairEntry*>>& l = *limits;
  if (l.empty()) return s_out;
  const size_t k = std::min(kRefined, l.size());
  const auto by_scale = [](const auto& x, const auto& y) { return x.first < y.first; };
  if (k < l.size()) {
    std::nth_element(l.begin(), l.begin() + k, l.end(), by_scale);
  }
  double s = k < l.size() ? l[k].first : s_out;
  for (size_t i = 0; i < k; ++i) {
    const PairEntry& e = *l[i].second;
    const Body &ba = bodies[e.a], &bb = bodies[e.b];
    double lo = std::max(0.0, l[i].first), hi = s_out;
    for (int it = 0; it < kBisections && lo < s; ++it) {
      const double mid = 0.5 * (lo + hi);
      if (intersect(ba.at_scale(mid), bb.at_scale(mid).translated(e.shift)).overlap) {
        hi = mid;
      } else {
        lo = mid;
      }
    }
    s = std::min(s, lo);
  }
  return s;
}

// The walls of a closed box, a pass of their own (each body against the six faces): contacts
// push the shape at the force scale s_out back inside, summed into *sums with the pairs'; returns
// the largest scale at which every (unpadded) shape is inside.
double wall_pass(const std::vector<Body>& bodies, const Box& box, double s_out, ContactSums* sums) {
  const size_t n = bodies.size();
  double s_in = s_out;
  double& max_overlap = sums->max_overlap;
  auto add = [&](int i, const Vec3& dx, const Vec3& dw) {
    sums->move[i] += dx;
    sums->turn[i] += dw;
  };
  for (size_t i = 0; i < n; ++i) {
    const Body& b = bodies[i];
    Vec3 half, lo, hi;
    b.shape.scaled(1.0).translated(-b.shape.center).aabb(&lo, &half);  // half extents
    const Shape cur = b.at_scale(s_out);
    cur.aabb(&lo, &hi);
    for (int a = 0; a < 3; ++a) {
      const double c = b.shape.center[a], w0 = box.origin[a], w1 = w0 + box.size[a];
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
        max_overlap = std::max(max_overlap, depth / cur.min_size());
        // The wall is an immovable body beyond the face (normal from the inclusion to it).
        Contact c;
        c.overlap = true;
        c.depth = depth;
        c.normal = -nrm;
        c.point = p;
        const ContactResponse r =
            contact_response(cur.center, b.mobility(cur), p, BodyMobility{}, c, 1.0);
        add(static_cast<int>(i), r.move_a, r.turn_a);
      }
    }
  }
  return s_in;
}

// What the pairs of one block do, in pair order: the additions to the bodies' moves and turns
// (applied in that order after the block, so that every sum is formed as in one pass over all
// pairs, whatever the number of threads), and the block's share of the pass's results.
using Add = ContactBlock::Add;
using Block = ContactBlock;

// Pairs per block (the unit of work of a thread) and blocks tested before their additions are
// applied (bounds the additions held at once). Fixed: the blocks, and so every sum, do not
// depend on the number of threads.
constexpr size_t kBlock = 2048, kWindow = 64;

// A thread's work space: its chains' pieces, the pieces near a pair, the contacts of a pair.
struct Scratch {
  explicit Scratch(const std::vector<Body>& bodies) : pieces(bodies) {}
  PieceCache pieces;
  NearPieces near;
  std::vector<Contact> found;
};

// The contact of the listed pair e at s_out, added to *block.
void visit_pair(const std::vector<Body>& bodies, const std::vector<Vec3>& axis, const PairEntry& e,
                double s_out, double skin, PieceCache* pieces, NearPieces* near,
                std::vector<Contact>* found, Block* block) {
  Block& out = *block;
  const Body &ba = bodies[e.a], &bb = bodies[e.b];
  const double fa = ba.force_scale(s_out), fb = bb.force_scale(s_out);
  if (ba.shape.kind == ShapeKind::Sphere && bb.shape.kind == ShapeKind::Sphere) {
    // Round pairs (balls, grains): round_contact without a tolerance (any overlap pushes;
    // validity comes from the certified scale, not from this decision), after the bounding balls'
    // test without a square root for the many listed pairs that are apart.
    const double ra0 = ba.shape.radius, rb0 = bb.shape.radius;
    const Vec3 d = bb.shape.center + e.shift - ba.shape.center;
    const double rr0 = fa * ra0 + fb * rb0;
    const double d2 = d.squaredNorm();
    if (d2 >= rr0 * rr0) return;
    const double dist = std::sqrt(d2);
    double ra = 0.0, rb = 0.0;
    const auto support_a = [&](const Vec3& u) { return ba.support_along(u); };
    const auto support_b = [&](const Vec3& u) { return bb.support_along(u); };
    const Contact c =
        round_contact(ba.shape.center, d, dist, fa, support_a, fb, support_b, 0.0, &ra, &rb);
    if (!c.overlap) return;
    const Vec3& nrm = c.normal;
    const double depth = c.depth;
    out.max_overlap = std::max(out.max_overlap, depth / std::min(fa * ra, fb * rb));
    out.s_in = std::min(out.s_in, (dist - ba.pad * ra - bb.pad * rb) / (ra + rb));
    const Vec3 J = (kRelaxation * depth / (1.0 / ba.volume + 1.0 / bb.volume)) * nrm;
    out.adds.push_back({e.a, false, Vec3(-(J / ba.volume)), Vec3::Zero()});
    out.adds.push_back({e.b, false, Vec3(J / bb.volume), Vec3::Zero()});
    return;
  }
  if (ba.radial && bb.radial && std::abs(axis[e.a].dot(axis[e.b])) >= 1.0 - kParallelCos) {
    // Parallel fibres in closed form: they overlap exactly when their axial ranges do and
    // their axes are nearer than the sum of the radii; the push is sideways only, so aligned
    // fibres never butt end to end in columns.
    // Continuous fibres along one axis span it whole: they share their span in the image
    // without a shift along it, and the images along it are the fibres themselves, continued.
    const Vec3& u = axis[e.a];
    const Vec3 d = bb.shape.center + e.shift - ba.shape.center;
    if (ba.continued_by(bb, e.shift)) return;
    const bool shared_span = ba.through_axis >= 0 && ba.through_axis == bb.through_axis;
    const double along = std::abs(d.dot(u));
    if (!shared_span && along >= ba.cap_half_at(s_out) + bb.cap_half_at(s_out)) return;
    const Vec3 side = d - d.dot(u) * u;
    const double dist = side.norm(), ra = ba.shape.radius, rb = bb.shape.radius;
    const double reach = ba.cap_radius_at(s_out) + bb.cap_radius_at(s_out);
    if (dist >= reach) return;
    const double depth = reach - dist;
    const Vec3 nrm = dist > 0.0 ? Vec3(side / dist) : any_orthogonal(u);
    out.max_overlap = std::max(out.max_overlap, depth / (s_out * std::min(ra, rb)));
    out.s_in = std::min(out.s_in, (dist - ba.add_radius - bb.add_radius) / (ra + rb));
    const Vec3 J = (kRelaxation * depth / (1.0 / ba.volume + 1.0 / bb.volume)) * nrm;
    out.adds.push_back({e.a, false, Vec3(-(J / ba.volume)), Vec3::Zero()});
    out.adds.push_back({e.b, false, Vec3(J / bb.volume), Vec3::Zero()});
    return;
  }
  {
    // Bounding spheres, then capsules: most listed pairs of long bodies are apart.
    const Vec3 cb = bb.shape.center + e.shift;
    const double rr = ba.cap_radius_at(s_out) + bb.cap_radius_at(s_out);
    const double ha = ba.cap_half_at(s_out), hb = bb.cap_half_at(s_out);
    const double reach = rr + ha + hb;
    if ((cb - ba.shape.center).squaredNorm() >= reach * reach) return;
    // The distance between the axes' lines bounds the segments' from below: most listed
    // pairs of long crossing fibres are told apart here, without the segment distance.
    const Vec3 n = axis[e.a].cross(axis[e.b]);
    const double n2 = n.squaredNorm(), dn = (cb - ba.shape.center).dot(n);
    if (n2 > kLineTestMinSine2 && dn * dn >= rr * rr * n2) return;
    const Vec3 ea = axis[e.a] * ha, eb = axis[e.b] * hb;
    if (segment_distance2(ba.shape.center - ea, ba.shape.center + ea, cb - eb, cb + eb) >=
        rr * rr) {
      return;
    }
  }
  if (ba.chain || bb.chain) {
    // Chains: the exact tests piece by piece; each contact acts on the whole bodies, with the
    // weight 1 / count (at full weight, the several contacts of a crossing would push it
    // apart several times over).
    const Vec3 ca = ba.shape.center, cb = bb.shape.center + e.shift;
    out.chain_pairs.push_back(&e);
    found->clear();
    if (!chain_overlaps(bodies, axis, pieces, e, s_out, skin, false, near, found)) {
      return;
    }
    const Shape A = ba.at_scale(s_out), B = bb.at_scale(s_out).translated(e.shift);
    double deepest = 0.0, total = 0.0;
    Vec3 sum = Vec3::Zero();
    for (const Contact& c : *found) {
      const double rel = c.depth / std::min(A.min_size(), B.min_size());
      out.max_overlap = std::max(out.max_overlap, rel);
      out.chain_depth = std::max(out.chain_depth, rel);
      deepest = std::max(deepest, rel);
      total += c.depth;
      sum += c.depth * c.normal;
    }
    const double pushed = sum.norm();
    if (pushed < kCancelling * total) {
      // The pieces' least translations cancel, so the pair would stay as it is: a body caught
      // inside a chain, or two parallel chains overlapping side by side. The pieces are slices
      // thinner than they are wide: each pair of them parts soonest along the fibre, into the
      // next piece, and such pushes point either way. One contact pushes the pair apart across
      // the chain's axis instead, by the deepest overlap.
      const Vec3& u = axis[ba.chain ? e.a : e.b];
      Vec3 n = cb - ca;
      n -= n.dot(u) * u;
      n = n.squaredNorm() > 0.0 ? Vec3(n.normalized()) : any_orthogonal(u);
      Contact c;
      c.overlap = true;
      c.type = ContactType::kPiece;
      c.depth = deepest * std::min(A.min_size(), B.min_size());
      c.normal = n;
      c.point = 0.5 * (ca + cb);
      found->assign(1, c);
    }
    const BodyMobility ma = ba.mobility(A), mb = bb.mobility(B);
    // Each contact at the weight that makes their summed push the deepest overlap's, as a
    // convex pair's single contact would be (at least 1 / count, at most full weight): at
    // 1 / count, their mean, a chain's contacts were softer than any other pair's, and chain
    // pairs took the deepest overlaps under pressure.
    const double count = static_cast<double>(found->size());
    const double weight =
        found->size() > 1 && pushed > 0.0
            ? std::clamp(kRelaxation * deepest * std::min(A.min_size(), B.min_size()) / pushed,
                         kRelaxation / count, kRelaxation)
            : kRelaxation / count;
    for (const Contact& c : *found) {
      const ContactResponse r = contact_response(ca, ma, cb, mb, c, weight);
      out.adds.push_back({e.a, true, r.move_a, r.turn_a});
      out.adds.push_back({e.b, true, r.move_b, r.turn_b});
    }
    return;
  }
  const Shape A = ba.at_scale(s_out);
  const Shape B = bb.at_scale(s_out).translated(e.shift);
  const Contact c = intersect(A, B);
  if (!c.overlap) return;
  out.max_overlap = std::max(out.max_overlap, c.depth / std::min(A.min_size(), B.min_size()));
  out.limits.push_back({separating_scale(ba, bb, e.shift, c.normal), &e});
  // An inclusion against its own periodic image (e.a == e.b) only turns: the two moves
  // cancel.
  const ContactResponse r =
      contact_response(A.center, ba.mobility(A), B.center, bb.mobility(B), c, kRelaxation);
  out.adds.push_back({e.a, true, r.move_a, r.turn_a});
  out.adds.push_back({e.b, true, r.move_b, r.turn_b});
}

}  // namespace

double contact_pass(const std::vector<Body>& bodies, const std::vector<int>& oriented,
                    const std::vector<PairEntry>& pairs, const Box& box, double s_out, double keep,
                    double skin, ContactSums* sums, const std::function<void()>& tick) {
  const size_t n = bodies.size();
  std::vector<Vec3>&move = sums->move, &turn = sums->turn, &axis = sums->axis;
  move.resize(n);
  turn.resize(n);
  for (size_t i = 0; i < n; ++i) {
    move[i].setZero();
    turn[i].setZero();
  }
  // Spheres have no axis: zero (their capsules are points), set once (bodies keep their order).
  if (axis.size() != n) axis.assign(n, Vec3::Zero());
  for (int i : oriented) axis[i] = principal_axis(bodies[i].shape);
  double s_in = s_out;
  double& max_overlap = sums->max_overlap;
  max_overlap = 0.0;
  PieceCache pieces(bodies);  // chains, for the certification below
  NearPieces near;
  std::vector<const PairEntry*> chain_pairs;  // pairs with a chain whose capsules meet
  double chain_depth = 0.0;                   // their deepest overlap, relative
  // Pairs that overlap at s_out (exact test) and the scale their contact plane certifies.
  std::vector<std::pair<double, const PairEntry*>>& limits = sums->limits;
  limits.clear();
  // The pairs in blocks of kBlock, kWindow blocks at a time: the blocks of a window are tested
  // on all cores, then their additions applied in block order.
  const size_t nb = (pairs.size() + kBlock - 1) / kBlock;
  std::vector<Block>& blocks = sums->blocks;
  if (blocks.size() < std::min(nb, kWindow)) blocks.resize(std::min(nb, kWindow));
  tbb::enumerable_thread_specific<Scratch> scratch([&] { return Scratch(bodies); });
  const auto caller = std::this_thread::get_id();
  for (size_t w0 = 0; w0 < nb; w0 += kWindow) {
    const size_t w1 = std::min(nb, w0 + kWindow);
    rvegen::parallel_for(w0, w1, [&](size_t k) {
      if (tick && std::this_thread::get_id() == caller) tick();
      Block& out = blocks[k - w0];
      out.adds.clear();
      out.chain_pairs.clear();
      out.limits.clear();
      out.s_in = s_out;
      out.max_overlap = 0.0;
      out.chain_depth = 0.0;
      Scratch& sc = scratch.local();
      const size_t end = std::min(pairs.size(), (k + 1) * kBlock);
      for (size_t i = k * kBlock; i < end; ++i) {
        visit_pair(bodies, axis, pairs[i], s_out, skin, &sc.pieces, &sc.near, &sc.found, &out);
      }
    });
    for (size_t k = w0; k < w1; ++k) {
      if (tick) tick();
      const Block& b = blocks[k - w0];
      for (const Add& a : b.adds) {
        move[a.body] += a.dx;
        if (a.turns) turn[a.body] += a.dw;
      }
      chain_pairs.insert(chain_pairs.end(), b.chain_pairs.begin(), b.chain_pairs.end());
      limits.insert(limits.end(), b.limits.begin(), b.limits.end());
      s_in = std::min(s_in, b.s_in);
      max_overlap = std::max(max_overlap, b.max_overlap);
      chain_depth = std::max(chain_depth, b.chain_depth);
    }
  }
  s_in = std::min(s_in, refined_scale(bodies, s_out, &limits));
  // Walls: their own pass.
  if (!box.periodic) s_in = std::min(s_in, wall_pass(bodies, box, s_out, sums));
  if (!chain_pairs.empty()) {
    // A chain is not convex: shrunk about its centre, a piece behind it moves towards what lies
    // beyond, so no pair is valid below a scale merely because it is valid at s_out. The scale
    // is tested: every chain pair whose capsules meet is checked piece by piece at it. Pairs
    // whose capsules do not meet stay apart below (capsules are convex about the centres); the
    // packer stops at scale 1.
    size_t first = 0;  // the pair that failed last is tested first
    // The answer (does any pair overlap) does not depend on the order the pairs are tested in:
    // all cores test them, and stop at the first overlap any finds.
    auto clear_at = [&](double s) {
      if (chain_overlaps(bodies, axis, &pieces, *chain_pairs[first], s, 0.0, true, &near,
                         nullptr)) {
        return false;
      }
      std::atomic<bool> hit{false};
      std::atomic<size_t> hit_at{first};
      rvegen::parallel_for_range(tbb::blocked_range<size_t>(0, chain_pairs.size(), 16),
                                 [&](const tbb::blocked_range<size_t>& r) {
                                   Scratch& sc = scratch.local();
                                   for (size_t i = r.begin(); i != r.end() && !hit; ++i) {
                                     if (chain_overlaps(bodies, axis, &sc.pieces, *chain_pairs[i],
                                                        s, 0.0, true, &sc.near, nullptr)) {
                                       hit = true;
                                       hit_at = i;
                                     }
                                   }
                                 });
      first = hit_at;
      return !hit;
    };
    // The force scale itself, when the contacts of the grown pieces have parted the pieces as
    // they are.
    const double s_top = std::min({s_in, 1.0, s_out});
    if (skin > 0.0 && s_top > 0.0 && clear_at(s_top)) return s_top;
    // Else the largest of s0 (1 - d) that passes, d = 0, then 0.001 2^k (k = 0..9), with s0 the
    // least of s_in, 1 and s_out less the deepest chain overlap (relative to the smaller body,
    // about the scale at which that pair's pieces part); 0 when none above `keep` does.
    const double s0 = std::min({s_in, 1.0, s_out * (1.0 - std::min(chain_depth, 0.5))});
    for (int k = -1; k <= 9; ++k) {
      const double at = s0 * (1.0 - (k < 0 ? 0.0 : 0.001 * std::ldexp(1.0, k)));
      if (at <= keep) break;
      if (clear_at(at)) return at;
    }
    return 0.0;
  }
  return std::max(0.0, s_in);
}

}  // namespace rvegen::md
