#include "vtkRVETetMesh.h"

#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/model/resources.hpp"
#include "rvegen/model/scene.hpp"
#include "vtkCellArray.h"
#include "vtkCellData.h"
#include "vtkFieldData.h"
#include "vtkIdTypeArray.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkIntArray.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkPoints.h"
#include "vtkRVECommon.h"
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
  t.keep_volumes = this->KeepVolumes;
  t.order = this->Order;
  t.optimize_threshold = this->OptimizeThreshold;
  rvegen::TetMesh mesh;
  try {
    rvegen::validate_tet_mesh_spec(scene);
    // A mesh the machine cannot hold is refused before it starts (as the command line does).
    rvegen::check_tet_meshable(set);
    const double have = rvegen::available_memory_bytes();
    const rvegen::TetMeshNeed need = rvegen::tet_mesh_need(set, scene.tet_mesh, have);
    if (have > 0.0 && need.bytes > have) {
      rvegen::TetMeshSpec fit;
      rvegen::TetMeshNeed fit_need;
      std::string instead;
      if (rvegen::coarser_tet_mesh_that_fits(
              set, scene.tet_mesh, have,
              [have](const rvegen::TetMeshNeed& n) { return n.bytes <= have; }, &fit, &fit_need)) {
        instead = "; with " +
                  rvegen::describe_tet_mesh_change(scene.tet_mesh, fit,
                                                   rvegen::SettingNames::kProperties) +
                  " it would need about " + rvegen::format_bytes(fit_need.bytes);
      }
      vtkErrorMacro(<< "the tetrahedral mesh (" << (need.capped ? "more than " : "about ")
                    << static_cast<long long>(need.elements) << " elements) would need about "
                    << rvegen::format_bytes(need.bytes) << ", more than the "
                    << rvegen::format_bytes(have) << " available" << instead
                    << " (raise ChordError or MaxSize, or lower GapElements)");
      return 0;
    }
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
     << indent << "KeepVolumes: " << this->KeepVolumes << "\n"
     << indent << "Order: " << this->Order << "\n"
     << indent << "OptimizeThreshold: " << this->OptimizeThreshold << "\n";
}
