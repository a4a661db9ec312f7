// Finite-element meshes of the RVE for Abaqus, CalculiX and Gmsh (one 8-node hexahedron per
// voxel of the image, or the conforming tetrahedral mesh of femesh/): element sets per phase, node
// sets of the faces, edges and corners, reference nodes for the macroscopic load, and decks with
// periodic equations that run as written.
//
// Periodic boundary conditions: a node with a coordinate on a box face at the upper end of an
// axis (x = L, y = L or z = L) is tied to its image with those coordinates brought to the lower
// end (its master, which lies on no upper face), by one equation per degree of freedom:
//   conductivity:  T(dep) - T(master) - sum_a s_a L_a G_a = 0,
//   elasticity:    u_c(dep) - u_c(master) - sum_a s_a L_a H_ca = 0  (c = 1..3),
// with s_a = 1 for each axis a the node was brought back along. G_a (the mean temperature
// gradient) and H_ca (the mean displacement gradient, column a) are the degrees of freedom of
// the reference nodes REFX, REFY, REFZ (DOF 11, or DOFs 1-3: column a of H on reference node a).
// Edge and corner nodes thus get one equation each, tied straight to the node at the origin's
// corner, edge or face: no node is constrained twice. The origin node is fixed (the constant
// mode); each load case prescribes the reference nodes. The decks print the flux or stress at
// every integration point (*EL PRINT of the set EALL): all voxel elements are equal, so the
// plain mean of those values is the box mean; the tetrahedral decks also print each element's
// volume, by which samples/ccx_effective.py weights its value.
#pragma once

#include <cstdio>
#include <string>

#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen {

/// mesh_voxel.inp: *NODE (node i + (nx+1) (j + (ny+1) k) + 1 at the grid point (i, j, k)),
/// *ELEMENT C3D8 (element v + 1 for voxel v, x fastest) in one ELSET per phase present (named
/// after the phase: matrix, the family names, <family>_coating, <family>_void), *NSET of the
/// faces (XMIN .. ZMAX), the twelve edges (EDGE_Y0Z0 .. along x, and so on), the eight corners
/// (CORNER_X0Y0Z0 ..), ORIGIN, and the reference nodes REFX, REFY, REFZ (set REFS); EALL.
void write_abaqus_voxel_mesh(const VoxelImage& image, std::FILE* out);

/// mesh_voxel.msh: the same mesh in Gmsh's format 4.1 (ASCII): a volume entity and a physical
/// group per phase present (named after it), six surface entities for the faces (XMIN, XMAX,
/// YMIN, YMAX, ZMIN, ZMAX: tags 1-6), the nodes and hexahedra of mesh_voxel.inp (same ids), and
/// a $Periodic section tying each upper face's nodes to their images on the lower face (the
/// translation by the box size as affine transform).
void write_gmsh_voxel_mesh(const VoxelImage& image, std::FILE* out);

/// mesh_tet.inp: the tetrahedral mesh (C3D4, or C3D10 for a second-order mesh; node and element
/// numbers from 1 in the mesh's order) with the node and element sets of mesh_voxel.inp: an ELSET
/// per phase present, EALL, the faces, edges and corners (nodes within 1e-9 of the box size of
/// those ends), ORIGIN (the node at the box's lower corner), and the reference nodes REFX, REFY,
/// REFZ (REFS).
void write_abaqus_tet_mesh(const TetMesh& mesh, std::FILE* out);

/// mesh_tet.msh: the tetrahedral mesh in Gmsh's format 4.1 as mesh_voxel.msh (physical groups
/// per phase, the six face entities, the nodes and elements of mesh_tet.inp with the same ids;
/// element type 4, or 11 with the midside nodes in Gmsh's order),
/// with a $Periodic section pairing each node on an upper face with its image on the lower one.
void write_gmsh_tet_mesh(const TetMesh& mesh, std::FILE* out);

/// run_voxel_conductivity.inp (elasticity false) or run_voxel_elasticity.inp: *INCLUDE of
/// mesh_voxel.inp, one material and section per phase, the periodic equations and three (unit
/// mean gradients along x, y, z) or six (unit mean strains 11, 22, 33, 23, 13, 12 in Mandel
/// form: shear components 1 / sqrt 2) load steps printing the flux or stress of EALL. Cores of a
/// transversely isotropic family get, inclusion by inclusion, an element set I<id>, an
/// orientation O<id> along the inclusion's axis (`set`) and an orthotropic section (engineering
/// constants; TYPE=ORTHO conductivity); voids a modulus of 1e-6 of the stiffest phase's. Empty
/// when a phase present lacks the property the physics needs.
std::string abaqus_voxel_deck(const Scene& scene, const InclusionSet& set, const VoxelImage& image,
                              bool elasticity);

/// run_tet_conductivity.inp or run_tet_elasticity.inp: the same deck on mesh_tet.inp, with the
/// periodic pairs of the mesh (each node on an upper face tied to its image at the lower ends);
/// each step also prints every element's volume (EVOL: the elements differ in volume, and the
/// box mean weights each by its own). Empty as abaqus_voxel_deck.
std::string abaqus_tet_deck(const Scene& scene, const InclusionSet& set, const TetMesh& mesh,
                            bool elasticity);

}  // namespace rvegen
