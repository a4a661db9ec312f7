#include "vtkRVEGenerator.h"

#include <exception>

#include "rvegen/mesh.hpp"
#include "rvegen/packing.hpp"
#include "rvegen/scene.hpp"
#include "rvegen/voxelize.hpp"
#include "rvegen/writers.hpp"
#include "vtkCellArray.h"
#include "vtkCellData.h"
#include "vtkDoubleArray.h"
#include "vtkFieldData.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkIntArray.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkStreamingDemandDrivenPipeline.h"
#include "vtkStringArray.h"
#include "vtkTypeInt64Array.h"
#include "vtkUnsignedCharArray.h"

vtkStandardNewMacro(vtkRVEGenerator);

struct vtkRVEGenerator::Cache {
  std::string key;  // scene JSON without the voxel resolution
  rvegen::PackingResult result;
};

vtkRVEGenerator::vtkRVEGenerator() {
  this->SetNumberOfInputPorts(0);
  this->SetNumberOfOutputPorts(2);
  const rvegen::Scene d = rvegen::default_scene();
  this->Seed = static_cast<int>(d.seed);
  for (int a = 0; a < 3; ++a) {
    this->BoxSize[a] = d.box.size[a];
    this->Resolution[a] = d.resolution[a];
    this->EllipsoidSemiAxes[a] = d.families[2].semi_axes[a].p1;
  }
  this->Periodic = d.box.periodic;
  this->MinGap = d.min_gap;
  this->SphereRadius = d.families[0].radius.p1;
  this->SphereVolumeFraction = d.families[0].volume_fraction;
  this->FibreRadius = d.families[1].radius.p1;
  this->FibreAspectRatio = d.families[1].aspect_ratio.p1;
  this->FibreVolumeFraction = d.families[1].volume_fraction;
  this->EllipsoidVolumeFraction = d.families[2].volume_fraction;
  this->SceneFile = nullptr;
}

vtkRVEGenerator::~vtkRVEGenerator() {
  this->SetSceneFile(nullptr);
}

int vtkRVEGenerator::FillOutputPortInformation(int port, vtkInformation* info) {
  info->Set(vtkDataObject::DATA_TYPE_NAME(), port == 0 ? "vtkPolyData" : "vtkImageData");
  return 1;
}

namespace {
// The scene the properties describe (families with a zero volume fraction are left out).
rvegen::Scene SceneFromProperties(const vtkRVEGenerator* g) {
  rvegen::Scene s = rvegen::default_scene();
  auto* self = const_cast<vtkRVEGenerator*>(g);
  s.seed = static_cast<uint64_t>(self->GetSeed());
  s.box.size = rvegen::Vec3(self->GetBoxSize()[0], self->GetBoxSize()[1], self->GetBoxSize()[2]);
  s.box.periodic = self->GetPeriodic();
  s.min_gap = self->GetMinGap();
  s.families[0].radius = self->GetSphereRadius();
  s.families[0].volume_fraction = self->GetSphereVolumeFraction();
  s.families[1].radius = self->GetFibreRadius();
  s.families[1].aspect_ratio = self->GetFibreAspectRatio();
  s.families[1].volume_fraction = self->GetFibreVolumeFraction();
  for (int a = 0; a < 3; ++a) s.families[2].semi_axes[a] = self->GetEllipsoidSemiAxes()[a];
  s.families[2].volume_fraction = self->GetEllipsoidVolumeFraction();
  std::vector<rvegen::Family> kept;
  for (const auto& f : s.families) {
    if (f.volume_fraction > 0.0) kept.push_back(f);
  }
  s.families = kept;
  for (int a = 0; a < 3; ++a) s.resolution[a] = self->GetResolution()[a];
  return s;
}
}  // namespace

int vtkRVEGenerator::RequestInformation(vtkInformation*, vtkInformationVector**,
                                        vtkInformationVector* outVec) {
  // The image geometry comes from the properties, or from the scene file when it is readable
  // (errors are reported by RequestData).
  rvegen::Scene scene = SceneFromProperties(this);
  if (this->SceneFile && *this->SceneFile) {
    try {
      scene = rvegen::parse_scene(rvegen::read_file(this->SceneFile));
    } catch (const std::exception&) {
    }
  }
  vtkInformation* info = outVec->GetInformationObject(1);
  int extent[6] = {0, scene.resolution[0], 0, scene.resolution[1], 0, scene.resolution[2]};
  double spacing[3], origin[3];
  for (int a = 0; a < 3; ++a) {
    spacing[a] = scene.box.size[a] / std::max(1, scene.resolution[a]);
    origin[a] = scene.box.origin[a];
  }
  info->Set(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), extent, 6);
  info->Set(vtkDataObject::SPACING(), spacing, 3);
  info->Set(vtkDataObject::ORIGIN(), origin, 3);
  return 1;
}

int vtkRVEGenerator::RequestData(vtkInformation*, vtkInformationVector**,
                                 vtkInformationVector* outVec) {
  vtkPolyData* surfaces = vtkPolyData::GetData(outVec, 0);
  vtkImageData* image = vtkImageData::GetData(outVec, 1);
  rvegen::Scene scene;
  try {
    if (this->SceneFile && *this->SceneFile) {
      scene = rvegen::parse_scene(rvegen::read_file(this->SceneFile));
    } else {
      scene = SceneFromProperties(this);
      rvegen::validate_scene(scene);
    }
  } catch (const std::exception& e) {
    this->Status = "invalid";
    vtkErrorMacro(<< "invalid scene: " << e.what());
    return 0;
  }
  rvegen::Scene key_scene = scene;
  key_scene.resolution = {0, 0, 0};
  const std::string key = rvegen::scene_to_json(key_scene);
  if (!this->Cached || this->Cached->key != key) {
    this->Cached.reset(new Cache{key, rvegen::generate(scene)});
  }
  const rvegen::PackingResult& result = this->Cached->result;
  this->Status = result.status;
  if (result.status != "ok") {
    vtkWarningMacro(<< "target volume fraction not reached (" << result.status
                    << "); showing the best configuration found");
  }

  // Port 0: surfaces.
  const rvegen::SurfaceMesh mesh = rvegen::tessellate(result.set);
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
  surfaces->SetPoints(points);
  surfaces->SetPolys(polys);
  auto int_array = [](const char* name, const std::vector<int32_t>& v) {
    vtkNew<vtkIntArray> a;
    a->SetName(name);
    a->SetNumberOfValues(static_cast<vtkIdType>(v.size()));
    for (size_t i = 0; i < v.size(); ++i) a->SetValue(static_cast<vtkIdType>(i), v[i]);
    return a;
  };
  surfaces->GetCellData()->AddArray(int_array("inclusion_id", mesh.inclusion_id));
  surfaces->GetCellData()->AddArray(int_array("family", mesh.family));
  surfaces->GetCellData()->AddArray(int_array("shape", mesh.shape));
  surfaces->GetCellData()->SetActiveScalars("family");
  vtkNew<vtkStringArray> status;
  status->SetName("status");
  status->InsertNextValue(result.status);
  surfaces->GetFieldData()->AddArray(status);

  // Port 1: voxels.
  const rvegen::VoxelImage vox = rvegen::voxelize(result.set, scene.resolution);
  image->SetExtent(0, vox.dims[0], 0, vox.dims[1], 0, vox.dims[2]);
  image->SetOrigin(vox.origin.data());
  image->SetSpacing(vox.spacing.data());
  vtkNew<vtkUnsignedCharArray> phase;
  phase->SetName("phase");
  phase->SetNumberOfValues(static_cast<vtkIdType>(vox.phase.size()));
  std::copy(vox.phase.begin(), vox.phase.end(), phase->GetPointer(0));
  vtkNew<vtkIntArray> ids;
  ids->SetName("inclusion_id");
  ids->SetNumberOfValues(static_cast<vtkIdType>(vox.inclusion_id.size()));
  std::copy(vox.inclusion_id.begin(), vox.inclusion_id.end(), ids->GetPointer(0));
  image->GetCellData()->AddArray(phase);
  image->GetCellData()->AddArray(ids);
  image->GetCellData()->SetActiveScalars("phase");
  return 1;
}

void vtkRVEGenerator::PrintSelf(ostream& os, vtkIndent indent) {
  this->Superclass::PrintSelf(os, indent);
  os << indent << "Seed: " << this->Seed << "\n";
  os << indent << "SceneFile: " << (this->SceneFile ? this->SceneFile : "(none)") << "\n";
  os << indent << "Status: " << this->Status << "\n";
}
