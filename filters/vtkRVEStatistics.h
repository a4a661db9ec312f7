/**
 * @class vtkRVEStatistics
 * @brief A table of an RVE's statistics.
 *
 * Input: the RVE Generator's inclusion surfaces, or inclusions.vtp read back from disk (field
 * data "rvegen_inclusions"). Output: a vtkTable in long form, one row per number, columns
 * quantity (string), name (phase or family name), index (int) and value (double):
 *  - volume_fraction per phase (exact; index = phase label),
 *  - count per family (index = family),
 *  - orientation_tensor per family with an axis (index = 3 i + j),
 *  - g_r and r per sphere family (index = bin; over five mean diameters),
 *  - nearest_neighbour_distance mean, std, min, max (name = the statistic).
 */
#ifndef vtkRVEStatistics_h
#define vtkRVEStatistics_h

#include "RVEGenFiltersModule.h"
#include "vtkTableAlgorithm.h"

class RVEGENFILTERS_EXPORT vtkRVEStatistics : public vtkTableAlgorithm {
 public:
  static vtkRVEStatistics* New();
  vtkTypeMacro(vtkRVEStatistics, vtkTableAlgorithm);

 protected:
  vtkRVEStatistics() = default;
  ~vtkRVEStatistics() override = default;
  int FillInputPortInformation(int port, vtkInformation* info) override;
  int RequestData(vtkInformation* request, vtkInformationVector** inInfo,
                  vtkInformationVector* outInfo) override;

 private:
  vtkRVEStatistics(const vtkRVEStatistics&) = delete;
  void operator=(const vtkRVEStatistics&) = delete;
};

#endif
