// The AMITEX_FFTP inputs beside material.vtk, so that an AMITEX user runs the RVE without hand
// work: zoneID.vtk (one zone per inclusion in each family's core material), the material file
// (Lame coefficients of isotropic phases; elasaniso in each fibre's own frame, per zone, for
// transversely isotropic ones), a loading file of the six unit mean strains, the default
// algorithm file and the command that runs them; when the scene gives conductivities, the
// same three files for AMITEX's stationary diffusion (Fourier's law, three unit mean
// gradients).
#pragma once

#include <cstdio>
#include <string>

#include "rvegen/model/scene.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen {

/// zoneID.vtk: legacy VTK STRUCTURED_POINTS, binary big-endian "ZoneId" per cell (unsigned
/// short, or int beyond 65535 zones), numbered 1..K within each material: in a family's core
/// material, zone k is the k-th of its inclusions present in the image (by id); elsewhere 1.
void write_zone_vtk(const VoxelImage& image, std::FILE* out);
/// amitex_materials.xml: one <Material> per material of material.vtk, in its numbering. A phase
/// without elastic constants in scene.materials gets FILL_IN values (AMITEX then refuses it).
std::string amitex_materials_xml(const Scene& scene, const InclusionSet& set,
                                 const VoxelImage& image);
/// amitex_loading.xml: six partial loadings of one increment each, the mean strain going to
/// 1e-3 along xx, yy, zz, then xy, xz, yz (Voigt: the engineering shear), the others back to 0.
/// Column k of the stiffness is the mean stress at the end of loading k over 1e-3.
std::string amitex_loading_xml();
/// amitex_algorithm.xml: AMITEX's default algorithm (basic scheme with convergence
/// acceleration, the hexahedral filter, small perturbations).
std::string amitex_algorithm_xml();
/// amitex_conductivity_materials.xml: one <Material> per material of material.vtk with the
/// Fourier_iso law and the phase's conductivity (the reference K0 the mean of the extremes). A
/// phase without an isotropic conductivity (none given, or a transversely isotropic one, for
/// which this file names no AMITEX law) gets FILL_IN (AMITEX then refuses it).
std::string amitex_conductivity_materials_xml(const Scene& scene, const VoxelImage& image);
/// amitex_conductivity_loading.xml: three loadings of one increment each, the mean gradient
/// going to 1 along x, y, z: column k of the conductivity is the mean flux at the end of loading
/// k (its sign as AMITEX writes Fourier's law).
std::string amitex_conductivity_loading_xml();
/// amitex_conductivity_algorithm.xml: the basic scheme for stationary diffusion.
std::string amitex_conductivity_algorithm_xml();
/// True when the scene's materials give some phase a conductivity (the conductivity files are
/// then written and run).
bool amitex_conductivity_wanted(const Scene& scene);
/// amitex_run.sh: the amitex_fftp commands on these files (MPI launcher from $MPIRUN): the
/// mechanical run unless the scene's materials give conductivities only, the diffusion run
/// when they give conductivities.
std::string amitex_run_sh(const Scene& scene);

}  // namespace rvegen
