#include "rvegen/raster/cut_voxels.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "rvegen/model/body.hpp"

namespace rvegen {

namespace {

// The step of the central differences that give an interface normal, as a share of the voxel.
constexpr double kGradientStep = 1e-6;

int wrap(int i, int n) {
  i %= n;
  return i < 0 ? i + n : i;
}

// Share of the voxel with centre x and sides h in the region r, on ss^3 points.
double sampled_share(const BodyQuery& body, const Vec3& x, const Vec3& h, int ss, Region r) {
  int inside = 0;
  for (int c = 0; c < ss; ++c) {
    for (int b = 0; b < ss; ++b) {
      for (int a = 0; a < ss; ++a) {
        const Vec3 d((a + 0.5) / ss - 0.5, (b + 0.5) / ss - 0.5, (c + 0.5) / ss - 0.5);
        inside += body.region(x + d.cwiseProduct(h)) == r;
      }
    }
  }
  return static_cast<double>(inside) / (ss * ss * ss);
}

// Share of the voxel with centre x and sides h inside the core.
double core_share(const BodyQuery& body, const Vec3& x, const Vec3& h, int ss) {
  if (body.straight_core()) {
    double inside = 0.0;
    const double x0 = x[0] - 0.5 * h[0], x1 = x[0] + 0.5 * h[0];
    for (int c = 0; c < ss; ++c) {
      for (int b = 0; b < ss; ++b) {
        const Vec3 p(0.0, x[1] + ((b + 0.5) / ss - 0.5) * h[1],
                     x[2] + ((c + 0.5) / ss - 0.5) * h[2]);
        double t0, t1;
        if (!body.x_interval(p, &t0, &t1)) continue;
        inside += std::max(0.0, std::min(t1, x1) - std::max(t0, x0));
      }
    }
    return inside / (h[0] * ss * ss);
  }
  return sampled_share(body, x, h, ss, Region::kCore);
}

}  // namespace

CutVoxels cut_voxels(const InclusionSet& set, const VoxelImage& img, int subsamples) {
  const auto& incs = set.inclusions;
  const bool periodic = set.box.periodic;
  const int ss = std::max(1, subsamples);
  // Region labels per family.
  std::vector<uint8_t> shell_label(img.phases.size(), 0), void_label(img.phases.size(), 0);
  for (const auto& p : img.phases) {
    if (p.kind == PhaseKind::kInterphase) shell_label[p.family] = p.label;
    if (p.kind == PhaseKind::kVoid) void_label[p.family] = p.label;
  }
  const double half_diagonal = 0.5 * img.spacing.norm();
  const double step = 0.25 * img.spacing.minCoeff();
  std::vector<std::vector<CutVoxel>> found(incs.size());
  tbb::parallel_for(size_t(0), incs.size(), [&](size_t m) {
    const Inclusion& inc = incs[m];
    // A continuous fibre is cut over one period along its axis, as a cylinder that covers the
    // whole period (its images continue it: the same voxels met again across the box were
    // counted twice and dropped as shared, and a voxel as long as the box held only part of
    // the finite fibre).
    const int axis = through_axis(inc);
    Inclusion endless = inc;
    if (axis >= 0) endless.shape.half_axis *= 3.0;
    const BodyQuery body(axis >= 0 ? static_cast<const Inclusion&>(endless) : inc);
    // Core, shell and matrix in layers (a debonded coated inclusion, whose void lies between
    // core and shell, keeps the two-phase rule at its core).
    const bool coated =
        inc.mod.coating > 0.0 && !inc.mod.debonded() && shell_label[inc.family] != 0;
    Vec3 lo, hi;
    outer_bound(inc).aabb(&lo, &hi);
    int flo[3], fhi[3];
    for (int a = 0; a < 3; ++a) {
      flo[a] = static_cast<int>(std::floor((lo[a] - img.origin[a]) / img.spacing[a]));
      fhi[a] = static_cast<int>(std::ceil((hi[a] - img.origin[a]) / img.spacing[a])) - 1;
      if (a == axis) {  // one period
        flo[a] = 0;
        fhi[a] = img.dims[a] - 1;
      } else if (!periodic) {
        flo[a] = std::max(flo[a], 0);
        fhi[a] = std::min(fhi[a], img.dims[a] - 1);
      }
    }
    for (int k = flo[2]; k <= fhi[2]; ++k) {
      const int kk = periodic ? wrap(k, img.dims[2]) : k;
      if (kk < img.extent[4] || kk >= img.extent[5]) continue;
      for (int j = flo[1]; j <= fhi[1]; ++j) {
        const int jj = periodic ? wrap(j, img.dims[1]) : j;
        if (jj < img.extent[2] || jj >= img.extent[3]) continue;
        for (int i = flo[0]; i <= fhi[0]; ++i) {
          const int ii = periodic ? wrap(i, img.dims[0]) : i;
          if (ii < img.extent[0] || ii >= img.extent[1]) continue;
          const Vec3 x = img.origin + Vec3(i + 0.5, j + 0.5, k + 0.5).cwiseProduct(img.spacing);
          if (body.clearance(x) >= half_diagonal) continue;  // one region holds the voxel
          const double share = core_share(body, x, img.spacing, ss);
          // A coated inclusion's shell: its share, never more than the core leaves.
          const double shell =
              coated
                  ? std::min(1.0 - share, sampled_share(body, x, img.spacing, ss, Region::kShell))
                  : 0.0;
          if (!(share < 1.0 && shell < 1.0 && share + shell > 0.0)) continue;  // one layer
          if (!coated && !(share > 0.0)) continue;
          CutVoxel v;
          v.voxel = img.index(ii, jj, kk);
          v.inclusion = static_cast<int>(m);
          v.inside = static_cast<uint8_t>(inc.family + 1);
          v.fraction = share;
          if (coated) {
            v.middle = shell_label[inc.family];
            v.middle_fraction = shell;
          }
          // The distance's gradient by central differences.
          const double e = kGradientStep * img.spacing.maxCoeff();
          Vec3 g;
          for (int a = 0; a < 3; ++a) {
            const Vec3 d = e * Vec3::Unit(a);
            g[a] = body.core_distance(x + d) - body.core_distance(x - d);
          }
          if (g.norm() > 0.0 && g.allFinite()) v.normal = g.normalized();
          // The phase just beyond the core's surface point nearest the centre (beyond the
          // shell for a coated inclusion: the matrix).
          const Vec3 beyond = x - body.core_distance(x) * v.normal + step * v.normal;
          const Region r = coated ? Region::kOutside : body.region(beyond);
          v.outside = r == Region::kShell  ? shell_label[inc.family]
                      : r == Region::kVoid ? void_label[inc.family]
                                           : uint8_t{0};
          found[m].push_back(v);
        }
      }
    }
  });
  CutVoxels out;
  for (auto& f : found) out.voxels.insert(out.voxels.end(), f.begin(), f.end());
  std::stable_sort(out.voxels.begin(), out.voxels.end(),
                   [](const CutVoxel& a, const CutVoxel& b) { return a.voxel < b.voxel; });
  // Drop every voxel listed more than once.
  std::vector<CutVoxel> single;
  single.reserve(out.voxels.size());
  for (size_t a = 0; a < out.voxels.size();) {
    size_t b = a + 1;
    while (b < out.voxels.size() && out.voxels[b].voxel == out.voxels[a].voxel) ++b;
    if (b == a + 1) {
      single.push_back(out.voxels[a]);
    } else {
      ++out.shared;
    }
    a = b;
  }
  out.voxels = std::move(single);
  return out;
}

}  // namespace rvegen
