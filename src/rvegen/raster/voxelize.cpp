#include "rvegen/raster/voxelize.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "rvegen/model/body.hpp"

namespace rvegen {
namespace {

int wrap(int i, int n) {
  i %= n;
  return i < 0 ? i + n : i;
}

// Where in the image an inclusion may leave a mark: unwrapped voxel index ranges [lo, hi].
struct Footprint {
  int lo[3], hi[3];
};

// Each inclusion's footprint on the grid (the voxels that meet its outer bound with partial
// volumes, else those whose centre lies in it), and for each z plane of the image's extent the
// (inclusion, unwrapped k) that reach it.
std::vector<Footprint> footprints(const InclusionSet& set, const VoxelImage& img, bool partial,
                                  std::vector<std::vector<std::pair<int, int>>>* planes) {
  const auto& incs = set.inclusions;
  const bool periodic = set.box.periodic;
  const std::array<int, 3>& dims = img.dims;
  std::vector<Footprint> fp(incs.size());
  planes->assign(img.size(2), {});
  for (size_t m = 0; m < incs.size(); ++m) {
    Vec3 lo, hi;
    outer_bound(incs[m]).aabb(&lo, &hi);
    Footprint& f = fp[m];
    for (int a = 0; a < 3; ++a) {
      const double h = img.spacing[a];
      if (partial) {
        // Every voxel [i h, (i + 1) h] that meets [lo, hi].
        f.lo[a] = static_cast<int>(std::floor((lo[a] - img.origin[a]) / h));
        f.hi[a] = static_cast<int>(std::ceil((hi[a] - img.origin[a]) / h)) - 1;
      } else {
        // Every voxel whose centre lies in [lo, hi].
        f.lo[a] = static_cast<int>(std::ceil((lo[a] - img.origin[a]) / h - 0.5));
        f.hi[a] = static_cast<int>(std::floor((hi[a] - img.origin[a]) / h - 0.5));
      }
      if (!periodic) {
        f.lo[a] = std::max(f.lo[a], 0);
        f.hi[a] = std::min(f.hi[a], dims[a] - 1);
      }
    }
    // An inclusion wholly outside a non-periodic box (an inclusion list can hold one) reaches
    // no voxel: an empty footprint, which must not be walked.
    if (f.lo[0] > f.hi[0] || f.lo[1] > f.hi[1] || f.lo[2] > f.hi[2]) continue;
    for (int k = f.lo[2]; k <= f.hi[2]; ++k) {
      const int kk = periodic ? wrap(k, dims[2]) : k;
      if (kk >= img.extent[4] && kk < img.extent[5]) {
        (*planes)[kk - img.extent[4]].emplace_back(static_cast<int>(m), k);
      }
    }
  }
  return fp;
}

// The partial volumes of a row of voxels (y, z; its index jj, kk) cut by a straight core:
// ss^2 lines across the row, each exact along x, the coverage accumulated as a difference
// array (+1 where a line enters whole voxels, -1 after) plus the partly covered end voxels.
void add_row_coverage(const BodyQuery& body, const Footprint& f, const VoxelImage& img, double y,
                      double z, int jj, int kk, int ss, bool periodic, float* frac_out,
                      std::vector<double>* row, std::vector<double>* diff) {
  const std::array<int, 3>& dims = img.dims;
  const double ox = img.origin[0], hx = img.spacing[0];
  double t0, t1;
  // Coverage of the row's voxels, accumulated as a difference array (+1 where a line
  // enters whole voxels, -1 after) plus the partly covered end voxels.
  const int span = f.hi[0] - f.lo[0] + 1;
  row->assign(span + 1, 0.0);
  diff->assign(span + 1, 0.0);
  bool any = false;
  for (int c = 0; c < ss; ++c) {
    const double zs = z + ((c + 0.5) / ss - 0.5) * img.spacing[2];
    for (int b = 0; b < ss; ++b) {
      const double ys = y + ((b + 0.5) / ss - 0.5) * img.spacing[1];
      if (!body.x_interval(Vec3(0.0, ys, zs), &t0, &t1)) continue;
      // In voxel units from the footprint's first voxel, clipped to the footprint.
      const double u0 = std::max((t0 - ox) / hx - f.lo[0], 0.0);
      const double u1 = std::min((t1 - ox) / hx - f.lo[0], static_cast<double>(span));
      if (u1 <= u0) continue;
      any = true;
      const int i0 = static_cast<int>(std::floor(u0));
      const int i1 = std::min(static_cast<int>(std::floor(u1)), span - 1);
      if (i0 == i1) {
        (*row)[i0] += u1 - u0;
        continue;
      }
      (*row)[i0] += i0 + 1.0 - u0;
      (*row)[i1] += u1 - i1;
      (*diff)[i0 + 1] += 1.0;
      (*diff)[i1] -= 1.0;
    }
  }
  if (!any) return;
  const double w = 1.0 / (ss * ss);
  double run = 0.0;
  int ii = periodic ? wrap(f.lo[0], dims[0]) : f.lo[0];
  for (int q = 0; q < span; ++q, ++ii) {
    if (ii == dims[0]) ii = 0;
    run += (*diff)[q];
    const double cover = (run + (*row)[q]) * w;
    if (cover > 0.0 && ii >= img.extent[0] && ii < img.extent[1]) {
      frac_out[img.index(ii, jj, kk)] += static_cast<float>(cover);
    }
  }
}

}  // namespace

VoxelImage voxel_layout(const InclusionSet& set, const std::array<int, 3>& dims,
                        const VoxelOptions& opt) {
  VoxelImage img;
  img.dims = dims;
  img.origin = set.box.origin;
  for (int a = 0; a < 3; ++a) {
    img.spacing[a] = set.box.size[a] / dims[a];
    const bool whole = opt.extent[2 * a + 1] < 0;
    img.extent[2 * a] = whole ? 0 : std::clamp(opt.extent[2 * a], 0, dims[a]);
    img.extent[2 * a + 1] = whole ? dims[a] : std::clamp(opt.extent[2 * a + 1], 0, dims[a]);
    img.extent[2 * a + 1] =
        std::max(img.extent[2 * a + 1], img.extent[2 * a]);  // empty, not negative
  }
  img.phases = phase_table(set);
  if (img.phases.size() > 256) {
    throw InputError("too many phases for 8-bit labels (" + std::to_string(img.phases.size()) +
                     ": the matrix, one per family, one per coating and per debonding); at "
                     "most 256");
  }
  return img;
}

VoxelImage voxelize(const InclusionSet& set, const std::array<int, 3>& dims,
                    const VoxelOptions& opt) {
  VoxelImage img = voxel_layout(set, dims, opt);
  const size_t n = img.count();
  img.phase.resize(n);
  img.inclusion_id.resize(n);
  if (opt.partial_volume) img.fraction.resize(n);
  img.conflicts = voxelize_into(set, img, opt, img.phase.data(), img.inclusion_id.data(),
                                opt.partial_volume ? img.fraction.data() : nullptr);
  return img;
}

long long voxelize_into(const InclusionSet& set, const VoxelImage& img, const VoxelOptions& opt,
                        uint8_t* phase_out, int32_t* id_out, float* frac_out) {
  const std::array<int, 3>& dims = img.dims;
  const size_t n = img.count();
  std::fill(phase_out, phase_out + n, uint8_t{0});
  std::fill(id_out, id_out + n, int32_t{-1});
  if (frac_out) std::fill(frac_out, frac_out + n, 0.0f);
  if (n == 0) return 0;

  // Labels of each inclusion's regions.
  std::vector<int> shell_label(img.phases.size(), 0), void_label(img.phases.size(), 0);
  std::vector<char> is_core(256, 0);
  for (const auto& p : img.phases) {
    if (p.kind == PhaseKind::kCore) is_core[p.label] = 1;
    if (p.kind == PhaseKind::kInterphase) shell_label[p.family] = p.label;
    if (p.kind == PhaseKind::kVoid) void_label[p.family] = p.label;
  }

  // Footprints and, for each z plane of the extent, the (inclusion, unwrapped k) that reach it.
  const auto& incs = set.inclusions;
  const bool periodic = set.box.periodic;
  std::vector<std::vector<std::pair<int, int>>> planes;
  const std::vector<Footprint> fp = footprints(set, img, frac_out != nullptr, &planes);

  const double half_diagonal = 0.5 * img.spacing.norm();
  const int ss = std::max(1, opt.subsamples);
  std::vector<long long> conflicts(planes.size(), 0);
  tbb::parallel_for(size_t(0), planes.size(), [&](size_t p) {
    std::vector<double> row, diff;  // per-row partial-volume scratch
    for (const auto& [m, k] : planes[p]) {
      const Inclusion& inc = incs[m];
      const BodyQuery body(inc);
      const Footprint& f = fp[m];
      const int kk = periodic ? wrap(k, dims[2]) : k;
      const double z = img.origin[2] + (k + 0.5) * img.spacing[2];
      const uint8_t core = static_cast<uint8_t>(core_label(inc.family));
      auto in_x = [&](int i, int* ii) {
        *ii = periodic ? wrap(i, dims[0]) : i;
        return *ii >= img.extent[0] && *ii < img.extent[1];
      };
      auto label_core = [&](size_t idx) {
        uint8_t& ph = phase_out[idx];
        if (is_core[ph]) ++conflicts[p];
        ph = core;
        id_out[idx] = inc.id;
      };
      auto label_outer = [&](size_t idx, Region r) {
        if (phase_out[idx] != 0) return;
        phase_out[idx] = static_cast<uint8_t>(r == Region::kShell ? shell_label[inc.family]
                                                                  : void_label[inc.family]);
        id_out[idx] = inc.id;
      };
      // Shell and void labels of a row (voxels the core did not take).
      auto label_outer_regions = [&](int jj, double y) {
        int ii;
        for (int i = f.lo[0]; i <= f.hi[0]; ++i) {
          if (!in_x(i, &ii)) continue;
          const size_t idx = img.index(ii, jj, kk);
          if (phase_out[idx] != 0) continue;
          const Region r = body.region(Vec3(img.origin[0] + (i + 0.5) * img.spacing[0], y, z));
          if (r == Region::kShell || r == Region::kVoid) label_outer(idx, r);
        }
      };
      for (int j = f.lo[1]; j <= f.hi[1]; ++j) {
        const int jj = periodic ? wrap(j, dims[1]) : j;
        if (jj < img.extent[2] || jj >= img.extent[3]) continue;
        const double y = img.origin[1] + (j + 0.5) * img.spacing[1];
        const double ox = img.origin[0], hx = img.spacing[0];
        if (body.straight_core()) {
          // Exact intersections of x lines with the core: the centre line gives the labels,
          // ss^2 lines across the row give the partial volumes (exact along x). A shell or a
          // void is then labelled by its centre test where the core left the matrix.
          double t0, t1;
          if (body.x_interval(Vec3(0.0, y, z), &t0, &t1)) {
            const int i0 = std::max(f.lo[0], static_cast<int>(std::ceil((t0 - ox) / hx - 0.5)));
            const int i1 = std::min(f.hi[0], static_cast<int>(std::floor((t1 - ox) / hx - 0.5)));
            int ii;
            for (int i = i0; i <= i1; ++i) {
              if (in_x(i, &ii)) label_core(img.index(ii, jj, kk));
            }
          }
          if (!body.plain()) label_outer_regions(jj, y);
          if (!frac_out) continue;
          add_row_coverage(body, f, img, y, z, jj, kk, ss, periodic, frac_out, &row, &diff);
          continue;
        }
        for (int i = f.lo[0]; i <= f.hi[0]; ++i) {
          int ii;
          if (!in_x(i, &ii)) continue;
          const Vec3 x(ox + (i + 0.5) * hx, y, z);
          const size_t idx = img.index(ii, jj, kk);
          const Region r = body.region(x);
          if (frac_out) {
            if (body.clearance(x) >= half_diagonal) {
              if (r == Region::kCore) frac_out[idx] += 1.0f;
            } else {
              int inside = 0;
              for (int c = 0; c < ss; ++c) {
                for (int b = 0; b < ss; ++b) {
                  for (int a = 0; a < ss; ++a) {
                    const Vec3 d((a + 0.5) / ss - 0.5, (b + 0.5) / ss - 0.5, (c + 0.5) / ss - 0.5);
                    inside += body.region(x + d.cwiseProduct(img.spacing)) == Region::kCore;
                  }
                }
              }
              frac_out[idx] += static_cast<float>(inside) / (ss * ss * ss);
            }
          }
          if (r == Region::kOutside) continue;
          if (r == Region::kCore) {
            label_core(idx);
          } else {
            label_outer(idx, r);
          }
        }
      }
    }
  });
  if (frac_out) {
    for (size_t i = 0; i < n; ++i) frac_out[i] = std::min(frac_out[i], 1.0f);
  }
  return std::accumulate(conflicts.begin(), conflicts.end(), 0LL);
}

std::vector<double> label_fractions(const VoxelImage& image) {
  std::vector<double> out(image.phases.size(), 0.0);
  for (uint8_t p : image.phase) {
    if (p < out.size()) out[p] += 1.0;
  }
  for (double& v : out) v /= static_cast<double>(std::max<size_t>(1, image.phase.size()));
  return out;
}

double partial_volume_fraction(const VoxelImage& image) {
  double sum = 0.0;
  for (float v : image.fraction) sum += v;
  return image.fraction.empty() ? 0.0 : sum / static_cast<double>(image.fraction.size());
}

}  // namespace rvegen
