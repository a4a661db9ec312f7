#include "effective.hpp"

#include <chrono>
#include <cstdio>
#include <memory>
#include <string>

#include "rvegen/homogenize/effective.hpp"

namespace rvegen::cli {

namespace {

using Json = nlohmann::ordered_json;

Json rows(const Eigen::MatrixXd& m) {
  Json out = Json::array();
  for (int i = 0; i < m.rows(); ++i) {
    Json row = Json::array();
    for (int j = 0; j < m.cols(); ++j) row.push_back(m(i, j));
    out.push_back(row);
  }
  return out;
}

Json bounds(const Bounds& b) {
  if (!b.stated) return "not stated: the isotropic bounds do not apply to anisotropic fibres";
  return {{"voigt", b.voigt}, {"reuss", b.reuss}, {"hashin_shtrikman", {b.hs_lower, b.hs_upper}}};
}

// A progress line at most once a second: "<physics>: load L/N, iteration I, residual R".
SolveProgress progress_lines(const ProgressFn& progress) {
  auto last =
      std::make_shared<std::chrono::steady_clock::time_point>(std::chrono::steady_clock::now());
  return [=](const char* physics, int load, int loads, int it, double rel) {
    if (!progress) return true;
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - *last).count() < 1.0) return true;
    *last = now;
    char buf[160];
    std::snprintf(buf, sizeof buf, "%s: load %d/%d, iteration %d, residual %.2e", physics, load + 1,
                  loads, it, rel);
    progress(buf);
    return true;
  };
}

}  // namespace

Json effective_properties(const Scene& scene, const InclusionSet& set, const VoxelImage& image,
                          const ProgressFn& progress, EffectiveProperties* keep,
                          const Communicator& comm) {
  const HomogenizationSpec& h = scene.homogenization;
  EffectiveProperties local;
  EffectiveProperties& e = keep ? *keep : local;
  e = rvegen::effective_properties(scene, set, image, progress_lines(progress), comm);
  Json out;
  if (ranks_of(comm) > 1) out["ranks"] = ranks_of(comm);
  out["voxel_rule"] = {
      {"rule", e.voxel_rule},
      {"meaning",
       e.voxel_rule == "plain"
           ? "each voxel has the properties of the phase at its centre"
           : "voxels cut by one core surface mix the two phases by the rule (laminate: exact "
             "share and normal); other voxels take the phase at their centre"},
      {"cut_voxels", e.cut_voxels},
      {"voxels_cut_by_two_cores", e.shared_voxels}};
  out["resolution"] = {e.resolution[0], e.resolution[1], e.resolution[2]};
  out["phase_shares"] = e.phase_shares;
  if (e.has_conductivity) {
    const ConductivityResult& r = e.conductivity;
    Json c;
    c["tensor"] = rows(r.tensor);
    c["mean_of_diagonal"] = r.tensor.trace() / 3.0;
    c["scheme"] = h.scheme;
    c["solver"] = h.solver;
    c["iterations"] = r.iterations;
    c["residual"] = r.residual;
    c["converged"] = r.converged;
    c["seconds"] = r.seconds;
    c["bounds"] = bounds(e.conductivity_bounds);
    out["conductivity"] = c;
  }
  if (e.has_stiffness) {
    const ElasticityResult& r = e.stiffness;
    const EngineeringConstants& k = e.constants;
    Json s;
    s["notation"] =
        "Mandel: rows and columns 11, 22, 33, 23, 13, 12, shear components times sqrt 2";
    s["tensor"] = rows(r.stiffness);
    s["engineering_constants"] = {{"E1", k.e1},     {"E2", k.e2},     {"E3", k.e3},
                                  {"G23", k.g23},   {"G13", k.g13},   {"G12", k.g12},
                                  {"nu12", k.nu12}, {"nu13", k.nu13}, {"nu23", k.nu23}};
    s["isotropic_projection"] = {{"bulk", e.bulk}, {"shear", e.shear}};
    s["scheme"] = h.scheme;
    s["iterations"] = r.iterations;
    s["residual"] = r.residual;
    s["converged"] = r.converged;
    s["seconds"] = r.seconds;
    if (e.bulk_bounds.stated) {
      s["bounds"] = {{"bulk", bounds(e.bulk_bounds)}, {"shear", bounds(e.shear_bounds)}};
    } else {
      s["bounds"] = bounds(e.bulk_bounds);
    }
    out["stiffness"] = s;
  }
  return out;
}

}  // namespace rvegen::cli
