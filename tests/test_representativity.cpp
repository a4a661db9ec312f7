// The statistics of the representativity study (model/representativity): sample summaries with
// Student's t, the fit of the variance law, the recommended volume and realization count, and
// the window method's integral range against the closed form of dilute spheres.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "rvegen/io/scene_json.hpp"
#include "rvegen/model/representativity.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen {
namespace {

TEST(Representativity, SummaryHasTheStudentInterval) {
  const SampleSummary s = summarize({1, 2, 3, 4, 5});
  EXPECT_EQ(s.n, 5u);
  EXPECT_DOUBLE_EQ(s.mean, 3.0);
  EXPECT_NEAR(s.sd, std::sqrt(2.5), 1e-14);
  // t(0.975, 4) = 2.776445 (tables).
  EXPECT_NEAR(s.ci_high - s.mean, 2.776445 * std::sqrt(2.5) / std::sqrt(5.0), 1e-5);
  EXPECT_NEAR(s.mean - s.ci_low, s.ci_high - s.mean, 1e-14);
  const SampleSummary one = summarize({7.0});
  EXPECT_EQ(one.sd, 0.0);
  EXPECT_EQ(one.ci_low, 7.0);
}

TEST(Representativity, StudentQuantilesMatchTables) {
  // Published two-sided 95 % values, including beyond the built-in table.
  const std::vector<std::pair<int, double>> known = {{1, 12.7062},  {2, 4.3027},   {9, 2.2622},
                                                     {30, 2.0423},  {40, 2.0211},  {60, 2.0003},
                                                     {120, 1.9799}, {1000, 1.9623}};
  for (const auto& [dof, t] : known) EXPECT_NEAR(student_t975(dof), t, 2e-4) << dof;
}

TEST(Representativity, FitRecoversAPowerLawAndItsIntegralRange) {
  // D^2(V) = D2 (A3 / V)^alpha with a point variance D2 = phi (1 - phi).
  const double phi = 0.3, d2 = phi * (1 - phi), a3 = 0.02, alpha = 0.8;
  std::vector<double> vols = {0.1, 0.3, 1.0, 3.0};
  std::vector<SampleSummary> s(vols.size());
  for (size_t i = 0; i < vols.size(); ++i) {
    s[i].n = 10;
    s[i].mean = phi;
    s[i].sd = std::sqrt(d2 * std::pow(a3 / vols[i], alpha));
  }
  const VarianceLaw law = fit_variance_law(vols, s, phi);
  ASSERT_TRUE(law.fitted);
  EXPECT_FALSE(law.exact);
  EXPECT_EQ(law.points, 4);
  EXPECT_NEAR(law.alpha, alpha, 1e-12);
  EXPECT_NEAR(law.integral_range(d2), a3, 1e-12);
  // At the recommended volume, n realizations give the target error, no more, no less.
  const double eps = 0.005;
  const int n = 10;
  const double v = recommended_volume(law, phi, eps, n);
  EXPECT_NEAR(2.0 * std::sqrt(law.variance_at(v)) / (phi * std::sqrt(double(n))), eps, 1e-12);
  // Realizations needed at one volume: the least n with 2 D / (Z sqrt n) <= eps.
  const double var = law.variance_at(1.0);
  const long long need = realizations_needed(var, phi, eps);
  EXPECT_LE(2.0 * std::sqrt(var / need) / phi, eps * (1 + 1e-12));
  EXPECT_GT(2.0 * std::sqrt(var / (need - 1)) / phi, eps);
}

TEST(Representativity, APropertyThatDoesNotVaryIsExactAtEverySize) {
  std::vector<SampleSummary> s(2);
  for (auto& x : s) {
    x.n = 5;
    x.mean = 0.25;
    x.sd = 0.0;
  }
  const VarianceLaw law = fit_variance_law({1.0, 8.0}, s, 0.25);
  EXPECT_TRUE(law.exact);
  EXPECT_EQ(recommended_volume(law, 0.25, 0.01, 5), 0.0);
  EXPECT_EQ(realizations_needed(0.0, 0.25, 0.01), 1);
  // One realization per size says nothing of the variance: neither exact nor fitted.
  for (auto& x : s) x.n = 1;
  const VarianceLaw none = fit_variance_law({1.0, 8.0}, s, 0.25);
  EXPECT_FALSE(none.exact);
  EXPECT_FALSE(none.fitted);
}

TEST(Representativity, GrowingVarianceRecommendsNoVolume) {
  std::vector<SampleSummary> s(2);
  s[0] = {5, 1.0, 0.01, 0, 0};
  s[1] = {5, 1.0, 0.02, 0, 0};  // variance grows with the volume: no decay measured
  const VarianceLaw law = fit_variance_law({1.0, 8.0}, s, 1.0);
  EXPECT_TRUE(law.fitted);
  EXPECT_LT(law.alpha, 0.0);
  EXPECT_TRUE(std::isinf(recommended_volume(law, 1.0, 0.01, 5)));
}

TEST(Windows, VarianceOfKnownWindowMeans) {
  // A 4 x 4 x 4 image whose 2 x 2 x 2 windows hold 0 or 1 (a checkerboard of windows): the
  // window means are 0 and 1, four of each, mean 1/2, variance 8 * 1/4 / 7. Its 4 x 4 x 4
  // windows of one voxel are the same values: 64 * 1/4 / 63.
  std::vector<float> f(64);
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 4; ++x) f[(z * 4 + y) * 4 + x] = float((x / 2 + y / 2 + z / 2) % 2);
  const auto w = window_variances(f, {4, 4, 4}, 0.5, {2, 4});
  ASSERT_EQ(w.size(), 2u);
  EXPECT_EQ(w[0].windows, 8u);
  EXPECT_DOUBLE_EQ(w[0].volume, 4.0);
  EXPECT_NEAR(w[0].variance, 2.0 / 7.0, 1e-15);
  EXPECT_DOUBLE_EQ(w[0].mean, 0.5);
  EXPECT_EQ(w[1].windows, 64u);
  EXPECT_NEAR(w[1].variance, 16.0 / 63.0, 1e-15);
  EXPECT_THROW(window_variances(f, {4, 4, 4}, 1.0, {3}), std::invalid_argument);
  EXPECT_THROW(window_variances(f, {4, 4, 4}, 1.0, {1}), std::invalid_argument);
  // The fit recovers A3 and b from exact V D^2 = phi (1 - phi) (A3 - b / L).
  const double phi = 0.2, a3 = 0.01, b = 0.05;
  std::vector<WindowVariance> exact;
  for (int k : {2, 3, 5}) {
    WindowVariance v;
    v.k = k;
    v.volume = std::pow(1.0 / k, 3);
    v.windows = size_t(k) * k * k;
    v.variance = phi * (1 - phi) * (a3 - b * k) / v.volume;
    exact.push_back(v);
  }
  const WindowIntegralRange r = window_integral_range(exact, phi);
  ASSERT_TRUE(r.fitted);
  EXPECT_NEAR(r.integral_range, a3, 1e-15);
  EXPECT_NEAR(r.surface_term, b, 1e-13);
}

// The window method's check: dilute random spheres, whose integral range is known
// in closed form. A point variable of Poisson centres gives the variance phi V_s / V of the
// volume fraction in a large window (Campbell's theorem), so A3 = V_s / (1 - phi); spheres that
// may not overlap lower it by the structure factor at zero wave number, S(0) = (1 - phi)^4 /
// (1 + 2 phi)^2 (Percus-Yevick, exact to second order in phi, where random sequential and
// equilibrium hard spheres agree to first). At phi = 0.02, S(0) = 0.85; over six sets of 12
// realizations the fitted A3 was 0.97-1.07 of this.
TEST(Windows, IntegralRangeOfDiluteSpheresMatchesTheClosedForm) {
  const double phi = 0.02, radius = 0.01;
  const int n = 120;  // voxel edge 0.83 of the radius; windows of edge 50 down to 12.5 radii
  const std::vector<int> ks = {2, 3, 4, 5, 6, 8};
  std::vector<std::vector<WindowVariance>> per;
  double mean_phi = 0.0;
  const int realizations = 12;
  for (int seed = 1; seed <= realizations; ++seed) {
    const Scene s =
        parse_scene(R"({"box":{"size":[1,1,1]},"method":"rsa","seed":)" + std::to_string(seed) +
                    R"(,"families":[{"shape":"sphere","radius":0.01,"volume_fraction":0.02}]})");
    const PackingResult r = generate(s);
    ASSERT_EQ(r.status, PackingStatus::kOk);
    VoxelOptions o;
    o.partial_volume = true;
    o.subsamples = 4;
    const VoxelImage img = voxelize(r.set, {n, n, n}, o);
    double sum = 0.0;
    for (float v : img.fraction) sum += v;
    mean_phi += sum / img.fraction.size() / realizations;
    per.push_back(window_variances(img.fraction, {n, n, n}, std::pow(1.0 / n, 3), ks));
  }
  const std::vector<WindowVariance> pooled = pool_window_variances(per);
  const WindowIntegralRange r = window_integral_range(pooled, mean_phi);
  ASSERT_TRUE(r.fitted);
  const double vs = 4.0 / 3.0 * M_PI * std::pow(radius, 3);
  const double s0 = std::pow(1 - phi, 4) / std::pow(1 + 2 * phi, 2);
  const double a3 = vs * s0 / (1 - phi);
  EXPECT_NEAR(r.integral_range / a3, 1.0, 0.10) << "fitted " << r.integral_range << ", closed form "
                                                << a3 << " (surface term " << r.surface_term << ")";
  // Without the surface term (the plain law D^2 = phi (1 - phi) A3 / V at the smallest
  // windows) the estimate is low: the windows' faces cut spheres.
  const WindowVariance& small = pooled.back();
  EXPECT_LT(small.volume * small.variance / (mean_phi * (1 - mean_phi)), r.integral_range);
}

}  // namespace
}  // namespace rvegen
