#include "rvegen/io/inclusions_json.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "rvegen/io/json_util.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/deformed_support.hpp"

namespace rvegen {

namespace {

// What a written inclusion list may carry of rounding: lengths and weights compared with the
// bounds they meet to kWrittenRounding (relative), unit vectors of norm 1 to kUnitRounding, and
// rotation matrices orthonormal to kRotationTolerance (lists written by other tools round more).
constexpr double kWrittenRounding = 1e-9, kUnitRounding = 1e-12, kRotationTolerance = 1e-6;
// Inclusions smaller than this share of the box are refused (the message says so).
constexpr double kMinRelativeSize = 1e-9;
Modifiers read_modifiers(const json_util::Json& j, const Shape& shape, const std::string& p) {
  using namespace json_util;
  only_keys(j,
            {"coating", "shells_may_touch", "wave_amplitude", "wave_length", "wave_phase",
             "wave_angle", "bend_radius", "bend_angle", "deform_amplitude", "deform_scale",
             "deform_waves", "debond_fraction", "debond_gap", "debond_axis", "packing_pad"},
            p);
  Modifiers m;
  auto num = [&](const char* key, double* out) {
    if (j.contains(key)) *out = number(j[key], join(p, key));
  };
  num("coating", &m.coating);
  if (m.coating < 0.0) fail(p + ".coating", "must be >= 0");
  if (j.contains("shells_may_touch"))
    m.shells_may_touch = boolean(j["shells_may_touch"], p + ".shells_may_touch");
  if (j.contains("wave_amplitude")) {
    if (shape.kind != ShapeKind::Cylinder) fail(p + ".wave_amplitude", "cylinders only");
    m.wave_amplitude = positive(j["wave_amplitude"], p + ".wave_amplitude");
    m.wave_length = positive(require(j, "wave_length", p), p + ".wave_length");
    num("wave_phase", &m.wave_phase);
    num("wave_angle", &m.wave_angle);
  }
  if (j.contains("bend_radius")) {
    if (shape.kind != ShapeKind::Cylinder) fail(p + ".bend_radius", "cylinders only");
    m.bend_radius = positive(j["bend_radius"], p + ".bend_radius");
    // As in scenes: at least the fibre's length with its coating (the arc turns by at most
    // about a radian, and the chain's pieces stay few).
    if (!(m.bend_radius >= 2.0 * (shape.half_axis.norm() + m.coating) * (1.0 - kWrittenRounding)))
      fail(p + ".bend_radius", "must be at least the fibre's length with its coating");
    num("bend_angle", &m.bend_angle);
  }
  if (j.contains("deform_amplitude")) {
    if (shape.kind == ShapeKind::Cylinder)
      fail(p + ".deform_amplitude", "spheres and ellipsoids only");
    m.deform_amplitude = positive(j["deform_amplitude"], p + ".deform_amplitude");
    if (m.deform_amplitude > 0.5) fail(p + ".deform_amplitude", "must be in (0, 0.5]");
    m.deform_scale = positive(require(j, "deform_scale", p), p + ".deform_scale");
    const Json& waves = require(j, "deform_waves", p);
    if (!waves.is_array()) fail(p + ".deform_waves", "expected an array");
    double sum = 0.0;
    for (size_t k = 0; k < waves.size(); ++k) {
      const std::string q = p + ".deform_waves[" + std::to_string(k) + "]";
      DeformationWave w;
      w.direction = vec3(require(waves[k], "direction", q), q + ".direction");
      // Unit vectors written by rvegen read back bit for bit; others are normalised.
      if (!(std::abs(w.direction.norm() - 1.0) <= kUnitRounding))
        w.direction = unit_vector(require(waves[k], "direction", q), q + ".direction");
      w.weight = positive(require(waves[k], "weight", q), q + ".weight");
      w.wavenumber = positive(require(waves[k], "wavenumber", q), q + ".wavenumber");
      w.phase = number(require(waves[k], "phase", q), q + ".phase");
      sum += w.weight;
      m.deform_waves.push_back(w);
    }
    if (sum > 1.0 + kWrittenRounding) fail(p + ".deform_waves", "weights must sum to at most 1");
    m.deform_peak = deformation_peak(m);
  }
  if (j.contains("packing_pad")) {
    m.packing_pad = number(j["packing_pad"], p + ".packing_pad");
    if (m.packing_pad < 0.0) fail(p + ".packing_pad", "must be >= 0");
  }
  if (j.contains("debond_gap")) {
    if (shape.kind != ShapeKind::Sphere) fail(p + ".debond_gap", "spheres only");
    m.debond_gap = positive(j["debond_gap"], p + ".debond_gap");
    m.debond_fraction = positive(require(j, "debond_fraction", p), p + ".debond_fraction");
    if (m.debond_fraction > 1.0) fail(p + ".debond_fraction", "must be in (0, 1]");
    const Vec3 a = vec3(require(j, "debond_axis", p), p + ".debond_axis");
    m.debond_axis = std::abs(a.norm() - 1.0) <= kUnitRounding
                        ? a
                        : unit_vector(require(j, "debond_axis", p), p + ".debond_axis");
  }
  return m;
}
}  // namespace

InclusionSet read_inclusions_json(const std::string& text) {
  using namespace json_util;
  const Json root = parse(text, "inclusion file");
  if (!root.is_object()) fail("(root)", "expected an object");
  if (root.contains("families") && !root.contains("inclusions")) {
    fail("(root)",
         "this is a scene (it has \"families\"), not an inclusion list: rvegen generate reads "
         "scenes, and writes the inclusions.json that rvegen check reads");
  }
  only_keys(root, {"format", "box", "family_names", "inclusions"}, "");
  const std::string fmt = string(require(root, "format", ""), "format");
  if (fmt != "rvegen.inclusions/1")
    fail("format", "expected \"rvegen.inclusions/1\", got \"" + fmt + "\"");
  InclusionSet set;
  set.box = box(require(root, "box", ""), "box");
  const Json& list = require(root, "inclusions", "");
  if (!list.is_array()) fail("inclusions", "expected an array");
  for (size_t n = 0; n < list.size(); ++n) {
    const std::string p = "inclusions[" + std::to_string(n) + "]";
    const Json& e = list[n];
    if (!e.is_object()) fail(p, "expected an object");
    only_keys(e,
              {"id", "family", "shape", "center", "radius", "half_axis", "semi_axes", "rotation",
               "through", "modifiers"},
              p);
    Inclusion inc;
    const double id = number(require(e, "id", p), p + ".id");
    if (id != std::floor(id) || id < 0 || id > 2147483647.0)
      fail(p + ".id", "must be an integer in [0, 2147483647]");
    inc.id = static_cast<int>(id);
    if (e.contains("family")) {
      const double fam = number(e["family"], p + ".family");
      if (fam != std::floor(fam) || fam < 0 || fam > 65535)
        fail(p + ".family", "must be an integer in [0, 65535]");
      inc.family = static_cast<int>(fam);
    }
    const std::string shape = string(require(e, "shape", p), p + ".shape");
    ShapeKind kind;
    if (!parse_shape_name(shape, &kind)) fail(p + ".shape", "unknown shape \"" + shape + "\"");
    const Vec3 c = vec3(require(e, "center", p), p + ".center");
    switch (kind) {
      case ShapeKind::Sphere:
        inc.shape = Shape::sphere(c, positive(require(e, "radius", p), p + ".radius"));
        break;
      case ShapeKind::Cylinder: {
        const double r = positive(require(e, "radius", p), p + ".radius");
        const Vec3 l = vec3(require(e, "half_axis", p), p + ".half_axis");
        if (!(l.norm() > 0.0)) fail(p + ".half_axis", "must be non-zero");
        inc.shape = Shape::cylinder(c, r, l);
        break;
      }
      case ShapeKind::Ellipsoid: {
        const Vec3 s = vec3(require(e, "semi_axes", p), p + ".semi_axes");
        for (int k = 0; k < 3; ++k) {
          if (!(s[k] > 0.0)) fail(p + ".semi_axes[" + std::to_string(k) + "]", "must be positive");
        }
        const Json& rj = require(e, "rotation", p);
        if (!rj.is_array() || rj.size() != 3) fail(p + ".rotation", "expected 3 rows of 3 numbers");
        Mat3 R;
        for (int r = 0; r < 3; ++r)
          R.row(r) = vec3(rj[r], p + ".rotation[" + std::to_string(r) + "]");
        if ((R.transpose() * R - Mat3::Identity()).norm() > kRotationTolerance ||
            R.determinant() < 0.0) {
          fail(p + ".rotation", "must be a proper rotation matrix (orthonormal, determinant +1)");
        }
        inc.shape = Shape::ellipsoid(c, s, R);
        break;
      }
    }
    if (e.contains("modifiers"))
      inc.mod = read_modifiers(e["modifiers"], inc.shape, p + ".modifiers");
    if (e.contains("through")) {
      // A continuous fibre: along a box axis, exactly as long as the periodic box along it.
      if (kind != ShapeKind::Cylinder) fail(p + ".through", "cylinders only");
      inc.mod.through = boolean(e["through"], p + ".through");
      if (inc.mod.through) {
        const Vec3& l = inc.shape.half_axis;
        int k = 0;
        l.cwiseAbs().maxCoeff(&k);
        if (!set.box.periodic) fail(p + ".through", "a continuous fibre needs a periodic box");
        if (l[(k + 1) % 3] != 0.0 || l[(k + 2) % 3] != 0.0 ||
            std::abs(2.0 * std::abs(l[k]) - set.box.size[k]) > kWrittenRounding * set.box.size[k]) {
          fail(p + ".half_axis",
               "a continuous fibre (\"through\": true) runs along a box axis and is as long as "
               "the box along it");
        }
      }
    }
    // Sizes and places the audit can serve: the number of periodic images it visits grows as
    // (bounding diameter / box)^3, and coordinates must keep their precision.
    const Box& b = set.box;
    const double reach = envelope(inc).bounding_radius(), small = inc.shape.min_size();
    // A continuous fibre meets no image of its own along its axis: its section is what must
    // fit across the other two.
    double across = b.size.minCoeff(), section = reach;
    if (inc.mod.through) {
      int k = 0;
      inc.shape.half_axis.cwiseAbs().maxCoeff(&k);
      across = std::min(b.size[(k + 1) % 3], b.size[(k + 2) % 3]);
      section = inc.shape.radius + inc.mod.coating;
    }
    if (b.periodic && section > 2.0 * across) {
      fail(p, "larger than twice the periodic box (bounding radius " + std::to_string(reach) +
                  "); such an inclusion overlaps its own images");
    }
    if (!b.periodic && reach > 1000.0 * b.size.maxCoeff()) {
      fail(p, "larger than 1000 box sizes (bounding radius " + std::to_string(reach) + ")");
    }
    if (small < kMinRelativeSize * b.size.maxCoeff()) fail(p, "smaller than 1e-9 of the box");
    for (int k = 0; k < 3; ++k) {
      if (std::abs(c[k] - b.origin[k]) > 1000.0 * b.size[k])
        fail(p + ".center", "more than 1000 box sizes away from the box");
    }
    set.inclusions.push_back(inc);
  }
  {
    std::vector<int> ids;
    ids.reserve(set.inclusions.size());
    for (const auto& inc : set.inclusions) ids.push_back(inc.id);
    std::sort(ids.begin(), ids.end());
    const auto dup = std::adjacent_find(ids.begin(), ids.end());
    if (dup != ids.end()) fail("inclusions", "id " + std::to_string(*dup) + " appears twice");
  }
  if (root.contains("family_names")) {
    const Json& names = root["family_names"];
    if (!names.is_array()) fail("family_names", "expected an array of strings");
    for (size_t k = 0; k < names.size(); ++k)
      set.family_names.push_back(string(names[k], "family_names[" + std::to_string(k) + "]"));
  }
  return set;
}

std::string write_inclusions_json(const InclusionSet& set) {
  using OJson = nlohmann::ordered_json;
  auto v3 = [](const Vec3& v) { return OJson::array({v[0], v[1], v[2]}); };
  OJson root;
  root["format"] = "rvegen.inclusions/1";
  root["box"] = {
      {"origin", v3(set.box.origin)}, {"size", v3(set.box.size)}, {"periodic", set.box.periodic}};
  OJson list = OJson::array();
  for (const auto& inc : set.inclusions) {
    OJson e;
    e["id"] = inc.id;
    e["family"] = inc.family;
    e["shape"] = shape_name(inc.shape.kind);
    e["center"] = v3(inc.shape.center);
    switch (inc.shape.kind) {
      case ShapeKind::Sphere:
        e["radius"] = inc.shape.radius;
        break;
      case ShapeKind::Cylinder:
        e["radius"] = inc.shape.radius;
        e["half_axis"] = v3(inc.shape.half_axis);
        if (inc.mod.through) e["through"] = true;
        break;
      case ShapeKind::Ellipsoid: {
        e["semi_axes"] = v3(inc.shape.semi_axes);
        OJson rows = OJson::array();
        for (int r = 0; r < 3; ++r) rows.push_back(v3(inc.shape.rotation.row(r).transpose()));
        e["rotation"] = rows;
        break;
      }
    }
    const Modifiers& m = inc.mod;
    if (m.any() || m.packing_pad > 0.0) {
      OJson mj;
      if (m.coated()) {
        mj["coating"] = m.coating;
        mj["shells_may_touch"] = m.shells_may_touch;
      }
      if (m.wavy()) {
        mj["wave_amplitude"] = m.wave_amplitude;
        mj["wave_length"] = m.wave_length;
        mj["wave_phase"] = m.wave_phase;
        mj["wave_angle"] = m.wave_angle;
      }
      if (m.bent()) {
        mj["bend_radius"] = m.bend_radius;
        mj["bend_angle"] = m.bend_angle;
      }
      if (m.deformed()) {
        mj["deform_amplitude"] = m.deform_amplitude;
        mj["deform_scale"] = m.deform_scale;
        OJson waves = OJson::array();
        for (const auto& w : m.deform_waves) {
          waves.push_back({{"direction", v3(w.direction)},
                           {"weight", w.weight},
                           {"wavenumber", w.wavenumber},
                           {"phase", w.phase}});
        }
        mj["deform_waves"] = waves;
      }
      if (m.debonded()) {
        mj["debond_fraction"] = m.debond_fraction;
        mj["debond_gap"] = m.debond_gap;
        mj["debond_axis"] = v3(m.debond_axis);
      }
      if (m.packing_pad > 0.0) mj["packing_pad"] = m.packing_pad;
      e["modifiers"] = mj;
    }
    list.push_back(e);
  }
  if (!set.family_names.empty()) root["family_names"] = set.family_names;
  root["inclusions"] = list;
  return root.dump(1) + "\n";
}

}  // namespace rvegen
