// Accuracy of the voxel rules (plain, Voigt, Reuss, laminate) against exact or converged values.
// Prints a tab-separated table, one row per rule:
//   inclined PHYSICS RES N1 N2 N3 CONTRAST
//     a laminate of layers of shares 0.4 (A) and 0.6 (A where frac(n . x + 0.137) < 0.4, n the
//     integer vector N, so the unit box is periodic; the offset keeps interfaces off voxel centres
//     and corners) with conductivity or stiffness contrast CONTRAST; voxel shares of the layers
//     computed exactly (volume of a cube under a plane). Columns: rule, res, relative error
//     (largest entry of the difference over the largest entry of the exact tensor), seconds.
//   cubic RES F CONTRAST
//     the simple cubic array of spheres (one sphere of volume fraction F in the unit periodic
//     box), conductivity CONTRAST in the spheres, 1 around. Columns: rule, res, k_xx, mean of
//     the diagonal, seconds, iterations of the first load case.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "rvegen/homogenize/conductivity.hpp"
#include "rvegen/homogenize/elasticity.hpp"
#include "rvegen/homogenize/medium.hpp"
#include "rvegen/raster/cut_voxels.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace {

using rvegen::Mat3;
using rvegen::Mat6;
using rvegen::Vec3;
using rvegen::VoxelRule;

const VoxelRule kRules[] = {VoxelRule::kPlain, VoxelRule::kVoigt, VoxelRule::kReuss,
                            VoxelRule::kLaminate};

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// Share of the unit cube where n . u <= t (the volume under a plane, by inclusion-exclusion
// over the corners; components of n of either sign or zero).
double under_plane(Vec3 n, double t) {
  std::vector<double> p;
  for (int a = 0; a < 3; ++a) {
    if (n[a] < 0.0) {  // u_a -> 1 - u_a
      t -= n[a];
      n[a] = -n[a];
    }
    if (n[a] > 1e-300) p.push_back(n[a]);
  }
  const int k = static_cast<int>(p.size());
  if (k == 0) return t >= 0.0 ? 1.0 : 0.0;
  double sum = 0.0, prod = 1.0, fact = 1.0;
  for (int a = 0; a < k; ++a) prod *= p[a], fact *= a + 1;
  for (int v = 0; v < (1 << k); ++v) {
    double s = t;
    int bits = 0;
    for (int a = 0; a < k; ++a) {
      if (v >> a & 1) s -= p[a], ++bits;
    }
    if (s > 0.0) sum += (bits % 2 ? -1.0 : 1.0) * std::pow(s, k);
  }
  return std::min(1.0, std::max(0.0, sum / (fact * prod)));
}

int inclined(const std::string& physics, int res, const Vec3& m, double contrast) {
  const Vec3 n = m.normalized();
  const size_t count = static_cast<size_t>(res) * res * res;
  const double h = 1.0 / res;
  std::vector<uint32_t> material(count);
  std::vector<rvegen::CompositeVoxel> cut;
  for (int k = 0; k < res; ++k) {
    for (int j = 0; j < res; ++j) {
      for (int i = 0; i < res; ++i) {
        const size_t v = (static_cast<size_t>(k) * res + j) * res + i;
        const Vec3 x0 = Vec3(i, j, k) * h;
        const double s0 = m.dot(x0) + 0.137, sc = m.dot(x0 + Vec3::Constant(0.5 * h)) + 0.137;
        material[v] = sc - std::floor(sc) < 0.4 ? 1 : 0;
        // A: s in [q, q + 0.4) for integers q; the voxel spans s0 + h m . u, u in [0, 1]^3.
        double share = 0.0;
        const double lo = s0 + h * std::min(0.0, m.minCoeff()) * 3.0 - 1.0;
        for (double q = std::floor(lo); q <= s0 + 3.0 * h * m.cwiseAbs().maxCoeff() + 1.0; ++q) {
          share += under_plane(h * m, q + 0.4 - s0) - under_plane(h * m, q - s0);
        }
        if (share > 1e-12 && share < 1.0 - 1e-12) {
          rvegen::CompositeVoxel c;
          c.voxel = v;
          c.inside = 1;
          c.outside = 0;
          c.fraction = share;
          c.normal = n;
          cut.push_back(c);
        }
      }
    }
  }
  // The shares must add up to the layers' 0.4 of the box.
  double a = 0.0;
  for (uint32_t v : material) a += v;
  for (const auto& c : cut) a += c.fraction - material[c.voxel];
  if (std::abs(a / static_cast<double>(count) - 0.4) > 1e-9) {
    std::fprintf(stderr, "layer shares add up to %.12f, not 0.4\n", a / count);
    return 1;
  }
  const std::array<int, 3> dims = {res, res, res};
  for (VoxelRule rule : kRules) {
    const auto t = std::chrono::steady_clock::now();
    double err = 0.0;
    if (physics == "conductivity") {
      const std::vector<Mat3> mats = {Mat3::Identity(), contrast * Mat3::Identity()};
      rvegen::ConductivityOptions opt;
      opt.tolerance = 1e-10;
      const auto r = rvegen::effective_conductivity(
          dims, Vec3(1, 1, 1), rvegen::compose_medium<3>(material, mats, cut, rule), opt);
      const Mat3 exact = rvegen::mix_conductivity(mats[1], mats[0], 0.4, n, VoxelRule::kLaminate);
      err = (r.tensor - exact).cwiseAbs().maxCoeff() / exact.cwiseAbs().maxCoeff();
    } else {
      const std::vector<Mat6> mats = {rvegen::isotropic_stiffness(1.0, 0.35),
                                      rvegen::isotropic_stiffness(contrast, 0.2)};
      rvegen::ElasticityOptions opt;
      opt.tolerance = 1e-10;
      const auto r = rvegen::effective_stiffness(
          dims, Vec3(1, 1, 1), rvegen::compose_medium<6>(material, mats, cut, rule), opt);
      const Mat6 exact = rvegen::mix_stiffness(mats[1], mats[0], 0.4, n, VoxelRule::kLaminate);
      err = (r.stiffness - exact).cwiseAbs().maxCoeff() / exact.cwiseAbs().maxCoeff();
    }
    std::printf("%s\t%d\t%.3e\t%.3f\n", rvegen::voxel_rule_name(rule), res, err, seconds_since(t));
    std::fflush(stdout);
  }
  return 0;
}

int cubic(int res, double f, double contrast) {
  rvegen::InclusionSet set;
  rvegen::Inclusion inc;
  inc.shape = rvegen::Shape::sphere(Vec3(0.5, 0.5, 0.5), std::cbrt(3.0 * f / (4.0 * M_PI)));
  set.inclusions = {inc};
  set.family_names = {"spheres"};
  rvegen::VoxelOptions vopt;
  vopt.partial_volume = false;
  const std::array<int, 3> dims = {res, res, res};
  for (VoxelRule rule : kRules) {
    const auto t = std::chrono::steady_clock::now();
    const rvegen::VoxelImage img = rvegen::voxelize(set, dims, vopt);
    rvegen::CutVoxels cut;
    if (rule != VoxelRule::kPlain) cut = rvegen::cut_voxels(set, img);
    std::vector<uint32_t> material(img.phase.begin(), img.phase.end());
    std::vector<rvegen::CompositeVoxel> comp;
    for (const rvegen::CutVoxel& c : cut.voxels) {
      comp.push_back(rvegen::composite_of(c));
    }
    const std::vector<Mat3> mats = {Mat3::Identity(), contrast * Mat3::Identity()};
    rvegen::ConductivityOptions opt;
    opt.tolerance = 1e-8;
    const auto r = rvegen::effective_conductivity(
        dims, Vec3(1, 1, 1), rvegen::compose_medium<3>(material, mats, comp, rule), opt);
    std::printf("%s\t%d\t%.8f\t%.8f\t%.3f\t%d\n", rvegen::voxel_rule_name(rule), res,
                r.tensor(0, 0), r.tensor.trace() / 3.0, seconds_since(t), r.iterations[0]);
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (mode == "inclined" && argc == 8) {
    return inclined(argv[2], std::atoi(argv[3]),
                    Vec3(std::atof(argv[4]), std::atof(argv[5]), std::atof(argv[6])),
                    std::atof(argv[7]));
  }
  if (mode == "cubic" && argc == 5) {
    return cubic(std::atoi(argv[2]), std::atof(argv[3]), std::atof(argv[4]));
  }
  std::fprintf(stderr,
               "usage: %s inclined conductivity|elasticity RES N1 N2 N3 CONTRAST\n"
               "       %s cubic RES F CONTRAST\n",
               argv[0], argv[0]);
  return 2;
}
