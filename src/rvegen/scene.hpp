// Scene description: what `rvegen generate` reads (JSON) and what the VTK source builds from
// its properties. Validation happens here, before any work or output.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "rvegen/inclusion_set.hpp"

namespace rvegen {

struct OrientationLaw {
  enum class Kind { kIsotropic, kAligned };
  Kind kind = Kind::kIsotropic;
  Vec3 axis = Vec3::UnitZ();  // unit, for kAligned
};

struct Family {
  std::string name;
  ShapeKind shape = ShapeKind::Sphere;
  double radius = 0.0;        // sphere, cylinder
  double aspect_ratio = 0.0;  // cylinder: a = |l| / r
  Vec3 semi_axes = Vec3::Zero();
  double volume_fraction = -1.0;  // < 0 when `count` is given
  int count = -1;                 // < 0 when `volume_fraction` is given
  OrientationLaw orientation;

  /// The shape of one inclusion of this family at the origin with its reference orientation.
  double inclusion_volume() const;
  double bounding_radius() const;
  /// Smallest width of the shape (the least box size it can pass through).
  double min_width() const;
};

struct Scene {
  Box box;
  uint64_t seed = 42;
  std::string method = "rsa";
  double min_gap = 0.0;
  std::vector<Family> families;
  std::array<int, 3> resolution = {64, 64, 64};
  /// RSA: attempts per inclusion before the target is declared out of reach.
  int rsa_max_attempts = 20000;

  /// Number of inclusions of family f (from count, or volume fraction and inclusion volume).
  int target_count(int f) const;
};

/// Parses and validates a scene (see README for the schema). Throws InputError naming the key.
Scene parse_scene(const std::string& json_text);
/// Checks cross-field constraints (also run by parse_scene); throws InputError.
void validate_scene(const Scene& scene);
/// The built-in default scene.
Scene default_scene();
/// JSON text of a scene (what parse_scene reads).
std::string scene_to_json(const Scene& scene);

/// Upper bound on the volume fraction that the scene's shapes can fill: the densest known
/// packing of the best-packing shape among the families: spheres pi/(3 sqrt 2) = 0.7405
/// (Kepler), ellipsoids 0.7707 (Donev et al. 2004), cylinders pi/(2 sqrt 3) = 0.9069 (aligned,
/// hexagonal). A target above it is rejected as invalid input before any work.
double max_packable_fraction(const Scene& scene);

}  // namespace rvegen
