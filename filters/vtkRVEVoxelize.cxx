#include "vtkRVEVoxelize.h"

#include <tbb/task_arena.h>

#include <algorithm>

#include "rvegen/raster/voxelize.hpp"
#include "vtkCellData.h"
#include "vtkDemandDrivenPipeline.h"
#include "vtkFloatArray.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkIntArray.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkRVECommon.h"
#include "vtkStreamingDemandDrivenPipeline.h"
#include "vtkUnsignedCharArray.h"

vtkStandardNewMacro(vtkRVEVoxelize);

vtkRVEVoxelize::vtkRVEVoxelize() : Resolution{128, 128, 128}, PartialVolume(true), Subsamples(4) {
  this->SetNumberOfInputPorts(1);
  this->SetNumberOfOutputPorts(1);
}

int vtkRVEVoxelize::FillInputPortInformation(int, vtkInformation* info) {
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkDataObject");
  return 1;
}

int vtkRVEVoxelize::FillOutputPortInformation(int, vtkInformation* info) {
  info->Set(vtkDataObject::DATA_TYPE_NAME(), "vtkImageData");
  return 1;
}

vtkTypeBool vtkRVEVoxelize::ProcessRequest(vtkInformation* request, vtkInformationVector** in,
                                           vtkInformationVector* out) {
  vtkInformation* outInfo = out->GetInformationObject(0);
  if (request->Has(vtkDemandDrivenPipeline::REQUEST_INFORMATION())) {
    // The extent follows from the resolution alone; origin and spacing (the box) come with the
    // data.
    const int ext[6] = {0, this->Resolution[0], 0, this->Resolution[1], 0, this->Resolution[2]};
    outInfo->Set(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), ext, 6);
    return 1;
  }
  if (request->Has(vtkDemandDrivenPipeline::REQUEST_DATA())) {
    vtkDataObject* input = in[0]->GetInformationObject(0)->Get(vtkDataObject::DATA_OBJECT());
    vtkImageData* image = vtkImageData::GetData(outInfo);
    rvegen::InclusionSet set;
    std::string error;
    if (!RVEInclusionsFromFieldData(input, &set, &error)) {
      vtkErrorMacro(<< error);
      return 0;
    }
    if (this->Subsamples < 1 || this->Subsamples > 16) {
      vtkErrorMacro(<< "Subsamples must be in [1, 16], got " << this->Subsamples);
      return 0;
    }
    for (int a = 0; a < 3; ++a) {
      if (this->Resolution[a] < 1 || this->Resolution[a] > 4096) {
        vtkErrorMacro(<< "Resolution[" << a << "] must be in [1, 4096], got "
                      << this->Resolution[a]);
        return 0;
      }
    }
    rvegen::VoxelOptions opt;
    opt.partial_volume = this->PartialVolume;
    opt.subsamples = this->Subsamples;
    const std::array<int, 3> dims = {this->Resolution[0], this->Resolution[1], this->Resolution[2]};
    tbb::task_arena arena;
    try {
      // Progress per slab of z planes; an abort leaves the image empty.
      const long long done = RVEVoxelizeInto(set, rvegen::voxel_layout(set, dims, opt), opt, image,
                                             arena, [this](double f) {
                                               this->UpdateProgress(f);
                                               return !this->GetAbortExecute();
                                             });
      if (done < 0) {
        image->Initialize();
        this->SetAbortExecute(0);
        vtkWarningMacro(<< "aborted; the image is empty");
      }
    } catch (const std::exception& e) {
      vtkErrorMacro(<< e.what());
      return 0;
    }
    return 1;
  }
  return this->Superclass::ProcessRequest(request, in, out);
}

void vtkRVEVoxelize::PrintSelf(ostream& os, vtkIndent indent) {
  this->Superclass::PrintSelf(os, indent);
  os << indent << "Resolution: " << this->Resolution[0] << " " << this->Resolution[1] << " "
     << this->Resolution[2] << "\n"
     << indent << "PartialVolume: " << this->PartialVolume << "\n"
     << indent << "Subsamples: " << this->Subsamples << "\n";
}
