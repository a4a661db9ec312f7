#include "rvegen/scene.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "rvegen/json_util.hpp"

namespace rvegen {

double Family::inclusion_volume() const {
  switch (shape) {
    case ShapeKind::Sphere:
      return 4.0 / 3.0 * M_PI * std::pow(radius, 3);
    case ShapeKind::Cylinder:
      return M_PI * radius * radius * 2.0 * aspect_ratio * radius;
    case ShapeKind::Ellipsoid:
      return 4.0 / 3.0 * M_PI * semi_axes.prod();
  }
  return 0.0;
}

double Family::bounding_radius() const {
  switch (shape) {
    case ShapeKind::Sphere:
      return radius;
    case ShapeKind::Cylinder:
      return radius * std::sqrt(1.0 + aspect_ratio * aspect_ratio);
    case ShapeKind::Ellipsoid:
      return semi_axes.maxCoeff();
  }
  return 0.0;
}

double Family::min_width() const {
  switch (shape) {
    case ShapeKind::Sphere:
      return 2.0 * radius;
    case ShapeKind::Cylinder:
      return 2.0 * radius * std::min(1.0, aspect_ratio);
    case ShapeKind::Ellipsoid:
      return 2.0 * semi_axes.minCoeff();
  }
  return 0.0;
}

int Scene::target_count(int f) const {
  const Family& fam = families[f];
  if (fam.count >= 0) return fam.count;
  return static_cast<int>(std::lround(fam.volume_fraction * box.volume() / fam.inclusion_volume()));
}

double max_packable_fraction(const Scene& scene) {
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
using json_util::Json;

OrientationLaw parse_orientation(const Json& j, const std::string& p) {
  using namespace json_util;
  OrientationLaw law;
  const std::string name = string(require(j, "law", p), p + ".law");
  if (name == "isotropic") {
    only_keys(j, {"law"}, p);
    law.kind = OrientationLaw::Kind::kIsotropic;
  } else if (name == "aligned") {
    only_keys(j, {"law", "axis"}, p);
    law.kind = OrientationLaw::Kind::kAligned;
    law.axis = vec3(require(j, "axis", p), p + ".axis");
    if (!(law.axis.norm() > 0.0)) fail(p + ".axis", "must be non-zero");
    law.axis.normalize();
  } else {
    fail(p + ".law", "unknown orientation law \"" + name + "\" (isotropic, aligned)");
  }
  return law;
}

Family parse_family(const Json& j, const std::string& p) {
  using namespace json_util;
  Family f;
  if (!j.is_object()) fail(p, "expected an object");
  const std::string shape = string(require(j, "shape", p), p + ".shape");
  if (!parse_shape_name(shape, &f.shape)) {
    fail(p + ".shape", "unknown shape \"" + shape + "\" (sphere, cylinder, ellipsoid)");
  }
  switch (f.shape) {
    case ShapeKind::Sphere:
      only_keys(j, {"name", "shape", "radius", "volume_fraction", "count"}, p);
      f.radius = positive(require(j, "radius", p), p + ".radius");
      break;
    case ShapeKind::Cylinder:
      only_keys(
          j, {"name", "shape", "radius", "aspect_ratio", "volume_fraction", "count", "orientation"},
          p);
      f.radius = positive(require(j, "radius", p), p + ".radius");
      f.aspect_ratio = positive(require(j, "aspect_ratio", p), p + ".aspect_ratio");
      break;
    case ShapeKind::Ellipsoid: {
      only_keys(j, {"name", "shape", "semi_axes", "volume_fraction", "count", "orientation"}, p);
      f.semi_axes = vec3(require(j, "semi_axes", p), p + ".semi_axes");
      for (int k = 0; k < 3; ++k) {
        if (!(f.semi_axes[k] > 0.0)) {
          fail(p + ".semi_axes[" + std::to_string(k) + "]", "must be positive");
        }
      }
      break;
    }
  }
  f.name = j.contains("name") ? string(j["name"], p + ".name") : std::string(shape_name(f.shape));
  if (j.contains("orientation"))
    f.orientation = parse_orientation(j["orientation"], p + ".orientation");
  const bool has_vf = j.contains("volume_fraction"), has_n = j.contains("count");
  if (has_vf == has_n) fail(p, "give exactly one of \"volume_fraction\" and \"count\"");
  if (has_vf) {
    f.volume_fraction = positive(j["volume_fraction"], p + ".volume_fraction");
    if (f.volume_fraction >= 1.0) fail(p + ".volume_fraction", "must be below 1");
  } else {
    const double n = number(j["count"], p + ".count");
    if (n != std::floor(n) || n < 0 || n > 1e8)
      fail(p + ".count", "must be an integer in [0, 1e8]");
    f.count = static_cast<int>(n);
  }
  return f;
}
}  // namespace

void validate_scene(const Scene& s) {
  using json_util::fail;
  if (s.families.empty()) fail("families", "at least one family is needed");
  if (!(s.min_gap >= 0.0) || !std::isfinite(s.min_gap)) fail("min_gap", "must be >= 0");
  if (s.method != "rsa") fail("method", "unknown method \"" + s.method + "\" (rsa)");
  for (int k = 0; k < 3; ++k) {
    if (s.resolution[k] < 1 || s.resolution[k] > 4096) {
      fail("voxels.resolution[" + std::to_string(k) + "]", "must be an integer in [1, 4096]");
    }
    if (!(s.box.size[k] > 0.0) || !std::isfinite(s.box.size[k])) {
      fail("box.size[" + std::to_string(k) + "]", "must be positive");
    }
  }
  const double box_min = s.box.size.minCoeff();
  double total = 0.0;
  for (size_t i = 0; i < s.families.size(); ++i) {
    const Family& f = s.families[i];
    const std::string p = "families[" + std::to_string(i) + "]";
    if (f.min_width() + 2.0 * s.min_gap >= box_min) {
      fail(p, "inclusion does not fit in the box (smallest width " + std::to_string(f.min_width()) +
                  " >= smallest box size " + std::to_string(box_min) + ")");
    }
    if (f.volume_fraction >= 0.0 && s.target_count(static_cast<int>(i)) < 1) {
      fail(p + ".volume_fraction", "too small for a single inclusion in this box");
    }
    total += s.target_count(static_cast<int>(i)) * f.inclusion_volume() / s.box.volume();
  }
  const double limit = max_packable_fraction(s);
  if (total > limit) {
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "total volume fraction %.4f exceeds %.4f, the densest packing these shapes allow",
                  total, limit);
    fail("families", buf);
  }
}

Scene parse_scene(const std::string& text) {
  using namespace json_util;
  const Json root = parse(text, "scene file");
  if (!root.is_object()) fail("(root)", "expected an object");
  only_keys(root, {"box", "seed", "method", "min_gap", "families", "voxels"}, "");
  Scene s;
  s.box = box(require(root, "box", ""), "box");
  if (root.contains("seed")) {
    const double seed = number(root["seed"], "seed");
    if (seed < 0 || seed != std::floor(seed) || seed > 9007199254740992.0) {
      fail("seed", "must be a non-negative integer");
    }
    s.seed = static_cast<uint64_t>(seed);
  }
  if (root.contains("method")) s.method = string(root["method"], "method");
  if (root.contains("min_gap")) {
    s.min_gap = number(root["min_gap"], "min_gap");
    if (s.min_gap < 0.0) fail("min_gap", "must be >= 0");
  }
  const Json& fams = require(root, "families", "");
  if (!fams.is_array()) fail("families", "expected an array");
  for (size_t i = 0; i < fams.size(); ++i) {
    s.families.push_back(parse_family(fams[i], "families[" + std::to_string(i) + "]"));
  }
  if (root.contains("voxels")) {
    const Json& v = root["voxels"];
    only_keys(v, {"resolution"}, "voxels");
    const Json& r = require(v, "resolution", "voxels");
    if (r.is_number()) {
      const double n = number(r, "voxels.resolution");
      if (n != std::floor(n)) fail("voxels.resolution", "must be an integer");
      s.resolution = {static_cast<int>(n), static_cast<int>(n), static_cast<int>(n)};
    } else {
      const Vec3 n = vec3(r, "voxels.resolution");
      for (int k = 0; k < 3; ++k) {
        if (n[k] != std::floor(n[k]) || n[k] < 1 || n[k] > 4096) {
          fail("voxels.resolution[" + std::to_string(k) + "]", "must be an integer in [1, 4096]");
        }
        s.resolution[k] = static_cast<int>(n[k]);
      }
    }
  }
  validate_scene(s);
  return s;
}

Scene default_scene() {
  Scene s;
  s.box.size = Vec3(1, 1, 1);
  s.box.periodic = true;
  s.seed = 42;
  s.method = "rsa";
  Family spheres;
  spheres.name = "spheres";
  spheres.shape = ShapeKind::Sphere;
  spheres.radius = 0.05;
  spheres.volume_fraction = 0.15;
  Family fibres;
  fibres.name = "fibres";
  fibres.shape = ShapeKind::Cylinder;
  fibres.radius = 0.02;
  fibres.aspect_ratio = 5.0;
  fibres.volume_fraction = 0.08;
  Family grains;
  grains.name = "grains";
  grains.shape = ShapeKind::Ellipsoid;
  grains.semi_axes = Vec3(0.06, 0.04, 0.03);
  grains.volume_fraction = 0.05;
  s.families = {spheres, fibres, grains};
  s.resolution = {64, 64, 64};
  return s;
}

std::string scene_to_json(const Scene& s) {
  using OJson = nlohmann::ordered_json;
  auto v3 = [](const Vec3& v) { return OJson::array({v[0], v[1], v[2]}); };
  OJson root;
  root["box"] = {
      {"origin", v3(s.box.origin)}, {"size", v3(s.box.size)}, {"periodic", s.box.periodic}};
  root["seed"] = s.seed;
  root["method"] = s.method;
  root["min_gap"] = s.min_gap;
  OJson fams = OJson::array();
  for (const auto& f : s.families) {
    OJson j;
    j["name"] = f.name;
    j["shape"] = shape_name(f.shape);
    if (f.shape == ShapeKind::Ellipsoid) {
      j["semi_axes"] = v3(f.semi_axes);
    } else {
      j["radius"] = f.radius;
    }
    if (f.shape == ShapeKind::Cylinder) j["aspect_ratio"] = f.aspect_ratio;
    if (f.count >= 0) {
      j["count"] = f.count;
    } else {
      j["volume_fraction"] = f.volume_fraction;
    }
    if (f.shape != ShapeKind::Sphere) {
      if (f.orientation.kind == OrientationLaw::Kind::kAligned) {
        j["orientation"] = {{"law", "aligned"}, {"axis", v3(f.orientation.axis)}};
      } else {
        j["orientation"] = {{"law", "isotropic"}};
      }
    }
    fams.push_back(j);
  }
  root["families"] = fams;
  root["voxels"] = {{"resolution", {s.resolution[0], s.resolution[1], s.resolution[2]}}};
  return root.dump(2) + "\n";
}

}  // namespace rvegen
