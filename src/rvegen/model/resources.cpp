#include "rvegen/model/resources.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "rvegen/model/body.hpp"

namespace rvegen {
namespace {

// Measured costs (bytes), see README "Resources": per inclusion in the packer and lists, per
// triangle of the surfaces (in memory and in the .vtp), per voxel, per narrow-band voxel.
constexpr double kBytesPerInclusion = 2500.0;
constexpr double kBytesPerFibrePiece = 400.0;  // per bounding sub-sphere of a long inclusion
constexpr double kBytesPerTriangle = 300.0;    // mesh, .vtp text and arrays
constexpr double kBytesPerBandVoxel = 40.0;    // values, OpenVDB leaves, the build's buffers
constexpr double kBytesPerGlyphPoint = 600.0;  // arrays and file, periodic images (x 1.3)
// The tetrahedral mesh before packing: elements per (surface area / element size^2) of the
// inclusions, with the size from the chord error, grown by 0.2 away from the surface (fitted on
// the analyst's sample); the gaps are not known yet (after packing, tet_elements_estimate
// counts them). The peak bytes per element of the whole command, its base and packing aside
// (measured on meshes of spheres and of fibres): the most measured, rounded up, since the check
// refuses what would not fit and should not fall short. Per inclusion, OpenCASCADE's solids and
// their fragments: what the default scene's peak leaves beyond its elements, rounded up. The
// measurements: docs/benchmarks.md.
constexpr double kTetsPerArea = 24.0;
constexpr double kBytesPerMeshedInclusion = 0.3e6;
// Ellipsoids' spline surfaces get more elements than the curvature asks for (measured:
// docs/benchmarks.md).
constexpr double kEllipsoidExtra = 1.5;
constexpr double kBytesPerTet = 900.0;
// Second order: the midside nodes (about 1.2 an element) and their numbers, and the sorted
// edge keys that find them (8 bytes for each of an element's six edges, while they are made).
constexpr double kSecondOrderBytesPerTet = 24.0 + 1.2 * 24.0 + 48.0;

// Triangles of one mean-size inclusion as tessellate() meshes it (MeshOptions defaults:
// segments for an edge of 1/96 of the smallest box size, clamped to [12, 64]), times 1.3 for
// the periodic images that cross the faces.
double triangles(const Family& f, double box_min) {
  auto segments = [&](double length) { return std::clamp(length / (box_min / 96.0), 12.0, 64.0); };
  double n = 0.0;
  switch (f.shape) {
    case ShapeKind::Sphere: {
      const double s = segments(2.0 * M_PI * f.radius.mean());
      n = s * s;
      break;
    }
    case ShapeKind::Ellipsoid: {
      const double a =
          std::max({f.semi_axes[0].mean(), f.semi_axes[1].mean(), f.semi_axes[2].mean()});
      const double s = segments(2.0 * M_PI * a);
      n = s * s;
      break;
    }
    case ShapeKind::Cylinder: {
      const double r = f.radius.mean(), s = segments(2.0 * M_PI * r);
      const FamilyModifiers& m = f.modifiers;
      const double rings = fibre_rings(2.0 * r * f.aspect_ratio.mean(), r,
                                       m.wave_amplitude > 0.0 ? m.wave_length : 0.0, m.bend_radius);
      n = 2.0 * s * rings + 2.0 * s;
      break;
    }
  }
  return 1.3 * n;
}
constexpr double kBaseBytes = 64.0 * 1024 * 1024;  // program, libraries, small buffers

// A shape of the family's mean sizes (centred at the origin, along z).
Shape mean_shape(const Family& f) {
  switch (f.shape) {
    case ShapeKind::Sphere:
      return Shape::sphere(Vec3::Zero(), f.radius.mean());
    case ShapeKind::Cylinder: {
      const double r = f.radius.mean();
      return Shape::cylinder(Vec3::Zero(), r, Vec3(0.0, 0.0, r * f.aspect_ratio.mean()));
    }
    case ShapeKind::Ellipsoid:
      return Shape::ellipsoid(
          Vec3::Zero(), Vec3(f.semi_axes[0].mean(), f.semi_axes[1].mean(), f.semi_axes[2].mean()),
          Mat3::Identity());
  }
  return Shape{};
}

// A shape's surface area (Knud Thomsen's approximation for ellipsoids).
double surface_area(const Shape& s) {
  switch (s.kind) {
    case ShapeKind::Sphere:
      return 4.0 * M_PI * s.radius * s.radius;
    case ShapeKind::Cylinder: {
      const double r = s.radius, l = s.half_axis.norm();
      return 2.0 * M_PI * r * r + 4.0 * M_PI * r * l;
    }
    case ShapeKind::Ellipsoid: {
      const double a = s.semi_axes[0], b = s.semi_axes[1], c = s.semi_axes[2], p = 1.6075;
      return 4.0 * M_PI *
             std::pow((std::pow(a * b, p) + std::pow(a * c, p) + std::pow(b * c, p)) / 3.0,
                      1.0 / p);
    }
  }
  return 0.0;
}

// Surface area of a family's mean-size inclusion (an estimate for the narrow band).
double mean_area(const Family& f) {
  return surface_area(mean_shape(f));
}

// The matrix away from the inclusions, at the largest size (six elements a cube).
double tet_elements_away(const Box& box, double largest) {
  return 6.0 * box.volume() / (largest * largest * largest);
}

}  // namespace

namespace {

double surface_elements(const Shape& s, double chord_error, double largest) {
  auto size2 = [&](double rho) {
    const double h = std::min(rho * std::sqrt(8.0 * chord_error), largest);
    return h * h;
  };
  switch (s.kind) {
    case ShapeKind::Sphere:
    case ShapeKind::Cylinder:
      return kTetsPerArea * surface_area(s) / size2(s.radius);
    case ShapeKind::Ellipsoid:
      break;
  }
  // Ellipsoids: a midpoint rule in their polar angles (the curvature varies over the surface:
  // c^2 / a at the ends of the longest axis).
  const Vec3 a = s.semi_axes;
  constexpr int kTheta = 48, kPhi = 96;
  const double dt = M_PI / kTheta, dp = 2.0 * M_PI / kPhi;
  double sum = 0.0;
  for (int i = 0; i < kTheta; ++i) {
    const double t = (i + 0.5) * dt, st = std::sin(t), ct = std::cos(t);
    for (int j = 0; j < kPhi; ++j) {
      const double p = (j + 0.5) * dp, sp = std::sin(p), cp = std::cos(p);
      const Vec3 x(a[0] * st * cp, a[1] * st * sp, a[2] * ct);
      const Vec3 dx_dt(a[0] * ct * cp, a[1] * ct * sp, -a[2] * st);
      const Vec3 dx_dp(-a[0] * st * sp, a[1] * st * cp, 0.0);
      sum += dx_dt.cross(dx_dp).norm() * dt * dp / size2(ellipsoid_least_curvature_radius(a, x));
    }
  }
  return kTetsPerArea * kEllipsoidExtra * sum;
}

}  // namespace

double tet_elements_near(const Shape& s, double coating, const TetMeshSpec& t, double largest) {
  double n = surface_elements(s, t.chord_error, largest);
  if (coating > 0.0) {
    // The shell: gap_elements across its thickness (six elements a cube), over the core's area.
    const double h = coating / t.gap_elements;
    n += 6.0 * surface_area(s) * coating / (h * h * h);
  }
  return n;
}

double tet_mesh_bytes(double elements, double inclusions, int order) {
  return elements * (kBytesPerTet + (order == 2 ? kSecondOrderBytesPerTet : 0.0)) +
         inclusions * kBytesPerMeshedInclusion;
}

double ResourceEstimate::total_bytes() const {
  return kBaseBytes + packing_bytes +
         std::max(
             {surface_bytes, voxel_bytes + homogenization_bytes, levelset_bytes, tet_mesh_bytes});
}

ResourceEstimate estimate_resources(const Scene& scene) {
  ResourceEstimate e;
  const double vs = scene.levelset_voxel_size > 0.0 ? scene.levelset_voxel_size
                                                    : scene.box.size.minCoeff() / 256.0;
  for (size_t i = 0; i < scene.families.size(); ++i) {
    const Family& f = scene.families[i];
    const double n = scene.expected_count(static_cast<int>(i));
    e.inclusions += n;
    e.packing_bytes += n * kBytesPerInclusion;
    if (f.shape != ShapeKind::Sphere) {
      // Long inclusions are strings of bounding spheres in the packer's broad phase.
      const double pieces =
          f.shape == ShapeKind::Cylinder ? 2.0 * f.aspect_ratio.mean() + 1.0 : 3.0;
      e.packing_bytes += n * pieces * kBytesPerFibrePiece;
    }
    const FamilyModifiers& m = f.modifiers;
    // Meshed: every inclusion with "mesh", otherwise the modified ones (not glyphs).
    const bool exact = m.wave_amplitude == 0.0 && m.bend_radius == 0.0 &&
                       m.deform_amplitude == 0.0 && m.debond_fraction == 0.0;
    const bool meshed = scene.outputs.mesh || !exact;
    if (meshed) e.surface_bytes += n * triangles(f, scene.box.size.minCoeff()) * kBytesPerTriangle;
    // Glyph points (inclusions.vtp): arrays and file, periodic images included.
    if (scene.outputs.inclusions) e.surface_bytes += n * kBytesPerGlyphPoint;
    const double area =
        mean_area(f) *
        (m.wave_amplitude > 0.0 || m.bend_radius > 0.0 || m.deform_amplitude > 0.0 ? 1.5 : 1.0);
    double surfaces = 0.0;
    if (m.wave_amplitude > 0.0 || m.bend_radius > 0.0 || m.deform_amplitude > 0.0) surfaces += 1.0;
    if (m.coating > 0.0 && (!exact || scene.outputs.levelsets_asked)) surfaces += 2.0;
    if (scene.outputs.levelsets)
      e.band_voxels += n * surfaces * area * 2.0 * scene.levelset_half_width / (vs * vs);
    if (scene.outputs.mesh_tet) {
      const TetMeshSpec& t = scene.tet_mesh;
      const double largest = t.largest_size(scene.box);
      e.tetrahedra += n * tet_elements_near(mean_shape(f), m.coating, t, largest);
    }
  }
  if (scene.outputs.mesh_tet) {
    // The matrix away from the inclusions, at the largest size (six elements a cube).
    const TetMeshSpec& t = scene.tet_mesh;
    const double largest = t.largest_size(scene.box);
    e.tetrahedra += tet_elements_away(scene.box, largest);
    e.tet_mesh_bytes = tet_mesh_bytes(e.tetrahedra, e.inclusions, t.order);
  }
  e.voxels = static_cast<double>(scene.resolution[0]) * scene.resolution[1] * scene.resolution[2];
  e.voxel_bytes = e.voxels * (scene.partial_volume ? 9.0 : 5.0) * 1.1;
  e.levelset_bytes = e.band_voxels * kBytesPerBandVoxel;
  // The FFT solver per voxel (its share of the whole process's peak, as measured:
  // docs/benchmarks.md): the buffers of one field's
  // transforms (the flux formed and transformed in them), conjugate gradients' residual and s = A p
  // in Fourier space (a strain's displacement, three complex values a frequency; a gradient's
  // potential, one), 1 / |k|, the medium's index and the composite voxels' tensors; the fixed-point
  // scheme keeps five 3-component fields; with the local fields, the direction and the unknown in
  // Fourier space, the unknown as doubles and the fields as floats for every load case
  // (conductivity: 8 + 8 + 24 + 3 x 2 x 3 x 4, elasticity: 24 + 24 + 48 + 6 x 2 x 6 x 4).
  const HomogenizationSpec& h = scene.homogenization;
  double solver = 0.0, fields = 0.0;
  if (h.conductivity) solver = h.solver == "fixed_point" ? 180.0 : 68.0;
  if (h.conductivity && h.fields) fields += 40.0 + 72.0;
  if (h.elasticity) solver = 135.0, fields += h.fields ? 96.0 + 288.0 : 0.0;
  e.homogenization_bytes = e.voxels * (1.15 * solver + fields);
  return e;
}

double peak_memory_mb() {
  struct rusage ru {};
  if (getrusage(RUSAGE_SELF, &ru) != 0) return 0.0;
  return ru.ru_maxrss / 1024.0;  // kilobytes on Linux
}

double available_memory_bytes() {
  double avail = 0.0;
  std::ifstream mi("/proc/meminfo");
  std::string key;
  double kb = 0.0;
  std::string unit;
  while (mi >> key >> kb >> unit) {
    if (key == "MemAvailable:") {
      avail = kb * 1024.0;
      break;
    }
  }
  // cgroup v2 limit of this process's group.
  std::ifstream maxf("/sys/fs/cgroup/memory.max"), curf("/sys/fs/cgroup/memory.current");
  std::string max_text;
  double cur = 0.0;
  if (maxf >> max_text && max_text != "max" && curf >> cur) {
    const double left = std::stod(max_text) - cur;
    if (left > 0.0 && (avail == 0.0 || left < avail)) avail = left;
  }
  // An address-space limit (ulimit -v) of this process, less what it maps already.
  struct rlimit as {};
  if (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
    double mapped = 0.0;
    std::ifstream statm("/proc/self/statm");
    if (statm >> mapped) mapped *= static_cast<double>(::sysconf(_SC_PAGESIZE));
    const double left = static_cast<double>(as.rlim_cur) - mapped;
    if (avail == 0.0 || left < avail) avail = std::max(left, 1.0);
  }
  return avail;
}

std::vector<TetMeshSpec> coarser_tet_meshes(const TetMeshSpec& spec) {
  std::vector<TetMeshSpec> out;
  // across: elements across the gaps, with 10-node elements (0: the spec's).
  auto offer = [&](double chord, double across) {
    TetMeshSpec t = spec;
    t.chord_error = std::max(spec.chord_error, chord);
    if (across > 0.0) {
      t.gap_elements = std::min(spec.gap_elements, across);
      t.order = 2;
    }
    if (t == spec) return;
    for (const TetMeshSpec& o : out) {
      if (o == t) return;
    }
    out.push_back(t);
  };
  offer(0.01, 0.0);
  offer(0.03, 0.0);
  offer(0.03, 1.0);
  offer(0.1, 0.0);
  offer(0.1, 1.0);
  offer(0.1, 0.5);
  return out;
}

std::string describe_tet_mesh_change(const TetMeshSpec& from, const TetMeshSpec& to,
                                     SettingNames names) {
  const bool scene = names == SettingNames::kScene;
  std::string keys;
  char buf[64];
  auto add = [&](const char* key, const char* property, double value) {
    std::snprintf(buf, sizeof buf, scene ? "%s\"%s\": %.10g" : "%s%s %.10g",
                  keys.empty() ? "" : ", ", scene ? key : property, value);
    keys += buf;
  };
  if (to.chord_error != from.chord_error) add("chord_error", "ChordError", to.chord_error);
  if (to.gap_elements != from.gap_elements) add("gap_elements", "GapElements", to.gap_elements);
  if (to.order != from.order) add("order", "Order", to.order);
  if (to.max_size != from.max_size) add("max_size", "MaxSize", to.max_size);
  if (to.min_size != from.min_size) add("min_size", "MinSize", to.min_size);
  return scene ? "\"mesh_tet\": {" + keys + "}" : keys;
}

std::string format_bytes(double bytes) {
  char buf[64];
  if (bytes >= 1e9) {
    std::snprintf(buf, sizeof buf, "%.1f GB", bytes / 1e9);
  } else {
    std::snprintf(buf, sizeof buf, "%.0f MB", std::ceil(bytes / 1e6));
  }
  return buf;
}

std::string describe(const ResourceEstimate& e) {
  return format_bytes(e.total_bytes()) + " (" +
         std::to_string(static_cast<long long>(e.inclusions)) +
         " inclusions: " + format_bytes(e.packing_bytes) + "; surfaces " +
         format_bytes(e.surface_bytes) + "; voxels " + format_bytes(e.voxel_bytes) +
         (e.homogenization_bytes > 0.0 ? "; FFT solver " + format_bytes(e.homogenization_bytes)
                                       : std::string()) +
         "; level sets " + format_bytes(e.levelset_bytes) +
         (e.tet_mesh_bytes > 0.0 ? "; tetrahedral mesh of about " +
                                       std::to_string(static_cast<long long>(e.tetrahedra)) +
                                       " elements " + format_bytes(e.tet_mesh_bytes)
                                 : std::string()) +
         ")";
}

}  // namespace rvegen
