#include "rvegen/model/scene.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "rvegen/model/body.hpp"
#include "rvegen/model/orientation.hpp"

namespace rvegen {

namespace {
// Parameters of the lognormal law with the given mean and std of the size itself.
void lognormal_params(double mean, double std, double* mu, double* sigma) {
  const double s2 = std::log(1.0 + (std * std) / (mean * mean));
  *sigma = std::sqrt(s2);
  *mu = std::log(mean) - 0.5 * s2;
}
constexpr double kTails = 6.0;         // truncation of normal and lognormal laws, in std / sigma
constexpr double kWeibullTail = 1e-9;  // truncation of weibull laws: quantiles q and 1 - q
double weibull_quantile(double k, double lambda, double q) {
  return lambda * std::pow(-std::log1p(-q), 1.0 / k);
}
}  // namespace

double SizeLaw::lower() const {
  switch (kind) {
    case Kind::kFixed:
      return p1;
    case Kind::kUniform:
      return p1;
    case Kind::kNormal:
      return std::max(p1 - kTails * p2, 1e-6 * p1);
    case Kind::kLognormal: {
      double mu, sigma;
      lognormal_params(p1, p2, &mu, &sigma);
      return std::exp(mu - kTails * sigma);
    }
    case Kind::kWeibull:
      return weibull_quantile(p1, p2, kWeibullTail);
  }
  return p1;
}

double SizeLaw::upper() const {
  switch (kind) {
    case Kind::kFixed:
      return p1;
    case Kind::kUniform:
      return p2;
    case Kind::kNormal:
      return p1 + kTails * p2;
    case Kind::kLognormal: {
      double mu, sigma;
      lognormal_params(p1, p2, &mu, &sigma);
      return std::exp(mu + kTails * sigma);
    }
    case Kind::kWeibull:
      return weibull_quantile(p1, p2, 1.0 - kWeibullTail);
  }
  return p1;
}

double SizeLaw::sample(Random& rng) const {
  const double lo = lower(), hi = upper();
  for (;;) {
    double x = p1;
    switch (kind) {
      case Kind::kFixed:
        return p1;
      case Kind::kUniform:
        return rng.uniform(p1, p2);
      case Kind::kNormal:
        x = p1 + p2 * rng.normal();
        break;
      case Kind::kLognormal: {
        double mu, sigma;
        lognormal_params(p1, p2, &mu, &sigma);
        x = std::exp(mu + sigma * rng.normal());
        break;
      }
      case Kind::kWeibull:
        // Inverse transform on the truncated range.
        return weibull_quantile(p1, p2, kWeibullTail + (1.0 - 2.0 * kWeibullTail) * rng.uniform());
    }
    if (x >= lo && x <= hi) return x;
  }
}

double SizeLaw::moment(int k) const {
  switch (kind) {
    case Kind::kFixed:
      return std::pow(p1, k);
    case Kind::kUniform:
      return p2 > p1 ? (std::pow(p2, k + 1) - std::pow(p1, k + 1)) / ((k + 1) * (p2 - p1))
                     : std::pow(p1, k);
    default:
      break;
  }
  // Truncated normal / lognormal / weibull: Simpson's rule on the density over [lower, upper].
  double mu = p1, sigma = p2;
  if (kind == Kind::kLognormal) lognormal_params(p1, p2, &mu, &sigma);
  auto density = [&](double x) {
    if (kind == Kind::kWeibull) {
      const double z = x / p2;
      return std::pow(z, p1 - 1.0) * std::exp(-std::pow(z, p1));
    }
    const double z = kind == Kind::kNormal ? (x - mu) / sigma : (std::log(x) - mu) / sigma;
    return std::exp(-0.5 * z * z) / (kind == Kind::kNormal ? 1.0 : x);
  };
  const int n = 4000;
  const double a = lower(), b = upper(), h = (b - a) / n;
  double mass = 0.0, mom = 0.0;
  for (int i = 0; i <= n; ++i) {
    const double x = a + i * h, w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
    mass += w * density(x);
    mom += w * density(x) * std::pow(x, k);
  }
  return mom / mass;
}

Vec3 OrientationLaw::sample(Random& rng) const {
  switch (kind) {
    case Kind::kIsotropic:
      return rng.unit_vector();
    case Kind::kAligned:
      return axis;
    case Kind::kVonMisesFisher: {
      // Wood (1994) in three dimensions: w = cos(angle to the axis) has density ~ exp(kappa w).
      const double u = rng.uniform();
      const double w = kappa > 1e-8 ? 1.0 + std::log(u + (1.0 - u) * std::exp(-2.0 * kappa)) / kappa
                                    : 2.0 * u - 1.0;
      const double phi = 2.0 * M_PI * rng.uniform();
      const Vec3 e1 = any_orthogonal(axis), e2 = axis.cross(e1);
      const double s = std::sqrt(std::max(0.0, 1.0 - w * w));
      return (w * axis + s * (std::cos(phi) * e1 + std::sin(phi) * e2)).normalized();
    }
    case Kind::kPlanar: {
      const double phi = 2.0 * M_PI * rng.uniform();
      const Vec3 e1 = any_orthogonal(axis), e2 = axis.cross(e1);
      return std::cos(phi) * e1 + std::sin(phi) * e2;
    }
    case Kind::kTensor:
      return fit_acg(a2).sample(rng);
  }
  return axis;
}

Mat3 OrientationLaw::tensor() const {
  switch (kind) {
    case Kind::kIsotropic:
      return Mat3::Identity() / 3.0;
    case Kind::kAligned:
      return axis * axis.transpose();
    case Kind::kVonMisesFisher: {
      // <(p.mu)^2> = 1 - 2 (coth k - 1/k) / k; series below k = 1e-3 (isotropic limit 1/3).
      const double k = kappa;
      const double c2 = k < 1e-3 ? 1.0 / 3.0 + 2.0 * k / 45.0 * k
                                 : 1.0 - 2.0 * (1.0 / std::tanh(k) - 1.0 / k) / k;
      return c2 * axis * axis.transpose() +
             0.5 * (1.0 - c2) * (Mat3::Identity() - axis * axis.transpose());
    }
    case Kind::kPlanar:
      return 0.5 * (Mat3::Identity() - axis * axis.transpose());
    case Kind::kTensor:
      return a2;
  }
  return Mat3::Identity() / 3.0;
}

double Family::mean_volume() const {
  switch (shape) {
    case ShapeKind::Sphere:
      return 4.0 / 3.0 * M_PI * radius.moment(3);
    case ShapeKind::Cylinder:
      return 2.0 * M_PI * radius.moment(3) * aspect_ratio.mean();
    case ShapeKind::Ellipsoid:
      return 4.0 / 3.0 * M_PI * semi_axes[0].mean() * semi_axes[1].mean() * semi_axes[2].mean();
  }
  return 0.0;
}

namespace {
// Bounds on how modifiers grow a core of largest size `size` into its envelope: the factor of
// a deformation (lambda (1 + e) <= (1 + e) / (1 - e)) and the added thickness.
double grown_size(const FamilyModifiers& m, double size) {
  const double e = m.deform_amplitude;
  return size * (1.0 + e) / (1.0 - e) + m.coating + m.wave_amplitude + m.debond_gap;
}
}  // namespace

double Family::max_bounding_radius() const {
  const FamilyModifiers& m = modifiers;
  switch (shape) {
    case ShapeKind::Sphere:
      return grown_size(m, radius.upper());
    case ShapeKind::Cylinder:
      return std::hypot(radius.upper() + m.coating + m.wave_amplitude,
                        radius.upper() * aspect_ratio.upper() + m.coating);
    case ShapeKind::Ellipsoid: {
      const double big =
          std::max({semi_axes[0].upper(), semi_axes[1].upper(), semi_axes[2].upper()});
      const double small =
          std::min({semi_axes[0].lower(), semi_axes[1].lower(), semi_axes[2].lower()});
      const double e = m.deform_amplitude;
      return big * (1.0 + e) / (1.0 - e) * (1.0 + m.coating / small);
    }
  }
  return 0.0;
}

double Family::max_min_width() const {
  const FamilyModifiers& m = modifiers;
  switch (shape) {
    case ShapeKind::Sphere:
      return 2.0 * grown_size(m, radius.upper());
    case ShapeKind::Cylinder:
      return 2.0 * std::min(radius.upper() + m.coating + m.wave_amplitude,
                            radius.upper() * aspect_ratio.upper() + m.coating);
    case ShapeKind::Ellipsoid: {
      const double small =
          std::min({semi_axes[0].upper(), semi_axes[1].upper(), semi_axes[2].upper()});
      return 2.0 * grown_size(m, small);
    }
  }
  return 0.0;
}

double Family::envelope_ratio() const {
  const FamilyModifiers& m = modifiers;
  if (!m.any()) return 1.0;
  // A representative inclusion of mean sizes; deformation counted at its smallest growth 1 + e.
  Random rng(0);
  Inclusion inc;
  Family mean = *this;
  mean.radius = radius.mean();
  mean.aspect_ratio = aspect_ratio.mean();
  for (int k = 0; k < 3; ++k) mean.semi_axes[k] = semi_axes[k].mean();
  inc.shape = mean.draw(Vec3::Zero(), rng);
  inc.mod = m.draw(rng);
  if (inc.mod.deformed()) inc.mod.deform_scale = 1.0;
  return envelope(inc).volume() / inc.shape.volume();
}

Modifiers FamilyModifiers::draw(Random& rng) const {
  Modifiers m;
  m.coating = coating;
  m.shells_may_touch = shells_may_touch;
  if (wave_amplitude > 0.0) {
    m.wave_amplitude = wave_amplitude;
    m.wave_length = wave_length;
    m.wave_phase = 2.0 * M_PI * rng.uniform();
    m.wave_angle = 2.0 * M_PI * rng.uniform();
  }
  if (deform_amplitude > 0.0) {
    // Eight waves of angular half-wavelength `smoothness` radians, weights summing to 1.
    m.deform_amplitude = deform_amplitude;
    double sum = 0.0;
    for (int k = 0; k < 8; ++k) {
      DeformationWave w;
      w.direction = rng.unit_vector();
      w.weight = rng.uniform(0.5, 1.0);
      w.wavenumber = M_PI / smoothness;
      w.phase = 2.0 * M_PI * rng.uniform();
      sum += w.weight;
      m.deform_waves.push_back(w);
    }
    for (auto& w : m.deform_waves) w.weight /= sum;
    m.deform_scale = deformation_volume_scale(m);
  }
  if (debond_gap > 0.0) {
    m.debond_fraction = debond_fraction;
    m.debond_gap = debond_gap;
    m.debond_axis = rng.unit_vector();
  }
  return m;
}

Shape Family::draw(const Vec3& center, Random& rng, const AcgLaw* acg) const {
  auto direction = [&] {
    return orientation.kind == OrientationLaw::Kind::kTensor && acg ? acg->sample(rng)
                                                                    : orientation.sample(rng);
  };
  switch (shape) {
    case ShapeKind::Sphere:
      return Shape::sphere(center, radius.sample(rng));
    case ShapeKind::Cylinder: {
      const double r = radius.sample(rng), a = aspect_ratio.sample(rng);
      return Shape::cylinder(center, r, direction() * (a * r));
    }
    case ShapeKind::Ellipsoid: {
      const Vec3 semi(semi_axes[0].sample(rng), semi_axes[1].sample(rng), semi_axes[2].sample(rng));
      // First principal axis from the law, random spin about it.
      const Vec3 a = direction();
      const Vec3 b0 = any_orthogonal(a);
      const double th = 2.0 * M_PI * rng.uniform();
      const Vec3 b = std::cos(th) * b0 + std::sin(th) * a.cross(b0);
      Mat3 R;
      R.col(0) = a;
      R.col(1) = b;
      R.col(2) = a.cross(b);
      return Shape::ellipsoid(center, semi, R);
    }
  }
  return Shape::sphere(center, radius.sample(rng));
}

double PackingSpec::expected_count(int f) const {
  const Family& fam = families[f];
  if (fam.count >= 0) return fam.count;
  return fam.volume_fraction * box.volume() / fam.mean_volume();
}

double PackingSpec::expected_volume_fraction() const {
  double total = 0.0;
  for (size_t f = 0; f < families.size(); ++f) {
    total += expected_count(static_cast<int>(f)) * families[f].mean_volume() / box.volume();
  }
  return total;
}

std::vector<Inclusion> draw_population(const PackingSpec& scene, Random& rng) {
  std::vector<Inclusion> out;
  const double V = scene.box.volume();
  Random mod_rng(scene.seed ^ 0x6d6f646966696572ULL);  // modifiers: their own stream
  double pad = 0.0;  // half the largest coating whose shells may touch (see envelope())
  for (const Family& f : scene.families) {
    if (f.modifiers.shells_may_touch) pad = std::max(pad, 0.5 * f.modifiers.coating);
  }
  for (size_t f = 0; f < scene.families.size(); ++f) {
    const Family& fam = scene.families[f];
    const size_t first = out.size();
    AcgLaw acg;
    if (fam.orientation.kind == OrientationLaw::Kind::kTensor) acg = fit_acg(fam.orientation.a2);
    auto add = [&](const Shape& s) {
      Inclusion inc;
      inc.id = static_cast<int>(out.size());
      inc.family = static_cast<int>(f);
      inc.shape = s;
      if (fam.modifiers.any()) inc.mod = fam.modifiers.draw(mod_rng);
      inc.mod.packing_pad = pad;
      out.push_back(inc);
    };
    if (fam.count >= 0) {
      for (int k = 0; k < fam.count; ++k) add(fam.draw(Vec3::Zero(), rng, &acg));
    } else {
      const double target = fam.volume_fraction * V;
      double sum = 0.0;
      for (;;) {
        // validate_scene bounds the expected count; this bounds an unlucky draw too.
        if (out.size() >= 100000000) {
          throw InputError("families[" + std::to_string(f) +
                           "]: more than 1e8 inclusions drawn for the volume fraction");
        }
        const Shape s = fam.draw(Vec3::Zero(), rng, &acg);
        const double v = s.volume();
        if (sum + v > target && (sum + v - target) >= (target - sum)) break;
        add(s);
        sum += v;
      }
    }
    if (fam.shape != ShapeKind::Sphere && fam.orientation.kind != OrientationLaw::Kind::kAligned) {
      // The sample's <p p^T> made the law's: a finite sample alone misses it by about
      // 1 / sqrt(n) (0.02 for 1,000 fibres).
      std::vector<Vec3> dirs;
      for (size_t i = first; i < out.size(); ++i) dirs.push_back(law_axis(out[i].shape));
      if (match_orientation_tensor(&dirs, fam.orientation.tensor())) {
        for (size_t i = first; i < out.size(); ++i) set_law_axis(&out[i].shape, dirs[i - first]);
      }
    }
  }
  return out;
}

double max_packable_fraction(const PackingSpec& scene) {
  double best = 0.0;
  for (const auto& f : scene.families) {
    switch (f.shape) {
      case ShapeKind::Sphere:
        best = std::max(best, M_PI / (3.0 * std::sqrt(2.0)));
        break;
      case ShapeKind::Ellipsoid:
        best = std::max(best, 0.7707);
        break;
      case ShapeKind::Cylinder:
        best = std::max(best, M_PI / (2.0 * std::sqrt(3.0)));
        break;
    }
  }
  return best;
}

namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw InputError(path + ": " + what);
}

void check_size_law(const SizeLaw& law, const std::string& p) {
  auto finite_positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  switch (law.kind) {
    case SizeLaw::Kind::kFixed:
      if (!finite_positive(law.p1)) fail(p, "must be positive and finite");
      break;
    case SizeLaw::Kind::kUniform:
      if (!finite_positive(law.p1)) fail(p + ".min", "must be positive and finite");
      if (!finite_positive(law.p2) || law.p2 < law.p1) fail(p + ".max", "must be >= min");
      break;
    case SizeLaw::Kind::kNormal:
    case SizeLaw::Kind::kLognormal:
      if (!finite_positive(law.p1)) fail(p + ".mean", "must be positive and finite");
      if (!(law.p2 >= 0.0 && law.p2 <= 10.0 * law.p1))
        fail(p + ".std", "must be in [0, 10 x mean]");
      break;
    case SizeLaw::Kind::kWeibull:
      if (!(law.p1 >= 0.1 && law.p1 <= 100.0)) fail(p + ".shape", "must be in [0.1, 100]");
      if (!finite_positive(law.p2)) fail(p + ".scale", "must be positive and finite");
      break;
  }
}

void check_orientation(const OrientationLaw& law, const std::string& p) {
  if (law.kind == OrientationLaw::Kind::kTensor) {
    const Mat3& a = law.a2;
    const std::string q = p + ".a2";
    if (!a.allFinite()) fail(q, "must be finite");
    if ((a - a.transpose()).cwiseAbs().maxCoeff() > 1e-6) {
      fail(q, "must be symmetric (a_ij = a_ji to 1e-6)");
    }
    char buf[160];
    if (std::abs(a.trace() - 1.0) > 1e-6) {
      std::snprintf(buf, sizeof buf, "must have trace 1 (to 1e-6), has %.9g", a.trace());
      fail(q, buf);
    }
    const double low =
        Eigen::SelfAdjointEigenSolver<Mat3>(0.5 * (a + a.transpose())).eigenvalues().minCoeff();
    if (low < -1e-9) {
      std::snprintf(buf, sizeof buf,
                    "must be positive semi-definite, has the eigenvalue %.6g (an orientation "
                    "tensor <p p^T> has none below 0)",
                    low);
      fail(q, buf);
    }
    return;
  }
  const char* key = law.kind == OrientationLaw::Kind::kPlanar ? ".normal" : ".axis";
  if (!law.axis.allFinite() || std::abs(law.axis.norm() - 1.0) > 1e-9) {
    fail(p + key, "must be a unit vector");
  }
  if (!(law.kappa >= 0.0 && law.kappa <= 1e6)) fail(p + ".kappa", "must be in [0, 1e6]");
}

// Smallest size of a mean-size inclusion of the family (radius, half length, semi-axis).
double mean_smallest_size(const Family& f) {
  switch (f.shape) {
    case ShapeKind::Sphere:
      return f.radius.mean();
    case ShapeKind::Cylinder:
      return std::min(f.radius.mean(), f.radius.mean() * f.aspect_ratio.mean());
    case ShapeKind::Ellipsoid:
      return std::min({f.semi_axes[0].mean(), f.semi_axes[1].mean(), f.semi_axes[2].mean()});
  }
  return 0.0;
}

}  // namespace

const char* method_name(Method method) {
  return method == Method::kRsa ? "rsa" : "md";
}

void validate_scene(const Scene& s) {
  check_box(s.box, "box");
  if (s.families.empty()) fail("families", "at least one family is needed");
  if (!(s.min_gap >= 0.0) || !std::isfinite(s.min_gap)) fail("min_gap", "must be >= 0");
  if (s.method != Method::kMd && s.method != Method::kRsa) {
    fail("method", "unknown method " + std::to_string(static_cast<int>(s.method)) + " (md, rsa)");
  }
  if (s.rsa_max_attempts < 1 || s.rsa_max_attempts > 1000000000)
    fail("rsa.max_attempts", "must be an integer in [1, 1e9]");
  if (!(s.rsa_max_seconds > 0.0 && s.rsa_max_seconds <= 1e7))
    fail("rsa.max_seconds", "must be in (0, 1e7]");
  if (s.md.max_steps < 1 || s.md.max_steps > 1000000000000LL)
    fail("md.max_steps", "must be an integer in [1, 1e12]");
  if (!(s.md.max_seconds > 0.0 && s.md.max_seconds <= 1e7))
    fail("md.max_seconds", "must be in (0, 1e7]");
  if (!(s.md.pressure > 0.0 && s.md.pressure <= 1.0)) fail("md.pressure", "must be in (0, 1]");
  if (s.md.patience < 1 || s.md.patience > 10000000)
    fail("md.patience", "must be an integer in [1, 1e7]");
  if (s.subsamples < 1 || s.subsamples > 16)
    fail("voxels.subsamples", "must be an integer in [1, 16]");
  if (!(s.levelset_half_width >= 1.0 && s.levelset_half_width <= 20.0))
    fail("levelsets.half_width", "must be in [1, 20] voxels");
  for (int k = 0; k < 3; ++k) {
    if (s.resolution[k] < 1 || s.resolution[k] > 4096) {
      fail("voxels.resolution[" + std::to_string(k) + "]", "must be an integer in [1, 4096]");
    }
  }
  const double box_min = s.box.size.minCoeff();
  if (!(s.levelset_voxel_size >= 0.0) || !std::isfinite(s.levelset_voxel_size))
    fail("levelsets.voxel_size", "must be positive");
  if (s.levelset_voxel_size > box_min / 16.0)
    fail("levelsets.voxel_size", "too large: at most 1/16 of the smallest box size");
  if (s.levelset_voxel_size > 0.0 && s.box.size.maxCoeff() / s.levelset_voxel_size > 8192) {
    fail("levelsets.voxel_size", "too small: more than 8192 voxels along the box");
  }
  if (s.min_gap >= box_min) fail("min_gap", "must be smaller than the box");
  // Phase labels are 8-bit (0 matrix, a core per family, an interphase per coated family and
  // a void per debonded family).
  size_t phases = 1 + s.families.size();
  for (const Family& f : s.families) {
    phases += (f.modifiers.coating > 0.0 ? 1 : 0) + (f.modifiers.debond_gap > 0.0 ? 1 : 0);
  }
  if (phases > 256) {
    fail("families", "too many phases (" + std::to_string(phases) +
                         ": the matrix, one per family, one per coating and per debonding); at "
                         "most 256");
  }
  for (size_t i = 0; i < s.families.size(); ++i) {
    const Family& f = s.families[i];
    const std::string p = "families[" + std::to_string(i) + "]";
    switch (f.shape) {
      case ShapeKind::Sphere:
        check_size_law(f.radius, p + ".radius");
        break;
      case ShapeKind::Cylinder:
        check_size_law(f.radius, p + ".radius");
        check_size_law(f.aspect_ratio, p + ".aspect_ratio");
        break;
      case ShapeKind::Ellipsoid:
        for (int k = 0; k < 3; ++k)
          check_size_law(f.semi_axes[k], p + ".semi_axes[" + std::to_string(k) + "]");
        break;
    }
    check_orientation(f.orientation, p + ".orientation");
    if (f.count < 0 && !(f.volume_fraction > 0.0 && f.volume_fraction < 1.0))
      fail(p + ".volume_fraction", "must be in (0, 1)");
    if (f.count > 100000000) fail(p + ".count", "must be an integer in [0, 1e8]");
    const double small = mean_smallest_size(f);
    if (!(small >= 1e-6 * s.box.size.maxCoeff())) {
      char buf[160];
      std::snprintf(buf, sizeof buf,
                    "inclusions smaller than 1e-6 of the box are not supported (mean smallest "
                    "size %.3g)",
                    small);
      fail(p, buf);
    }
  }
  double count = 0.0;
  for (size_t i = 0; i < s.families.size(); ++i) {
    const Family& f = s.families[i];
    const std::string p = "families[" + std::to_string(i) + "]";
    // Modifiers: which shapes take them, ranges, combinations.
    const FamilyModifiers& m = f.modifiers;
    auto finite_at_least_0 = [](double v) { return std::isfinite(v) && v >= 0.0; };
    if (!finite_at_least_0(m.coating)) fail(p + ".coating.thickness", "must be >= 0");
    if (!finite_at_least_0(m.wave_amplitude)) fail(p + ".waviness.amplitude", "must be >= 0");
    if (m.wave_amplitude > 0.0) {
      if (f.shape != ShapeKind::Cylinder)
        fail(p + ".waviness", "waviness applies to cylinders only");
      if (!(m.wave_length > 0.0) || !std::isfinite(m.wave_length))
        fail(p + ".waviness.wavelength", "must be positive");
    }
    if (!(m.deform_amplitude >= 0.0 && m.deform_amplitude <= 0.5))
      fail(p + ".deformation.amplitude", "must be in (0, 0.5]");
    if (m.deform_amplitude > 0.0) {
      if (f.shape == ShapeKind::Cylinder)
        fail(p + ".deformation", "deformation applies to spheres and ellipsoids only");
      if (!(m.smoothness >= 0.1 && m.smoothness <= 10.0))
        fail(p + ".deformation.smoothness", "must be in [0.1, 10]");
    }
    if (!finite_at_least_0(m.debond_gap)) fail(p + ".debonding.gap", "must be positive");
    if (!(m.debond_fraction >= 0.0 && m.debond_fraction <= 1.0))
      fail(p + ".debonding.fraction", "must be in (0, 1]");
    if ((m.debond_gap > 0.0) != (m.debond_fraction > 0.0))
      fail(p + ".debonding", "give both a fraction and a gap");
    if (m.debond_gap > 0.0 && f.shape != ShapeKind::Sphere)
      fail(p + ".debonding", "debonding applies to spheres only");
    if (m.coating > 0.0 && m.deform_amplitude > 0.0)
      fail(p, "coating and deformation together are not supported");
    if (m.coating > 0.0 && m.debond_gap > 0.0)
      fail(p, "coating and debonding together are not supported");
    if (m.deform_amplitude > 0.0 && m.debond_gap > 0.0)
      fail(p, "deformation and debonding together are not supported");
    if (f.max_min_width() + 2.0 * s.min_gap >= box_min) {
      fail(p, "inclusion does not fit in the box (smallest width " +
                  std::to_string(f.max_min_width()) + " >= smallest box size " +
                  std::to_string(box_min) + ")");
    }
    if (!s.box.periodic && 2.0 * f.max_bounding_radius() >= box_min) {
      // A non-periodic box must hold every inclusion whatever its orientation.
      fail(p, "inclusion does not fit in the non-periodic box (largest length " +
                  std::to_string(2.0 * f.max_bounding_radius()) + " >= smallest box size " +
                  std::to_string(box_min) + ")");
    }
    const double n = s.expected_count(static_cast<int>(i));
    if (f.volume_fraction >= 0.0 && f.count < 0 && n < 0.5) {
      fail(p + ".volume_fraction", "too small for a single inclusion in this box");
    }
    count += n;
  }
  if (count > 2e7) fail("families", "more than 2e7 inclusions asked for");
  const double total = s.expected_volume_fraction(), limit = max_packable_fraction(s);
  if (total > limit) {
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "total volume fraction %.4f exceeds %.4f, the densest packing these shapes allow",
                  total, limit);
    fail("families", buf);
  }
  // Modified inclusions are packed by their envelopes (core + shell, waves, bumps, voids).
  double packed = 0.0;
  for (size_t f = 0; f < s.families.size(); ++f) {
    packed += s.expected_count(static_cast<int>(f)) * s.families[f].mean_volume() *
              s.families[f].envelope_ratio() / s.box.volume();
  }
  if (packed > limit) {
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "the envelopes of the inclusions (with coatings, waves, deformations, voids) "
                  "would fill %.4f of the box, above %.4f, the densest packing these shapes allow",
                  packed, limit);
    fail("families", buf);
  }
}

Scene default_scene() {
  Scene s;
  s.box.size = Vec3(1, 1, 1);
  s.box.periodic = true;
  s.seed = 42;
  s.method = Method::kMd;
  Family spheres;
  spheres.name = "spheres";
  spheres.shape = ShapeKind::Sphere;
  spheres.radius = 0.05;
  spheres.volume_fraction = 0.20;
  Family fibres;
  fibres.name = "fibres";
  fibres.shape = ShapeKind::Cylinder;
  fibres.radius = 0.02;
  fibres.aspect_ratio = 5.0;
  fibres.volume_fraction = 0.10;
  Family grains;
  grains.name = "grains";
  grains.shape = ShapeKind::Ellipsoid;
  grains.semi_axes = {0.06, 0.04, 0.03};
  grains.volume_fraction = 0.05;
  s.families = {spheres, fibres, grains};
  s.resolution = {64, 64, 64};
  return s;
}

}  // namespace rvegen
