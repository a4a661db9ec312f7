#include "rvegen/pipeline/run.hpp"

#include <tbb/parallel_invoke.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <utility>

#include "rvegen/io/amitex.hpp"
#include "rvegen/io/fe_mesh.hpp"
#include "rvegen/io/hdf5_writer.hpp"
#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/report.hpp"
#include "rvegen/io/report_sections.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/raster/glyphs.hpp"
#include "rvegen/raster/levelset.hpp"
#include "rvegen/raster/mesh.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// A mesh's three files (STEM.inp, .msh, .vtu), formatted side by side: each writer is serial,
// and they only read the mesh.
using Fill = std::function<void(std::FILE*)>;
void write_mesh_files(OutputSet& out, const std::string& stem, const Fill& inp, const Fill& msh,
                      const Fill& vtu) {
  tbb::parallel_invoke([&] { out.write_with(stem + ".inp", inp); },
                       [&] { out.write_with(stem + ".msh", msh); },
                       [&] { out.write_with(stem + ".vtu", vtu); });
}

// The run's state between its stages: what is kept for the report, and each stage's time.
struct Run {
  const Scene& scene;
  const RunPlan& plan;
  const RunOptions& options;
  OutputSet& out;
  Packed packed;
  TetMeshNeed mesh_need;
  RunTimings timings;
  LevelSets levelsets;  // the grid summaries (the grids are written and dropped)
  VoxelImage image;
  ReportStatistics stats;
  EffectiveProperties solved;
  std::vector<ReportSection> sections;
  RunOutcome outcome;

  void say(const std::string& line) const {
    if (options.progress) options.progress(line);
  }
  void timed(const std::string& what, const std::function<void()>& f) {
    const auto t = std::chrono::steady_clock::now();
    f();
    const double sec = seconds_since(t);
    timings.phases.emplace_back(what, sec);
    char buf[160];
    std::snprintf(buf, sizeof buf, "%s: %.2f s", what.c_str(), sec);
    say(buf);
  }
  const InclusionSet& set() const { return packed.result.set; }
};

void pack_stage(Run& run) {
  Monitor monitor;
  monitor.line = run.options.progress;
  run.packed = pack_scene(run.scene, monitor, run.options.before_audit);
  run.timings.phases.emplace_back("packing", run.packed.result.seconds);
  run.timings.phases.emplace_back("audit", run.packed.result.audit_seconds);
  const Nudged& n = run.packed.nudged;
  if (n.moved > 0 || n.stuck > 0) {
    run.say("tetrahedral mesh: " + std::to_string(n.moved) +
            " inclusions moved off the cell's faces, " + std::to_string(n.stuck) +
            " with no room to");
  }
  // The tetrahedral mesh of the packed set, from the mesher's own size field (the gaps between
  // the inclusions are known now), against the same limit, before anything is written.
  if (run.scene.outputs.mesh_tet) {
    run.mesh_need =
        check_tet_mesh_fits(run.set(), run.scene.tet_mesh, run.plan.limit, run.plan.need);
    ResourceEstimate e = run.plan.need;
    e.tetrahedra = run.mesh_need.elements;
    e.tet_mesh_bytes = run.mesh_need.bytes;
    run.say(std::string("tetrahedral mesh: ") + (run.mesh_need.capped ? "more than " : "about ") +
            std::to_string(static_cast<long long>(run.mesh_need.elements)) + " elements, " +
            format_bytes(e.total_bytes()) + " expected");
  }
}

void shapes_stage(Run& run) {
  const Outputs& want = run.scene.outputs;
  std::string inclusions;
  if (want.inclusions) {
    run.timed("write inclusions.json", [&] {
      inclusions = write_inclusions_json(run.set());
      run.out.write("inclusions.json", inclusions);
    });
    run.timed("write inclusions.vtp", [&] {
      run.out.write_with("inclusions.vtp",
                         [&](std::FILE* f) { write_points_vtp(run.set(), inclusions, f); });
    });
  }
  // Surfaces: of every inclusion when the mesh is asked for; otherwise of the wavy, deformed,
  // coated and debonded ones only (their shape is not a glyph), when there are any.
  const InclusionSet meshed = meshed_inclusions(run.set(), want.mesh, true);
  if (!meshed.inclusions.empty()) {
    run.timed("surfaces", [&] {
      const SurfaceMesh mesh = tessellate(meshed, mesh_options(run.scene, run.scene.box));
      run.out.write_with("surfaces.vtp",
                         [&](std::FILE* f) { write_surfaces_vtp(mesh, inclusions, f); });
    });
  }
}

// The level sets of the inclusions whose shape is not exact (after shapes_stage has let go
// of the surfaces and the inclusion list's text).
void levelset_stage(Run& run) {
  const Outputs& want = run.scene.outputs;
  if (run.plan.need.band_voxels > 0.0) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "level sets: about %.3g narrow-band voxels to compute",
                  run.plan.need.band_voxels);
    run.say(buf);
  }
  if (want.levelsets)
    run.timed("level sets", [&] {
      LevelSetOptions lopt;
      lopt.voxel_size = run.scene.levelset_voxel_size;
      lopt.half_width = run.scene.levelset_half_width;
      lopt.exact_shapes = want.levelsets_asked;
      run.levelsets = build_level_sets(run.set(), lopt);
      if (!run.levelsets.empty())
        run.out.write("levelsets.vdb", vdb_bytes(run.levelsets, run.set()));
      run.levelsets.data.reset();  // the report keeps the grid summaries only
    });
}

void write_amitex(Run& run) {
  const Scene& scene = run.scene;
  OutputSet& out = run.out;
  const VoxelImage& image = run.image;
  out.write_with("material.vtk", [&](std::FILE* f) { write_material_vtk(image, f); });
  out.write_with("zoneID.vtk", [&](std::FILE* f) { write_zone_vtk(image, f); });
  out.write("amitex_materials.xml", amitex_materials_xml(scene, run.set(), image));
  out.write("amitex_loading.xml", amitex_loading_xml());
  out.write("amitex_algorithm.xml", amitex_algorithm_xml());
  if (amitex_conductivity_wanted(scene)) {
    out.write("amitex_conductivity_materials.xml", amitex_conductivity_materials_xml(scene, image));
    out.write("amitex_conductivity_loading.xml", amitex_conductivity_loading_xml());
    out.write("amitex_conductivity_algorithm.xml", amitex_conductivity_algorithm_xml());
  }
  out.write("amitex_run.sh", amitex_run_sh(scene));
}

void voxel_stage(Run& run) {
  const Scene& scene = run.scene;
  const Outputs& want = scene.outputs;
  if (want.image() || scene.homogenization.any()) {
    run.timed("voxels", [&] {
      VoxelOptions vopt;
      vopt.partial_volume = scene.partial_volume;
      vopt.subsamples = scene.subsamples;
      run.image = voxelize(run.set(), scene.resolution, vopt);
    });
  }
  const VoxelImage& image = run.image;
  if (want.voxels) {
    run.timed("write voxels.vti", [&] {
      run.out.write_with("voxels.vti", [&](std::FILE* f) { write_vti(image, f); });
    });
  }
  if (want.amitex) run.timed("write material.vtk", [&] { write_amitex(run); });
  if (want.mesh_voxel) {
    run.timed("write mesh_voxel.inp, .msh, .vtu", [&] {
      write_mesh_files(
          run.out, "mesh_voxel", [&](std::FILE* f) { write_abaqus_voxel_mesh(image, f); },
          [&](std::FILE* f) { write_gmsh_voxel_mesh(image, f); },
          [&](std::FILE* f) { write_voxel_mesh_vtu(image, f); });
      for (const bool elastic : {false, true}) {
        const std::string deck = abaqus_voxel_deck(scene, run.set(), image, elastic);
        if (!deck.empty()) {
          run.out.write(elastic ? "run_voxel_elasticity.inp" : "run_voxel_conductivity.inp", deck);
        }
      }
    });
  }
}

void tet_mesh_stage(Run& run) {
  const Scene& scene = run.scene;
  TetMesh tets;
  run.timed("tetrahedral mesh", [&] {
    TetMeshOptions topt;
    static_cast<TetMeshSpec&>(topt) = scene.tet_mesh;
    topt.threads = run.options.threads;
    tets = tet_mesh(run.set(), topt, [&](double, const std::string& line) {
      if (!line.empty()) run.say(line);
      return true;
    });
  });
  run.timed("write mesh_tet.inp, .msh, .vtu", [&] {
    write_mesh_files(
        run.out, "mesh_tet", [&](std::FILE* f) { write_abaqus_tet_mesh(tets, f); },
        [&](std::FILE* f) { write_gmsh_tet_mesh(tets, f); },
        [&](std::FILE* f) { write_tet_mesh_vtu(tets, f); });
  });
  TetMeshRun info;
  info.nudged = run.packed.nudged.moved;
  info.nudge_stuck = run.packed.nudged.stuck;
  info.estimated_elements = run.mesh_need.elements;
  info.face_clearance = face_clearance(run.set(), tets.box.origin);
  info.edge_clearance = edge_clearance(run.set(), tets.box.origin);
  for (const bool elastic : {false, true}) {
    const std::string deck = abaqus_tet_deck(scene, run.set(), tets, elastic);
    const char* name = elastic ? "run_tet_elasticity.inp" : "run_tet_conductivity.inp";
    if (!deck.empty()) {
      run.out.write(name, deck);
      info.decks.push_back(name);
    }
  }
  const TetQuality q = tet_quality(tets);
  run.outcome.slivers = q.below_5_degrees;
  run.outcome.least_dihedral = q.min_dihedral;
  run.sections.emplace_back("mesh_tet", tet_mesh_section(run.set(), tets, q, info));
}

// The local fields for rve.h5 (scene.homogenization.fields), per load case.
std::vector<LocalField> local_fields(const EffectiveProperties& solved) {
  std::vector<LocalField> fields;
  auto add = [&](const char* physics, const char* what, const char* names, int count,
                 const std::vector<std::vector<float>>& per_load) {
    for (size_t l = 0; l < per_load.size(); ++l) {
      fields.push_back({std::string(physics) + "/load_" + std::to_string(l) + "/" + what, names,
                        count, &per_load[l]});
    }
  };
  add("conductivity", "gradient", "1 2 3", 3, solved.gradient);
  add("conductivity", "flux", "1 2 3", 3, solved.flux);
  add("elasticity", "strain", "11 22 33 23 13 12", 6, solved.strain);
  add("elasticity", "stress", "11 22 33 23 13 12", 6, solved.stress);
  return fields;
}

void report_stage(Run& run) {
  const Scene& scene = run.scene;
  const Outputs& want = scene.outputs;
  std::vector<LocalField> fields;
  if (scene.homogenization.any()) {
    run.timed("homogenization", [&] {
      run.solved = solve_effective(scene, run.set(), run.image, run.options.progress);
    });
    run.outcome.not_converged = unconverged(run.solved, scene.homogenization.tolerance);
    run.sections.emplace_back("effective", effective_section(scene.homogenization, run.solved));
    fields = local_fields(run.solved);
  }
  if (want.statistics) {
    run.timed("statistics", [&] { run.stats = report_statistics(scene, run.packed.result); });
  }
  auto report_now = [&] {
    run.timings.total_seconds = seconds_since(run.options.start);
    run.timings.peak_memory_mb = peak_memory_mb();
    return report_json(scene, run.packed.result, want.image() ? &run.image : nullptr, run.timings,
                       &run.levelsets, want.statistics ? &run.stats : nullptr, run.sections);
  };
  // rve.h5 carries the report as it stood before rve.h5 itself was written.
  if (want.h5) {
    run.timed("write rve.h5", [&] {
      run.out.write("rve.xdmf", xdmf_text(run.image, "rve.h5", fields));
      write_hdf5(run.out.staged_path("rve.h5"), run.image, run.set(), scene_to_json(scene),
                 report_now(), fields);
    });
  }
  // The files of the set and their sizes: what a later run checks before it replaces them.
  run.sections.emplace_back("files", run.out.files_json());
  run.out.write("report.json", report_now());
}

}  // namespace

std::string MemoryLimit::above() const {
  return std::string(", above the ") + (given ? "--max-memory limit of " : "memory available, ") +
         format_bytes(bytes);
}

MemoryLimit memory_limit(double max_memory) {
  MemoryLimit m;
  m.given = max_memory > 0.0;
  m.bytes = m.given ? max_memory : available_memory_bytes();
  return m;
}

RunPlan plan_run(const Scene& scene, const MemoryLimit& limit) {
  RunPlan plan;
  plan.limit = limit;
  plan.need = estimate_resources(scene);
  const bool over = limit.exceeded_by(plan.need.total_bytes());
  if (over && scene.outputs.mesh_tet) {
    Scene without = scene;
    without.outputs.mesh_tet = false;
    plan.mesh_guess_over = !limit.exceeded_by(estimate_resources(without).total_bytes());
  }
  if (over && !plan.mesh_guess_over)
    throw InputError("the scene needs about " + describe(plan.need) + limit.above());
  return plan;
}

Nudged nudge_for_tet_mesh(InclusionSet* set, const TetMeshSpec& spec, double min_gap) {
  check_tet_meshable(*set);
  Nudged nudged;
  if (!spec.shift_cell || !spec.nudge) return nudged;
  InclusionSet moved = *set;
  nudged = nudge_off_chosen_cell(&moved, min_gap);
  if (nudged.moved > 0) {
    if (audit(moved, 16).clean()) {
      *set = std::move(moved);
    } else {
      nudged.stuck += nudged.moved;
      nudged.moved = 0;
    }
  }
  return nudged;
}

TetMeshNeed check_tet_mesh_fits(const InclusionSet& set, const TetMeshSpec& spec,
                                const MemoryLimit& limit, const ResourceEstimate& others,
                                SettingNames names) {
  const TetMeshNeed need = tet_mesh_need(set, spec, limit.bytes);
  ResourceEstimate packed = others;
  packed.tetrahedra = need.elements;
  packed.tet_mesh_bytes = need.bytes;
  if (!limit.exceeded_by(packed.total_bytes())) return need;
  const std::string about = (need.capped ? "more than " : "about ") +
                            std::to_string(static_cast<long long>(need.elements)) + " elements, " +
                            format_bytes(packed.total_bytes());
  // The first coarser mesh of this RVE that would fit, if any.
  TetMeshSpec fit;
  TetMeshNeed fit_need;
  std::string instead;
  auto fits = [&](const TetMeshNeed& n) {
    ResourceEstimate e = packed;
    e.tet_mesh_bytes = n.bytes;
    return !limit.exceeded_by(e.total_bytes());
  };
  if (coarser_tet_mesh_that_fits(set, spec, limit.bytes, fits, &fit, &fit_need)) {
    packed.tet_mesh_bytes = fit_need.bytes;
    instead = "; with " + describe_tet_mesh_change(spec, fit, names) +
              " this RVE's mesh would need about " +
              std::to_string(static_cast<long long>(fit_need.elements)) + " elements, " +
              format_bytes(packed.total_bytes());
  }
  const bool scene = names == SettingNames::kScene;
  throw InputError(std::string(scene ? "mesh_tet: " : "") +
                   "the tetrahedral mesh of this RVE needs " + about + " at peak" + limit.above() +
                   instead +
                   (scene ? " (raise mesh_tet.chord_error or max_size, lower gap_elements, or "
                            "give a larger min_gap: thin gaps take the smallest elements)"
                          : " (raise ChordError or MaxSize, or lower GapElements)"));
}

Packed pack_scene(const Scene& scene, const Monitor& monitor,
                  const std::function<void(InclusionSet&)>& before_audit) {
  Packed p;
  p.result = generate(scene, monitor, before_audit);
  // Inclusions that the mesh's cell cannot keep off are moved off its faces where there is
  // room, before anything is made of them.
  if (scene.outputs.mesh_tet)
    p.nudged = nudge_for_tet_mesh(&p.result.set, scene.tet_mesh, scene.min_gap);
  return p;
}

EffectiveProperties solve_effective(const Scene& scene, const InclusionSet& set,
                                    const VoxelImage& image, const ProgressFn& progress,
                                    const Communicator& comm) {
  auto last =
      std::make_shared<std::chrono::steady_clock::time_point>(std::chrono::steady_clock::now());
  SolveProgress lines = [=](const char* physics, int load, int loads, int it, double rel) {
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
  return effective_properties(scene, set, image, lines, comm);
}

RunOutcome run_to_directory(const Scene& scene, const RunPlan& plan, const RunOptions& options,
                            OutputSet& out) {
  Run run{scene, plan, options, out, {}, {}, {}, {}, {}, {}, {}, {}, {}};
  if (plan.mesh_guess_over) {
    run.say("tetrahedral mesh: about " +
            std::to_string(static_cast<long long>(plan.need.tetrahedra)) +
            " elements guessed from the scene, " + format_bytes(plan.need.total_bytes()) +
            " at peak" + plan.limit.above() + ": packing, then the packed inclusions' gaps decide");
  }
  pack_stage(run);
  shapes_stage(run);
  levelset_stage(run);
  voxel_stage(run);
  if (scene.outputs.mesh_tet) tet_mesh_stage(run);
  report_stage(run);
  run.outcome.result = std::move(run.packed.result);
  return std::move(run.outcome);
}

}  // namespace rvegen
