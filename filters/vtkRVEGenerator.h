/**
 * @class vtkRVEGenerator
 * @brief Generates a Representative Volume Element: inclusions packed without overlap.
 *
 * Output port 0: vtkPolyData, one vertex per inclusion and periodic image with glyph
 *                attributes; field data rvegen_inclusions (the inclusion list) and status.
 * Output port 1: vtkImageData with one cell per voxel (cell data phase, inclusion_id and
 *                fraction, the partial volume of the inclusions; field data phase_names).
 * Output port 2: vtkPolyData of the level-set surfaces (wavy, deformed and coated inclusions:
 *                OpenVDB narrow-band grids meshed at their zero level); empty without them.
 * Output port 3: vtkPolyData of the tessellated surfaces: of every inclusion up to MeshUpTo
 *                inclusions (or with Mesh), otherwise of the modified ones (cell data
 *                inclusion_id, family, shape, phase, axis).
 * Only the port that is asked for is computed. The packing reports its progress
 * (UpdateProgress) and stops at its next check when AbortExecute is set.
 * Properties describe the built-in three-family scene (spheres, fibres, ellipsoids); a scene
 * file (JSON, the format `rvegen generate` reads) overrides all of them when set.
 * The packing is computed once per change of the properties and shared by all ports.
 */
#ifndef vtkRVEGenerator_h
#define vtkRVEGenerator_h

#include <functional>
#include <memory>
#include <string>

#include "RVEGenFiltersModule.h"
#include "vtkPolyDataAlgorithm.h"
#include "vtkTimeStamp.h"

class vtkImageData;
class vtkStringArray;
namespace rvegen {
struct InclusionSet;
struct Scene;
}  // namespace rvegen

class RVEGENFILTERS_EXPORT vtkRVEGenerator : public vtkPolyDataAlgorithm {
 public:
  static vtkRVEGenerator* New();
  vtkTypeMacro(vtkRVEGenerator, vtkPolyDataAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;
  /// After an abort, always newer than the outputs until the next execution (see EndAborted).
  vtkMTimeType GetMTime() override;

  vtkSetMacro(Seed, int);
  vtkGetMacro(Seed, int);
  vtkSetVector3Macro(BoxSize, double);
  vtkGetVector3Macro(BoxSize, double);
  vtkSetMacro(Periodic, bool);
  vtkGetMacro(Periodic, bool);
  vtkBooleanMacro(Periodic, bool);
  vtkSetMacro(MinGap, double);
  vtkGetMacro(MinGap, double);

  vtkSetMacro(SphereRadius, double);
  vtkGetMacro(SphereRadius, double);
  vtkSetMacro(SphereVolumeFraction, double);
  vtkGetMacro(SphereVolumeFraction, double);
  vtkSetMacro(FibreRadius, double);
  vtkGetMacro(FibreRadius, double);
  vtkSetMacro(FibreAspectRatio, double);
  vtkGetMacro(FibreAspectRatio, double);
  vtkSetMacro(FibreVolumeFraction, double);
  vtkGetMacro(FibreVolumeFraction, double);
  vtkSetVector3Macro(EllipsoidSemiAxes, double);
  vtkGetVector3Macro(EllipsoidSemiAxes, double);
  vtkSetMacro(EllipsoidVolumeFraction, double);
  vtkGetMacro(EllipsoidVolumeFraction, double);

  /// Surfaces output (port 3): the tessellated mesh of every inclusion when on; otherwise of the
  /// wavy, deformed, coated and debonded ones only (the Inclusions output draws the others as
  /// glyphs).
  vtkSetMacro(Mesh, bool);
  vtkGetMacro(Mesh, bool);
  vtkBooleanMacro(Mesh, bool);

  /// Cut the surfaces of periodic images at the box faces.
  vtkSetMacro(ClipSurfaces, bool);
  vtkGetMacro(ClipSurfaces, bool);
  vtkBooleanMacro(ClipSurfaces, bool);

  /// Method: 0 molecular dynamics, 1 random sequential adsorption. Size spreads: lognormal standard
  /// deviation (0: fixed). Orientation laws: 0 isotropic, 1 aligned (axis), 2 von Mises-Fisher
  /// (axis, kappa), 3 planar (axis = the plane normal), 4 tensor (fibres only:
  /// FibreOrientationTensor, the orientation tensor A2 as a11 a22 a33 a12 a13 a23). Modifiers: see
  /// the scene file's "coating", "waviness", "deformation", "debonding" (0 leaves a modifier out).
  vtkSetMacro(Method, int);
  vtkGetMacro(Method, int);
  vtkSetMacro(SphereRadiusStd, double);
  vtkGetMacro(SphereRadiusStd, double);
  /// How each family's amount is given: 0 by its volume fraction (SphereVolumeFraction, ...),
  /// 1 by its count (SphereCount, ...). A family whose chosen amount is 0 is left out.
  vtkSetMacro(SphereAmount, int);
  vtkGetMacro(SphereAmount, int);
  vtkSetMacro(FibreAmount, int);
  vtkGetMacro(FibreAmount, int);
  vtkSetMacro(EllipsoidAmount, int);
  vtkGetMacro(EllipsoidAmount, int);
  vtkSetMacro(SphereCount, int);
  vtkGetMacro(SphereCount, int);
  /// Law of the fibres' aspect ratio (their length over the radius): 0 fixed (FibreAspectRatio),
  /// 1 lognormal (mean FibreAspectRatio, standard deviation FibreAspectRatioStd), 2 Weibull
  /// (shape FibreWeibullShape, scale FibreWeibullScale: the usual fit of moulded fibre lengths).
  vtkSetMacro(FibreLengthLaw, int);
  vtkGetMacro(FibreLengthLaw, int);
  vtkSetMacro(FibreAspectRatioStd, double);
  vtkGetMacro(FibreAspectRatioStd, double);
  vtkSetMacro(FibreWeibullShape, double);
  vtkGetMacro(FibreWeibullShape, double);
  vtkSetMacro(FibreWeibullScale, double);
  vtkGetMacro(FibreWeibullScale, double);
  vtkSetMacro(FibreRadiusStd, double);
  vtkGetMacro(FibreRadiusStd, double);
  vtkSetMacro(FibreCount, int);
  vtkGetMacro(FibreCount, int);
  vtkSetMacro(EllipsoidCount, int);
  vtkGetMacro(EllipsoidCount, int);
  vtkSetMacro(FibreOrientation, int);
  vtkGetMacro(FibreOrientation, int);
  vtkSetMacro(FibreKappa, double);
  vtkGetMacro(FibreKappa, double);
  vtkSetMacro(EllipsoidOrientation, int);
  vtkGetMacro(EllipsoidOrientation, int);
  vtkSetMacro(EllipsoidKappa, double);
  vtkGetMacro(EllipsoidKappa, double);
  vtkSetMacro(SphereCoating, double);
  vtkGetMacro(SphereCoating, double);
  vtkSetMacro(FibreCoating, double);
  vtkGetMacro(FibreCoating, double);
  vtkSetMacro(EllipsoidCoating, double);
  vtkGetMacro(EllipsoidCoating, double);
  vtkSetMacro(ShellsMayTouch, bool);
  vtkGetMacro(ShellsMayTouch, bool);
  vtkSetMacro(FibreWaveAmplitude, double);
  vtkGetMacro(FibreWaveAmplitude, double);
  vtkSetMacro(FibreWavelength, double);
  vtkGetMacro(FibreWavelength, double);
  vtkSetMacro(FibreCurvatureRadius, double);
  vtkGetMacro(FibreCurvatureRadius, double);
  vtkSetMacro(SphereDeformation, double);
  vtkGetMacro(SphereDeformation, double);
  vtkSetMacro(EllipsoidDeformation, double);
  vtkGetMacro(EllipsoidDeformation, double);
  vtkSetMacro(DeformationSmoothness, double);
  vtkGetMacro(DeformationSmoothness, double);
  vtkSetMacro(SphereDebondFraction, double);
  vtkGetMacro(SphereDebondFraction, double);
  vtkSetMacro(SphereDebondGap, double);
  vtkGetMacro(SphereDebondGap, double);
  vtkSetMacro(PartialVolume, bool);
  vtkGetMacro(PartialVolume, bool);
  vtkSetMacro(LevelSetVoxelSize, double);
  vtkGetMacro(LevelSetVoxelSize, double);
  vtkSetVector3Macro(FibreAxis, double);
  vtkGetVector3Macro(FibreAxis, double);
  vtkSetVector6Macro(FibreOrientationTensor, double);
  vtkGetVector6Macro(FibreOrientationTensor, double);
  vtkSetVector3Macro(EllipsoidAxis, double);
  vtkGetVector3Macro(EllipsoidAxis, double);

  /// Time budget of the packing in seconds (md.max_seconds and rsa.max_seconds of a scene
  /// file); when it is spent the best valid configuration is shown (status target_not_reached).
  vtkSetMacro(TimeBudget, double);
  vtkGetMacro(TimeBudget, double);

  /// The Surfaces output meshes every inclusion when the RVE holds at most this many (so Apply
  /// shows the true shapes); above, only the modified ones unless Mesh is on.
  vtkSetMacro(MeshUpTo, int);
  vtkGetMacro(MeshUpTo, int);

  /// Threads for the packing and the voxels (0: all cores; the same RVE with any number). Under
  /// MPI with several ranks on one machine, give each rank its share (cores / ranks) rather than
  /// letting every rank use all cores.
  vtkSetMacro(Threads, int);
  vtkGetMacro(Threads, int);

  vtkSetVector3Macro(Resolution, int);
  vtkGetVector3Macro(Resolution, int);

  /// JSON scene file; when non-empty it overrides every other property.
  vtkSetStringMacro(SceneFile);
  vtkGetStringMacro(SceneFile);

  /// "ok" or "target_not_reached" after an update (empty before, "invalid" on bad input).
  const char* GetStatus() const { return this->Status.c_str(); }
  /// How many times each output port has been computed (shows that ports are lazy).
  vtkGetVectorMacro(PortExecutions, int, 4);
  /// How many times the RVE has been packed, summed over all MPI ranks (under MPI rank 0 packs
  /// and broadcasts the inclusion list: one packing per scene, whatever the number of ranks).
  vtkGetMacro(PackingRuns, int);

 protected:
  vtkRVEGenerator();
  ~vtkRVEGenerator() override;

  int FillOutputPortInformation(int port, vtkInformation* info) override;
  vtkTypeBool ProcessRequest(vtkInformation* request, vtkInformationVector** inInfo,
                             vtkInformationVector* outInfo) override;
  int RequestInformation(vtkInformation* request, vtkInformationVector** inInfo,
                         vtkInformationVector* outInfo) override;
  int RequestData(vtkInformation* request, vtkInformationVector** inInfo,
                  vtkInformationVector* outInfo) override;

  int Seed;
  double BoxSize[3];
  bool Periodic;
  double MinGap;
  double SphereRadius;
  double SphereVolumeFraction;
  double FibreRadius;
  double FibreAspectRatio;
  double FibreVolumeFraction;
  double EllipsoidSemiAxes[3];
  double EllipsoidVolumeFraction;
  int Resolution[3];
  char* SceneFile;
  bool ClipSurfaces;
  bool Mesh;
  int Method;
  double SphereRadiusStd;
  int SphereCount;
  double FibreRadiusStd;
  int FibreCount;
  int EllipsoidCount;
  int FibreOrientation;
  double FibreKappa;
  int EllipsoidOrientation;
  double EllipsoidKappa;
  double SphereCoating;
  double FibreCoating;
  double EllipsoidCoating;
  bool ShellsMayTouch;
  double FibreWaveAmplitude;
  double FibreWavelength;
  double FibreCurvatureRadius;
  double SphereDeformation;
  double EllipsoidDeformation;
  double DeformationSmoothness;
  double SphereDebondFraction;
  double SphereDebondGap;
  bool PartialVolume;
  double LevelSetVoxelSize;
  int Threads = 0;
  double TimeBudget;
  int MeshUpTo = 20000;
  int FibreLengthLaw = 0;
  double FibreAspectRatioStd = 1.0;
  double FibreWeibullShape = 2.0;
  double FibreWeibullScale = 5.0;
  int SphereAmount = 0;
  int FibreAmount = 0;
  int EllipsoidAmount = 0;
  double FibreAxis[3];
  double FibreOrientationTensor[6];
  double EllipsoidAxis[3];
  int PortExecutions[4] = {0, 0, 0, 0};
  int PackingRuns = 0;

 private:
  vtkRVEGenerator(const vtkRVEGenerator&) = delete;
  void operator=(const vtkRVEGenerator&) = delete;

  // Empties this execution's outputs after an abort of the update of `key` at `port`, and
  // clears the flag for the next update.
  int EndAborted(vtkInformationVector* outVec, const std::string& key, int port);

  struct Cache;
  // Packs the scene into `cache` (rank 0 packs and broadcasts where the ranks run in step);
  // returns the error ("" when packed), *aborted when an abort stopped it.
  std::string PackShared(const rvegen::Scene& scene, Cache* cache, bool* aborted);
  // The outputs of ports 0 (points), 3 (surfaces), 1 (voxels: false when aborted) and 2 (level
  // sets), of `set` packed for `scene`.
  void FillPoints(const rvegen::Scene& scene, const rvegen::InclusionSet& set,
                  vtkInformationVector* outVec, vtkStringArray* status);
  void FillSurfaces(const rvegen::Scene& scene, const rvegen::InclusionSet& set,
                    vtkInformationVector* outVec, vtkStringArray* status);
  bool FillVoxels(const rvegen::Scene& scene, const rvegen::InclusionSet& set,
                  vtkInformationVector* outVec, vtkImageData* image,
                  const std::function<void(double)>& progress);
  void FillLevelSets(const rvegen::Scene& scene, const rvegen::InclusionSet& set,
                     vtkInformationVector* outVec);

  std::unique_ptr<Cache> Cached;
  std::string Status;
  // The packing key and the port of the last aborted execution (-1: none pending).
  std::string AbortedKey;
  int AbortedPort = -1;
  bool AbortPending = false;
  vtkTimeStamp AbortTime;
};

#endif
