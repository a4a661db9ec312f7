// Deformed particles packed by their own shape: the certified peak of the deformation field, the
// certified support table, and packings and audits that rest on them.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/report.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/deformed_support.hpp"
#include "rvegen/model/stats.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/md_bodies.hpp"
#include "rvegen/packing/packing.hpp"

namespace rvegen {
namespace {

Modifiers drawn(double amplitude, double smoothness, uint64_t seed) {
  FamilyModifiers f;
  f.deform_amplitude = amplitude;
  f.smoothness = smoothness;
  Random rng(seed);
  return f.draw(rng);
}

std::vector<Vec3> random_directions(int n, uint64_t seed) {
  Random rng(seed);
  std::vector<Vec3> out(n);
  for (auto& u : out) u = rng.unit_vector();
  return out;
}

// A lower bound of the maximum of f over the unit sphere by dense sampling refined by local
// ascent (the true maximum lies between it and a certified bound).
template <class F>
double sampled_max(F f, const std::vector<Vec3>& dirs) {
  double best = -1e300;
  Vec3 arg = Vec3::UnitZ();
  for (const Vec3& d : dirs) {
    const double v = f(d);
    if (v > best) best = v, arg = d;
  }
  for (double step = 0.02; step > 1e-7; step *= 0.5) {
    for (bool moved = true; moved;) {
      moved = false;
      const Vec3 e1 = any_orthogonal(arg), e2 = arg.cross(e1);
      for (const Vec3 t : {e1, Vec3(-e1), e2, Vec3(-e2)}) {
        const Vec3 d = (arg + step * t).normalized();
        const double v = f(d);
        if (v > best) best = v, arg = d, moved = true;
      }
    }
  }
  return best;
}

double sampled_peak(const Modifiers& m, const std::vector<Vec3>& dirs) {
  return sampled_max([&](const Vec3& n) { return deformation_field(m, n); }, dirs);
}

// h(u) of the true surface, from below.
double sampled_support(const Modifiers& m, const std::vector<Vec3>& dirs, const Vec3& u) {
  return sampled_max([&](const Vec3& n) { return deformed_radius(m, n) * n.dot(u); }, dirs);
}

TEST(DeformedSupport, PeakIsCertifiedAndTight) {
  const std::vector<Vec3> dirs = random_directions(100000, 1);
  for (double smoothness : {0.5, 1.0, 2.0}) {
    for (double amplitude : {0.1, 0.2, 0.5}) {
      for (uint64_t seed = 1; seed <= 4; ++seed) {
        const Modifiers m = drawn(amplitude, smoothness, seed);
        const double peak = deformation_peak(m), sampled = sampled_peak(m, dirs);
        EXPECT_GE(peak, sampled) << smoothness << " " << amplitude << " " << seed;
        EXPECT_LE(peak, 1.0);
        // Tight: the search stops within 0.001 of the radius, 0.001 / amplitude in g.
        EXPECT_LE(peak, sampled + 0.0011 / amplitude) << smoothness << " " << amplitude;
        EXPECT_EQ(m.deform_peak, peak);  // set where the waves are drawn
      }
    }
  }
  // Rough deformations too.
  const Modifiers rough = drawn(0.2, 0.1, 3);
  EXPECT_GE(deformation_peak(rough), sampled_peak(rough, dirs));
  EXPECT_LE(deformation_peak(rough), sampled_peak(rough, dirs) + 0.0011 / 0.2);
}

TEST(DeformedSupport, TableIsATightUpperBound) {
  const std::vector<Vec3> dirs = random_directions(10000, 2);
  const std::vector<Vec3> probes = random_directions(150, 3);
  for (double smoothness : {0.6, 1.0, 3.0}) {
    for (double amplitude : {0.2, 0.4}) {
      const Modifiers m = drawn(amplitude, smoothness, 7);
      const auto table = DeformedSupport::make(m);
      if (!table) {
        ADD_FAILURE() << "no table for " << smoothness << " " << amplitude;
        continue;
      }
      // The certified ball (the envelope's radius at unit core radius).
      const double ball = m.deform_scale * (1.0 + amplitude * m.deform_peak);
      double worst_excess = 0.0;
      for (const Vec3& u : probes) {
        const double h = sampled_support(m, dirs, u), t = (*table)(u);
        EXPECT_GE(t, h) << smoothness << " " << amplitude << " " << u.transpose();
        worst_excess = std::max(worst_excess, t - h);
        EXPECT_NEAR((*table)(2.5 * u), 2.5 * t, 1e-12);  // positively homogeneous
        EXPECT_LE(h, ball);
      }
      // Tight: about 0.7 % of the radius for smooth deformations, more for rough ones.
      EXPECT_LE(worst_excess, 0.005 + 0.05 * amplitude / smoothness)
          << smoothness << " " << amplitude;
      // A table is a tighter bound than the ball along most directions.
      EXPECT_LT((*table)(Vec3::UnitX()), ball + 1e-9);
    }
  }
  // Too rough for a table: the ball of the certified peak is used.
  EXPECT_FALSE(DeformedSupport::make(drawn(0.2, 0.1, 3)));
}

Inclusion deformed_sphere(const Vec3& c, double r, uint64_t seed) {
  Inclusion inc;
  inc.shape = Shape::sphere(c, r);
  inc.mod = drawn(0.2, 1.0, seed);
  return inc;
}

// The audit of deformed spheres: the true surfaces of two placed so that their radial
// functions along the line of centres overlap are refused; placed one table sum apart, they pass.
TEST(DeformedSupport, AuditRefusesTrueOverlapAndPassesCertifiedSeparation) {
  InclusionSet set;
  set.box.size = Vec3(10, 10, 10);
  set.box.periodic = true;
  const Vec3 u = Vec3(1, 2, 2).normalized();
  const Inclusion a = deformed_sphere(Vec3(5, 5, 5), 1.0, 11);
  Inclusion b = deformed_sphere(Vec3(5, 5, 5), 1.2, 12);
  const double ra = deformed_radius(a.mod, u), rb = 1.2 * deformed_radius(b.mod, -u);
  b.shape.center = a.shape.center + (ra + rb - 0.01) * u;  // surface points overlap on the line
  set.inclusions = {a, b};
  const auto bad = find_overlaps(set);
  ASSERT_EQ(bad.size(), 1u);
  EXPECT_EQ(bad[0].contact.type, ContactType::kSupport);
  const auto ta = DeformedSupport::make(a.mod), tb = DeformedSupport::make(b.mod);
  const double sum = (*ta)(u) + 1.2 * (*tb)(-u);
  set.inclusions[1].shape.center = a.shape.center + sum * (1.0 + 1e-12) * u;
  EXPECT_TRUE(find_overlaps(set).empty());
  // Still much closer than the balls |g| <= 1 would allow.
  EXPECT_LT(sum, 0.95 * (a.mod.deform_scale + 1.2 * b.mod.deform_scale) * 1.2);
}

// Packed by their support functions, deformed spheres reach densities their balls cannot, and
// no surface point of one lies inside another (tested with the inside test of the true shape).
TEST(DeformedSupport, PackingReachesHalfAndTrueSurfacesDoNotOverlap) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":4,"families":[
      {"shape":"sphere","radius":0.09,"volume_fraction":0.5,
       "deformation":{"amplitude":0.2,"smoothness":1}}]})");
  const PackingResult r = generate(s);
  ASSERT_EQ(r.status, PackingStatus::kOk);
  const auto vf = family_volume_fractions(r.set, 1);
  EXPECT_NEAR(vf[0], 0.5, 4.0 / 3.0 * M_PI * std::pow(0.09, 3));  // the nearest whole count
  // The balls of the old bound lambda (1 + e) would fill more than any sphere packing allows.
  double balls = 0.0;
  for (const auto& inc : r.set.inclusions) {
    balls += 4.0 / 3.0 * M_PI * std::pow(inc.shape.radius * inc.mod.deform_scale * 1.2, 3);
  }
  EXPECT_GT(balls, 0.7405);
  const std::vector<Vec3> dirs = random_directions(4000, 5);
  const auto& inc = r.set.inclusions;
  int close = 0;
  for (size_t i = 0; i < inc.size(); ++i) {
    for (size_t j = 0; j < inc.size(); ++j) {
      if (i == j) continue;
      // The nearest periodic image of j.
      Vec3 d = inc[j].shape.center - inc[i].shape.center;
      for (int k = 0; k < 3; ++k) d[k] -= std::round(d[k]);
      if (d.norm() > 1.25 * (inc[i].shape.radius + inc[j].shape.radius)) continue;
      ++close;
      Inclusion other = inc[j];
      other.shape.center = inc[i].shape.center + d;
      const BodyQuery q(other);
      for (const Vec3& n : dirs) {
        const Vec3 x =
            inc[i].shape.center + inc[i].shape.radius * deformed_radius(inc[i].mod, n) * n;
        ASSERT_EQ(q.region(x), Region::kOutside) << i << " " << j;
      }
    }
  }
  EXPECT_GT(close, static_cast<int>(inc.size()));  // neighbours were tested
  // Written and read back, the result passes the same audit (check runs it).
  const InclusionSet back = read_inclusions_json(write_inclusions_json(r.set));
  EXPECT_TRUE(find_overlaps(back).empty());
}

// The packer's bodies and the audit bound a deformed sphere by the same support values (the
// smaller of the table's and the ball's): were the packer's larger or smaller anywhere, packed
// pairs could fail the audit or be looser than it allows.
TEST(DeformedSupport, PackerBodiesAndAuditAgree) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":6,"families":[
      {"shape":"sphere","radius":0.05,"volume_fraction":0.1,
       "deformation":{"amplitude":0.2,"smoothness":1}}]})");
  Random rng(s.seed);
  const std::vector<Inclusion> pop = draw_population(s, rng);
  const md::Bodies bodies = md::make_bodies(s, pop, rng);
  const std::vector<Vec3> probes = random_directions(2000, 9);
  int below_ball = 0, at_ball = 0;
  for (size_t i = 0; i < 20; ++i) {
    const md::Body& b = bodies.all[i];
    ASSERT_TRUE(b.support);
    const auto table = support_table(pop[i]);
    for (const Vec3& u : probes) {
      const double audit = envelope_support(pop[i], *table, u);
      EXPECT_DOUBLE_EQ(b.support_along(u), audit);
      EXPECT_LE(audit, envelope(pop[i]).radius);
      (audit < envelope(pop[i]).radius ? below_ball : at_ball)++;
    }
  }
  EXPECT_GT(below_ball, 10 * at_ball);  // the table is what keeps them apart, mostly
  EXPECT_GT(at_ball, 0);                // and the ball caps it near the peak
}

// Above jamming: the packer stops jammed with its best valid configuration, which passes the
// audit (the packer and the audit bound each pair by the same certified support values) and is
// far denser than the balls |g| <= 1 would let through.
TEST(DeformedSupport, AboveJammingStopsJammedWithTheAuditPassed) {
  const Scene s = parse_scene(R"({"box":{"size":[1,1,1]},"seed":6,"families":[
      {"shape":"sphere","radius":0.08,"volume_fraction":0.7,
       "deformation":{"amplitude":0.2,"smoothness":1}}]})");
  PackingResult r;
  ASSERT_NO_THROW(r = generate(s));  // generate throws when the audit fails
  EXPECT_EQ(r.status, PackingStatus::kTargetNotReached);
  EXPECT_EQ(r.stop_reason, StopReason::kJammed);
  const double vf = family_volume_fractions(r.set, 1)[0];
  EXPECT_GT(vf, 0.55);
  EXPECT_LT(vf, 0.7);
  EXPECT_TRUE(find_overlaps(read_inclusions_json(write_inclusions_json(r.set))).empty());
}

}  // namespace
}  // namespace rvegen
