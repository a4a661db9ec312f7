/**
 * @class vtkRVEEffectiveProperties
 * @brief Effective conductivity and stiffness of an RVE's voxel image by FFT.
 *
 * Input: the RVE Generator's Voxels output or RVE Voxelize's (cell data phase and
 * inclusion_id, field data rvegen_inclusions). Materials: the scene's
 * "materials" object as JSON text, keyed by "matrix", family name and "<family>.coating"
 * (isotropic conductivity, young and poisson, or transversely isotropic fibre constants).
 * Output: a vtkTable in long form, one row per number, columns quantity, name, index, value:
 *  - conductivity (name k_ij, index 3 i + j) and stiffness (name C_ij, Mandel, index 6 i + j),
 *  - engineering_constant (E1 .. nu23), isotropic_projection (bulk, shear),
 *  - bounds of isotropic phases: conductivity_bound, bulk_bound, shear_bound (voigt, reuss,
 *    hs_lower, hs_upper),
 *  - iterations and residual per load case, seconds, cut_voxels.
 * Progress rises with the load cases and each case's residual; AbortExecute stops the solve
 * (the table is then empty).
 *
 * Under MPI with every rank running the pipeline in step (pvbatch --symmetric), each rank asks
 * its input for its own z slab of the image (FFTW's MPI distribution) and the ranks solve
 * together: the image is never gathered; rank 0 gives the table (row ranks/solve: the number
 * of ranks). Otherwise each rank solves the whole image.
 */
#ifndef vtkRVEEffectiveProperties_h
#define vtkRVEEffectiveProperties_h

#include <string>

#include "RVEGenFiltersModule.h"
#include "vtkTableAlgorithm.h"

class RVEGENFILTERS_EXPORT vtkRVEEffectiveProperties : public vtkTableAlgorithm {
 public:
  static vtkRVEEffectiveProperties* New();
  vtkTypeMacro(vtkRVEEffectiveProperties, vtkTableAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  /// JSON object of phase properties (the scene's "materials").
  vtkSetStdStringFromCharMacro(Materials);
  vtkGetCharFromStdStringMacro(Materials);
  /// 0 conductivity, 1 elasticity, 2 both.
  vtkSetMacro(Physics, int);  // checked in RequestData, as the command line checks it
  vtkGetMacro(Physics, int);
  /// 0 plain, 1 Voigt, 2 Reuss, 3 laminate.
  vtkSetMacro(VoxelRule, int);
  vtkGetMacro(VoxelRule, int);
  /// 0 Willot's rotated scheme, 1 Moulinec-Suquet.
  vtkSetMacro(Scheme, int);
  vtkGetMacro(Scheme, int);
  vtkSetMacro(Tolerance, double);
  vtkGetMacro(Tolerance, double);
  vtkSetMacro(MaxIterations, int);
  vtkGetMacro(MaxIterations, int);

 protected:
  vtkRVEEffectiveProperties();
  ~vtkRVEEffectiveProperties() override = default;
  int FillInputPortInformation(int port, vtkInformation* info) override;
  int RequestUpdateExtent(vtkInformation* request, vtkInformationVector** inInfo,
                          vtkInformationVector* outInfo) override;
  int RequestData(vtkInformation* request, vtkInformationVector** inInfo,
                  vtkInformationVector* outInfo) override;

  std::string Materials;
  int Physics = 0;
  int VoxelRule = 3;
  int Scheme = 0;
  double Tolerance = 1e-6;
  int MaxIterations = 1000;

 private:
  vtkRVEEffectiveProperties(const vtkRVEEffectiveProperties&) = delete;
  void operator=(const vtkRVEEffectiveProperties&) = delete;
};

#endif
