#include "rvegen/model/deformed_support.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rvegen/geometry/tolerances.hpp"
#include "rvegen/model/body.hpp"

namespace rvegen {

namespace {
// The floor of a deformation amplitude the table's accuracy is divided by (an undeformed sphere
// needs no table; the floor keeps the division finite).
constexpr double kAmplitudeFloor = 1e-12;
}  // namespace
namespace {

constexpr int kMaxSampleCells = 96;   // finest sample grid (6 x 97^2 directions)
constexpr int kBlock = 4;             // sample cells per block side (the search's bounding spheres)
constexpr double kTolerance = 0.004;  // sampling margin aimed at, relative to the radius

// The node vector of face f (axis f / 2, sign + for even f) at face coordinates (x, y).
Vec3 face_vector(int f, double x, double y) {
  const int a = f / 2;
  Vec3 c;
  c[a] = (f % 2 == 0) ? 1.0 : -1.0;
  c[(a + 1) % 3] = x;
  c[(a + 2) % 3] = y;
  return c;
}

// Sums of the wave weights w and of w k^p: the derivative bounds of g along great circles
// (|g'| <= sum w k, |g''| <= sum w (k^2 + k)).
struct WaveBounds {
  double w = 0.0, wk = 0.0, wk2 = 0.0;
};
WaveBounds wave_bounds(const Modifiers& m) {
  WaveBounds b;
  for (const auto& wv : m.deform_waves) {
    const double w = std::abs(wv.weight), k = std::abs(wv.wavenumber);
    b.w += w;
    b.wk += w * k;
    b.wk2 += w * k * k;
  }
  return b;
}

// Cells per face side giving a margin M delta^2 / 2 of at most `tol` (delta = sqrt(2) / n),
// rounded up to whole blocks; 0 when that needs more than kMaxSampleCells.
int sample_cells(double M, double tol) {
  const int n = static_cast<int>(std::ceil(std::sqrt(M / tol)));
  const int rounded = std::max(kBlock * 2, (n + kBlock - 1) / kBlock * kBlock);
  return rounded <= kMaxSampleCells ? rounded : 0;
}

// The unit directions of a cube map with n cells a face side, face by face, row by row.
std::vector<Vec3> cube_directions(int n) {
  std::vector<Vec3> out;
  out.reserve(6 * (n + 1) * (n + 1));
  for (int f = 0; f < 6; ++f) {
    for (int j = 0; j <= n; ++j) {
      for (int i = 0; i <= n; ++i) {
        out.push_back(face_vector(f, -1.0 + 2.0 * i / n, -1.0 + 2.0 * j / n).normalized());
      }
    }
  }
  return out;
}

}  // namespace

double deformation_peak(const Modifiers& m) {
  const WaveBounds b = wave_bounds(m);
  if (m.deform_waves.empty()) return 0.0;
  // Branch and bound over cube-face cells. In a cell of side s about its centre direction c,
  // every direction is within angle s / sqrt(2) of c, and along the great circle
  // g <= g(c) + |grad g(c)| theta + M theta^2 / 2 with M = sum w (k^2 + k).
  const double M = b.wk2 + b.wk;
  const double tol = 0.001 / std::max(m.deform_amplitude, kAmplitudeFloor);  // 0.001 of the radius
  struct Cell {
    int f;
    double x, y, s;  // centre and side on the face
  };
  auto value_and_slope = [&](const Vec3& n, double* slope) {
    double g = 0.0;
    Vec3 grad = Vec3::Zero();
    for (const auto& wv : m.deform_waves) {
      const double t = n.dot(wv.direction), a = wv.wavenumber * t + wv.phase;
      g += wv.weight * std::cos(a);
      grad -= (wv.weight * wv.wavenumber * std::sin(a)) * (wv.direction - t * n);
    }
    *slope = grad.norm();
    return g;
  };
  std::vector<Cell> open;
  constexpr int kStart = 8;
  for (int f = 0; f < 6; ++f) {
    for (int j = 0; j < kStart; ++j) {
      for (int i = 0; i < kStart; ++i) {
        open.push_back(
            {f, -1.0 + (2.0 * i + 1.0) / kStart, -1.0 + (2.0 * j + 1.0) / kStart, 2.0 / kStart});
      }
    }
  }
  double best = -b.w, bound = -b.w;
  size_t visited = 0;
  while (!open.empty()) {
    const Cell c = open.back();
    open.pop_back();
    double slope;
    const double g = value_and_slope(face_vector(c.f, c.x, c.y).normalized(), &slope);
    best = std::max(best, g);
    const double theta = c.s / std::sqrt(2.0);
    const double up = g + slope * theta + 0.5 * M * theta * theta;
    if (up <= best + tol || ++visited > 200000) {
      bound = std::max(bound, up);  // settled (or out of patience: still an upper bound)
      continue;
    }
    const double h = 0.25 * c.s;
    for (int k = 0; k < 4; ++k) {
      open.push_back({c.f, c.x + (k % 2 ? h : -h), c.y + (k / 2 ? h : -h), 0.5 * c.s});
    }
  }
  // The relative 1e-12 covers the rounding of the sums.
  return std::min(b.w, std::max(best, bound) + kBoundMargin * b.w);
}

std::shared_ptr<const DeformedSupport> DeformedSupport::make(const Modifiers& m) {
  if (!m.deformed() || m.deform_waves.empty()) return nullptr;
  const WaveBounds b = wave_bounds(m);
  const double lam = m.deform_scale, e = m.deform_amplitude;
  // f(n) = R(n) (n . u) with R = lam (1 + e g): |f''| <= |R''| + 2 |R'| + R along great circles.
  const double M = lam * (e * (b.wk2 + 3.0 * b.wk) + 1.0 + e * b.w);
  const int ns = sample_cells(M, kTolerance * lam);
  if (ns == 0) return nullptr;
  const double delta = std::sqrt(2.0) / ns;
  const double margin = 0.5 * M * delta * delta + kBoundMargin * lam * (1.0 + e * b.w);

  // Surface points at the sample directions, and a bounding sphere of each block of them.
  const std::vector<Vec3> dirs = cube_directions(ns);
  std::vector<Vec3> pts(dirs.size());
  for (size_t j = 0; j < dirs.size(); ++j) pts[j] = deformed_radius(m, dirs[j]) * dirs[j];
  // Blocks of kBlock x kBlock sample cells, and groups of up to 3 x 3 blocks, each with a
  // bounding sphere of its points: the search for a node's best point skips every group and
  // block whose sphere cannot beat the best point found so far.
  const int side = ns + 1, blocks = ns / kBlock, groups = (blocks + 2) / 3;
  struct Ball {
    Vec3 center = Vec3::Zero();
    double radius = 0.0;
    int f = 0, i0 = 0, j0 = 0, i1 = 0, j1 = 0;  // sample index ranges (inclusive)
  };
  auto ball_of = [&](int f, int i0, int j0, int i1, int j1) {
    Ball B{Vec3::Zero(), 0.0, f, i0, j0, i1, j1};
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) B.center += pts[(f * side + j) * side + i];
    }
    B.center /= (i1 - i0 + 1) * (j1 - j0 + 1);
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        B.radius = std::max(B.radius, (pts[(f * side + j) * side + i] - B.center).norm());
      }
    }
    B.radius *= 1.0 + kBoundMargin;
    return B;
  };
  std::vector<Ball> group_ball;
  std::vector<std::vector<Ball>> block_ball;
  for (int f = 0; f < 6; ++f) {
    for (int gj = 0; gj < groups; ++gj) {
      for (int gi = 0; gi < groups; ++gi) {
        std::vector<Ball> inner;
        for (int bj = 3 * gj; bj < std::min(blocks, 3 * gj + 3); ++bj) {
          for (int bi = 3 * gi; bi < std::min(blocks, 3 * gi + 3); ++bi) {
            inner.push_back(
                ball_of(f, bi * kBlock, bj * kBlock, (bi + 1) * kBlock, (bj + 1) * kBlock));
          }
        }
        const int i1 = std::min(ns, (3 * gi + 3) * kBlock),
                  j1 = std::min(ns, (3 * gj + 3) * kBlock);
        group_ball.push_back(ball_of(f, 3 * gi * kBlock, 3 * gj * kBlock, i1, j1));
        block_ball.push_back(std::move(inner));
      }
    }
  }

  std::shared_ptr<DeformedSupport> out(new DeformedSupport);
  constexpr int n = kCells;
  out->h_.resize(6 * (n + 1) * (n + 1));
  Vec3 seed = Vec3::Zero();  // the best point of the previous node: a good first guess
  for (int f = 0; f < 6; ++f) {
    for (int j = 0; j <= n; ++j) {
      for (int i = 0; i <= n; ++i) {
        const Vec3 c = face_vector(f, -1.0 + 2.0 * i / n, -1.0 + 2.0 * j / n);
        const double len = c.norm();
        const Vec3 v = c / len;
        // Any surface point is a lower bound of the best: the one straight along v, the seed.
        double best = std::max(deformed_radius(m, v), seed.dot(v));
        const Vec3* arg = nullptr;
        for (size_t g = 0; g < group_ball.size(); ++g) {
          if (group_ball[g].center.dot(v) + group_ball[g].radius <= best) continue;
          for (const Ball& B : block_ball[g]) {
            if (B.center.dot(v) + B.radius <= best) continue;
            for (int jj = B.j0; jj <= B.j1; ++jj) {
              const Vec3* row = &pts[(B.f * side + jj) * side];
              for (int ii = B.i0; ii <= B.i1; ++ii) {
                const double t = row[ii].dot(v);
                if (t > best) {
                  best = t;
                  arg = &row[ii];
                }
              }
            }
          }
        }
        if (arg) seed = *arg;
        const double h = len * (best + margin);
        float hf = static_cast<float>(h);
        if (static_cast<double>(hf) < h) hf = std::nextafter(hf, std::numeric_limits<float>::max());
        out->h_[(f * (n + 1) + j) * (n + 1) + i] = hf;
      }
    }
  }
  return out;
}

double DeformedSupport::operator()(const Vec3& u) const {
  const Vec3 a = u.cwiseAbs();
  const int ax = a[0] >= a[1] ? (a[0] >= a[2] ? 0 : 2) : (a[1] >= a[2] ? 1 : 2);
  const double w = a[ax];
  if (!(w > 0.0)) return 0.0;
  const int f = 2 * ax + (u[ax] < 0.0 ? 1 : 0);
  constexpr int n = kCells;
  const double gx = (u[(ax + 1) % 3] / w + 1.0) * 0.5 * n,
               gy = (u[(ax + 2) % 3] / w + 1.0) * 0.5 * n;
  const int i = std::clamp(static_cast<int>(gx), 0, n - 1),
            j = std::clamp(static_cast<int>(gy), 0, n - 1);
  const double tx = std::clamp(gx - i, 0.0, 1.0), ty = std::clamp(gy - j, 0.0, 1.0);
  const float* row0 = &h_[(f * (n + 1) + j) * (n + 1) + i];
  const float* row1 = row0 + (n + 1);
  const double v = (1.0 - ty) * ((1.0 - tx) * row0[0] + tx * row0[1]) +
                   ty * ((1.0 - tx) * row1[0] + tx * row1[1]);
  // The relative 1e-12 covers the rounding of this arithmetic.
  return w * v * (1.0 + kBoundMargin);
}

std::shared_ptr<const DeformedSupport> support_table(const Inclusion& inc) {
  if (inc.shape.kind != ShapeKind::Sphere || !inc.mod.deformed() || inc.mod.debonded()) {
    return nullptr;
  }
  return DeformedSupport::make(inc.mod);
}

double envelope_support(const Inclusion& inc, const DeformedSupport& table, const Vec3& u) {
  const Modifiers& m = inc.mod;
  const double extra = (m.shells_may_touch ? 0.0 : m.coating) + m.packing_pad;
  return bounded_support(table, inc.shape.radius, extra, envelope(inc).radius, u);
}

}  // namespace rvegen
