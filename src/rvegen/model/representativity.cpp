#include "rvegen/model/representativity.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rvegen {

namespace {
// Variances below this share of the squared mean are rounding: the property does not vary.
constexpr double kExactVariance = 1e-24;
}  // namespace

double student_t975(int dof) {
  // Exact table to 30 degrees of freedom, then the Cornish-Fisher expansion about the normal
  // quantile (error below 1e-5 from 30 on).
  static const double table[] = {
      12.7062, 4.30265, 3.18245, 2.77645, 2.57058, 2.44691, 2.36462, 2.30600, 2.26216, 2.22814,
      2.20099, 2.17881, 2.16037, 2.14479, 2.13145, 2.11991, 2.10982, 2.10092, 2.09302, 2.08596,
      2.07961, 2.07387, 2.06866, 2.06390, 2.05954, 2.05553, 2.05183, 2.04841, 2.04523, 2.04227};
  if (dof < 1) return std::numeric_limits<double>::infinity();
  if (dof <= 30) return table[dof - 1];
  const double z = 1.959963984540054, z2 = z * z, n = dof;
  return z + (z2 + 1.0) * z / (4.0 * n) + ((5.0 * z2 + 16.0) * z2 + 3.0) * z / (96.0 * n * n);
}

SampleSummary summarize(const std::vector<double>& values) {
  SampleSummary s;
  s.n = values.size();
  if (s.n == 0) return s;
  double sum = 0.0;
  for (double v : values) sum += v;
  s.mean = sum / static_cast<double>(s.n);
  double ss = 0.0;
  for (double v : values) ss += (v - s.mean) * (v - s.mean);
  s.sd = s.n > 1 ? std::sqrt(ss / static_cast<double>(s.n - 1)) : 0.0;
  const double half =
      s.n > 1 ? student_t975(static_cast<int>(s.n) - 1) * s.sd / std::sqrt(double(s.n)) : 0.0;
  s.ci_low = s.mean - half;
  s.ci_high = s.mean + half;
  return s;
}

double VarianceLaw::variance_at(double volume) const {
  return exact ? 0.0 : K * std::pow(volume, -alpha);
}

double VarianceLaw::integral_range(double point_variance) const {
  if (exact || !(point_variance > 0.0) || !(K > 0.0)) return 0.0;
  return std::pow(K / point_variance, 1.0 / alpha);
}

VarianceLaw fit_variance_law(const std::vector<double>& volumes,
                             const std::vector<SampleSummary>& samples, double mean_scale) {
  VarianceLaw law;
  std::vector<double> x, y;
  bool any = false;
  const double floor = kExactVariance * mean_scale * mean_scale;
  for (size_t i = 0; i < volumes.size() && i < samples.size(); ++i) {
    if (samples[i].n < 2) continue;
    any = true;
    const double d2 = samples[i].sd * samples[i].sd;
    if (!(d2 > floor)) continue;
    x.push_back(std::log(volumes[i]));
    y.push_back(std::log(d2));
  }
  if (!any) return law;
  law.points = static_cast<int>(x.size());
  if (x.empty()) {
    law.exact = true;
    return law;
  }
  const double n = static_cast<double>(x.size());
  double mx = 0.0, my = 0.0;
  for (size_t i = 0; i < x.size(); ++i) {
    mx += x[i] / n;
    my += y[i] / n;
  }
  double sxx = 0.0, sxy = 0.0;
  for (size_t i = 0; i < x.size(); ++i) {
    sxx += (x[i] - mx) * (x[i] - mx);
    sxy += (x[i] - mx) * (y[i] - my);
  }
  if (x.size() >= 2 && sxx > 0.0) {
    law.alpha = -sxy / sxx;
    law.fitted = true;
  } else {
    law.alpha = 1.0;
  }
  law.K = std::exp(my + law.alpha * mx);
  return law;
}

double recommended_volume(const VarianceLaw& law, double mean, double rel_error, int n) {
  if (law.exact) return 0.0;
  if (!(law.alpha > 0.0) || !(law.K > 0.0) || !(rel_error > 0.0) || n < 1 || mean == 0.0) {
    return std::numeric_limits<double>::infinity();
  }
  // 2 sqrt(K V^-alpha) / (|mean| sqrt n) = rel_error.
  const double d2 = std::pow(rel_error * std::abs(mean), 2) * n / 4.0;
  return std::pow(law.K / d2, 1.0 / law.alpha);
}

long long realizations_needed(double variance, double mean, double rel_error) {
  if (!(variance > 0.0)) return 1;
  if (mean == 0.0 || !(rel_error > 0.0)) return std::numeric_limits<long long>::max();
  const double n = 4.0 * variance / std::pow(rel_error * mean, 2);
  return std::max<long long>(1, static_cast<long long>(std::ceil(n)));
}

std::vector<WindowVariance> window_variances(const std::vector<float>& field,
                                             const std::array<int, 3>& dims, double voxel_volume,
                                             const std::vector<int>& ks) {
  const size_t n = static_cast<size_t>(dims[0]) * dims[1] * dims[2];
  if (dims[0] < 1 || dims[1] < 1 || dims[2] < 1 || field.size() != n) {
    throw std::invalid_argument("window_variances: the field does not have dims' size");
  }
  double total = 0.0;
  for (float v : field) total += v;
  const double mean = total / static_cast<double>(n);
  std::vector<WindowVariance> out;
  for (int k : ks) {
    if (k < 2 || dims[0] % k || dims[1] % k || dims[2] % k) {
      throw std::invalid_argument("window_variances: k = " + std::to_string(k) +
                                  " must be at least 2 and divide every dimension");
    }
    const int w[3] = {dims[0] / k, dims[1] / k, dims[2] / k};
    std::vector<double> sums(static_cast<size_t>(k) * k * k, 0.0);
    for (int z = 0; z < dims[2]; ++z) {
      for (int y = 0; y < dims[1]; ++y) {
        const float* row = field.data() + (static_cast<size_t>(z) * dims[1] + y) * dims[0];
        const size_t base = (static_cast<size_t>(z / w[2]) * k + y / w[1]) * k;
        for (int x = 0; x < dims[0]; ++x) sums[base + x / w[0]] += row[x];
      }
    }
    const double per = static_cast<double>(w[0]) * w[1] * w[2];
    double ss = 0.0;
    for (double s : sums) ss += (s / per - mean) * (s / per - mean);
    WindowVariance v;
    v.k = k;
    v.volume = per * voxel_volume;
    v.windows = sums.size();
    v.variance = ss / static_cast<double>(sums.size() - 1);
    v.mean = mean;
    out.push_back(v);
  }
  return out;
}

std::vector<WindowVariance> pool_window_variances(
    const std::vector<std::vector<WindowVariance>>& realizations) {
  std::vector<WindowVariance> out;
  if (realizations.empty()) return out;
  out = realizations.front();
  for (WindowVariance& w : out) {
    w.variance = 0.0;
    w.mean = 0.0;
    w.windows = 0;
  }
  for (const auto& r : realizations) {
    if (r.size() != out.size()) throw std::invalid_argument("pool_window_variances: ks differ");
    for (size_t i = 0; i < r.size(); ++i) {
      if (r[i].k != out[i].k) throw std::invalid_argument("pool_window_variances: ks differ");
      out[i].variance += r[i].variance / static_cast<double>(realizations.size());
      out[i].mean += r[i].mean / static_cast<double>(realizations.size());
      out[i].windows += r[i].windows;
    }
  }
  return out;
}

WindowIntegralRange window_integral_range(const std::vector<WindowVariance>& windows, double phi) {
  WindowIntegralRange r;
  if (!(phi > 0.0 && phi < 1.0)) return r;
  // Weighted least squares of y = V D^2 / (phi (1 - phi)) against x = 1 / L.
  double sw = 0.0, sx = 0.0, sy = 0.0, sxx = 0.0, sxy = 0.0;
  for (const WindowVariance& w : windows) {
    if (!(w.volume > 0.0) || w.windows < 2) continue;
    const double x = 1.0 / std::cbrt(w.volume);
    const double y = w.volume * w.variance / (phi * (1.0 - phi));
    const double wt = static_cast<double>(w.windows);
    sw += wt;
    sx += wt * x;
    sy += wt * y;
    sxx += wt * x * x;
    sxy += wt * x * y;
    ++r.sizes;
  }
  const double det = sw * sxx - sx * sx;
  if (r.sizes < 2 || !(det > 0.0)) return r;
  const double slope = (sw * sxy - sx * sy) / det;
  r.integral_range = (sy - slope * sx) / sw;
  r.surface_term = -slope;
  r.fitted = true;
  return r;
}

}  // namespace rvegen
