// Statistics of an RVE's geometry: what report.json gives beyond volume fractions.
#pragma once

#include <vector>

#include "rvegen/model/inclusion_set.hpp"

namespace rvegen {

/// Second-order orientation tensor <u u^T> of the axes the orientation laws govern (law_axis:
/// cylinder axis, ellipsoid first semi-axis) over the inclusions of `family` that have one
/// (trace 1; I/3 for isotropic, e e^T for aligned along e). Zero when there are none.
Mat3 orientation_tensor(const InclusionSet& set, int family);

struct Summary {
  int n = 0;
  double mean = 0.0, std = 0.0, min = 0.0, max = 0.0;
};

/// Centre-to-centre distance from each inclusion to its nearest neighbour (periodic images
/// included), summarised. n = 0 when there are fewer than two inclusions (or images).
Summary nearest_neighbour_distances(const InclusionSet& set);

struct RadialDistribution {
  std::vector<double> r;  // bin centres
  std::vector<double> g;
};

/// Radial distribution function g(r) of the centres of `family` (pairs within the family,
/// minimum-image distances) on `bins` bins over (0, r_max]; r_max is capped at half the
/// smallest periodic box size. g -> 1 for an uncorrelated (ideal gas) arrangement. Above 2,000
/// centres, an evenly spread subset of 2,000 serves as references (each with all neighbours).
RadialDistribution radial_distribution(const InclusionSet& set, int family, int bins, double r_max);

}  // namespace rvegen
