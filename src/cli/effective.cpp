#include "effective.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "rvegen/homogenize/conductivity.hpp"
#include "rvegen/homogenize/elasticity.hpp"

namespace rvegen::cli {

namespace {

using Json = nlohmann::ordered_json;

// Properties per phase label (voids: nothing conducts or carries load there).
struct PhaseProperties {
  std::vector<double> conductivity, young, poisson;
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
  }
  return p;
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

Json effective_properties(const Scene& scene, const VoxelImage& image, const ProgressFn& progress) {
  const HomogenizationSpec& h = scene.homogenization;
  const PhaseProperties props = phase_properties(scene, image);
  const std::vector<double> f = label_shares(image);
  const std::array<int, 3> dims = {image.size(0), image.size(1), image.size(2)};
  const Vec3 box = scene.box.size;
  const GradientScheme scheme =
      h.scheme == "moulinec_suquet" ? GradientScheme::kMoulinecSuquet : GradientScheme::kRotated;
  Json out;
  out["voxel_rule"] = "plain: each voxel has the properties of the phase at its centre";
  out["resolution"] = {dims[0], dims[1], dims[2]};
  out["phase_shares"] = f;
  if (h.conductivity) {
    std::vector<double> k(image.phase.size());
    for (size_t i = 0; i < k.size(); ++i) k[i] = props.conductivity[image.phase[i]];
    ConductivityOptions opt;
    opt.scheme = scheme;
    opt.solver =
        h.solver == "fixed_point" ? LinearSolver::kFixedPoint : LinearSolver::kConjugateGradient;
    opt.tolerance = h.tolerance;
    opt.max_iterations = h.max_iterations;
    opt.progress = progress_lines(progress, "conductivity", 3);
    const ConductivityResult r = effective_conductivity(dims, box, k, opt);
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
    c["bounds"] = {
        {"voigt", arithmetic(f, props.conductivity)},
        {"reuss", harmonic(f, props.conductivity)},
        {"hashin_shtrikman",
         {walpole(f, props.conductivity, 2.0 * kmin), walpole(f, props.conductivity, 2.0 * kmax)}}};
    out["conductivity"] = c;
  }
  if (h.elasticity) {
    std::vector<double> young(image.phase.size()), poisson(image.phase.size());
    for (size_t i = 0; i < young.size(); ++i) {
      young[i] = props.young[image.phase[i]];
      poisson[i] = props.poisson[image.phase[i]];
    }
    ElasticityOptions opt;
    opt.scheme = scheme;
    opt.tolerance = h.tolerance;
    opt.max_iterations = h.max_iterations;
    opt.progress = progress_lines(progress, "elasticity", 6);
    const ElasticityResult r = effective_stiffness(dims, box, young, poisson, opt);
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
