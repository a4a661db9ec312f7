/**
 * @class vtkRVETetMesh
 * @brief Conforming periodic tetrahedral mesh of an RVE (Gmsh), for ParaView and FE codes.
 *
 * Input: the Inclusions output of the RVE Generator, or inclusions.vtp written by rvegen
 * generate (both carry the inclusion list in field data "rvegen_inclusions"). Output: a
 * vtkUnstructuredGrid of tetrahedra following every interface, with opposite box faces meshed
 * alike (cell data phase and inclusion_id; field data phase_names, merged_nodes (the nodes
 * the mesher left at one position and rvegen merged), cell_origin (the lower corner of the cell
 * meshed: the box moved along its axes with ShiftCell), nudged_inclusions and rvegen_inclusions,
 * the inclusions meshed). The steps are the command line's (rvegen/pipeline/run.hpp): the same
 * inclusions give the same nudged inclusions and the same cell. Spheres, cylinders and ellipsoids,
 * coated or not, and debonded spheres; other inclusions give an error naming the family. The sizes
 * are those of a scene's "mesh_tet" object (0: the default). Progress follows the mesher's stages;
 * Abort stops it (within a stage it first finishes with coarse elements) and leaves the output
 * empty.
 */
#ifndef vtkRVETetMesh_h
#define vtkRVETetMesh_h

#include "RVEGenFiltersModule.h"
#include "vtkUnstructuredGridAlgorithm.h"

class RVEGENFILTERS_EXPORT vtkRVETetMesh : public vtkUnstructuredGridAlgorithm {
 public:
  static vtkRVETetMesh* New();
  vtkTypeMacro(vtkRVETetMesh, vtkUnstructuredGridAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  /// Largest element size (0: a tenth of the smallest box side).
  vtkSetMacro(MaxSize, double);
  vtkGetMacro(MaxSize, double);
  /// Least element size (0: a fiftieth of the smallest inclusion).
  vtkSetMacro(MinSize, double);
  vtkGetMacro(MinSize, double);
  /// Chord error against the inclusions' surfaces, a fraction of their radius of curvature.
  vtkSetMacro(ChordError, double);
  vtkGetMacro(ChordError, double);
  /// Elements across the gap between two surfaces.
  vtkSetMacro(GapElements, double);
  vtkGetMacro(GapElements, double);
  /// Whether the mesh's cell may be the box moved along its axes, off the inclusions' extremes
  /// (the same periodic medium; thin caps at the faces otherwise bound the elements' angles).
  vtkSetMacro(ShiftCell, bool);
  vtkGetMacro(ShiftCell, bool);
  vtkBooleanMacro(ShiftCell, bool);
  /// With ShiftCell, whether inclusions that every cell would graze move off its faces by a
  /// few of their sizes at most, where there is room (a scene's mesh_tet.nudge).
  vtkSetMacro(Nudge, bool);
  vtkGetMacro(Nudge, bool);
  vtkBooleanMacro(Nudge, bool);
  /// The least gap a nudged inclusion keeps to the others; negative: the scene's, which the
  /// RVE Generator's Inclusions carry (field data rvegen_min_gap), else 0.
  vtkSetMacro(MinGap, double);
  vtkGetMacro(MinGap, double);
  /// Whether the nodes inside curved interfaces move along the normal so that each phase keeps
  /// its exact volume (off: every interface node on the exact surface).
  vtkSetMacro(KeepVolumes, bool);
  vtkGetMacro(KeepVolumes, bool);
  vtkBooleanMacro(KeepVolumes, bool);
  /// Element order: 1 for 4-node tetrahedra, 2 for 10-node ones (VTK_QUADRATIC_TETRA).
  vtkSetMacro(Order, int);
  vtkGetMacro(Order, int);
  /// The mesher's optimiser improves the elements of quality (0 to 1) under this (0: none).
  vtkSetMacro(OptimizeThreshold, double);
  vtkGetMacro(OptimizeThreshold, double);
  /// The same mesh on every run (Gmsh's Delaunay volume mesher instead of HXT; slower).
  vtkSetMacro(Reproducible, bool);
  vtkGetMacro(Reproducible, bool);
  /// The lower corner of the cell the last mesh fills (the box's origin without ShiftCell, or
  /// before any mesh): shown in the panel, read-only; field data cell_origin too.
  vtkGetVector3Macro(CellOrigin, double);
  /// Inclusions the last mesh's nudge moved (field data nudged_inclusions too).
  vtkGetMacro(NudgedInclusions, int);

 protected:
  vtkRVETetMesh();
  ~vtkRVETetMesh() override = default;
  int FillInputPortInformation(int port, vtkInformation* info) override;
  int RequestData(vtkInformation* request, vtkInformationVector** in,
                  vtkInformationVector* out) override;

  double MaxSize;
  double MinSize;
  double ChordError;
  double GapElements;
  bool ShiftCell;
  bool Nudge;
  double MinGap;
  bool KeepVolumes;
  int Order;
  double OptimizeThreshold;
  bool Reproducible = false;
  double CellOrigin[3] = {0.0, 0.0, 0.0};
  int NudgedInclusions = 0;

 private:
  vtkRVETetMesh(const vtkRVETetMesh&) = delete;
  void operator=(const vtkRVETetMesh&) = delete;
};

#endif
