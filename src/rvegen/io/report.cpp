#include "rvegen/io/report.hpp"

#include <algorithm>
#include <nlohmann/json.hpp>

#include "rvegen/model/body.hpp"
#include "rvegen/model/stats.hpp"

namespace rvegen {

std::vector<double> family_volume_fractions(const InclusionSet& set, int n_families) {
  std::vector<double> vf(n_families, 0.0);
  for (const auto& inc : set.inclusions) {
    if (inc.family >= 0 && inc.family < n_families) vf[inc.family] += inc.shape.volume();
  }
  for (double& v : vf) v /= set.box.volume();
  return vf;
}

std::vector<double> phase_volume_fractions(const InclusionSet& set,
                                           const std::vector<Phase>& phases) {
  return phase_volume_fractions(set, phases, shell_overlaps(set));
}

std::vector<double> phase_volume_fractions(const InclusionSet& set,
                                           const std::vector<Phase>& phases,
                                           const ShellOverlaps& overlaps) {
  std::vector<double> exact(phases.size(), 0.0);
  for (const auto& inc : set.inclusions) {
    const RegionVolumes v = region_volumes(inc);
    for (const auto& p : phases) {
      if (p.family != inc.family) continue;
      if (p.kind == PhaseKind::kCore) exact[p.label] += v.core;
      if (p.kind == PhaseKind::kInterphase) exact[p.label] += v.shell;
      if (p.kind == PhaseKind::kVoid) exact[p.label] += v.void_;
    }
  }
  // Shells that may touch: a lens where two overlap belongs to the earlier inclusion's shell.
  for (const auto& p : phases) {
    if (p.kind == PhaseKind::kInterphase && p.family >= 0 &&
        p.family < static_cast<int>(overlaps.taken.size())) {
      exact[p.label] -= overlaps.taken[p.family];
    }
  }
  double solid = 0.0;
  for (double& v : exact) {
    v /= set.box.volume();
    solid += v;
  }
  if (!exact.empty()) exact[0] = 1.0 - solid;
  return exact;
}

ReportStatistics report_statistics(const Scene& scene, const PackingResult& r) {
  ReportStatistics out;
  const int nf = static_cast<int>(scene.families.size());
  out.radial.resize(nf);
  for (int f = 0; f < nf; ++f) {
    if (scene.families[f].shape != ShapeKind::Sphere) continue;
    // g(r) of the centres over five mean diameters (at most half the box).
    double mean_d = 0.0;
    int n = 0;
    for (const auto& inc : r.set.inclusions) {
      if (inc.family == f) {
        mean_d += 2.0 * inc.shape.radius;
        ++n;
      }
    }
    if (n > 1) out.radial[f] = radial_distribution(r.set, f, 50, 5.0 * mean_d / n);
  }
  out.nearest = nearest_neighbour_distances(r.set);
  return out;
}

namespace {

// report.json's "levelsets": the grids and their memory against a dense grid's.
nlohmann::ordered_json levelsets_json(const LevelSets& levelsets) {
  using OJson = nlohmann::ordered_json;
  OJson ls;
  ls["voxel_size"] = levelsets.voxel_size;
  ls["half_width_voxels"] = levelsets.half_width;
  OJson grids = OJson::array();
  for (const auto& g : levelsets.grids) {
    grids.push_back({{"name", g.name},
                     {"kind", phase_kind_name(g.kind)},
                     {"family", g.family},
                     {"phase", g.phase},
                     {"inclusions", g.inclusions},
                     {"active_voxels", g.active_voxels},
                     {"memory_bytes", g.memory_bytes}});
  }
  ls["grids"] = grids;
  ls["memory_bytes"] = levelsets.memory_bytes;
  ls["dense_bytes"] = levelsets.dense_bytes;
  ls["memory_ratio"] = static_cast<double>(levelsets.memory_bytes) /
                       static_cast<double>(std::max(1LL, levelsets.dense_bytes));
  return ls;
}

}  // namespace

std::string report_json(const Scene& scene, const PackingResult& r, const VoxelImage* image,
                        const RunTimings& timings, const LevelSets* levelsets,
                        const ReportStatistics* stats, const std::vector<ReportSection>& sections) {
  using OJson = nlohmann::ordered_json;
  const int nf = static_cast<int>(scene.families.size());
  const std::vector<double> vf = family_volume_fractions(r.set, nf);
  std::vector<double> voxel_vf(nf, 0.0);
  std::vector<double> label_vf;
  if (image) {
    label_vf = label_fractions(*image);
    for (int f = 0; f < nf && core_label(f) < static_cast<int>(label_vf.size()); ++f)
      voxel_vf[f] = label_vf[core_label(f)];
  }
  OJson root;
  root["status"] = status_name(r.status);
  root["method"] = method_name(scene.method);
  root["seed"] = scene.seed;
  double total = 0.0, target_total = 0.0;
  OJson fams = OJson::array();
  for (int f = 0; f < nf; ++f) {
    const Family& fam = scene.families[f];
    const double target = r.target_volume_fraction[f];
    OJson j;
    j["name"] = fam.name;
    j["shape"] = shape_name(fam.shape);
    j["count"] = r.placed_count[f];
    j["target_count"] = r.target_count[f];
    j["volume_fraction"] = vf[f];
    j["target_volume_fraction"] = target;
    if (image) j["voxel_volume_fraction"] = voxel_vf[f];
    if (fam.shape != ShapeKind::Sphere) {
      const Mat3 a = orientation_tensor(r.set, f);
      OJson rows = OJson::array();
      for (int k = 0; k < 3; ++k) rows.push_back({a(k, 0), a(k, 1), a(k, 2)});
      j["orientation_tensor"] = rows;
      // The law's tensor next to it, and the largest difference of a component.
      const Mat3 t = fam.orientation.tensor();
      OJson trows = OJson::array();
      for (int k = 0; k < 3; ++k) trows.push_back({t(k, 0), t(k, 1), t(k, 2)});
      j["target_orientation_tensor"] = trows;
      if (r.placed_count[f] > 0) j["orientation_tensor_error"] = (a - t).cwiseAbs().maxCoeff();
    } else if (stats && !stats->radial[f].r.empty()) {
      const RadialDistribution& g = stats->radial[f];
      j["radial_distribution"] = {{"r", g.r}, {"g", g.g}};
    }
    fams.push_back(j);
    total += vf[f];
    target_total += target;
  }
  root["volume_fraction"] = total;
  root["target_volume_fraction"] = target_total;
  root["count"] = r.set.inclusions.size();
  root["families"] = fams;
  // Every phase: the exact volume fraction from the geometry and, with an image, the share of
  // voxel centres carrying the label.
  const std::vector<Phase> phases = image ? image->phases : phase_table(r.set);
  const ShellOverlaps overlaps = shell_overlaps(r.set);
  const std::vector<double> exact = phase_volume_fractions(r.set, phases, overlaps);
  bool merged_shells = false;
  for (const auto& inc : r.set.inclusions) {
    merged_shells = merged_shells || (inc.mod.coated() && inc.mod.shells_may_touch);
  }
  OJson ph = OJson::array();
  for (const auto& p : phases) {
    OJson j;
    j["label"] = p.label;
    j["name"] = p.name;
    j["kind"] = phase_kind_name(p.kind);
    if (p.family >= 0) j["family"] = p.family;
    j["volume_fraction"] = exact[p.label];
    // Shells counted whole where they merge: the interphases' shares are upper bounds, the
    // matrix's a lower one (never below 0).
    if (merged_shells && !overlaps.exact && p.kind == PhaseKind::kInterphase) {
      // At most what the cores and voids leave.
      double others = 0.0;
      for (const auto& q : phases) {
        if (q.kind == PhaseKind::kCore || q.kind == PhaseKind::kVoid) others += exact[q.label];
      }
      j["volume_fraction"] = std::min(exact[p.label], std::max(0.0, 1.0 - others));
      j["bound"] = "upper";
    }
    if (merged_shells && !overlaps.exact && p.kind == PhaseKind::kMatrix) {
      j["volume_fraction"] = std::max(0.0, exact[p.label]);
      j["bound"] = "lower";
    }
    if (image) j["voxel_volume_fraction"] = label_vf[p.label];
    ph.push_back(j);
  }
  root["phases"] = ph;
  if (merged_shells) {
    root["shell_overlaps"] = {
        {"pairs", overlaps.pairs}, {"triples", overlaps.triples}, {"exact", overlaps.exact}};
    root["phases_note"] =
        overlaps.exact
            ? "shells_may_touch: where two shells overlap, the lens is counted once, in the "
              "earlier inclusion's shell (exact)"
            : "shells_may_touch: interphase volume fractions are the sum of the shells, an upper "
              "bound (merged shells count once in the image): " +
                  overlaps.why_not;
  }
  if (stats && stats->nearest.n > 0) {
    const Summary& nn = stats->nearest;
    root["nearest_neighbour_distance"] = {
        {"mean", nn.mean}, {"std", nn.std}, {"min", nn.min}, {"max", nn.max}};
  }
  if (levelsets && !levelsets->empty()) root["levelsets"] = levelsets_json(*levelsets);
  root["stop_reason"] = stop_reason_name(r.stop_reason);
  if (scene.method == Method::kMd) {
    root["steps"] = r.steps;
    root["scale"] = r.scale;
  } else {
    root["attempts"] = r.attempts;
  }
  root["packing_seconds"] = r.seconds;
  root["audit_seconds"] = r.audit_seconds;
  root["seconds"] = timings.total_seconds;
  OJson by_phase = OJson::object();
  for (const auto& [name, sec] : timings.phases) by_phase[name] = sec;
  root["timings"] = by_phase;
  if (timings.peak_memory_mb > 0.0) root["peak_memory_mb"] = timings.peak_memory_mb;
  if (image) {
    OJson vox;
    vox["resolution"] = {image->dims[0], image->dims[1], image->dims[2]};
    if (!image->fraction.empty()) {
      // The partial-volume estimate of the total core volume fraction.
      vox["partial_volume_fraction"] = partial_volume_fraction(*image);
    }
    vox["conflicts"] = image->conflicts;
    root["voxels"] = vox;
  }
  for (const ReportSection& s : sections) root[s.first] = OJson::parse(s.second);
  return root.dump(2) + "\n";
}

}  // namespace rvegen
