// Quadrature rules: Gauss-Legendre on [-1, 1], and integrals over the unit sphere.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "rvegen/geometry/shapes.hpp"

namespace rvegen {

/// Nodes and weights of the n-point Gauss-Legendre rule on [-1, 1].
void gauss_legendre(int n, std::vector<double>* x, std::vector<double>* w);

// Integral over the unit sphere of f(n), by Gauss-Legendre in cos(theta) and the trapezoid
// rule in phi (spectrally accurate for smooth f).
/// (f: Vec3 -> double.)
template <class F>
double sphere_integral(int n_theta, F f) {
  std::vector<double> x, w;
  gauss_legendre(n_theta, &x, &w);
  const int n_phi = 2 * n_theta;
  double sum = 0.0;
  for (int i = 0; i < n_theta; ++i) {
    const double st = std::sqrt(std::max(0.0, 1.0 - x[i] * x[i]));
    for (int j = 0; j < n_phi; ++j) {
      const double ph = 2.0 * M_PI * (j + 0.5) / n_phi;
      sum += w[i] * f(Vec3(st * std::cos(ph), st * std::sin(ph), x[i]));
    }
  }
  return sum * 2.0 * M_PI / n_phi;
}

}  // namespace rvegen
