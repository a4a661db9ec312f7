#include "effective.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "rvegen/homogenize/conductivity.hpp"
#include "rvegen/homogenize/elasticity.hpp"
#include "rvegen/homogenize/medium.hpp"
#include "rvegen/raster/cut_voxels.hpp"

namespace rvegen::cli {

namespace {

using Json = nlohmann::ordered_json;

// Properties per phase label (voids: nothing conducts or carries load there). A core phase with
// transversely isotropic properties has them in `material` (its isotropic values are unused).
struct PhaseProperties {
  std::vector<double> conductivity, young, poisson;
  std::vector<const Material*> material;
};

PhaseProperties phase_properties(const Scene& scene, const VoxelImage& image) {
  PhaseProperties p;
  for (const Phase& ph : image.phases) {
    std::string key;
    if (ph.kind == PhaseKind::kMatrix) key = "matrix";
    if (ph.kind == PhaseKind::kCore) key = scene.families[ph.family].name;
    if (ph.kind == PhaseKind::kInterphase) key = scene.families[ph.family].name + ".coating";
    const Material* m = key.empty() ? nullptr : scene.material(key);
    p.conductivity.push_back(m && m->conductivity >= 0.0 ? m->conductivity : 0.0);
    p.young.push_back(m && m->young >= 0.0 ? m->young : 0.0);
    p.poisson.push_back(m && m->poisson > -1.0 ? m->poisson : 0.0);
    p.material.push_back(m);
  }
  return p;
}

// The medium of one physics: a row per phase label, then a row per inclusion whose core is
// transversely isotropic (its tensor turned to the inclusion's axis); composite voxels by the
// rule. `phase_tensor(label)` gives a label's tensor, `own_tensor(material, axis)` a turned one
// (or nothing when the material is isotropic for this physics).
template <int D, class PhaseTensor, class OwnTensor>
TensorMedium<D> build_medium(const InclusionSet& set, const VoxelImage& image, const CutVoxels& cut,
                             VoxelRule rule, const PhaseProperties& props, PhaseTensor phase_tensor,
                             OwnTensor own_tensor, size_t* own_rows) {
  using T = Eigen::Matrix<double, D, D>;
  std::vector<T> rows;
  for (size_t l = 0; l < image.phases.size(); ++l) rows.push_back(phase_tensor(l));
  // Rows of the inclusions' own tensors, by inclusion index and by id.
  std::vector<int64_t> own(set.inclusions.size(), -1);
  std::unordered_map<int, uint32_t> own_by_id;
  for (size_t m = 0; m < set.inclusions.size(); ++m) {
    const Inclusion& inc = set.inclusions[m];
    const Material* mat = props.material[inc.family + 1];
    T t;
    if (!mat || !own_tensor(*mat, principal_axis(inc.shape), &t)) continue;
    own[m] = static_cast<int64_t>(rows.size());
    own_by_id[inc.id] = static_cast<uint32_t>(rows.size());
    rows.push_back(t);
  }
  *own_rows = own_by_id.size();
  std::vector<uint32_t> material(image.phase.size());
  for (size_t v = 0; v < material.size(); ++v) {
    material[v] = image.phase[v];
    if (!own_by_id.empty() && image.phases[image.phase[v]].kind == PhaseKind::kCore) {
      const auto it = own_by_id.find(image.inclusion_id[v]);
      if (it != own_by_id.end()) material[v] = it->second;
    }
  }
  std::vector<CompositeVoxel> composites;
  composites.reserve(cut.voxels.size());
  for (const CutVoxel& c : cut.voxels) {
    CompositeVoxel v;
    v.voxel = c.voxel;
    v.inside = own[c.inclusion] >= 0 ? static_cast<uint32_t>(own[c.inclusion]) : c.inside;
    v.outside = c.outside;
    v.fraction = c.fraction;
    v.normal = c.normal;
    composites.push_back(v);
  }
  return compose_medium<D>(material, rows, composites, rule);
}

// Shares of each phase label in the image.
std::vector<double> label_shares(const VoxelImage& image) {
  std::vector<double> f(image.phases.size(), 0.0);
  for (uint8_t l : image.phase) f[l] += 1.0;
  for (double& v : f) v /= static_cast<double>(image.phase.size());
  return f;
}

double arithmetic(const std::vector<double>& f, const std::vector<double>& v) {
  double s = 0.0;
  for (size_t i = 0; i < f.size(); ++i) s += f[i] * v[i];
  return s;
}

double harmonic(const std::vector<double>& f, const std::vector<double>& v) {
  double s = 0.0;
  for (size_t i = 0; i < f.size(); ++i) {
    if (f[i] <= 0.0) continue;
    if (!(v[i] > 0.0)) return 0.0;
    s += f[i] / v[i];
  }
  return 1.0 / s;
}

// (sum f_i / (v_i + z))^-1 - z: the Hashin-Shtrikman-Walpole form with the comparison value z.
double walpole(const std::vector<double>& f, const std::vector<double>& v, double z) {
  double s = 0.0;
  for (size_t i = 0; i < f.size(); ++i) {
    if (f[i] <= 0.0) continue;
    if (!(v[i] + z > 0.0)) return 0.0;
    s += f[i] / (v[i] + z);
  }
  return 1.0 / s - z;
}

// The extreme values over the phases present.
std::pair<double, double> range(const std::vector<double>& f, const std::vector<double>& v) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (size_t i = 0; i < f.size(); ++i) {
    if (f[i] <= 0.0) continue;
    lo = std::min(lo, v[i]);
    hi = std::max(hi, v[i]);
  }
  return {lo, hi};
}

Json rows(const Eigen::MatrixXd& m) {
  Json out = Json::array();
  for (int i = 0; i < m.rows(); ++i) {
    Json row = Json::array();
    for (int j = 0; j < m.cols(); ++j) row.push_back(m(i, j));
    out.push_back(row);
  }
  return out;
}

// A progress line at most once a second: "<what>: load L/N, iteration I, residual R".
std::function<bool(int, int, double)> progress_lines(const ProgressFn& progress, const char* what,
                                                     int loads) {
  auto last =
      std::make_shared<std::chrono::steady_clock::time_point>(std::chrono::steady_clock::now());
  return [=](int load, int it, double rel) {
    if (!progress) return true;
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - *last).count() < 1.0) return true;
    *last = now;
    char buf[160];
    std::snprintf(buf, sizeof buf, "%s: load %d/%d, iteration %d, residual %.2e", what, load + 1,
                  loads, it, rel);
    progress(buf);
    return true;
  };
}

}  // namespace

Json effective_properties(const Scene& scene, const InclusionSet& set, const VoxelImage& image,
                          const ProgressFn& progress) {
  const HomogenizationSpec& h = scene.homogenization;
  const PhaseProperties props = phase_properties(scene, image);
  const std::vector<double> f = label_shares(image);
  const std::array<int, 3> dims = {image.size(0), image.size(1), image.size(2)};
  const Vec3 box = scene.box.size;
  const GradientScheme scheme =
      h.scheme == "moulinec_suquet" ? GradientScheme::kMoulinecSuquet : GradientScheme::kRotated;
  const VoxelRule rule = voxel_rule_from_name(h.voxel_rule);
  CutVoxels cut;
  if (rule != VoxelRule::kPlain) cut = cut_voxels(set, image);
  Json out;
  out["voxel_rule"] = {
      {"rule", h.voxel_rule},
      {"meaning",
       rule == VoxelRule::kPlain
           ? "each voxel has the properties of the phase at its centre"
           : "voxels cut by one core surface mix the two phases by the rule (laminate: exact "
             "share and normal); other voxels take the phase at their centre"},
      {"cut_voxels", cut.voxels.size()},
      {"voxels_cut_by_two_cores", cut.shared}};
  out["resolution"] = {dims[0], dims[1], dims[2]};
  out["phase_shares"] = f;
  if (h.conductivity) {
    size_t own = 0;
    const ConductivityMedium medium = build_medium<3>(
        set, image, cut, rule, props,
        [&](size_t l) { return Mat3(props.conductivity[l] * Mat3::Identity()); },
        [](const Material& m, const Vec3& axis, Mat3* t) {
          if (!m.transverse_conduction()) return false;
          *t = transverse_conductivity(m.axial_conductivity, m.transverse_conductivity, axis);
          return true;
        },
        &own);
    ConductivityOptions opt;
    opt.scheme = scheme;
    opt.solver =
        h.solver == "fixed_point" ? LinearSolver::kFixedPoint : LinearSolver::kConjugateGradient;
    opt.tolerance = h.tolerance;
    opt.max_iterations = h.max_iterations;
    opt.progress = progress_lines(progress, "conductivity", 3);
    const ConductivityResult r = effective_conductivity(dims, box, medium, opt);
    const auto [kmin, kmax] = range(f, props.conductivity);
    Json c;
    c["tensor"] = rows(r.tensor);
    c["mean_of_diagonal"] = r.tensor.trace() / 3.0;
    c["scheme"] = h.scheme;
    c["solver"] = h.solver;
    c["iterations"] = r.iterations;
    c["residual"] = r.residual;
    c["converged"] = r.converged;
    c["seconds"] = r.seconds;
    if (own == 0) {
      c["bounds"] = {{"voigt", arithmetic(f, props.conductivity)},
                     {"reuss", harmonic(f, props.conductivity)},
                     {"hashin_shtrikman",
                      {walpole(f, props.conductivity, 2.0 * kmin),
                       walpole(f, props.conductivity, 2.0 * kmax)}}};
    } else {
      c["bounds"] = "not stated: the isotropic bounds do not apply to anisotropic fibres";
    }
    out["conductivity"] = c;
  }
  if (h.elasticity) {
    size_t own = 0;
    const StiffnessMedium medium = build_medium<6>(
        set, image, cut, rule, props,
        [&](size_t l) { return isotropic_stiffness(props.young[l], props.poisson[l]); },
        [](const Material& m, const Vec3& axis, Mat6* t) {
          if (!m.transverse_elasticity()) return false;
          *t = transverse_stiffness(m.axial_young, m.transverse_young, m.axial_shear,
                                    m.axial_poisson, m.transverse_poisson, axis);
          return true;
        },
        &own);
    ElasticityOptions opt;
    opt.scheme = scheme;
    opt.tolerance = h.tolerance;
    opt.max_iterations = h.max_iterations;
    opt.progress = progress_lines(progress, "elasticity", 6);
    const ElasticityResult r = effective_stiffness(dims, box, medium, opt);
    const EngineeringConstants e = engineering_constants(r.stiffness);
    // Bulk and shear moduli per phase, the isotropic projection of the result, and the bounds.
    std::vector<double> bulk(f.size()), shear(f.size());
    for (size_t i = 0; i < f.size(); ++i) {
      bulk[i] = props.young[i] / (3.0 * (1.0 - 2.0 * props.poisson[i]));
      shear[i] = props.young[i] / (2.0 * (1.0 + props.poisson[i]));
    }
    const double three_k = r.stiffness.topLeftCorner<3, 3>().sum() / 3.0;
    const double two_g = (r.stiffness.trace() - three_k) / 5.0;
    const auto [gmin, gmax] = range(f, shear);
    const auto [kmin, kmax] = range(f, bulk);
    auto zeta = [](double k, double g) {
      return k + 2 * g > 0 ? g / 6.0 * (9 * k + 8 * g) / (k + 2 * g) : 0.0;
    };
    Json s;
    s["notation"] =
        "Mandel: rows and columns 11, 22, 33, 23, 13, 12, shear components times sqrt 2";
    s["tensor"] = rows(r.stiffness);
    s["engineering_constants"] = {{"E1", e.e1},     {"E2", e.e2},     {"E3", e.e3},
                                  {"G23", e.g23},   {"G13", e.g13},   {"G12", e.g12},
                                  {"nu12", e.nu12}, {"nu13", e.nu13}, {"nu23", e.nu23}};
    s["isotropic_projection"] = {{"bulk", three_k / 3.0}, {"shear", two_g / 2.0}};
    s["scheme"] = h.scheme;
    s["iterations"] = r.iterations;
    s["residual"] = r.residual;
    s["converged"] = r.converged;
    s["seconds"] = r.seconds;
    if (own > 0) {
      s["bounds"] = "not stated: the isotropic bounds do not apply to anisotropic fibres";
      out["stiffness"] = s;
      return out;
    }
    s["bounds"] = {
        {"bulk",
         {{"voigt", arithmetic(f, bulk)},
          {"reuss", harmonic(f, bulk)},
          {"hashin_shtrikman",
           {walpole(f, bulk, 4.0 / 3.0 * gmin), walpole(f, bulk, 4.0 / 3.0 * gmax)}}}},
        {"shear",
         {{"voigt", arithmetic(f, shear)},
          {"reuss", harmonic(f, shear)},
          {"hashin_shtrikman",
           {walpole(f, shear, zeta(kmin, gmin)), walpole(f, shear, zeta(kmax, gmax))}}}}};
    out["stiffness"] = s;
  }
  return out;
}

}  // namespace rvegen::cli
