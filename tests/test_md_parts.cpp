// The parts of the molecular-dynamics packer, one at a time: bodies, Verlet list, contact pass,
// integrator.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <set>
#include <string>
#include <tuple>

#include "rvegen/io/scene_json.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/packing/body_contacts.hpp"
#include "rvegen/packing/md_integrator.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {
namespace {

using md::Body;

// Bodies of a scene at their random starting centres.
md::Bodies bodies_of(const std::string& json) {
  const Scene scene = parse_scene(json);
  Random rng(scene.seed);
  const std::vector<Inclusion> pop = draw_population(scene, rng);
  return md::make_bodies(scene, pop, rng);
}

const char* kMixed = R"({"box":{"size":[1,1,1],"periodic":true},"seed":5,"families":[
  {"shape":"sphere","radius":0.04,"count":150},
  {"shape":"cylinder","radius":0.012,"aspect_ratio":16,"count":150},
  {"shape":"ellipsoid","semi_axes":[0.08,0.03,0.02],"count":100}]})";

// Every pair of bodies that overlaps at scale s (exact test, all periodic images).
std::set<std::tuple<int, int, int, int, int>> overlapping(const std::vector<Body>& b,
                                                          const Box& box, double s) {
  std::set<std::tuple<int, int, int, int, int>> out;
  for (size_t i = 0; i < b.size(); ++i) {
    const Shape A = b[i].at_scale(s);
    for (size_t j = i; j < b.size(); ++j) {
      const Shape B = b[j].at_scale(s);
      for_each_image(box, A.center, A.bounding_radius(), B.center, B.bounding_radius(),
                     [&](const Vec3& sh) {
                       if (i == j && sh.isZero()) return;
                       if (!intersect(A, B.translated(sh)).overlap) return;
                       const int kx = static_cast<int>(std::lround(sh[0] / box.size[0])),
                                 ky = static_cast<int>(std::lround(sh[1] / box.size[1])),
                                 kz = static_cast<int>(std::lround(sh[2] / box.size[2]));
                       out.insert({static_cast<int>(i), static_cast<int>(j), kx, ky, kz});
                     });
    }
  }
  return out;
}

TEST(MdParts, VerletListHoldsEveryOverlapUntilItIsStale) {
  md::Bodies bodies = bodies_of(kMixed);
  const Box box = parse_scene(kMixed).box;
  std::vector<Body>& b = bodies.all;
  const double s = 0.9;
  md::VerletList list;
  EXPECT_TRUE(list.stale(b, s));
  list.build(&b, box, s, nullptr);
  EXPECT_FALSE(list.stale(b, s));
  Random rng(11);
  int checked = 0;
  size_t overlaps = 0;
  for (int round = 0; round < 40; ++round) {
    // Small random moves and turns, as long as the list says it still holds.
    std::vector<Body> moved = b;
    for (size_t i = 0; i < moved.size(); ++i) {
      Vec3 d(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5);
      moved[i].shape.center += 0.004 * d;
    }
    if (list.stale(moved, s)) break;
    b = moved;
    std::set<std::tuple<int, int, int, int, int>> listed;
    for (const md::PairEntry& e : list.pairs()) {
      const int kx = static_cast<int>(std::lround(e.shift[0] / box.size[0])),
                ky = static_cast<int>(std::lround(e.shift[1] / box.size[1])),
                kz = static_cast<int>(std::lround(e.shift[2] / box.size[2]));
      listed.insert({e.a, e.b, kx, ky, kz});
      if (e.a == e.b) listed.insert({e.a, e.b, -kx, -ky, -kz});
    }
    const auto over = overlapping(b, box, s);
    overlaps += over.size();
    for (const auto& p : over) {
      EXPECT_TRUE(listed.count(p)) << "round " << round << ": pair " << std::get<0>(p) << ", "
                                   << std::get<1>(p) << " overlaps and is not listed";
    }
    ++checked;
  }
  EXPECT_GE(checked, 2);
  EXPECT_GT(overlaps, 20u);  // random centres: many overlapping pairs to find
  // A large move makes it stale.
  b[3].shape.center += Vec3(0.2, 0, 0);
  EXPECT_TRUE(list.stale(b, s));
}

// update() refreshes the bodies that left their skin one by one, against the others' reference
// capsules, and rebuilds everything when many did: through moves of a few bodies far, of all
// a little, and growth, every overlapping pair stays listed, in periodic and closed boxes.
TEST(MdParts, VerletListUpdatedBodyByBodyHoldsEveryOverlap) {
  for (const bool periodic : {true, false}) {
    std::string json = kMixed;
    if (!periodic) json.replace(json.find("true"), 4, "false");
    md::Bodies bodies = bodies_of(json);
    const Box box = parse_scene(json).box;
    std::vector<Body>& b = bodies.all;
    md::VerletList list;
    double s = 0.8;
    list.update(&b, box, s, nullptr);
    Random rng(3);
    size_t overlaps = 0;
    for (int round = 0; round < 60; ++round) {
      for (size_t i = 0; i < b.size(); ++i) {
        const Vec3 d(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5);
        b[i].shape.center += (rng.uniform() < 0.02 ? 0.06 : 0.002) * d;
      }
      s *= 1.002;
      list.update(&b, box, s, nullptr);
      std::set<std::tuple<int, int, int, int, int>> listed;
      for (const md::PairEntry& e : list.pairs()) {
        const int kx = static_cast<int>(std::lround(e.shift[0] / box.size[0])),
                  ky = static_cast<int>(std::lround(e.shift[1] / box.size[1])),
                  kz = static_cast<int>(std::lround(e.shift[2] / box.size[2]));
        EXPECT_LE(e.a, e.b);
        listed.insert({e.a, e.b, kx, ky, kz});
        if (e.a == e.b) listed.insert({e.a, e.b, -kx, -ky, -kz});
      }
      const auto over = overlapping(b, box, s);
      overlaps += over.size();
      for (const auto& p : over) {
        ASSERT_TRUE(listed.count(p))
            << "periodic " << periodic << " round " << round << ": pair " << std::get<0>(p) << ", "
            << std::get<1>(p) << " overlaps and is not listed";
      }
    }
    EXPECT_GT(overlaps, 200u);
    EXPECT_GT(list.refreshed(), 20) << "periodic " << periodic;  // body by body, mostly
    EXPECT_LT(list.rebuilds(), 30) << "periodic " << periodic;
  }
}

TEST(MdParts, ContactPassCertifiesTheTouchingScale) {
  // Two spheres of radius 0.1 at distance 0.15: they touch at scale 0.75; in a closed box, a
  // third one pokes out of the wall at x = 0.
  const char* json = R"({"box":{"size":[1,1,1],"periodic":false},"seed":1,"families":[
    {"shape":"sphere","radius":0.1,"count":3}]})";
  md::Bodies bodies = bodies_of(json);
  std::vector<Body>& b = bodies.all;
  b[0].shape.center = Vec3(0.4, 0.5, 0.5);
  b[1].shape.center = Vec3(0.55, 0.5, 0.5);
  b[2].shape.center = Vec3(0.05, 0.2, 0.2);
  const Box box = parse_scene(json).box;
  md::VerletList list;
  list.build(&b, box, 1.0, nullptr);
  md::ContactSums sums;
  const double s_in =
      md::contact_pass(b, bodies.oriented, list.pairs(), box, 1.0, 0.0, 0.0, &sums, nullptr);
  EXPECT_NEAR(s_in, 0.5, 1e-12);    // the wall: sphere 2 is inside up to radius 0.05
  EXPECT_LT(sums.move[0][0], 0.0);  // pushed apart along x
  EXPECT_GT(sums.move[1][0], 0.0);
  EXPECT_NEAR(sums.move[0][0], -sums.move[1][0], 1e-15);
  EXPECT_GT(sums.move[2][0], 0.0);  // pushed back into the box
  EXPECT_NEAR(sums.max_overlap, 0.05 / 0.1, 1e-12);
  // Without the wall's sphere, the pair alone: valid up to their touching scale.
  b[2].shape.center = Vec3(0.5, 0.8, 0.8);
  list.build(&b, box, 1.0, nullptr);
  EXPECT_NEAR(
      md::contact_pass(b, bodies.oriented, list.pairs(), box, 1.0, 0.0, 0.0, &sums, nullptr), 0.75,
      1e-12);
}

// The contact plane's scale is not the pair's: a tilted fibre whose rim presses on another's
// side is valid well above the scale at which the plane of its contact normal (at the outer
// scale) separates the pair. The pass bisects such pairs with the exact test: the scale it
// returns is valid and within 1e-3 of the exact one, above the plane's.
TEST(MdParts, ContactPassRefinesTheScaleOfTheLimitingPairs) {
  const char* json = R"({"box":{"size":[1,1,1],"periodic":true},"seed":1,"families":[
    {"shape":"cylinder","radius":0.02,"aspect_ratio":5,"count":2}]})";
  md::Bodies bodies = bodies_of(json);
  std::vector<Body>& b = bodies.all;
  const Box box = parse_scene(json).box;
  const double h = b[0].shape.half_axis.norm(), r = b[0].shape.radius;
  b[0].shape.center = Vec3(0.5, 0.5, 0.5);
  b[0].shape.half_axis = Vec3(h, 0, 0);
  const Vec3 u = Vec3(0.3, 0.2, 1.0).normalized();
  b[1].shape.half_axis = h * u;
  b[1].shape.center =
      Vec3(0.52, 0.5, 0.5 + r + h * u[2] + 0.6 * r * std::sqrt(1 - u[2] * u[2]) - 0.01);
  md::VerletList list;
  list.build(&b, box, 1.0, nullptr);
  md::ContactSums sums;
  const double s_in =
      md::contact_pass(b, bodies.oriented, list.pairs(), box, 1.0, 0.0, 0.0, &sums, nullptr);
  const auto overlap_at = [&](double s) {
    return intersect(b[0].at_scale(s), b[1].at_scale(s)).overlap;
  };
  ASSERT_TRUE(overlap_at(1.0));
  double lo = 0.0, hi = 1.0;  // the exact scale
  for (int it = 0; it < 60; ++it) (overlap_at(0.5 * (lo + hi)) ? hi : lo) = 0.5 * (lo + hi);
  const Contact c = intersect(b[0].at_scale(1.0), b[1].at_scale(1.0));
  const double plane = md::separating_scale(b[0], b[1], Vec3::Zero(), c.normal);
  EXPECT_FALSE(overlap_at(s_in));
  EXPECT_LE(s_in, lo);
  EXPECT_GT(s_in, lo - 1e-3);
  EXPECT_LT(plane, s_in - 1e-3) << "plane " << plane << " exact " << lo;
}

TEST(MdParts, IntegratorKeepsMomentumAndCapsTurns) {
  md::Bodies bodies = bodies_of(R"({"box":{"size":[1,1,1]},"seed":2,"families":[
    {"shape":"cylinder","radius":0.02,"aspect_ratio":5,"count":1,
     "orientation":{"law":"isotropic"}}]})");
  std::vector<Body>& b = bodies.all;
  ASSERT_EQ(b[0].turn, md::Turn::kFree);
  md::VerletList list;
  list.build(&b, Box{}, 1.0, nullptr);
  md::Integrator integrator(1);
  md::ContactSums sums;
  sums.move = {Vec3(0.01, 0, 0)};
  sums.turn = {Vec3(0, 0, 1.0)};  // far above the cap per step
  const Vec3 c0 = b[0].shape.center, a0 = b[0].shape.half_axis;
  integrator.step(sums, &b, &list);
  EXPECT_NEAR((b[0].shape.center - c0)[0], 0.01, 1e-15);
  // Turned by the cap (0.2 rad a step) about z, not by the full 1 rad asked.
  const Vec3 expected = Eigen::AngleAxisd(0.2, Vec3::UnitZ()) * a0;
  EXPECT_LT((b[0].shape.half_axis - expected).norm(), 1e-12 * a0.norm());
  EXPECT_NEAR(b[0].shape.half_axis.norm(), a0.norm(), 1e-14);  // length kept
  // No new contact: the body coasts at 0.9 of its last step.
  sums.move = {Vec3::Zero()};
  sums.turn = {Vec3::Zero()};
  const Vec3 c1 = b[0].shape.center;
  integrator.step(sums, &b, &list);
  EXPECT_NEAR((b[0].shape.center - c1)[0], 0.009, 1e-15);
}

// A chain turns as a rigid body: its pieces turn with its axis, also when the turn spins it
// about that axis or the axis crosses where the frame of CentreLine (any_orthogonal) switches
// coordinate axis. (Before, the wave kept its angle about that frame: a spin did nothing and a
// switch turned the wave by up to 90 degrees in one step.)
TEST(MdParts, ChainTurnsWithItsWave) {
  md::Bodies bodies = bodies_of(R"({"box":{"size":[1,1,1]},"seed":3,"families":[
    {"shape":"cylinder","radius":0.02,"aspect_ratio":8,"count":1,
     "waviness":{"amplitude":0.02,"wavelength":0.2}}]})");
  Body& b = bodies.all[0];
  ASSERT_TRUE(b.chain);
  const Vec3 c = b.shape.center;
  const std::vector<Mat3> turns = {
      Mat3(Eigen::AngleAxisd(0.7, b.shape.half_axis.normalized())),  // a spin only
      Mat3(Eigen::AngleAxisd(0.3, Vec3(1, 2, -1).normalized())),
      Mat3(Eigen::AngleAxisd(2.5, Vec3(-0.2, 0.9, 0.4).normalized()))};
  for (int axis = 0; axis < 3; ++axis) {
    // Axes near the switches of any_orthogonal: |u_x| = |u_y|, |u_y| = |u_z|.
    Vec3 u(1.0, 1.0 + 1e-9, 0.3);
    u[axis] = 0.2;
    b.shape.half_axis = u.normalized() * b.shape.half_axis.norm();
    for (const Mat3& R : turns) {
      std::vector<ShearedPiece> before, after;
      chain_pieces(b.chain_at(1.0), &before);
      Body turned = b;
      turned.turn_by(R);
      chain_pieces(turned.chain_at(1.0), &after);
      ASSERT_EQ(before.size(), after.size());
      ASSERT_GE(before.size(), 3u);
      for (size_t k = 0; k < before.size(); ++k) {
        EXPECT_LT((after[k].center - c - R * (before[k].center - c)).norm(), 1e-12);
        EXPECT_LT((after[k].half_axis - R * before[k].half_axis).norm(), 1e-12);
      }
      EXPECT_LT((turned.shape.half_axis - R * b.shape.half_axis).norm(), 1e-12);
    }
  }
}

// A coated wavy fibre (radius 0.02, L/D 8, amplitude = radius, the given wavelength) packed as
// a chain, along z about the middle of the unit box, and a sphere of the given radius: the
// bodies, which is which, and one contact pass with the sphere where it is.
struct ChainAndGrain {
  ChainAndGrain(double wavelength, double grain_radius) {
    const std::string json =
        R"({"box":{"size":[1,1,1]},"seed":4,"families":[
    {"shape":"cylinder","radius":0.02,"aspect_ratio":8,"count":1,
     "waviness":{"amplitude":0.02,"wavelength":)" +
        std::to_string(wavelength) + R"(},"coating":{"thickness":0.005}},
    {"shape":"sphere","radius":)" +
        std::to_string(grain_radius) + R"(,"count":1}]})";
    bodies = bodies_of(json);
    box = parse_scene(json).box;
    f = bodies.all[0].chain ? 0 : 1;
    g = 1 - f;
    Body& fibre = bodies.all[f];
    fibre.shape.center = Vec3(0.5, 0.5, 0.5);
    fibre.shape.half_axis = Vec3(0, 0, fibre.shape.half_axis.norm());
  }
  double pass(double skin, md::ContactSums* sums) {
    md::VerletList list;
    list.build(&bodies.all, box, 1.0, nullptr);
    return md::contact_pass(bodies.all, bodies.oriented, list.pairs(), box, 1.0, 0.0, skin, sums,
                            nullptr);
  }
  md::Bodies bodies;
  Box box;
  int f = 0, g = 1;
};

// Chain pairs push at pieces grown by the skin and are certified at the force scale when the
// pieces as they are do not meet: a grain 0.4 skin radii from a chain is pushed away and valid
// at scale 1; without a skin it is not pushed; 0.4 skin radii into the chain it is not valid at
// scale 1.
TEST(MdParts, ChainContactsActAtTheSkinAndCertifyTheForceScale) {
  ChainAndGrain scene(0.2, 0.05);
  std::vector<Body>& b = scene.bodies.all;
  const int f = scene.f, g = scene.g;
  ASSERT_TRUE(b[f].chain);
  ASSERT_FALSE(b[g].chain);
  std::vector<ShearedPiece> pieces;
  chain_pieces(b[f].chain_at(1.0), &pieces);
  const Vec3 dir = Vec3(1, 1, 0).normalized();
  auto meets = [&](double d) {
    const Shape grain = Shape::sphere(b[f].shape.center + d * dir, b[g].shape.radius);
    for (const ShearedPiece& p : pieces) {
      if (intersect_pieces(Piece::of(p), Piece::of(grain)).overlap) return true;
    }
    return false;
  };
  // The touching distance along dir, by bisection.
  double lo = 0.0, hi = 0.5;
  for (int it = 0; it < 60; ++it) (meets(0.5 * (lo + hi)) ? lo : hi) = 0.5 * (lo + hi);
  constexpr double kSkin = 0.01;
  const double gap = 0.4 * kSkin * b[g].shape.radius;
  auto pass = [&](double d, double skin, md::ContactSums* sums) {
    b[g].shape.center = b[f].shape.center + d * dir;
    return scene.pass(skin, sums);
  };
  md::ContactSums sums;
  EXPECT_EQ(pass(hi + gap, kSkin, &sums), 1.0);
  EXPECT_GT(sums.move[g].dot(dir), 0.0);  // pushed away from the chain
  EXPECT_GT(sums.max_overlap, 0.0);
  EXPECT_EQ(pass(hi + gap, 0.0, &sums), 1.0);
  EXPECT_EQ(sums.move[g].norm(), 0.0);
  EXPECT_LT(pass(lo - gap, kSkin, &sums), 1.0);
  EXPECT_GT(sums.move[g].dot(dir), 0.0);
}

// A grain pressed into a wavy fibre meets several of its pieces at once. Their contacts push
// the pair apart as far as the deepest of them, as a convex pair's single contact would: at a
// share 1 / count each (their mean), chain pairs were softer than any other pair and took the
// deepest overlaps under pressure.
TEST(MdParts, AChainPairIsPushedApartByItsDeepestOverlap) {
  ChainAndGrain scene(0.2, 0.05);
  std::vector<Body>& b = scene.bodies.all;
  const int f = scene.f, g = scene.g;
  std::vector<ShearedPiece> pieces;
  chain_pieces(b[f].chain_at(1.0), &pieces);
  const Vec3 dir = Vec3(1, 1, 0).normalized();
  auto contacts = [&](double d) {
    std::vector<Contact> out;
    const Shape grain = Shape::sphere(b[f].shape.center + d * dir, b[g].shape.radius);
    for (const ShearedPiece& p : pieces) {
      const Contact c = intersect_pieces(Piece::of(p), Piece::of(grain));
      if (c.overlap) out.push_back(c);
    }
    return out;
  };
  double lo = 0.0, hi = 0.5;  // the touching distance along dir
  for (int it = 0; it < 60; ++it) (contacts(0.5 * (lo + hi)).empty() ? hi : lo) = 0.5 * (lo + hi);
  for (double into : {0.25, 0.4}) {
    const double d = hi - into * b[g].shape.radius;
    const std::vector<Contact> found = contacts(d);
    ASSERT_GE(found.size(), 3u);
    double deepest = 0.0;
    Vec3 mean = Vec3::Zero();  // the push at a share 1 / count each
    for (const Contact& c : found) {
      deepest = std::max(deepest, c.depth);
      mean += c.depth * c.normal / static_cast<double>(found.size());
    }
    EXPECT_LT(mean.norm(), 0.75 * deepest);  // what a share 1 / count each would give
    b[g].shape.center = b[f].shape.center + d * dir;
    md::ContactSums sums;
    scene.pass(0.0, &sums);
    // Apart by the deepest overlap, less the share the fibre's turn takes.
    const double apart = (sums.move[g] - sums.move[f]).dot(dir);
    EXPECT_GT(apart, 0.85 * deepest);
    EXPECT_LT(apart, 1.5 * deepest);
  }
}

// A small grain caught inside a chain, near its axis (as random placement leaves some at the
// start scale): the inner pieces' least translations run along the fibre and cancel, so without
// a push across the axis it stays there (a 1-wave mixture in a 1.2 box jammed at 0.0006 so). The
// pass pushes it out across the axis, on the side its centre lies.
TEST(MdParts, GrainCaughtInsideAChainIsPushedOutAcrossTheAxis) {
  ChainAndGrain scene(0.32, 0.004);
  std::vector<Body>& b = scene.bodies.all;
  const int f = scene.f, g = scene.g;
  ASSERT_TRUE(b[f].chain);
  const Vec3 u(0, 0, 1);
  // On the centre line, a little off it across the axis (the wave's offset at the middle).
  const Vec3 side = Vec3(1, 2, 0).normalized();
  b[g].shape.center = b[f].shape.center + centre_offset(b[f].chain_at(1.0), 0.0) + 0.001 * side;
  md::ContactSums sums;
  EXPECT_EQ(scene.pass(0.0, &sums), 0.0);
  EXPECT_GT(sums.max_overlap, 0.5);
  const Vec3 push = sums.move[g] - sums.move[f];
  const Vec3 across = push - push.dot(u) * u;
  EXPECT_GT(across.norm(), 0.004) << push.transpose();  // out by about the grain's size or more
  EXPECT_GT(across.normalized().dot(b[g].shape.center - b[f].shape.center -
                                    (b[g].shape.center - b[f].shape.center).dot(u) * u),
            0.0);
}

// Two parallel wavy fibres overlapping side by side (here a fibre and its copy moved across by
// 0.4 of its radius): the pieces are slices thinner than they are wide, so each pair of pieces
// parts soonest along the fibres, and those pushes point either way and cancel; with them
// alone the pair stays as it is (a three-wave mixture in a unit box stalled 40 s on such a pair
// at 8 % overlap). The pass pushes them apart across the axes, on the side the copy lies.
TEST(MdParts, ParallelChainsOverlappingSideBySideArePushedApartAcrossTheAxis) {
  const std::string json =
      R"({"box":{"size":[1,1,1]},"seed":4,"families":[
    {"shape":"cylinder","radius":0.02,"aspect_ratio":8,"count":2,
     "waviness":{"amplitude":0.02,"wavelength":0.106667},"coating":{"thickness":0.005}}]})";
  md::Bodies bodies = bodies_of(json);
  const Box box = parse_scene(json).box;
  std::vector<Body>& b = bodies.all;
  ASSERT_EQ(b.size(), 2u);
  ASSERT_TRUE(b[0].chain && b[1].chain);
  const Vec3 u(0, 0, 1);
  b[0].shape.center = Vec3(0.5, 0.5, 0.5);
  b[0].shape.half_axis = b[0].shape.half_axis.norm() * u;
  b[1] = b[0];
  const Vec3 side = Vec3(2, 1, 0).normalized();
  b[1].shape.center += 0.01 * side;
  // The premise: the pieces' contacts, as the pass finds them, cancel at an overlap well below
  // a body caught inside the other.
  std::vector<ShearedPiece> pa, pb;
  chain_pieces(b[0].chain_at(1.0), &pa);
  chain_pieces(b[1].chain_at(1.0), &pb);
  std::vector<Piece> a_pieces, b_pieces;
  for (const ShearedPiece& p : pa) a_pieces.push_back(Piece::of(p));
  for (const ShearedPiece& p : pb) b_pieces.push_back(Piece::of(p));
  std::vector<const Piece*> a_near;
  for (const Piece& p : a_pieces) a_near.push_back(&p);
  std::vector<Contact> found;
  ASSERT_TRUE(piece_contacts(a_near, b_pieces, nullptr, nullptr, false, &found));
  Vec3 sum = Vec3::Zero();
  double total = 0.0;
  for (const Contact& c : found) {
    sum += c.depth * c.normal;
    total += c.depth;
  }
  EXPECT_GE(found.size(), 10u);
  EXPECT_LT(sum.norm(), 0.25 * total);
  md::VerletList list;
  list.build(&b, box, 1.0, nullptr);
  md::ContactSums sums;
  EXPECT_EQ(md::contact_pass(b, bodies.oriented, list.pairs(), box, 1.0, 0.0, 0.0, &sums, nullptr),
            0.0);
  EXPECT_GT(sums.max_overlap, 0.1);
  EXPECT_LT(sums.max_overlap, 0.5);
  const Vec3 push = sums.move[1] - sums.move[0];
  EXPECT_GT(push.dot(side), 0.9 * push.norm()) << push.transpose();
  EXPECT_GT(push.norm(), 0.005) << push.transpose();
}

TEST(MdParts, SpaceOrderKeepsEveryBodyAndPutsNeighboursTogether) {
  const md::Bodies before = bodies_of(kMixed);
  md::Bodies after = before;
  const Box box = parse_scene(kMixed).box;
  const std::vector<int> drawn = md::order_in_space(box, &after);
  ASSERT_EQ(drawn.size(), before.all.size());
  std::set<int> seen(drawn.begin(), drawn.end());
  EXPECT_EQ(seen.size(), drawn.size());  // a permutation
  double step_before = 0.0, step_after = 0.0;
  for (size_t k = 0; k < drawn.size(); ++k) {
    EXPECT_EQ(after.all[k].shape.center, before.all[drawn[k]].shape.center);
    EXPECT_EQ(after.all[k].family, before.all[drawn[k]].family);
    if (k > 0) {
      step_before += (before.all[k].shape.center - before.all[k - 1].shape.center).norm();
      step_after += (after.all[k].shape.center - after.all[k - 1].shape.center).norm();
    }
  }
  // Consecutive bodies are close along the curve: far closer than in the drawn (random) order.
  EXPECT_LT(step_after, 0.4 * step_before);
  // The index lists follow their bodies.
  ASSERT_EQ(after.oriented.size(), before.oriented.size());
  for (int k : after.oriented) EXPECT_NE(after.all[k].shape.kind, ShapeKind::Sphere);
}

// Above md::kSpaceOrderFrom bodies the packer works in space order, and writes the inclusions in
// the order drawn all the same: inclusion j has the size drawn j-th.
TEST(MdParts, LargePackingWritesInclusionsInDrawnOrder) {
  const std::string json = R"({"box":{"size":[1,1,1]},"seed":3,"families":[
    {"shape":"sphere","radius":{"law":"lognormal","mean":0.008,"std":0.002},"count":33000}]})";
  const Scene scene = parse_scene(json);
  Random rng(scene.seed);
  const std::vector<Inclusion> pop = draw_population(scene, rng);
  ASSERT_GE(pop.size(), md::kSpaceOrderFrom);
  const PackingResult res = generate(scene);
  ASSERT_EQ(res.status, PackingStatus::kOk);
  ASSERT_EQ(res.set.inclusions.size(), pop.size());
  for (size_t j = 0; j < pop.size(); ++j) {
    ASSERT_EQ(res.set.inclusions[j].id, static_cast<int>(j));
    ASSERT_EQ(res.set.inclusions[j].shape.radius, pop[j].shape.radius) << j;
  }
}

}  // namespace
}  // namespace rvegen
