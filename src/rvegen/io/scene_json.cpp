#include "rvegen/io/scene_json.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "rvegen/io/json_util.hpp"

namespace rvegen {

namespace {
using json_util::Json;

OrientationLaw parse_orientation(const Json& j, const std::string& p) {
  using namespace json_util;
  OrientationLaw law;
  const std::string name = string(require(j, "law", p), p + ".law");
  auto unit = [&](const char* key) { return unit_vector(require(j, key, p), join(p, key)); };
  if (name == "isotropic") {
    only_keys(j, {"law"}, p);
    law.kind = OrientationLaw::Kind::kIsotropic;
  } else if (name == "aligned") {
    only_keys(j, {"law", "axis"}, p);
    law.kind = OrientationLaw::Kind::kAligned;
    law.axis = unit("axis");
  } else if (name == "von_mises_fisher") {
    only_keys(j, {"law", "axis", "kappa"}, p);
    law.kind = OrientationLaw::Kind::kVonMisesFisher;
    law.axis = unit("axis");
    law.kappa = number(require(j, "kappa", p), p + ".kappa");
  } else if (name == "planar") {
    only_keys(j, {"law", "normal"}, p);
    law.kind = OrientationLaw::Kind::kPlanar;
    law.axis = unit("normal");
  } else if (name == "tensor") {
    only_keys(j, {"law", "a2"}, p);
    law.kind = OrientationLaw::Kind::kTensor;
    const std::string q = p + ".a2";
    const Json& a = require(j, "a2", p);
    if (!a.is_array() || a.size() != 3) fail(q, "expected a 3 x 3 array [[a11,a12,a13],...]");
    for (int r = 0; r < 3; ++r) {
      const std::string qr = q + "[" + std::to_string(r) + "]";
      if (!a[r].is_array() || a[r].size() != 3) fail(qr, "expected a row of 3 numbers");
      for (int c = 0; c < 3; ++c) {
        law.a2(r, c) = number(a[r][c], qr + "[" + std::to_string(c) + "]");
      }
    }
    law.a2 = OrientationLaw::as_typed(law.a2);
  } else {
    fail(p + ".law", "unknown orientation law \"" + name +
                         "\" (isotropic, aligned, von_mises_fisher, planar, tensor)");
  }
  return law;
}

SizeLaw parse_size(const Json& j, const std::string& p) {
  using namespace json_util;
  SizeLaw law;
  if (j.is_number()) {
    law.p1 = positive(j, p);
    return law;
  }
  if (!j.is_object()) fail(p, "expected a positive number or a size law object");
  const std::string name = string(require(j, "law", p), p + ".law");
  if (name == "uniform") {
    only_keys(j, {"law", "min", "max"}, p);
    law.kind = SizeLaw::Kind::kUniform;
    law.p1 = positive(require(j, "min", p), p + ".min");
    law.p2 = positive(require(j, "max", p), p + ".max");
  } else if (name == "normal" || name == "lognormal") {
    only_keys(j, {"law", "mean", "std"}, p);
    law.kind = name == "normal" ? SizeLaw::Kind::kNormal : SizeLaw::Kind::kLognormal;
    law.p1 = positive(require(j, "mean", p), p + ".mean");
    law.p2 = number(require(j, "std", p), p + ".std");
  } else if (name == "weibull") {
    only_keys(j, {"law", "shape", "scale"}, p);
    law.kind = SizeLaw::Kind::kWeibull;
    law.p1 = positive(require(j, "shape", p), p + ".shape");
    law.p2 = positive(require(j, "scale", p), p + ".scale");
  } else {
    fail(p + ".law", "unknown size law \"" + name + "\" (uniform, normal, lognormal, weibull)");
  }
  return law;
}

// Reads the modifier keys; which shapes take them, ranges and combinations are checked by
// validate_scene (which also sees the scenes built in code, such as the ParaView source's).
FamilyModifiers parse_modifiers(const Json& j, const std::string& p) {
  using namespace json_util;
  FamilyModifiers m;
  if (j.contains("coating")) {
    const std::string q = p + ".coating";
    const Json& c = j["coating"];
    only_keys(c, {"thickness", "shells_may_touch"}, q);
    m.coating = positive(require(c, "thickness", q), q + ".thickness");
    if (c.contains("shells_may_touch"))
      m.shells_may_touch = boolean(c["shells_may_touch"], q + ".shells_may_touch");
  }
  if (j.contains("waviness")) {
    const std::string q = p + ".waviness";
    const Json& w = j["waviness"];
    only_keys(w, {"amplitude", "wavelength"}, q);
    m.wave_amplitude = positive(require(w, "amplitude", q), q + ".amplitude");
    m.wave_length = positive(require(w, "wavelength", q), q + ".wavelength");
  }
  if (j.contains("curvature")) {
    const std::string q = p + ".curvature";
    const Json& c = j["curvature"];
    only_keys(c, {"radius"}, q);
    m.bend_radius = positive(require(c, "radius", q), q + ".radius");
  }
  if (j.contains("deformation")) {
    const std::string q = p + ".deformation";
    const Json& d = j["deformation"];
    only_keys(d, {"amplitude", "smoothness"}, q);
    m.deform_amplitude = positive(require(d, "amplitude", q), q + ".amplitude");
    if (d.contains("smoothness")) m.smoothness = positive(d["smoothness"], q + ".smoothness");
  }
  if (j.contains("debonding")) {
    const std::string q = p + ".debonding";
    const Json& d = j["debonding"];
    only_keys(d, {"fraction", "gap"}, q);
    m.debond_fraction = positive(require(d, "fraction", q), q + ".fraction");
    m.debond_gap = positive(require(d, "gap", q), q + ".gap");
  }
  return m;
}

// An axis within this of a box axis, and a length within this (relative) of the box's: a
// continuous fibre (the aspect ratio of a length of one box written in decimals, say).
constexpr double kThroughRounding = 1e-9;

// Continuous fibres ("length": "through"): along a box axis (the aligned law's, z when no
// orientation is given), exactly as long as the periodic box along it.
void parse_through(const Json& j, const std::string& p, const Box& box, Family* f) {
  using namespace json_util;
  const Json& len = j["length"];
  if (!len.is_string() || len.get<std::string>() != "through")
    fail(p + ".length",
         "expected \"through\" (continuous fibres; finite fibres take aspect_ratio)");
  if (j.contains("aspect_ratio"))
    fail(p + ".aspect_ratio", "not allowed with \"length\": \"through\" (the box sets the length)");
  if (!box.periodic)
    fail(p + ".length", "continuous fibres need a periodic box (\"box\": {\"periodic\": true})");
  OrientationLaw law;
  law.kind = OrientationLaw::Kind::kAligned;
  law.axis = Vec3::UnitZ();
  if (j.contains("orientation")) law = parse_orientation(j["orientation"], p + ".orientation");
  int k = 0;
  law.axis.cwiseAbs().maxCoeff(&k);
  if (law.kind != OrientationLaw::Kind::kAligned ||
      std::abs(law.axis[k]) < 1.0 - kThroughRounding) {
    fail(p + ".orientation",
         "continuous fibres run along a box axis: give {\"law\": \"aligned\", \"axis\": [0,0,1]} "
         "(or [1,0,0], [0,1,0])");
  }
  law.axis = Vec3::Unit(k) * (law.axis[k] > 0.0 ? 1.0 : -1.0);
  f->orientation = law;
  f->through_length = box.size[k];
  f->aspect_ratio = 1.0;  // unused: the length is the box's
}

// The box axis along which the family's fibres are continuous: given so ("length": "through"),
// or aligned fibres of one size exactly as long as the periodic box along a box axis (to
// kThroughRounding), which meet their own images end to end; -1 otherwise.
int continuous_axis(const Family& f, const Box& box) {
  int k = 0;
  f.orientation.axis.cwiseAbs().maxCoeff(&k);
  if (f.through()) return k;
  if (f.shape != ShapeKind::Cylinder || !box.periodic ||
      f.orientation.kind != OrientationLaw::Kind::kAligned || !f.radius.fixed() ||
      !f.aspect_ratio.fixed())
    return -1;
  const double length = 2.0 * f.radius.p1 * f.aspect_ratio.p1;
  return std::abs(f.orientation.axis[k]) >= 1.0 - kThroughRounding &&
                 std::abs(length - box.size[k]) <= kThroughRounding * box.size[k]
             ? k
             : -1;
}

// Fibres as long as the box become continuous fibres, written as such, when every family of the
// scene is continuous along that axis (continuous fibres pack beside no other inclusion): beside
// others they stay the finite fibres they were.
void make_fibres_continuous(Scene* s) {
  int common = -1;
  for (const Family& f : s->families) {
    const int k = continuous_axis(f, s->box);
    if (k < 0 || (common >= 0 && k != common)) return;
    common = k;
  }
  for (Family& f : s->families) {
    if (f.through()) continue;
    const int k = common;
    f.orientation.axis = Vec3::Unit(k) * (f.orientation.axis[k] > 0.0 ? 1.0 : -1.0);
    f.through_length = s->box.size[k];
    f.aspect_ratio = 1.0;
  }
}

Family parse_family(const Json& j, const std::string& p, const Box& box) {
  const double box_volume = box.volume();
  using namespace json_util;
  Family f;
  if (!j.is_object()) fail(p, "expected an object");
  const std::string shape = string(require(j, "shape", p), p + ".shape");
  if (!parse_shape_name(shape, &f.shape)) {
    fail(p + ".shape", "unknown shape \"" + shape + "\" (sphere, cylinder, ellipsoid)");
  }
  // Unknown keys first: a misspelled "volume_fraction" is named as such, not reported as a
  // missing amount.
  switch (f.shape) {
    case ShapeKind::Sphere:
      only_keys(j,
                {"name", "shape", "radius", "volume_fraction", "count", "coating", "waviness",
                 "curvature", "deformation", "debonding"},
                p);
      break;
    case ShapeKind::Cylinder:
      only_keys(j,
                {"name", "shape", "radius", "aspect_ratio", "length", "volume_fraction", "count",
                 "orientation", "coating", "waviness", "curvature", "deformation", "debonding"},
                p);
      break;
    case ShapeKind::Ellipsoid:
      only_keys(j,
                {"name", "shape", "semi_axes", "axis_ratios", "volume_fraction", "count",
                 "orientation", "coating", "waviness", "curvature", "deformation", "debonding"},
                p);
      break;
  }
  f.modifiers = parse_modifiers(j, p);
  const bool has_vf = j.contains("volume_fraction"), has_n = j.contains("count");
  if (!has_vf && !has_n) fail(p, "give \"volume_fraction\", \"count\" or both");
  if (has_vf) {
    f.volume_fraction = positive(j["volume_fraction"], p + ".volume_fraction");
  }
  if (has_n) {
    const double n = number(j["count"], p + ".count");
    if (n != std::floor(n) || n < 1 || n > 1e8)
      fail(p + ".count", "must be an integer in [1, 1e8]");
    f.count = static_cast<int>(n);
  }
  // Both given: the size follows (the paper's set-up), so no size key may be given.
  const bool derived = has_vf && has_n;
  const double per = derived ? f.volume_fraction * box_volume / f.count : 0.0;
  switch (f.shape) {
    case ShapeKind::Sphere:
      if (derived) {
        if (j.contains("radius"))
          fail(p + ".radius",
               "not allowed with both volume_fraction and count (the radius follows from them)");
        f.radius = std::cbrt(3.0 * per / (4.0 * M_PI));
      } else {
        f.radius = parse_size(require(j, "radius", p), p + ".radius");
      }
      break;
    case ShapeKind::Cylinder:
      if (j.contains("length")) {
        parse_through(j, p, box, &f);
      } else {
        f.aspect_ratio = parse_size(require(j, "aspect_ratio", p), p + ".aspect_ratio");
      }
      if (derived) {
        if (j.contains("radius"))
          fail(p + ".radius",
               "not allowed with both volume_fraction and count (the radius follows from them)");
        f.radius = f.through() ? std::sqrt(per / (M_PI * f.through_length))
                               : std::cbrt(per / (2.0 * M_PI * f.aspect_ratio.mean()));
      } else {
        f.radius = parse_size(require(j, "radius", p), p + ".radius");
      }
      break;
    case ShapeKind::Ellipsoid: {
      if (derived) {
        if (j.contains("semi_axes"))
          fail(p + ".semi_axes",
               "not allowed with both volume_fraction and count (give axis_ratios)");
        const Vec3 r = vec3(require(j, "axis_ratios", p), p + ".axis_ratios");
        for (int k = 0; k < 3; ++k) {
          if (!(r[k] > 0.0))
            fail(p + ".axis_ratios[" + std::to_string(k) + "]", "must be positive");
        }
        const double scale = std::cbrt(3.0 * per / (4.0 * M_PI * r.prod()));
        for (int k = 0; k < 3; ++k) f.semi_axes[k] = scale * r[k];
      } else {
        if (j.contains("axis_ratios"))
          fail(p + ".axis_ratios", "only with both volume_fraction and count");
        const Json& s = require(j, "semi_axes", p);
        if (!s.is_array() || s.size() != 3) fail(p + ".semi_axes", "expected an array of 3 sizes");
        for (int k = 0; k < 3; ++k) {
          f.semi_axes[k] = parse_size(s[k], p + ".semi_axes[" + std::to_string(k) + "]");
        }
      }
      break;
    }
  }
  f.name = j.contains("name") ? string(j["name"], p + ".name") : std::string(shape_name(f.shape));
  if (j.contains("orientation") && !f.through())
    f.orientation = parse_orientation(j["orientation"], p + ".orientation");
  if (derived) f.volume_fraction = -1.0;  // the count now says it all
  return f;
}

// Phase properties: {"matrix": {"conductivity": k, "young": E, "poisson": nu}, ...}; names and
// ranges are validate_scene's.
void parse_materials(const Json& m, Scene* s) {
  using namespace json_util;
  s->materials.clear();
  if (!m.is_object()) fail("materials", "expected an object of phase names");
  for (auto it = m.begin(); it != m.end(); ++it) {
    const std::string p = "materials." + it.key();
    only_keys(
        it.value(),
        {"conductivity", "young", "poisson", "axial_conductivity", "transverse_conductivity",
         "axial_young", "transverse_young", "axial_shear", "axial_poisson", "transverse_poisson"},
        p);
    Material mat;
    const std::pair<const char*, double*> fields[] = {
        {"conductivity", &mat.conductivity},
        {"young", &mat.young},
        {"poisson", &mat.poisson},
        {"axial_conductivity", &mat.axial_conductivity},
        {"transverse_conductivity", &mat.transverse_conductivity},
        {"axial_young", &mat.axial_young},
        {"transverse_young", &mat.transverse_young},
        {"axial_shear", &mat.axial_shear},
        {"axial_poisson", &mat.axial_poisson},
        {"transverse_poisson", &mat.transverse_poisson}};
    for (const auto& [key, value] : fields) {
      if (it.value().contains(key)) *value = number(it.value()[key], p + "." + key);
    }
    s->materials.emplace_back(it.key(), mat);
  }
}
// The scene's "md" object (the molecular dynamics' budgets and settings).
void parse_md(const Json& m, Scene* scene) {
  using namespace json_util;
  Scene& s = *scene;
  only_keys(m, {"max_steps", "max_seconds", "pressure", "patience", "rotation", "shake"}, "md");
  if (m.contains("rotation")) {
    const std::string r = string(m["rotation"], "md.rotation");
    if (r == "keep_tensor") {
      s.md.rotation = MdSettings::Rotation::kKeepTensor;
    } else if (r == "fixed") {
      s.md.rotation = MdSettings::Rotation::kFixed;
    } else if (r == "free") {
      s.md.rotation = MdSettings::Rotation::kFree;
    } else {
      fail("md.rotation", "unknown rotation mode \"" + r + "\" (keep_tensor, fixed, free)");
    }
  }
  if (m.contains("pressure")) {
    s.md.pressure = positive(m["pressure"], "md.pressure");
  }
  if (m.contains("patience")) {
    const double n = number(m["patience"], "md.patience");
    if (n != std::floor(n) || n < 1 || n > 1e7)
      fail("md.patience", "must be an integer in [1, 1e7]");
    s.md.patience = static_cast<int>(n);
  }
  if (m.contains("max_steps")) {
    const double n = number(m["max_steps"], "md.max_steps");
    if (n != std::floor(n) || n < 1 || n > 1e12) fail("md.max_steps", "must be an integer >= 1");
    s.md.max_steps = static_cast<long long>(n);
  }
  if (m.contains("max_seconds")) s.md.max_seconds = positive(m["max_seconds"], "md.max_seconds");
  if (m.contains("shake")) s.md.shake = number(m["shake"], "md.shake");
}

// The scene's "rsa" object (random sequential addition's budgets).
void parse_rsa(const Json& r, Scene* scene) {
  using namespace json_util;
  Scene& s = *scene;
  only_keys(r, {"max_attempts", "max_seconds"}, "rsa");
  if (r.contains("max_attempts")) {
    const double n = number(r["max_attempts"], "rsa.max_attempts");
    if (n != std::floor(n) || n < 1 || n > 1e9)
      fail("rsa.max_attempts", "must be an integer in [1, 1e9]");
    s.rsa_max_attempts = static_cast<int>(n);
  }
  if (r.contains("max_seconds")) s.rsa_max_seconds = positive(r["max_seconds"], "rsa.max_seconds");
}

// The scene's "voxels" object (the image's resolution and partial volumes).
void parse_voxels(const Json& v, Scene* scene) {
  using namespace json_util;
  Scene& s = *scene;
  only_keys(v, {"resolution", "partial_volume", "subsamples"}, "voxels");
  if (v.contains("partial_volume"))
    s.partial_volume = boolean(v["partial_volume"], "voxels.partial_volume");
  if (v.contains("subsamples")) {
    const double n = number(v["subsamples"], "voxels.subsamples");
    if (n != std::floor(n) || n < 1 || n > 16)
      fail("voxels.subsamples", "must be an integer in [1, 16]");
    s.subsamples = static_cast<int>(n);
  }
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

// The scene's "levelsets" object (the grids' voxel size and narrow band).
void parse_levelsets(const Json& l, Scene* scene) {
  using namespace json_util;
  only_keys(l, {"voxel_size", "half_width"}, "levelsets");
  if (l.contains("voxel_size"))
    scene->levelset_voxel_size = positive(l["voxel_size"], "levelsets.voxel_size");
  if (l.contains("half_width"))
    scene->levelset_half_width = positive(l["half_width"], "levelsets.half_width");
}

}  // namespace

void read_materials_json(const std::string& text, Scene* scene) {
  parse_materials(json_util::parse(text, "materials"), scene);
}

Outputs outputs_from_names(const std::vector<std::string>& names, bool mesh,
                           const std::string& where) {
  Outputs out{false, false, false, false, false, false, mesh, false, false, false};
  for (size_t k = 0; k < names.size(); ++k) {
    const std::string& name = names[k];
    if (name == "inclusions") {
      out.inclusions = true;
    } else if (name == "voxels") {
      out.voxels = true;
    } else if (name == "h5") {
      out.h5 = true;
    } else if (name == "amitex") {
      out.amitex = true;
    } else if (name == "levelsets") {
      out.levelsets = true;
      out.levelsets_asked = true;
    } else if (name == "mesh") {
      out.mesh = true;
    } else if (name == "mesh_voxel") {
      out.mesh_voxel = true;
    } else if (name == "mesh_tet") {
      out.mesh_tet = true;
    } else if (name == "statistics") {
      out.statistics = true;
    } else {
      // A flag's list is named as the flag; a scene's "outputs" by its index.
      const std::string at =
          where.rfind("--", 0) == 0 ? where : where + "[" + std::to_string(k) + "]";
      throw InputError(
          at + ": unknown output \"" + name + "\"" +
          json_util::did_you_mean(name, {"inclusions", "voxels", "h5", "amitex", "levelsets",
                                         "mesh", "mesh_voxel", "mesh_tet", "statistics"}) +
          " (inclusions, voxels, h5, amitex, levelsets, mesh, mesh_voxel, mesh_tet, statistics)");
    }
  }
  return out;
}

Scene parse_scene(const std::string& text) {
  using namespace json_util;
  const Json root = parse(text, "scene file");
  if (!root.is_object()) fail("(root)", "expected an object");
  only_keys(root,
            {"box", "seed", "method", "min_gap", "families", "voxels", "levelsets", "surfaces",
             "md", "rsa", "outputs", "materials", "homogenization", "mesh_tet"},
            "");
  Scene s;
  s.box = box(require(root, "box", ""), "box");
  if (root.contains("seed")) {
    // Any unsigned 64-bit integer, read exactly (not through a double, which holds integers
    // exactly only up to 2^53); a number written with a fraction or an exponent only where it
    // is an integer a double holds exactly.
    const Json& v = root["seed"];
    if (v.is_number_unsigned()) {
      s.seed = v.get<uint64_t>();
    } else {
      const double seed = number(v, "seed");
      if (!(seed >= 0 && seed == std::floor(seed))) {
        fail("seed", "must be an integer in [0, 18446744073709551615] (got " + v.dump() + ")");
      }
      // From 2^52 up, a double holds no fraction (4503599627370496.5 reads as ...496) and from
      // 2^53 not every integer (9007199254740993.0 reads as ...992).
      if (seed >= 4503599627370496.0) {
        fail("seed", "from 2^52 (4503599627370496) up, give the seed as digits only (got " +
                         v.dump() + ", which is read through a double)");
      }
      s.seed = static_cast<uint64_t>(seed);
    }
  }
  if (root.contains("method")) {
    const std::string m = string(root["method"], "method");
    if (m == "md") {
      s.method = Method::kMd;
    } else if (m == "rsa") {
      s.method = Method::kRsa;
    } else {
      throw InputError("method: unknown method \"" + m + "\" (md, rsa)");
    }
  }
  if (root.contains("min_gap")) {
    s.min_gap = number(root["min_gap"], "min_gap");
  }
  if (root.contains("md")) parse_md(root["md"], &s);
  if (root.contains("rsa")) parse_rsa(root["rsa"], &s);
  const Json& fams = require(root, "families", "");
  if (!fams.is_array()) fail("families", "expected an array");
  for (size_t i = 0; i < fams.size(); ++i) {
    s.families.push_back(parse_family(fams[i], "families[" + std::to_string(i) + "]", s.box));
  }
  make_fibres_continuous(&s);
  if (root.contains("voxels")) parse_voxels(root["voxels"], &s);
  if (root.contains("levelsets")) parse_levelsets(root["levelsets"], &s);
  if (root.contains("surfaces")) {
    const Json& m = root["surfaces"];
    only_keys(m, {"clip", "mesh", "chord_error"}, "surfaces");
    if (m.contains("clip")) s.clip_surfaces = boolean(m["clip"], "surfaces.clip");
    if (m.contains("mesh")) s.outputs.mesh = boolean(m["mesh"], "surfaces.mesh");
    if (m.contains("chord_error")) {
      s.surface_chord_error = number(m["chord_error"], "surfaces.chord_error");
    }
  }
  if (root.contains("mesh_tet")) {
    const Json& m = root["mesh_tet"];
    only_keys(m,
              {"max_size", "min_size", "chord_error", "gap_elements", "shift_cell", "nudge",
               "keep_volumes", "order", "optimize_threshold", "reproducible"},
              "mesh_tet");
    TetMeshSpec& t = s.tet_mesh;
    if (m.contains("max_size")) t.max_size = positive(m["max_size"], "mesh_tet.max_size");
    if (m.contains("min_size")) t.min_size = positive(m["min_size"], "mesh_tet.min_size");
    if (m.contains("chord_error"))
      t.chord_error = positive(m["chord_error"], "mesh_tet.chord_error");
    if (m.contains("gap_elements"))
      t.gap_elements = positive(m["gap_elements"], "mesh_tet.gap_elements");
    if (m.contains("shift_cell")) t.shift_cell = boolean(m["shift_cell"], "mesh_tet.shift_cell");
    if (m.contains("nudge")) t.nudge = boolean(m["nudge"], "mesh_tet.nudge");
    if (m.contains("keep_volumes"))
      t.keep_volumes = boolean(m["keep_volumes"], "mesh_tet.keep_volumes");
    if (m.contains("order")) {
      const double n = number(m["order"], "mesh_tet.order");
      if (n != 1.0 && n != 2.0)
        fail("mesh_tet.order", "must be 1 (4-node) or 2 (10-node tetrahedra)");
      t.order = static_cast<int>(n);
    }
    if (m.contains("optimize_threshold"))
      t.optimize_threshold = number(m["optimize_threshold"], "mesh_tet.optimize_threshold");
    if (m.contains("reproducible"))
      t.reproducible = boolean(m["reproducible"], "mesh_tet.reproducible");
  }
  if (root.contains("materials")) parse_materials(root["materials"], &s);
  if (root.contains("homogenization")) {
    const Json& h = root["homogenization"];
    only_keys(
        h, {"physics", "scheme", "solver", "tolerance", "max_iterations", "voxel_rule", "fields"},
        "homogenization");
    HomogenizationSpec& spec = s.homogenization;
    {
      // A homogenization object asks for a solve: without a physics nothing would be solved.
      const Json& ph = require(h, "physics", "homogenization");
      if (!ph.is_array() || ph.empty())
        fail("homogenization.physics",
             "expected a non-empty array: give conductivity, elasticity or both");
      for (size_t k = 0; k < ph.size(); ++k) {
        const std::string q = "homogenization.physics[" + std::to_string(k) + "]";
        const std::string name = string(ph[k], q);
        if (name == "conductivity") {
          spec.conductivity = true;
        } else if (name == "elasticity") {
          spec.elasticity = true;
        } else {
          fail(q, "unknown physics \"" + name + "\" (conductivity, elasticity)");
        }
      }
    }
    if (h.contains("scheme")) spec.scheme = string(h["scheme"], "homogenization.scheme");
    if (h.contains("solver")) spec.solver = string(h["solver"], "homogenization.solver");
    if (h.contains("fields")) {
      if (!h["fields"].is_boolean()) fail("homogenization.fields", "expected true or false");
      spec.fields = h["fields"].get<bool>();
    }
    if (h.contains("voxel_rule"))
      spec.voxel_rule = string(h["voxel_rule"], "homogenization.voxel_rule");
    if (h.contains("tolerance"))
      spec.tolerance = number(h["tolerance"], "homogenization.tolerance");
    if (h.contains("max_iterations")) {
      const double it = number(h["max_iterations"], "homogenization.max_iterations");
      if (it != std::floor(it) || it < 1 || it > 1e6)
        fail("homogenization.max_iterations", "must be an integer in [1, 1e6]");
      spec.max_iterations = static_cast<int>(it);
    }
  }
  if (root.contains("outputs")) {
    // The files to write: exactly the names listed (report.json always).
    const Json& o = root["outputs"];
    if (!o.is_array()) fail("outputs", "expected an array of output names");
    std::vector<std::string> names;
    for (size_t k = 0; k < o.size(); ++k) {
      names.push_back(string(o[k], "outputs[" + std::to_string(k) + "]"));
    }
    s.outputs = outputs_from_names(names, s.outputs.mesh, "outputs");
  }
  validate_scene(s);
  return s;
}

namespace {
nlohmann::ordered_json size_json(const SizeLaw& l) {
  switch (l.kind) {
    case SizeLaw::Kind::kFixed:
      return l.p1;
    case SizeLaw::Kind::kUniform:
      return {{"law", "uniform"}, {"min", l.p1}, {"max", l.p2}};
    case SizeLaw::Kind::kNormal:
      return {{"law", "normal"}, {"mean", l.p1}, {"std", l.p2}};
    case SizeLaw::Kind::kLognormal:
      return {{"law", "lognormal"}, {"mean", l.p1}, {"std", l.p2}};
    case SizeLaw::Kind::kWeibull:
      return {{"law", "weibull"}, {"shape", l.p1}, {"scale", l.p2}};
  }
  return l.p1;
}

using OJson = nlohmann::ordered_json;

OJson packing_json(const PackingSpec& s) {
  auto v3 = [](const Vec3& v) { return OJson::array({v[0], v[1], v[2]}); };
  OJson root;
  root["box"] = {
      {"origin", v3(s.box.origin)}, {"size", v3(s.box.size)}, {"periodic", s.box.periodic}};
  root["seed"] = s.seed;
  root["method"] = method_name(s.method);
  root["min_gap"] = s.min_gap;
  root["md"] = {{"max_steps", s.md.max_steps},
                {"max_seconds", s.md.max_seconds},
                {"pressure", s.md.pressure},
                {"patience", s.md.patience}};
  // (Written when set, so that the scenes of earlier versions read the same.)
  if (s.md.shake) root["md"]["shake"] = *s.md.shake;
  if (s.md.rotation != MdSettings::Rotation::kKeepTensor) {
    root["md"]["rotation"] = s.md.rotation == MdSettings::Rotation::kFixed ? "fixed" : "free";
  }
  root["rsa"] = {{"max_attempts", s.rsa_max_attempts}, {"max_seconds", s.rsa_max_seconds}};
  OJson fams = OJson::array();
  for (const auto& f : s.families) {
    OJson j;
    j["name"] = f.name;
    j["shape"] = shape_name(f.shape);
    if (f.shape == ShapeKind::Ellipsoid) {
      j["semi_axes"] = OJson::array(
          {size_json(f.semi_axes[0]), size_json(f.semi_axes[1]), size_json(f.semi_axes[2])});
    } else {
      j["radius"] = size_json(f.radius);
    }
    if (f.shape == ShapeKind::Cylinder) {
      if (f.through()) {
        j["length"] = "through";
      } else {
        j["aspect_ratio"] = size_json(f.aspect_ratio);
      }
    }
    if (f.count >= 0) {
      j["count"] = f.count;
    } else {
      j["volume_fraction"] = f.volume_fraction;
    }
    if (f.shape != ShapeKind::Sphere) {
      const auto& o = f.orientation;
      switch (o.kind) {
        case OrientationLaw::Kind::kIsotropic:
          j["orientation"] = {{"law", "isotropic"}};
          break;
        case OrientationLaw::Kind::kAligned:
          j["orientation"] = {{"law", "aligned"}, {"axis", v3(o.axis)}};
          break;
        case OrientationLaw::Kind::kVonMisesFisher:
          j["orientation"] = {
              {"law", "von_mises_fisher"}, {"axis", v3(o.axis)}, {"kappa", o.kappa}};
          break;
        case OrientationLaw::Kind::kPlanar:
          j["orientation"] = {{"law", "planar"}, {"normal", v3(o.axis)}};
          break;
        case OrientationLaw::Kind::kTensor: {
          OJson rows = OJson::array();
          for (int r = 0; r < 3; ++r) rows.push_back({o.a2(r, 0), o.a2(r, 1), o.a2(r, 2)});
          j["orientation"] = {{"law", "tensor"}, {"a2", rows}};
          break;
        }
      }
    }
    const FamilyModifiers& m = f.modifiers;
    if (m.coating > 0.0)
      j["coating"] = {{"thickness", m.coating}, {"shells_may_touch", m.shells_may_touch}};
    if (m.wave_amplitude > 0.0)
      j["waviness"] = {{"amplitude", m.wave_amplitude}, {"wavelength", m.wave_length}};
    if (m.bend_radius > 0.0) j["curvature"] = {{"radius", m.bend_radius}};
    if (m.deform_amplitude > 0.0)
      j["deformation"] = {{"amplitude", m.deform_amplitude}, {"smoothness", m.smoothness}};
    if (m.debond_gap > 0.0)
      j["debonding"] = {{"fraction", m.debond_fraction}, {"gap", m.debond_gap}};
    fams.push_back(j);
  }
  root["families"] = fams;
  return root;
}
}  // namespace

std::string packing_to_json(const PackingSpec& s) {
  return packing_json(s).dump(2) + "\n";
}

std::string scene_to_json(const Scene& s) {
  OJson root = packing_json(s);
  root["voxels"] = {{"resolution", {s.resolution[0], s.resolution[1], s.resolution[2]}},
                    {"partial_volume", s.partial_volume},
                    {"subsamples", s.subsamples}};
  root["levelsets"] = {{"half_width", s.levelset_half_width}};
  if (s.levelset_voxel_size > 0.0) root["levelsets"]["voxel_size"] = s.levelset_voxel_size;
  root["surfaces"] = {{"clip", s.clip_surfaces}, {"chord_error", s.surface_chord_error}};
  if (s.outputs.mesh_tet || !(s.tet_mesh == TetMeshSpec{})) {
    const TetMeshSpec& t = s.tet_mesh;
    root["mesh_tet"] = {{"chord_error", t.chord_error},
                        {"gap_elements", t.gap_elements},
                        {"shift_cell", t.shift_cell},
                        {"nudge", t.nudge},
                        {"keep_volumes", t.keep_volumes},
                        {"order", t.order},
                        {"optimize_threshold", t.optimize_threshold}};
    if (t.max_size > 0.0) root["mesh_tet"]["max_size"] = t.max_size;
    if (t.min_size > 0.0) root["mesh_tet"]["min_size"] = t.min_size;
    if (t.reproducible) root["mesh_tet"]["reproducible"] = true;
  }
  if (!s.materials.empty()) {
    OJson m = OJson::object();
    for (const auto& [name, mat] : s.materials) {
      OJson one = OJson::object();
      if (mat.conductivity >= 0.0) one["conductivity"] = mat.conductivity;
      if (mat.young >= 0.0) one["young"] = mat.young;
      if (mat.poisson > -1.0) one["poisson"] = mat.poisson;
      if (mat.axial_conductivity >= 0.0) one["axial_conductivity"] = mat.axial_conductivity;
      if (mat.transverse_conductivity >= 0.0)
        one["transverse_conductivity"] = mat.transverse_conductivity;
      if (mat.axial_young >= 0.0) one["axial_young"] = mat.axial_young;
      if (mat.transverse_young >= 0.0) one["transverse_young"] = mat.transverse_young;
      if (mat.axial_shear >= 0.0) one["axial_shear"] = mat.axial_shear;
      if (mat.axial_poisson > -1.0) one["axial_poisson"] = mat.axial_poisson;
      if (mat.transverse_poisson > -1.0) one["transverse_poisson"] = mat.transverse_poisson;
      m[name] = one;
    }
    root["materials"] = m;
  }
  if (s.homogenization.any()) {
    const HomogenizationSpec& h = s.homogenization;
    OJson physics = OJson::array();
    if (h.conductivity) physics.push_back("conductivity");
    if (h.elasticity) physics.push_back("elasticity");
    root["homogenization"] = {{"physics", physics},
                              {"scheme", h.scheme},
                              {"solver", h.solver},
                              {"tolerance", h.tolerance},
                              {"max_iterations", h.max_iterations},
                              {"voxel_rule", h.voxel_rule},
                              {"fields", h.fields}};
  }
  if (!(s.outputs == Outputs{})) {
    OJson names = OJson::array();
    const Outputs& o = s.outputs;
    for (const auto& [on, name] : {std::pair<bool, const char*>{o.inclusions, "inclusions"},
                                   {o.voxels, "voxels"},
                                   {o.h5, "h5"},
                                   {o.amitex, "amitex"},
                                   {o.levelsets, "levelsets"},
                                   {o.mesh, "mesh"},
                                   {o.mesh_voxel, "mesh_voxel"},
                                   {o.mesh_tet, "mesh_tet"},
                                   {o.statistics, "statistics"}}) {
      if (on) names.push_back(name);
    }
    root["outputs"] = names;
  }
  return root.dump(2) + "\n";
}

}  // namespace rvegen
