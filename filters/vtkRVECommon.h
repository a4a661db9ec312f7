// Shared by the RVE algorithms: core results copied into VTK data, and the inclusion list an
// RVE carries in its field data. Header-only, thin.
#ifndef vtkRVECommon_h
#define vtkRVECommon_h

#include <algorithm>
#include <functional>
#include <string>

#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/raster/glyphs.hpp"
#include "rvegen/raster/mesh.hpp"
#include "rvegen/raster/voxelize.hpp"
#include "vtkCellArray.h"
#include "vtkCellData.h"
#include "vtkDataObject.h"
#include "vtkDoubleArray.h"
#include "vtkFieldData.h"
#include "vtkFloatArray.h"
#include "vtkImageData.h"
#include "vtkIntArray.h"
#include "vtkNew.h"
#include "vtkPointData.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkStringArray.h"
#include "vtkTable.h"
#include "vtkTypeInt64Array.h"
#include "vtkUnsignedCharArray.h"

// Copies a core mesh into a vtkPolyData (points, triangles, cell arrays).
inline void RVEPolyDataFromMesh(const rvegen::SurfaceMesh& mesh, vtkPolyData* out) {
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(static_cast<vtkIdType>(mesh.points.size()));
  for (size_t i = 0; i < mesh.points.size(); ++i) {
    points->SetPoint(static_cast<vtkIdType>(i), mesh.points[i].data());
  }
  vtkNew<vtkTypeInt64Array> offsets, connectivity;
  offsets->SetNumberOfValues(static_cast<vtkIdType>(mesh.triangles.size() + 1));
  connectivity->SetNumberOfValues(static_cast<vtkIdType>(3 * mesh.triangles.size()));
  for (size_t t = 0; t <= mesh.triangles.size(); ++t) offsets->SetValue(t, 3 * t);
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) connectivity->SetValue(3 * t + k, mesh.triangles[t][k]);
  }
  vtkNew<vtkCellArray> polys;
  polys->SetData(offsets, connectivity);
  out->SetPoints(points);
  out->SetPolys(polys);
  auto int_array = [](const char* name, const std::vector<int32_t>& v) {
    vtkNew<vtkIntArray> a;
    a->SetName(name);
    a->SetNumberOfValues(static_cast<vtkIdType>(v.size()));
    std::copy(v.begin(), v.end(), a->GetPointer(0));
    return a;
  };
  out->GetCellData()->AddArray(int_array("inclusion_id", mesh.inclusion_id));
  out->GetCellData()->AddArray(int_array("family", mesh.family));
  out->GetCellData()->AddArray(int_array("shape", mesh.shape));
  out->GetCellData()->AddArray(int_array("phase", mesh.phase));
  vtkNew<vtkFloatArray> axis;
  axis->SetName("axis");
  axis->SetNumberOfComponents(3);
  axis->SetNumberOfTuples(static_cast<vtkIdType>(mesh.axis.size()));
  for (size_t t = 0; t < mesh.axis.size(); ++t) axis->SetTypedTuple(t, mesh.axis[t].data());
  out->GetCellData()->AddArray(axis);
  out->GetCellData()->SetActiveScalars("family");
}

// Copies glyph points (rvegen::glyph_points) into a vtkPolyData: one vertex per point, point
// data as inclusions.vtp (see rvegen/raster/glyphs.hpp).
inline void RVEPolyDataFromGlyphs(const rvegen::GlyphPoints& g, vtkPolyData* out) {
  const vtkIdType n = static_cast<vtkIdType>(g.size());
  vtkNew<vtkDoubleArray> xyz;
  xyz->SetNumberOfComponents(3);
  xyz->SetNumberOfTuples(n);
  std::copy(g.points.begin(), g.points.end(), xyz->GetPointer(0));
  vtkNew<vtkPoints> points;
  points->SetData(xyz);
  vtkNew<vtkTypeInt64Array> offsets, connectivity;
  offsets->SetNumberOfValues(n + 1);
  connectivity->SetNumberOfValues(n);
  for (vtkIdType i = 0; i <= n; ++i) offsets->SetValue(i, i);
  for (vtkIdType i = 0; i < n; ++i) connectivity->SetValue(i, i);
  vtkNew<vtkCellArray> verts;
  verts->SetData(offsets, connectivity);
  out->SetPoints(points);
  out->SetVerts(verts);
  vtkPointData* pd = out->GetPointData();
  auto int_array = [&](const char* name, const std::vector<int32_t>& v) {
    vtkNew<vtkIntArray> a;
    a->SetName(name);
    a->SetNumberOfValues(n);
    std::copy(v.begin(), v.end(), a->GetPointer(0));
    pd->AddArray(a);
  };
  auto double_array = [&](const char* name, int components, const std::vector<double>& v) {
    vtkNew<vtkDoubleArray> a;
    a->SetName(name);
    a->SetNumberOfComponents(components);
    a->SetNumberOfTuples(n);
    std::copy(v.begin(), v.end(), a->GetPointer(0));
    pd->AddArray(a);
  };
  int_array("inclusion_id", g.inclusion_id);
  int_array("family", g.family);
  int_array("shape", g.shape);
  int_array("phase", g.phase);
  int_array("image", g.image);
  int_array("modified", g.modified);
  double_array("radius", 1, g.radius);
  double_array("coating", 1, g.coating);
  double_array("half_axis", 3, g.half_axis);
  double_array("semi_axes", 3, g.semi_axes);
  double_array("orientation", 4, g.orientation);
  double_array("direction", 3, g.direction);
  double_array("scale", 3, g.scale);
  pd->SetActiveScalars("family");
  pd->SetActiveVectors("scale");
}

/// Field data "phase_names": the name of each phase label, in label order.
inline void RVEAddPhaseNames(const std::vector<rvegen::Phase>& phases, vtkDataObject* out) {
  vtkNew<vtkStringArray> names;
  names->SetName("phase_names");
  for (const auto& p : phases) names->InsertNextValue(p.name);
  out->GetFieldData()->AddArray(names);
}

/// Voxelizes `set` straight into the arrays of `out` (no copy): cell data phase, inclusion_id,
/// fraction (with partial volumes), field data phase_names; the geometry of `layout`
/// (voxel_layout). Runs in `arena` when given (the source's Threads). Returns the conflicts.
/// `progress`, when given, is called with the share done (0 to 1) after each of up to
/// kVoxelChunks slabs along z; when it returns false the rest is not computed and -1 is
/// returned (the arrays are then incomplete).
constexpr int kVoxelChunks = 16;
template <class Arena>
long long RVEVoxelizeInto(const rvegen::InclusionSet& set, const rvegen::VoxelImage& layout,
                          const rvegen::VoxelOptions& opt, vtkImageData* out, Arena& arena,
                          const std::function<bool(double)>& progress = nullptr) {
  out->SetExtent(layout.extent[0], layout.extent[1], layout.extent[2], layout.extent[3],
                 layout.extent[4], layout.extent[5]);
  out->SetOrigin(layout.origin.data());
  out->SetSpacing(layout.spacing.data());
  const vtkIdType n = static_cast<vtkIdType>(layout.count());
  vtkNew<vtkUnsignedCharArray> phase;
  phase->SetName("phase");
  phase->SetNumberOfValues(n);
  vtkNew<vtkIntArray> ids;
  ids->SetName("inclusion_id");
  ids->SetNumberOfValues(n);
  vtkNew<vtkFloatArray> fraction;
  fraction->SetName("fraction");
  if (opt.partial_volume) fraction->SetNumberOfValues(n);
  long long conflicts = 0;
  // Slabs of whole z planes: each is a contiguous block of the arrays ([z][y][x]).
  const int z0 = layout.extent[4], nz = layout.size(2);
  const int chunks = progress ? std::max(1, std::min(kVoxelChunks, nz)) : 1;
  const size_t plane = static_cast<size_t>(layout.size(0)) * layout.size(1);
  for (int c = 0; c < chunks; ++c) {
    rvegen::VoxelImage slab = layout;
    slab.extent[4] = z0 + static_cast<int>(static_cast<long long>(nz) * c / chunks);
    slab.extent[5] = z0 + static_cast<int>(static_cast<long long>(nz) * (c + 1) / chunks);
    const size_t offset = plane * static_cast<size_t>(slab.extent[4] - z0);
    arena.execute([&] {
      conflicts += rvegen::voxelize_into(
          set, slab, opt, phase->GetPointer(0) + offset, ids->GetPointer(0) + offset,
          opt.partial_volume ? fraction->GetPointer(0) + offset : nullptr);
    });
    if (progress && !progress(static_cast<double>(c + 1) / chunks)) return -1;
  }
  out->GetCellData()->AddArray(phase);
  out->GetCellData()->AddArray(ids);
  if (opt.partial_volume) out->GetCellData()->AddArray(fraction);
  out->GetCellData()->SetActiveScalars("phase");
  RVEAddPhaseNames(layout.phases, out);
  // The inclusion list, for the filters that need the exact geometry (RVE Effective Properties).
  vtkNew<vtkStringArray> inclusions;
  inclusions->SetName("rvegen_inclusions");
  inclusions->InsertNextValue(rvegen::write_inclusions_json(set));
  out->GetFieldData()->AddArray(inclusions);
  return conflicts;
}

/// The long-form table the RVE filters give: columns quantity, name, index, value, one row per
/// number.
struct RVELongTable {
  vtkNew<vtkStringArray> quantity, name;
  vtkNew<vtkIntArray> index;
  vtkNew<vtkDoubleArray> value;
  RVELongTable() {
    quantity->SetName("quantity");
    name->SetName("name");
    index->SetName("index");
    value->SetName("value");
  }
  void Row(const char* q, const std::string& n, int i, double v) {
    quantity->InsertNextValue(q);
    name->InsertNextValue(n);
    index->InsertNextValue(i);
    value->InsertNextValue(v);
  }
  void AddTo(vtkTable* table) {
    table->AddColumn(quantity);
    table->AddColumn(name);
    table->AddColumn(index);
    table->AddColumn(value);
  }
};

/// Reads field data "rvegen_inclusions" (the JSON of inclusions.json) of `input`: what the RVE
/// Generator's surfaces carry, and inclusions.vtp written by `rvegen generate`. Returns false
/// with `error` set when it is missing or invalid.
inline bool RVEInclusionsFromFieldData(vtkDataObject* input, rvegen::InclusionSet* set,
                                       std::string* error) {
  vtkFieldData* fd = input ? input->GetFieldData() : nullptr;
  auto* a = fd ? vtkStringArray::SafeDownCast(fd->GetAbstractArray("rvegen_inclusions")) : nullptr;
  if (!a || a->GetNumberOfValues() < 1) {
    *error =
        "the input has no field data \"rvegen_inclusions\" (use the Inclusions output of the "
        "RVE Generator, or inclusions.vtp written by rvegen generate)";
    return false;
  }
  try {
    *set = rvegen::read_inclusions_json(a->GetValue(0));
  } catch (const std::exception& e) {
    *error = std::string("invalid rvegen_inclusions: ") + e.what();
    return false;
  }
  // What is handed in is audited like what is packed (as rvegen homogenize does): no RVE with
  // overlapping inclusions, or one leaving a closed box, is voxelized, meshed or solved.
  const rvegen::AuditReport report = rvegen::audit(*set, 3);
  if (!report.clean()) {
    *error = "invalid rvegen_inclusions: " + rvegen::describe_failure(report, *set);
    return false;
  }
  return true;
}

#endif
