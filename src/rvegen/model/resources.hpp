// What a scene will cost before any of it is done: an estimate of the peak memory of a
// `rvegen generate` run, to refuse a scene the machine cannot hold (exit 2, naming the figure)
// instead of failing half-way.
#pragma once

#include <string>
#include <vector>

#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/scene.hpp"

namespace rvegen {

struct ResourceEstimate {
  double inclusions = 0.0;            // expected number of inclusions
  double voxels = 0.0;                // voxels of the image
  double band_voxels = 0.0;           // narrow-band voxels of the level sets
  double packing_bytes = 0.0;         // the packer's bodies, pair lists and the inclusion list
  double surface_bytes = 0.0;         // the tessellated surfaces and their file
  double voxel_bytes = 0.0;           // the voxel image (written as it is, no copy)
  double levelset_bytes = 0.0;        // the OpenVDB grids while they are built and written
  double homogenization_bytes = 0.0;  // the FFT solver's fields (the image stays alive)
  double tetrahedra = 0.0;            // elements of the tetrahedral mesh (mesh_tet)
  double tet_mesh_bytes = 0.0;        // Gmsh's model and mesh, rvegen's copy, the writers
  /// Peak: the phases run one after the other, the inclusion list stays throughout.
  double total_bytes() const;
};

/// Estimates from the scene alone (expected counts, mean sizes, resolution, voxel size). The
/// per-item costs were measured on this program's runs, and the estimate checked against the
/// measured peak of whole runs (docs/benchmarks.md).
ResourceEstimate estimate_resources(const Scene& scene);

/// Elements of a tetrahedral mesh near one inclusion's surface (the element size there is the
/// chord bound on the least radius of curvature, rho sqrt(8 chord_error), at most `largest`, and
/// grows away from it) and, when coated, in its shell (gap_elements across the coating).
double tet_elements_near(const Shape& s, double coating, const TetMeshSpec& t, double largest);

/// Peak bytes of a tetrahedral mesh of `elements` elements of a set of `inclusions` inclusions
/// (of first or second order): the mesher's model and mesh, rvegen's copy and the writers, and
/// OpenCASCADE's solids and fragments for each inclusion.
double tet_mesh_bytes(double elements, double inclusions, int order);

/// Coarser tetrahedral meshes than `spec`, to offer when its mesh does not fit, in the order
/// to try them: the least loss of accuracy first. A larger chord error (0.01, 0.03, 0.1), and
/// at 0.03 and 0.1 one element across the gaps with 10-node elements (on near-touching
/// spheres these came far closer to the FFT than 4-node ones two across: docs/analyst.md), then
/// at 0.1 half an element across (close to one across, with fewer elements). Each is at least
/// as coarse as `spec` in every setting; none equal to it.
std::vector<TetMeshSpec> coarser_tet_meshes(const TetMeshSpec& spec);

/// The settings of `to` that differ from `from`: as the scene's object,
/// "\"mesh_tet\": {\"chord_error\": 0.03, \"gap_elements\": 1, \"order\": 2}", or as the
/// ParaView filter's properties, "ChordError 0.03, GapElements 1, Order 2".
enum class SettingNames { kScene, kProperties };
std::string describe_tet_mesh_change(const TetMeshSpec& from, const TetMeshSpec& to,
                                     SettingNames names = SettingNames::kScene);

/// Memory this process may still take: the smallest of MemAvailable (/proc/meminfo), what its
/// cgroup allows, and what its address-space limit (ulimit -v) leaves; 0 when unknown.
double available_memory_bytes();

/// Peak resident memory of this process so far, in MiB (0 when unknown).
double peak_memory_mb();

/// "1.2 GB (packing 0.3 GB, surfaces 0.1 GB, voxels 0.8 GB, level sets 0 GB)".
std::string describe(const ResourceEstimate& e);
/// "1.2 GB".
std::string format_bytes(double bytes);

}  // namespace rvegen
