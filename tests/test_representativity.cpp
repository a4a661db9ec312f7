// The statistics of the representativity study (model/representativity): sample summaries with
// Student's t, the fit of the variance law, the recommended volume and realization count.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "rvegen/model/representativity.hpp"

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

}  // namespace
}  // namespace rvegen
