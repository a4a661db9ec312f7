/**
 * @class vtkRVEVoxelize
 * @brief Voxelizes an RVE again at another resolution, without packing it again.
 *
 * Input: the RVE Generator's inclusion surfaces, or inclusions.vtp read back from disk (both
 * carry the inclusion list in field data "rvegen_inclusions"). Output: vtkImageData over the
 * RVE's box with cell data phase, inclusion_id and (when PartialVolume is on) fraction, as the
 * generator's voxel port.
 */
#ifndef vtkRVEVoxelize_h
#define vtkRVEVoxelize_h

#include "RVEGenFiltersModule.h"
#include "vtkAlgorithm.h"

class RVEGENFILTERS_EXPORT vtkRVEVoxelize : public vtkAlgorithm {
 public:
  static vtkRVEVoxelize* New();
  vtkTypeMacro(vtkRVEVoxelize, vtkAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  vtkSetVector3Macro(Resolution, int);
  vtkGetVector3Macro(Resolution, int);
  vtkSetMacro(PartialVolume, bool);
  vtkGetMacro(PartialVolume, bool);
  vtkSetMacro(Subsamples, int);
  vtkGetMacro(Subsamples, int);

  vtkTypeBool ProcessRequest(vtkInformation* request, vtkInformationVector** inInfo,
                             vtkInformationVector* outInfo) override;

 protected:
  vtkRVEVoxelize();
  ~vtkRVEVoxelize() override = default;
  int FillInputPortInformation(int port, vtkInformation* info) override;
  int FillOutputPortInformation(int port, vtkInformation* info) override;

  int Resolution[3];
  bool PartialVolume;
  int Subsamples;

 private:
  vtkRVEVoxelize(const vtkRVEVoxelize&) = delete;
  void operator=(const vtkRVEVoxelize&) = delete;
};

#endif
