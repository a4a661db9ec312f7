#include "rvegen/homogenize/effective.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "rvegen/homogenize/medium.hpp"
#include "rvegen/model/errors.hpp"
#include "rvegen/raster/cut_voxels.hpp"

namespace rvegen {

namespace {

// Properties per phase label (voids: nothing conducts or carries load there). A core phase with
// transversely isotropic properties has them in `material` (its isotropic values are unused).
struct PhaseProperties {
  std::vector<double> conductivity, young, poisson;
  std::vector<const Material*> material;
};

// The phases' tensors' spread: the phase whose eigenvalues lie furthest apart (largest over
// least; a phase with a zero eigenvalue is infinitely spread) and, across all phases, the largest
// eigenvalue over the least positive one.
template <int D>
std::string eigenvalue_spread(const char* what, const VoxelImage& image,
                              const std::vector<Eigen::Matrix<double, D, D>>& tensors) {
  double worst = 0.0, top = 0.0, least = std::numeric_limits<double>::infinity();
  std::string name;
  for (size_t l = 0; l < tensors.size() && l < image.phases.size(); ++l) {
    if (image.phases[l].kind == PhaseKind::kVoid) continue;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, D, D>> eig(tensors[l]);
    const double lo = eig.eigenvalues().minCoeff(), hi = eig.eigenvalues().maxCoeff();
    const double spread = lo > 0.0 ? hi / lo : std::numeric_limits<double>::infinity();
    if (spread > worst || name.empty()) worst = spread, name = image.phases[l].name;
    top = std::max(top, hi);
    if (lo > 0.0) least = std::min(least, lo);
  }
  if (name.empty()) return "";
  char text[200];
  std::snprintf(text, sizeof text,
                "phase \"%s\" has %s eigenvalues %.1e apart; the phases' span %.1e", name.c_str(),
                what, worst, least > 0.0 && std::isfinite(least) ? top / least : worst);
  return text;
}

PhaseProperties phase_properties(const Scene& scene, const VoxelImage& image) {
  PhaseProperties p;
  for (const Phase& ph : image.phases) {
    // Voids carry nothing.
    const Material* m =
        ph.kind == PhaseKind::kVoid ? nullptr : scene.material(material_key(scene, ph));
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
    const Material* mat = props.material[core_label(inc.family)];
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
    CompositeVoxel v = composite_of(c);
    if (own[c.inclusion] >= 0) v.inside = static_cast<uint32_t>(own[c.inclusion]);
    composites.push_back(v);
  }
  // Debonding gaps and shells are thin: one that carries nothing keeps the laminate.
  std::vector<bool> thin(rows.size(), false);
  for (size_t l = 0; l < image.phases.size(); ++l) {
    thin[l] =
        image.phases[l].kind == PhaseKind::kVoid || image.phases[l].kind == PhaseKind::kInterphase;
  }
  return compose_medium<D>(material, rows, composites, rule, thin);
}

// Shares of each phase label in the whole image (every rank's slab).
std::vector<double> label_shares(const VoxelImage& image, const Communicator& comm) {
  std::vector<double> f(image.phases.size(), 0.0);
  for (uint8_t l : image.phase) f[l] += 1.0;
  sum_over_ranks(f.data(), static_cast<int>(f.size()), comm);
  const double whole = static_cast<double>(image.dims[0]) * image.dims[1] * image.dims[2];
  for (double& v : f) v /= whole;
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

Bounds scalar_bounds(const std::vector<double>& f, const std::vector<double>& v, double zlo,
                     double zhi) {
  Bounds b;
  b.stated = true;
  b.voigt = arithmetic(f, v);
  b.reuss = harmonic(f, v);
  b.hs_lower = walpole(f, v, zlo);
  b.hs_upper = walpole(f, v, zhi);
  return b;
}

}  // namespace

EffectiveProperties effective_properties(const Scene& scene, const InclusionSet& set,
                                         const VoxelImage& image, const SolveProgress& progress,
                                         const Communicator& comm) {
  const HomogenizationSpec& h = scene.homogenization;
  const std::array<int, 3> dims = image.dims;
  const std::array<int, 2> slab = spectral::fft_slab(dims, comm);
  const std::array<int, 6> want = {0, dims[0], 0, dims[1], slab[0], slab[1]};
  if (image.extent != want || image.phase.size() != image.count() ||
      image.inclusion_id.size() != image.count()) {
    throw InputError("homogenization: the image is not " +
                     std::string(comm.set ? "this rank's slab" : "whole"));
  }
  const PhaseProperties props = phase_properties(scene, image);
  EffectiveProperties out;
  out.phase_shares = label_shares(image, comm);
  const std::vector<double>& f = out.phase_shares;
  out.resolution = dims;
  const Vec3 box = scene.box.size;
  const GradientScheme scheme =
      h.scheme == "moulinec_suquet" ? GradientScheme::kMoulinecSuquet : GradientScheme::kRotated;
  const VoxelRule rule = voxel_rule_from_name(h.voxel_rule);
  CutVoxels cut;
  if (rule != VoxelRule::kPlain) cut = cut_voxels(set, image);
  out.voxel_rule = h.voxel_rule;
  double counts[2] = {static_cast<double>(cut.voxels.size()), static_cast<double>(cut.shared)};
  sum_over_ranks(counts, 2, comm);
  out.cut_voxels = static_cast<size_t>(counts[0]);
  out.shared_voxels = static_cast<size_t>(counts[1]);
  auto report = [&](const char* physics, int loads) {
    return [=, &progress](int load, int it, double rel) {
      return !progress || progress(physics, load, loads, it, rel);
    };
  };
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
    opt.progress = report("conductivity", 3);
    opt.comm = comm;
    if (h.fields) {
      opt.field = [&](int, const std::vector<double>& g) {
        const size_t n = g.size() / 3;
        std::vector<float> grad(g.begin(), g.end()), q(3 * n);
        for (size_t i = 0; i < n; ++i) {
          const Vec3 f = medium.at(i) * Vec3(g[i], g[n + i], g[2 * n + i]);
          for (int a = 0; a < 3; ++a) q[a * n + i] = static_cast<float>(f[a]);
        }
        out.gradient.push_back(std::move(grad));
        out.flux.push_back(std::move(q));
      };
    }
    out.conductivity = effective_conductivity(dims, box, medium, opt);
    out.has_conductivity = true;
    std::vector<Mat3> phase_conductivity;
    for (size_t l = 0; l < image.phases.size(); ++l) {
      const Material* m = props.material[l];
      phase_conductivity.push_back(
          m && m->transverse_conduction()
              ? Mat3(Vec3(m->transverse_conductivity, m->transverse_conductivity,
                          m->axial_conductivity)
                         .asDiagonal())
              : Mat3(props.conductivity[l] * Mat3::Identity()));
    }
    out.conductivity_spread = eigenvalue_spread<3>("conductivity", image, phase_conductivity);
    if (own == 0) {
      const auto [kmin, kmax] = range(f, props.conductivity);
      out.conductivity_bounds = scalar_bounds(f, props.conductivity, 2.0 * kmin, 2.0 * kmax);
    }
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
    opt.progress = report("elasticity", 6);
    opt.comm = comm;
    if (h.fields) {
      // Mandel to tensor components: shear ones over sqrt 2.
      opt.field = [&](int, const std::vector<double>& e) {
        const size_t n = e.size() / 6;
        const double w[6] = {1, 1, 1, M_SQRT1_2, M_SQRT1_2, M_SQRT1_2};
        std::vector<float> eps(6 * n), sig(6 * n);
        for (size_t i = 0; i < n; ++i) {
          Eigen::Matrix<double, 6, 1> v;
          for (int c = 0; c < 6; ++c) v[c] = e[c * n + i];
          const Eigen::Matrix<double, 6, 1> t = medium.at(i) * v;
          for (int c = 0; c < 6; ++c) {
            eps[c * n + i] = static_cast<float>(w[c] * v[c]);
            sig[c * n + i] = static_cast<float>(w[c] * t[c]);
          }
        }
        out.strain.push_back(std::move(eps));
        out.stress.push_back(std::move(sig));
      };
    }
    out.stiffness = effective_stiffness(dims, box, medium, opt);
    out.has_stiffness = true;
    std::vector<Mat6> phase_stiffness;
    for (size_t l = 0; l < image.phases.size(); ++l) {
      const Material* m = props.material[l];
      phase_stiffness.push_back(m && m->transverse_elasticity()
                                    ? transverse_stiffness(m->axial_young, m->transverse_young,
                                                           m->axial_shear, m->axial_poisson,
                                                           m->transverse_poisson, Vec3::UnitZ())
                                    : isotropic_stiffness(props.young[l], props.poisson[l]));
    }
    out.stiffness_spread = eigenvalue_spread<6>("stiffness", image, phase_stiffness);
    const Mat6& c = out.stiffness.stiffness;
    out.constants = engineering_constants(c);
    const double three_k = c.topLeftCorner<3, 3>().sum() / 3.0;
    out.bulk = three_k / 3.0;
    out.shear = (c.trace() - three_k) / 10.0;
    if (own == 0) {
      // Bulk and shear moduli per phase, and the Hashin-Shtrikman-Walpole comparison values.
      std::vector<double> bulk(f.size()), shear(f.size());
      for (size_t i = 0; i < f.size(); ++i) {
        bulk[i] = props.young[i] / (3.0 * (1.0 - 2.0 * props.poisson[i]));
        shear[i] = props.young[i] / (2.0 * (1.0 + props.poisson[i]));
      }
      const auto [gmin, gmax] = range(f, shear);
      const auto [kmin, kmax] = range(f, bulk);
      auto zeta = [](double k, double g) {
        return k + 2 * g > 0 ? g / 6.0 * (9 * k + 8 * g) / (k + 2 * g) : 0.0;
      };
      out.bulk_bounds = scalar_bounds(f, bulk, 4.0 / 3.0 * gmin, 4.0 / 3.0 * gmax);
      out.shear_bounds = scalar_bounds(f, shear, zeta(kmin, gmin), zeta(kmax, gmax));
    }
  }
  return out;
}

namespace {

// "1", "1 and 2", "1, 2 and 3".
std::string listed(const std::vector<int>& k) {
  std::string out;
  for (size_t i = 0; i < k.size(); ++i) {
    if (i > 0) out += i + 1 == k.size() ? " and " : ", ";
    out += std::to_string(k[i]);
  }
  return out;
}

template <size_t N>
std::string unconverged_cases(const char* physics, const std::array<int, N>& iterations,
                              const std::array<double, N>& residual,
                              const std::array<std::string, N>& breakdown, double tolerance,
                              const std::string& spread) {
  std::vector<int> broken;
  std::string first;
  for (size_t l = 0; l < N; ++l) {
    if (breakdown[l].empty()) continue;
    broken.push_back(static_cast<int>(l) + 1);
    if (first.empty()) first = breakdown[l];
  }
  std::string out;
  if (!broken.empty()) {
    out = std::string(physics) + ": load case" + (broken.size() > 1 ? "s " : " ") + listed(broken) +
          " broke down (" + (broken.size() > 1 ? "the first: " : "") + first +
          "): the solver's arithmetic failed, which is no slow convergence; " + spread;
  }
  std::vector<int> cases;
  int most = 0;
  double worst = 0.0;
  for (size_t l = 0; l < N; ++l) {
    if (!breakdown[l].empty()) continue;
    if (iterations[l] > 0 && !(residual[l] < tolerance)) {
      cases.push_back(static_cast<int>(l) + 1);
      most = std::max(most, iterations[l]);
      worst = std::max(worst, residual[l]);
    }
  }
  if (cases.empty()) return out;
  char tail[160];
  std::snprintf(tail, sizeof tail,
                " stopped at %d iterations with relative residuals up to %.1e, above the "
                "tolerance %.0e",
                most, worst, tolerance);
  return out + (out.empty() ? "" : "; ") + physics + ": load case" +
         (cases.size() > 1 ? "s " : " ") + listed(cases) + tail;
}

}  // namespace

std::string unconverged(const EffectiveProperties& e, double tolerance) {
  std::string out;
  auto add = [&](const std::string& part) {
    if (!part.empty()) out += (out.empty() ? "" : "; ") + part;
  };
  if (e.has_conductivity) {
    add(unconverged_cases("conductivity", e.conductivity.iterations, e.conductivity.residual,
                          e.conductivity.breakdown, tolerance, e.conductivity_spread));
  }
  if (e.has_stiffness) {
    add(unconverged_cases("elasticity", e.stiffness.iterations, e.stiffness.residual,
                          e.stiffness.breakdown, tolerance, e.stiffness_spread));
  }
  return out;
}

}  // namespace rvegen
