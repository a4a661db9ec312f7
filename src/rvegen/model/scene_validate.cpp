// validate_scene: every field and cross-field rule of a scene, however it was built.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "rvegen/model/body.hpp"
#include "rvegen/model/scene.hpp"

namespace rvegen {

namespace {

// Orientation tensors typed by users: symmetric and of trace 1 to this (their messages say so).
constexpr double kTensorInputTolerance = OrientationLaw::kTypedTolerance;
// Unit vectors given by users have norm 1 to this, and a tensor's eigenvalues may fall this far
// below 0 (rounding of a tensor computed elsewhere).
constexpr double kUnitInputTolerance = 1e-9;
// Inclusions smaller than this share of the box lose the precision the exact tests need.
constexpr double kMinRelativeSize = 1e-6;

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
    if ((a - a.transpose()).cwiseAbs().maxCoeff() > kTensorInputTolerance) {
      fail(q, "must be symmetric (a_ij = a_ji to 1e-6)");
    }
    char buf[160];
    if (std::abs(a.trace() - 1.0) > kTensorInputTolerance) {
      std::snprintf(buf, sizeof buf, "must have trace 1 (to 1e-6), has %.9g", a.trace());
      fail(q, buf);
    }
    const double low =
        Eigen::SelfAdjointEigenSolver<Mat3>(0.5 * (a + a.transpose())).eigenvalues().minCoeff();
    if (low < -kUnitInputTolerance) {
      std::snprintf(buf, sizeof buf,
                    "must be positive semi-definite, has the eigenvalue %.6g (an orientation "
                    "tensor <p p^T> has none below 0)",
                    low);
      fail(q, buf);
    }
    return;
  }
  const char* key = law.kind == OrientationLaw::Kind::kPlanar ? ".normal" : ".axis";
  if (!law.axis.allFinite() || std::abs(law.axis.norm() - 1.0) > kUnitInputTolerance) {
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

// The largest conductivity or modulus taken: any unit system's values are far below it, and the
// solvers' products of a few of them stay finite.
constexpr double kLargestProperty = 1e100;

std::string number_text(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// Transversely isotropic properties: a family's cores only, all constants of a physics together,
// instead of the isotropic ones, and a positive-definite stiffness.
void validate_transverse(const Scene& s, const std::string& name, const Material& m,
                         const std::string& p) {
  const auto given = Material::given;
  const bool tc = given(m.axial_conductivity) || given(m.transverse_conductivity);
  const bool te = given(m.axial_young) || given(m.transverse_young) || given(m.axial_shear) ||
                  given(m.axial_poisson) || given(m.transverse_poisson);
  if (!tc && !te) return;
  const Family* family = nullptr;
  for (const Family& f : s.families) {
    if (f.name == name) family = &f;
  }
  if (!family)
    fail(p,
         "transversely isotropic properties are for a family's cores (about each "
         "inclusion's axis), not for the matrix or a coating");
  if (family->shape == ShapeKind::Sphere)
    fail(p,
         "transversely isotropic properties need an axis: cylinders or ellipsoids, not "
         "spheres");
  if (tc) {
    if (given(m.conductivity))
      fail(p,
           "give \"conductivity\" or \"axial_conductivity\" with "
           "\"transverse_conductivity\", not both");
    for (const auto& [key, v] :
         {std::pair<const char*, double>{"axial_conductivity", m.axial_conductivity},
          {"transverse_conductivity", m.transverse_conductivity}}) {
      if (!(v >= 0.0 && v <= kLargestProperty))
        fail(p + "." + key,
             "must be >= 0 and at most 1e100 (give both axial and transverse), got " +
                 number_text(v));
    }
  }
  if (te) {
    if (given(m.young) || given(m.poisson))
      fail(p,
           "give isotropic (\"young\", \"poisson\") or transversely isotropic constants, "
           "not both");
    for (const auto& [key, v] : {std::pair<const char*, double>{"axial_young", m.axial_young},
                                 {"transverse_young", m.transverse_young},
                                 {"axial_shear", m.axial_shear}}) {
      if (!(v > 0.0 && v <= kLargestProperty))
        fail(p + "." + key,
             "must be > 0 and at most 1e100 (transversely isotropic elasticity needs "
             "axial_young, transverse_young, axial_shear, axial_poisson and transverse_poisson), "
             "got " +
                 number_text(v));
    }
    if (!(m.transverse_poisson > -1.0 && m.transverse_poisson < 1.0))
      fail(p + ".transverse_poisson", "must lie in (-1, 1)");
    if (!(m.axial_poisson > -1.0 && std::isfinite(m.axial_poisson)))
      fail(p + ".axial_poisson", "must be given, finite and > -1");
    // Positive definite: 1 - nu_TT - 2 nu_LT^2 E_T / E_L > 0.
    if (!(1.0 - m.transverse_poisson -
              2.0 * m.axial_poisson * m.axial_poisson * m.transverse_young / m.axial_young >
          0.0))
      fail(p,
           "these constants give no stable material (need 1 - transverse_poisson - 2 "
           "axial_poisson^2 transverse_young / axial_young > 0)");
  }
}

// "materials" and "homogenization": known phase names, properties in range, and every phase
// the image can hold has what the asked physics need.
void validate_materials(const Scene& s) {
  std::vector<std::string> names = {"matrix"};
  for (const Family& f : s.families) {
    names.push_back(f.name);
    if (f.modifiers.coating > 0.0) names.push_back(f.name + ".coating");
  }
  if (!s.materials.empty()) {
    // Materials are keyed by family name: each must name one phase only.
    for (size_t i = 0; i < s.families.size(); ++i) {
      const std::string& n = s.families[i].name;
      const std::string p = "families[" + std::to_string(i) + "].name";
      if (n == "matrix")
        fail(p, "\"matrix\" names the matrix's material: give the family another name");
      if (n.size() >= 8 && n.compare(n.size() - 8, 8, ".coating") == 0)
        fail(p,
             "\"" + n + "\" would read as a coating's material key: give the family another name");
      for (size_t j = 0; j < i; ++j) {
        if (s.families[j].name == n)
          fail(p, "\"" + n + "\" is also families[" + std::to_string(j) +
                      "]'s name: materials are keyed by name, so give each family its own");
      }
    }
  }
  for (size_t m = 0; m < s.materials.size(); ++m) {
    const std::string& name = s.materials[m].first;
    const Material& mat = s.materials[m].second;
    const std::string p = "materials." + name;
    if (std::find(names.begin(), names.end(), name) == names.end()) {
      const std::string stem = name.size() > 8 ? name.substr(0, name.size() - 8) : "";
      for (const Family& f : s.families) {
        if (name == f.name + ".coating")
          fail(p, "family \"" + stem + "\" has no coating, so no interphase to give a material");
      }
      std::string list;
      for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
      fail(p, "no phase of this name (phases: " + list + ")");
    }
    for (size_t o = 0; o < m; ++o) {
      if (s.materials[o].first == name) fail(p, "given twice");
    }
    // Each value on its own, whatever the physics asked for (AMITEX files carry them all).
    if (Material::given(mat.conductivity) &&
        !(mat.conductivity >= 0.0 && mat.conductivity <= kLargestProperty))
      fail(p + ".conductivity",
           "must be >= 0 and at most 1e100, got " + number_text(mat.conductivity));
    if (Material::given(mat.young) && !(mat.young >= 0.0 && mat.young <= kLargestProperty))
      fail(p + ".young", "must be >= 0 and at most 1e100, got " + number_text(mat.young));
    if (Material::given(mat.poisson) && !(mat.poisson > -1.0 && mat.poisson < 0.5))
      fail(p + ".poisson", "must lie in (-1, 0.5), got " + number_text(mat.poisson));
    if (Material::given(mat.young) != Material::given(mat.poisson))
      fail(p + (Material::given(mat.young) ? ".poisson" : ".young"),
           "missing: give both \"young\" and \"poisson\" (isotropic elasticity), or neither");
    validate_transverse(s, name, mat, p);
  }
  const HomogenizationSpec& h = s.homogenization;
  if (h.scheme != "rotated" && h.scheme != "moulinec_suquet")
    fail("homogenization.scheme", "unknown scheme \"" + h.scheme + "\" (rotated, moulinec_suquet)");
  if (h.solver != "cg" && h.solver != "fixed_point")
    fail("homogenization.solver", "unknown solver \"" + h.solver + "\" (cg, fixed_point)");
  if (h.solver == "fixed_point" && h.elasticity)
    fail("homogenization.solver", "fixed_point is for conductivity only; use cg");
  if (!(h.tolerance > 0.0 && h.tolerance < 1.0))
    fail("homogenization.tolerance", "must lie in (0, 1)");
  if (h.max_iterations < 1 || h.max_iterations > 1000000)
    fail("homogenization.max_iterations", "must be an integer in [1, 1e6]");
  if (h.voxel_rule != "laminate" && h.voxel_rule != "voigt" && h.voxel_rule != "reuss" &&
      h.voxel_rule != "plain")
    fail("homogenization.voxel_rule",
         "unknown rule \"" + h.voxel_rule + "\" (laminate, voigt, reuss, plain)");
  if (!h.any()) return;
  // The phases the image holds: the matrix, every family's cores, the coated families' shells.
  std::vector<std::string> needed = {"matrix"};
  for (const Family& f : s.families) {
    needed.push_back(f.name);
    if (f.modifiers.coating > 0.0) needed.push_back(f.name + ".coating");
  }
  for (const std::string& name : needed) {
    const Material* mat = nullptr;
    for (const auto& m : s.materials) {
      if (m.first == name) mat = &m.second;
    }
    if (h.conductivity && (!mat || !mat->conducts()))
      fail("materials." + name + ".conductivity", "needed by homogenization.physics conductivity");
    if (h.elasticity && (!mat || !mat->elastic()))
      fail("materials." + name + ".young",
           "needed (with poisson) by homogenization.physics elasticity");
  }
}

}  // namespace

void validate_homogenization(const Scene& scene) {
  validate_materials(scene);
}

std::string material_key(const Scene& scene, const Phase& p) {
  if (p.kind == PhaseKind::kMatrix) return "matrix";
  if (p.family < 0 || p.family >= static_cast<int>(scene.families.size())) return p.name;
  const std::string& f = scene.families[p.family].name;
  return p.kind == PhaseKind::kInterphase ? f + ".coating" : f;
}

const Material* OutputSpec::material(const std::string& key) const {
  for (const auto& m : materials) {
    if (m.first == key) return &m.second;
  }
  return nullptr;
}

void validate_tet_mesh_spec(const Scene& s) {
  const double box_min = s.box.size.minCoeff();
  const TetMeshSpec& t = s.tet_mesh;
  if (!(t.max_size >= 0.0 && t.max_size <= box_min))
    fail("mesh_tet.max_size", "must be positive and at most the smallest box size");
  if (!(t.min_size >= 0.0 && t.min_size <= box_min))
    fail("mesh_tet.min_size", "must be positive and at most the smallest box size");
  if (t.max_size > 0.0 && t.min_size > t.max_size)
    fail("mesh_tet.min_size", "must not exceed mesh_tet.max_size");
  if (t.max_size > 0.0 && box_min / t.max_size > 1000.0)
    fail("mesh_tet.max_size", "too small: more than 1000 elements along the box");
  if (!(t.chord_error >= 1e-5 && t.chord_error <= 0.1))
    fail("mesh_tet.chord_error", "must be in [1e-5, 0.1] (a fraction of the radius of curvature)");
  if (!(t.gap_elements >= 0.5 && t.gap_elements <= 20.0))
    fail("mesh_tet.gap_elements", "must be in [0.5, 20]");
  if (t.order != 1 && t.order != 2)
    fail("mesh_tet.order", "must be 1 (4-node) or 2 (10-node tetrahedra)");
  if (!(t.optimize_threshold >= 0.0 && t.optimize_threshold < 1.0))
    fail("mesh_tet.optimize_threshold", "must be in [0, 1) (an element quality)");
}

namespace {

// What the meshes refuse, refused before the packing rather than after it: the tetrahedral
// mesher's shapes and box, and phase names the finite-element decks would merge.
void check_mesh_outputs(const Scene& s) {
  if (s.outputs.mesh_tet) {
    // What the tetrahedral mesher refuses, refused before the packing rather than after it.
    if (!s.box.periodic) fail("outputs", "mesh_tet needs a periodic box (box.periodic false)");
    for (size_t i = 0; i < s.families.size(); ++i) {
      const FamilyModifiers& m = s.families[i].modifiers;
      if (m.wave_amplitude > 0.0 || m.bend_radius > 0.0 || m.deform_amplitude > 0.0) {
        fail("outputs",
             "mesh_tet meshes spheres, cylinders and ellipsoids, plain, coated or (spheres) "
             "debonded; family \"" +
                 s.families[i].name + "\" (families[" + std::to_string(i) +
                 "]) is wavy, bent or deformed (use mesh_voxel for it)");
      }
    }
  }
  if (s.outputs.mesh_voxel || s.outputs.mesh_tet) {
    // Finite-element decks name each phase's element set and material by deck_name ("a b" and
    // "a_b" are both a_b): two phases of one name would share a set and a material, and the
    // solver runs them without a word.
    std::vector<std::pair<std::string, size_t>> seen = {{"matrix", s.families.size()}};
    for (size_t i = 0; i < s.families.size(); ++i) {
      const Family& f = s.families[i];
      std::vector<std::string> names = {f.name};
      if (f.modifiers.coating > 0.0) names.push_back(f.name + " interphase");
      if (f.modifiers.debond_gap > 0.0) names.push_back(f.name + " void");
      for (const std::string& n : names) {
        for (const auto& [other, j] : seen) {
          if (deck_name(n) != deck_name(other)) continue;
          fail("families[" + std::to_string(i) + "].name",
               "the phase \"" + n + "\" and " +
                   (j == s.families.size()
                        ? std::string("the matrix")
                        : "families[" + std::to_string(j) + "]'s \"" + other + "\"") +
                   " would both be " + deck_name(n) +
                   " in the finite-element decks (letters and digits kept, the rest '_'): give "
                   "the families names that differ there");
        }
        seen.push_back({n, i});
      }
    }
  }
}

// Families[i]'s modifiers (which shapes take them, ranges, combinations) and whether it fits
// the box; returns the inclusions it asks for.
double check_family_modifiers(const Scene& s, size_t i, double box_min) {
  const Family& f = s.families[i];
  const std::string p = "families[" + std::to_string(i) + "]";
  // Modifiers: which shapes take them, ranges, combinations.
  const FamilyModifiers& m = f.modifiers;
  auto finite_at_least_0 = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!finite_at_least_0(m.coating)) fail(p + ".coating.thickness", "must be >= 0");
  if (!finite_at_least_0(m.wave_amplitude)) fail(p + ".waviness.amplitude", "must be >= 0");
  if (m.wave_amplitude > 0.0) {
    if (f.shape != ShapeKind::Cylinder) fail(p + ".waviness", "waviness applies to cylinders only");
    if (!(m.wave_length > 0.0) || !std::isfinite(m.wave_length))
      fail(p + ".waviness.wavelength", "must be positive");
  }
  if (!finite_at_least_0(m.bend_radius)) fail(p + ".curvature.radius", "must be positive");
  if (m.bend_radius > 0.0) {
    if (f.shape != ShapeKind::Cylinder)
      fail(p + ".curvature", "curvature applies to cylinders only");
    // The arc of the longest fibre (with its shell) turns by at most about a radian.
    const double longest = 2.0 * (f.longest_half() + m.coating);
    if (!(m.bend_radius >= longest)) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "must be at least the longest fibre's length with its coating (%.4g)", longest);
      fail(p + ".curvature.radius", buf);
    }
  }
  if (f.shape == ShapeKind::Cylinder && (m.wave_amplitude > 0.0 || m.bend_radius > 0.0)) {
    // A wave far shorter than the fibre's radius (or a bend far tighter) folds the fibre into
    // itself and makes chains of thousands of pieces: refused here, not stuck in the packer.
    const double shell = m.shells_may_touch ? 0.0 : m.coating;
    // The longest, thinnest fibre, counted as chain_plan counts it (CentreLine's bound).
    const double H = f.longest_half() + shell, R = f.radius.lower() + shell;
    const double k = m.wave_amplitude > 0.0 ? 2.0 * M_PI / m.wave_length : 0.0;
    const double K =
        centre_line_curvature(m.wave_amplitude, k, m.bend_radius, f.longest_half() + m.coating);
    const double pieces = chain_piece_count(H, R, K);
    if (!(pieces <= kMaxChainPieces)) {
      char buf[400];
      if (m.wave_amplitude > 0.0) {
        std::snprintf(buf, sizeof buf,
                      "a wave of amplitude %.3g and wavelength %.3g on fibres of radius %.3g "
                      "and length %.3g bends too sharply to pack (%.3g chain pieces per fibre, "
                      "at most %.0f): give a wavelength of at least %.3g or a smaller amplitude",
                      m.wave_amplitude, m.wave_length, f.radius.lower(), 2.0 * f.longest_half(),
                      pieces, kMaxChainPieces, m.wave_length * pieces / kMaxChainPieces);
        fail(p + ".waviness.wavelength", buf);
      }
      std::snprintf(buf, sizeof buf,
                    "bends fibres of radius %.3g too sharply to pack (%.3g chain pieces per "
                    "fibre, at most %.0f)",
                    f.radius.lower(), pieces, kMaxChainPieces);
      fail(p + ".curvature.radius", buf);
    }
  }
  if (f.through()) {
    // Continuous fibres: straight, along a box axis, as long as the periodic box along it.
    if (f.shape != ShapeKind::Cylinder)
      fail(p + ".length", "\"through\" applies to cylinders only");
    if (!s.box.periodic) fail(p + ".length", "continuous fibres need a periodic box");
    const Vec3& a = f.orientation.axis;
    int k = 0;
    a.cwiseAbs().maxCoeff(&k);
    if (f.orientation.kind != OrientationLaw::Kind::kAligned || std::abs(a[k]) != 1.0 ||
        a[(k + 1) % 3] != 0.0 || a[(k + 2) % 3] != 0.0)
      fail(p + ".orientation", "continuous fibres are aligned along a box axis");
    if (f.through_length != s.box.size[k])
      fail(p + ".length", "continuous fibres are as long as the box along their axis");
    if (m.wave_amplitude > 0.0 || m.bend_radius > 0.0)
      fail(p + ".length", "continuous fibres are straight (no waviness or curvature)");
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
  if (f.through()) {
    // A continuous fibre is as long as the box: its section must fit across it.
    int k = 0;
    f.orientation.axis.cwiseAbs().maxCoeff(&k);
    const double across = std::min(s.box.size[(k + 1) % 3], s.box.size[(k + 2) % 3]);
    const double width = 2.0 * (f.radius.upper() + m.coating);
    if (width + 2.0 * s.min_gap >= across) {
      fail(p, "continuous fibre does not fit across the box (diameter with coating " +
                  std::to_string(width) +
                  (s.min_gap > 0.0 ? " plus twice min_gap " + std::to_string(s.min_gap) : "") +
                  " >= box size across the fibres " + std::to_string(across) + ")");
    }
  } else if (f.max_min_width() + 2.0 * s.min_gap >= box_min) {
    fail(p, "inclusion does not fit in the box (smallest width " +
                std::to_string(f.max_min_width()) +
                (s.min_gap > 0.0 ? " plus twice min_gap " + std::to_string(s.min_gap) : "") +
                " >= smallest box size " + std::to_string(box_min) + ")");
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
  return n;
}

}  // namespace

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
  if (s.md.shake && !(*s.md.shake >= 0.0 && *s.md.shake <= 1.0))
    fail("md.shake", "must be in [0, 1]");
  if (!(s.surface_chord_error >= 0.001 && s.surface_chord_error <= 10.0))
    fail("surfaces.chord_error", "must be in [0.001, 10] voxels");
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
  validate_tet_mesh_spec(s);
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
    if (f.count == 0 || f.count > 100000000) fail(p + ".count", "must be an integer in [1, 1e8]");
    const double small = mean_smallest_size(f);
    if (!(small >= kMinRelativeSize * s.box.size.maxCoeff())) {
      char buf[160];
      std::snprintf(buf, sizeof buf,
                    "inclusions smaller than 1e-6 of the box are not supported (mean smallest "
                    "size %.3g)",
                    small);
      fail(p, buf);
    }
  }
  double count = 0.0;
  for (size_t i = 0; i < s.families.size(); ++i) count += check_family_modifiers(s, i, box_min);
  if (count > 2e7) fail("families", "more than 2e7 inclusions asked for");
  // Continuous fibres pack with continuous fibres along their axis only: against other bodies
  // their pair tests see the ends of the cylinder one period long that stands for each, where
  // the fibre continues, and such mixtures jammed far below their targets.
  for (size_t i = 0; i < s.families.size(); ++i) {
    if (!s.families[i].through()) continue;
    int k = 0;
    s.families[i].orientation.axis.cwiseAbs().maxCoeff(&k);
    for (size_t j = 0; j < s.families.size(); ++j) {
      int kj = -1;
      if (s.families[j].through()) s.families[j].orientation.axis.cwiseAbs().maxCoeff(&kj);
      if (kj == k) continue;
      fail("families[" + std::to_string(j) + "]",
           std::string("continuous fibres (families[") + std::to_string(i) + "], along " +
               "xyz"[k] +
               ") pack only with continuous fibres along the same axis: mixing them with other "
               "inclusions, or with continuous fibres along another axis, is not supported");
    }
  }
  check_mesh_outputs(s);
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
  validate_materials(s);
}

}  // namespace rvegen
