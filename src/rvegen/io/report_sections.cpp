#include "rvegen/io/report_sections.hpp"

#include <algorithm>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "rvegen/io/report.hpp"

namespace rvegen {

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

}  // namespace

std::string tet_mesh_section(const InclusionSet& set, const TetMesh& mesh, const TetQuality& q,
                             const TetMeshRun& run) {
  std::vector<double> exact = phase_volume_fractions(set, mesh.phases);
  for (double& v : exact) v *= set.box.volume();
  Json r;
  r["files"] = {"mesh_tet.inp", "mesh_tet.msh", "mesh_tet.vtu"};
  for (const std::string& deck : run.decks) r["files"].push_back(deck);
  r["mesher"] = "Gmsh (OpenCASCADE, " + mesh.volume_mesher + ")";
  r["tetrahedra"] = mesh.tets.size();
  // 1: 4-node tetrahedra (C3D4); 2: 10-node (C3D10), straight edges (mesh_tet.order).
  r["order"] = mesh.mid.empty() ? 1 : 2;
  r["nodes"] = mesh.nodes.size();
  r["periodic_pairs"] = mesh.periodic.size();
  r["merged_nodes"] = mesh.merged_nodes;
  r["snapped_nodes"] = mesh.snapped_nodes;
  // Interface nodes moved along the normal to keep the phases' volumes (mesh_tet.keep_volumes).
  r["moved_nodes"] = mesh.moved_nodes;
  // Nodes inside one region moved to lift elements under 5 degrees.
  r["relocated_nodes"] = mesh.relocated_nodes;
  // Nodes added inside one region where elements under 5 degrees were left.
  r["inserted_nodes"] = mesh.inserted_nodes;
  r["remade_slivers"] = mesh.remade_slivers;
  r["sliver_rounds"] = mesh.sliver_rounds;
  r["flat_elements_removed"] = mesh.flat_elements_removed;
  r["raised_triangles"] = mesh.raised_triangles;
  r["flipped_chords"] = mesh.flipped_chords;
  r["retries"] = mesh.retries;
  // The cell meshed: the box, or the box moved along its axes (mesh_tet.shift_cell).
  r["cell_origin"] = {mesh.box.origin[0], mesh.box.origin[1], mesh.box.origin[2]};
  // (1 and more alike: far from grazing anything; no inclusion near an edge gives 1.)
  r["face_clearance"] = std::min(1.0, run.face_clearance);
  r["edge_clearance"] = std::min(1.0, run.edge_clearance);
  r["min_element_volume"] = q.min_volume;
  Json phases = Json::array();
  for (const Phase& p : mesh.phases) {
    const double v = q.phase_volume[p.label];
    phases.push_back({{"label", p.label},
                      {"name", p.name},
                      {"volume", v},
                      {"exact_volume", exact[p.label]},
                      {"relative_error", exact[p.label] > 0.0 ? v / exact[p.label] - 1.0 : 0.0}});
  }
  r["phases"] = phases;
  Json d;
  d["min"] = q.min_dihedral;
  d["quantile_1_percent"] = q.quantiles[0];
  d["quantile_5_percent"] = q.quantiles[1];
  d["median"] = q.quantiles[2];
  d["below_5_degrees"] = q.below_5_degrees;
  d["bins_from"] = TetQuality::kBins;
  d["counts"] = q.dihedral_counts;
  r["min_dihedral_degrees"] = d;
  // Inclusions moved off the cell's faces before anything was written (mesh_tet.nudge), and
  // those that graze it with no room to move.
  r["nudged_inclusions"] = run.nudged;
  r["nudge_stuck"] = run.nudge_stuck;
  // The estimate the memory check used, beside the count it estimated.
  r["estimated_tetrahedra"] = std::llround(run.estimated_elements);
  return r.dump();
}

std::string effective_section(const HomogenizationSpec& h, const EffectiveProperties& e,
                              int ranks) {
  Json out;
  if (ranks > 1) out["ranks"] = ranks;
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
    if (std::any_of(r.breakdown.begin(), r.breakdown.end(),
                    [](const std::string& b) { return !b.empty(); })) {
      c["breakdown"] = r.breakdown;  // per load case, "" where none
      c["spread"] = e.conductivity_spread;
    }
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
    if (std::any_of(r.breakdown.begin(), r.breakdown.end(),
                    [](const std::string& b) { return !b.empty(); })) {
      s["breakdown"] = r.breakdown;  // per load case, "" where none
      s["spread"] = e.stiffness_spread;
    }
    s["seconds"] = r.seconds;
    if (e.bulk_bounds.stated) {
      s["bounds"] = {{"bulk", bounds(e.bulk_bounds)}, {"shear", bounds(e.shear_bounds)}};
    } else {
      s["bounds"] = bounds(e.bulk_bounds);
    }
    out["stiffness"] = s;
  }
  return out.dump();
}

std::string audit_json(const InclusionSet& set, const AuditReport& report) {
  const auto& inc = set.inclusions;
  Json j;
  j["n"] = inc.size();
  j["count"] = report.overlaps.size();
  j["truncated"] = report.truncated;
  Json list = Json::array();
  for (const auto& o : report.overlaps) {
    list.push_back({{"a", inc[o.a].id},
                    {"b", inc[o.b].id},
                    {"type", contact_type_name(o.contact.type)},
                    {"depth", o.contact.depth},
                    {"shift", {o.shift[0], o.shift[1], o.shift[2]}}});
  }
  j["overlapping_pairs"] = list;
  Json out = Json::array();
  for (int i : report.outside) out.push_back(inc[i].id);
  j["outside_box"] = out;
  return j.dump(1) + "\n";
}

std::string audit_text(const InclusionSet& set, const AuditReport& report) {
  const auto& inc = set.inclusions;
  std::string text;
  char buf[200];
  for (const auto& o : report.overlaps) {
    std::snprintf(buf, sizeof buf, "overlap: %d %d type %s depth %.6g%s\n", inc[o.a].id,
                  inc[o.b].id, contact_type_name(o.contact.type), o.contact.depth,
                  o.shift.isZero() ? "" : " (periodic image)");
    text += buf;
  }
  for (int i : report.outside) {
    std::snprintf(buf, sizeof buf, "outside box: %d\n", inc[i].id);
    text += buf;
  }
  std::snprintf(buf, sizeof buf, "%zu inclusions, %s%zu overlapping pairs, %zu outside the box\n",
                inc.size(), report.truncated ? "at least " : "", report.overlaps.size(),
                report.outside.size());
  return text + buf;
}

}  // namespace rvegen
