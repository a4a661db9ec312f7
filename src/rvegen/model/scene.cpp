#include "rvegen/model/scene.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "rvegen/model/body.hpp"
#include "rvegen/model/deformed_support.hpp"
#include "rvegen/model/orientation.hpp"

namespace rvegen {

double Family::mean_volume() const {
  switch (shape) {
    case ShapeKind::Sphere:
      return 4.0 / 3.0 * M_PI * radius.moment(3);
    case ShapeKind::Cylinder:
      if (through()) return M_PI * radius.moment(2) * through_length;
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
// Largest sideways reach of a fibre's centre line (wave and bend) over the family's fibres:
// the bend's grows with the half length.
double fibre_reach(const FamilyModifiers& m, double longest_half) {
  double reach = m.wave_amplitude;
  if (m.bend_radius > 0.0)
    reach += bend_reach(m.bend_radius, longest_half, longest_half + m.coating);
  return reach;
}
}  // namespace

double Family::max_bounding_radius() const {
  const FamilyModifiers& m = modifiers;
  switch (shape) {
    case ShapeKind::Sphere:
      return grown_size(m, radius.upper());
    case ShapeKind::Cylinder:
      return std::hypot(radius.upper() + m.coating + fibre_reach(m, longest_half()),
                        longest_half() + m.coating);
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
      return 2.0 * std::min(radius.upper() + m.coating + fibre_reach(m, longest_half()),
                            longest_half() + m.coating);
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
  // A representative inclusion of mean sizes. Deformation is not counted: a deformed sphere is
  // packed by its own support function (deformed_support.hpp), whose hull has about the volume
  // of the core, and how far a deformed ellipsoid's bound grows depends on the draw. Nor is a
  // large waviness or bend: such fibres are packed as chains that follow them (body.hpp,
  // chain_pieces).
  Random rng(0);
  Inclusion inc;
  Family mean = *this;
  mean.radius = radius.mean();
  mean.aspect_ratio = aspect_ratio.mean();
  for (int k = 0; k < 3; ++k) mean.semi_axes[k] = semi_axes[k].mean();
  inc.shape = mean.draw(Vec3::Zero(), rng);
  inc.mod = m.draw(rng);
  inc.mod.deform_amplitude = 0.0;
  inc.mod.through = through();
  if (packs_as_chain(inc)) inc.mod.wave_amplitude = inc.mod.bend_radius = 0.0;
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
  if (bend_radius > 0.0) {
    m.bend_radius = bend_radius;
    m.bend_angle = 2.0 * M_PI * rng.uniform();
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
    m.deform_peak = deformation_peak(m);
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
      if (through())
        return Shape::cylinder(center, radius.sample(rng),
                               orientation.axis * (0.5 * through_length));
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
      inc.mod.through = fam.through();
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
      // 1 / sqrt(n).
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

const char* method_name(Method method) {
  return method == Method::kRsa ? "rsa" : "md";
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
