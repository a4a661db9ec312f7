#include "vtkRVETetMesh.h"

#include <limits>

#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/model/resources.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/pipeline/run.hpp"
#include "vtkCellArray.h"
#include "vtkCellData.h"
#include "vtkDoubleArray.h"
#include "vtkFieldData.h"
#include "vtkIdTypeArray.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkIntArray.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkPoints.h"
#include "vtkRVECommon.h"
#include "vtkStringArray.h"
#include "vtkUnsignedCharArray.h"
#include "vtkUnstructuredGrid.h"

vtkStandardNewMacro(vtkRVETetMesh);

namespace {
const rvegen::TetMeshSpec kDefaults;
}

vtkRVETetMesh::vtkRVETetMesh()
    : MaxSize(kDefaults.max_size),
      MinSize(kDefaults.min_size),
      ChordError(kDefaults.chord_error),
      GapElements(kDefaults.gap_elements),
      ShiftCell(kDefaults.shift_cell),
      Nudge(kDefaults.nudge),
      MinGap(-1.0),
      KeepVolumes(kDefaults.keep_volumes),
      Order(kDefaults.order),
      OptimizeThreshold(kDefaults.optimize_threshold) {}

int vtkRVETetMesh::FillInputPortInformation(int, vtkInformation* info) {
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkDataObject");
  return 1;
}

int vtkRVETetMesh::RequestData(vtkInformation*, vtkInformationVector** in,
                               vtkInformationVector* out) {
  vtkDataObject* input = in[0]->GetInformationObject(0)->Get(vtkDataObject::DATA_OBJECT());
  vtkUnstructuredGrid* grid = vtkUnstructuredGrid::GetData(out);
  // No cell until a mesh is made (a failed run leaves none).
  for (double& c : this->CellOrigin) c = std::numeric_limits<double>::quiet_NaN();
  this->NudgedInclusions = -1;
  rvegen::InclusionSet set;
  std::string error;
  if (!RVEInclusionsFromFieldData(input, &set, &error)) {
    vtkErrorMacro(<< error);
    return 0;
  }
  // The sizes are checked as a scene's "mesh_tet" is.
  rvegen::Scene scene;
  scene.box = set.box;
  rvegen::TetMeshSpec& t = scene.tet_mesh;
  t.max_size = this->MaxSize;
  t.min_size = this->MinSize;
  t.chord_error = this->ChordError;
  t.gap_elements = this->GapElements;
  t.shift_cell = this->ShiftCell;
  t.nudge = this->Nudge;
  t.keep_volumes = this->KeepVolumes;
  t.order = this->Order;
  t.optimize_threshold = this->OptimizeThreshold;
  t.reproducible = this->Reproducible;
  // The least gap a nudge keeps: MinGap, or the scene's that the input carries (the RVE
  // Generator's field data rvegen_min_gap), else 0.
  double min_gap = this->MinGap;
  if (min_gap < 0.0) {
    auto* given = vtkDoubleArray::SafeDownCast(
        input->GetFieldData() ? input->GetFieldData()->GetArray("rvegen_min_gap") : nullptr);
    min_gap = given && given->GetNumberOfValues() > 0 ? given->GetValue(0) : 0.0;
  }
  if (!(min_gap >= 0.0 && min_gap < set.box.size.minCoeff())) {
    vtkErrorMacro(<< "the least gap (MinGap, or the input's field data rvegen_min_gap) must lie in "
                     "[0, the box's least side), got "
                  << min_gap);
    return 0;
  }
  rvegen::TetMesh mesh;
  rvegen::Nudged nudged;
  try {
    if (this->Order != 1 && this->Order != 2)
      throw rvegen::InputError("Order: 1 (4-node) or 2 (10-node), got " +
                               std::to_string(this->Order));
    rvegen::validate_tet_mesh_spec(scene);
    // The pipeline's steps, as the command line takes them: the inclusions moved off the
    // chosen cell's faces where there is room, then a mesh the machine cannot hold refused
    // before it starts.
    nudged = rvegen::nudge_for_tet_mesh(&set, t, min_gap);
    rvegen::check_tet_mesh_fits(set, t, rvegen::memory_limit(0.0), rvegen::ResourceEstimate{},
                                rvegen::SettingNames::kProperties);
    rvegen::TetMeshOptions opt;
    static_cast<rvegen::TetMeshSpec&>(opt) = scene.tet_mesh;
    this->UpdateProgress(0.0);
    mesh = rvegen::tet_mesh(set, opt, [this](double f, const std::string&) {
      this->UpdateProgress(f);
      return !this->GetAbortExecute();
    });
  } catch (const rvegen::Cancelled&) {
    vtkWarningMacro(<< "aborted; the mesh is empty");
    this->SetAbortExecute(0);
    return 1;
  } catch (const std::exception& e) {
    vtkErrorMacro(<< e.what());
    return 0;
  }
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(static_cast<vtkIdType>(mesh.nodes.size()));
  for (size_t i = 0; i < mesh.nodes.size(); ++i) {
    points->SetPoint(static_cast<vtkIdType>(i), mesh.nodes[i].data());
  }
  const vtkIdType cells = static_cast<vtkIdType>(mesh.tets.size());
  // 4 corners, then for second order the midside nodes (TetMesh::mid: VTK's order).
  const vtkIdType n = mesh.mid.empty() ? 4 : 10;
  vtkNew<vtkIdTypeArray> offsets, connectivity;
  offsets->SetNumberOfValues(cells + 1);
  connectivity->SetNumberOfValues(n * cells);
  vtkNew<vtkUnsignedCharArray> phase;
  phase->SetName("phase");
  phase->SetNumberOfValues(cells);
  vtkNew<vtkIntArray> ids;
  ids->SetName("inclusion_id");
  ids->SetNumberOfValues(cells);
  for (vtkIdType e = 0; e < cells; ++e) {
    offsets->SetValue(e, n * e);
    for (int c = 0; c < 4; ++c) connectivity->SetValue(n * e + c, mesh.tets[e][c]);
    for (vtkIdType c = 4; c < n; ++c) connectivity->SetValue(n * e + c, mesh.mid[e][c - 4]);
    phase->SetValue(e, static_cast<unsigned char>(mesh.phase[e]));
    ids->SetValue(e, mesh.inclusion_id[e]);
  }
  offsets->SetValue(cells, n * cells);
  vtkNew<vtkCellArray> tets;
  tets->SetData(offsets, connectivity);
  grid->SetPoints(points);
  grid->SetCells(n == 4 ? VTK_TETRA : VTK_QUADRATIC_TETRA, tets);
  grid->GetCellData()->AddArray(phase);
  grid->GetCellData()->AddArray(ids);
  grid->GetCellData()->SetActiveScalars("phase");
  RVEAddPhaseNames(mesh.phases, grid);
  vtkNew<vtkIntArray> merged;
  merged->SetName("merged_nodes");
  merged->InsertNextValue(static_cast<int>(mesh.merged_nodes));
  grid->GetFieldData()->AddArray(merged);
  vtkNew<vtkIntArray> moved;
  moved->SetName("moved_nodes");
  moved->InsertNextValue(static_cast<int>(mesh.moved_nodes));
  grid->GetFieldData()->AddArray(moved);
  // The cell meshed (the box moved along its axes, ShiftCell): the mesh lies there, not at the
  // box, and is the same periodic medium.
  vtkNew<vtkDoubleArray> origin;
  origin->SetName("cell_origin");
  origin->SetNumberOfComponents(3);
  origin->InsertNextTuple(mesh.box.origin.data());
  grid->GetFieldData()->AddArray(origin);
  // The inclusions nudged for this mesh: by the scene's own mesh_tet in the RVE Generator
  // (its field data nudged_inclusions), and here.
  auto* before = vtkIntArray::SafeDownCast(
      input->GetFieldData() ? input->GetFieldData()->GetArray("nudged_inclusions") : nullptr);
  const int total_nudged =
      nudged.moved + (before && before->GetNumberOfValues() > 0 ? before->GetValue(0) : 0);
  for (int a = 0; a < 3; ++a) this->CellOrigin[a] = mesh.box.origin[a];
  this->NudgedInclusions = total_nudged;
  vtkNew<vtkIntArray> nudge_counts;
  nudge_counts->SetName("nudged_inclusions");
  nudge_counts->InsertNextValue(total_nudged);
  grid->GetFieldData()->AddArray(nudge_counts);
  // The inclusions meshed (after the nudge), as inclusions.json has them.
  vtkNew<vtkStringArray> inclusions;
  inclusions->SetName("rvegen_inclusions");
  inclusions->InsertNextValue(rvegen::write_inclusions_json(set));
  grid->GetFieldData()->AddArray(inclusions);
  this->UpdateProgress(1.0);
  return 1;
}

void vtkRVETetMesh::PrintSelf(ostream& os, vtkIndent indent) {
  this->Superclass::PrintSelf(os, indent);
  os << indent << "MaxSize: " << this->MaxSize << "\n"
     << indent << "MinSize: " << this->MinSize << "\n"
     << indent << "ChordError: " << this->ChordError << "\n"
     << indent << "GapElements: " << this->GapElements << "\n"
     << indent << "ShiftCell: " << this->ShiftCell << "\n"
     << indent << "Nudge: " << this->Nudge << "\n"
     << indent << "MinGap: " << this->MinGap << "\n"
     << indent << "KeepVolumes: " << this->KeepVolumes << "\n"
     << indent << "Order: " << this->Order << "\n"
     << indent << "OptimizeThreshold: " << this->OptimizeThreshold << "\n"
     << indent << "Reproducible: " << this->Reproducible << "\n";
}
