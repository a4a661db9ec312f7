// Conforming periodic tetrahedral meshes of an RVE, built on Gmsh (its OpenCASCADE kernel and
// its HXT volume mesher): each inclusion is cut by the box faces, its pieces are brought into the
// box by their periodic shifts and fragmented against it, so every interface and every box face
// is a surface of the mesh, and a cut face lies on opposite box faces as one face and its exact
// translate; the faces at the upper end of each axis are meshed as translated copies of those at
// the lower end (Gmsh's periodic surfaces), so opposite faces carry identical triangulations.
// The cell may be the box moved along its axes, off inclusions its faces, edges or corners would
// graze (cell_origin). The element size follows the local gap between surfaces (two inclusions,
// an inclusion and a box face it does not cross, a shell's two surfaces) and the curvature of
// the inclusions (a bound on the chord error, grown away from the surface), between a least and
// a largest size. Second order (options.order 2) adds a node in the middle of each edge.
//
// Spheres, cylinders (flat ends) and ellipsoids, coated or not, with their interphase shells (the
// exact offsets of the cores; an ellipsoid's, which is no ellipsoid, built by OpenCASCADE:
// offset_solid.hpp); debonded spheres with their voids (a phase: the spherical shell of the gap
// over the cap, ended by a cone). Wavy, bent and deformed inclusions are refused (InputError),
// and so are closed boxes.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "rvegen/model/errors.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/phases.hpp"
#include "rvegen/model/scene.hpp"

namespace rvegen {

/// The mesher failed (its message), or the mesh it gave is not what the RVE needs.
class MeshError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct TetMeshOptions : TetMeshSpec {
  /// Threads of the volume mesher (0: all cores).
  int threads = 0;
};

struct TetMesh {
  /// The mesh's cell: the set's box, moved along its axes when the options allow (cell_shift).
  Box box;
  std::vector<Phase> phases;  // phase_table of the set
  std::vector<Vec3> nodes;
  /// Node indices (0-based) of each tetrahedron, positively oriented.
  std::vector<std::array<int32_t, 4>> tets;
  /// Second order (order 2): the node at the middle of each tetrahedron's edges, in the order
  /// of kTetEdges; these nodes follow the corners in `nodes`. Empty for first order.
  std::vector<std::array<int32_t, 6>> mid;
  std::vector<int32_t> phase;         // per tetrahedron: phase label
  std::vector<int32_t> inclusion_id;  // per tetrahedron: -1 in the matrix
  /// (dependent, master) node pairs: every node with a coordinate at the upper end of an axis,
  /// and the node at its coordinates brought to the lower ends (which lies on no upper face).
  std::vector<std::array<int32_t, 2>> periodic;
  /// Nodes the volume mesher left at the position of another, merged (merge_coincident_nodes).
  long long merged_nodes = 0;
  /// Nodes on upper box faces that were more than 1e-9 of the box off the translates of their
  /// images, put there (snap_periodic_nodes).
  long long snapped_nodes = 0;
  /// Interface nodes moved off the exact surface to keep the phases' volumes
  /// (keep_phase_volumes).
  long long moved_nodes = 0;
  /// Nodes moved (inside one region, or along one interface) to lift elements under 5 degrees
  /// (lift_slivers).
  long long relocated_nodes = 0;
  /// Nodes added inside one region, each with the elements about it remade, to lift elements
  /// under 5 degrees that moving nodes did not (insert_nodes_in_slivers).
  long long inserted_nodes = 0;
  /// Elements under 5 degrees remade with their neighbours by flips and collapses of short
  /// edges (remake_slivers).
  long long remade_slivers = 0;
  /// Rounds of the three repairs above (repair_slivers).
  int sliver_rounds = 0;
  /// Triangles of curved surfaces that lay flat in a box face, split about a node on the
  /// surface (raise_flat_triangles).
  long long raised_triangles = 0;
  /// Edges of those triangles that lay in the face and on no curve, flipped off it.
  long long flipped_chords = 0;
  /// Flat elements lying in a box face, removed (remove_flat_face_elements).
  long long flat_elements_removed = 0;
  /// What ended each attempt before the one that made this mesh (empty when the first did), in
  /// order: the mesher's message and what was done next.
  std::vector<std::string> retries;
  /// Gmsh's volume mesher that made it: "HXT", or "Delaunay" where HXT refused every attempt's
  /// surfaces.
  std::string volume_mesher = "HXT";
};

/// A tetrahedron's edges as pairs of its corners, in the order of the midside nodes of Abaqus's
/// C3D10 and VTK's quadratic tetrahedron (Gmsh's 10-node tetrahedron swaps the last two).
inline constexpr int kTetEdges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}};

/// The signed volume of tetrahedron `t` of the mesh (positive when oriented as tet_mesh gives it).
inline double tet_volume(const std::vector<Vec3>& nodes, const std::array<int32_t, 4>& t) {
  const Vec3& p0 = nodes[t[0]];
  return (nodes[t[1]] - p0).cross(nodes[t[2]] - p0).dot(nodes[t[3]] - p0) / 6.0;
}

/// Where each node lies: per axis -1 inside, 0 at the box's lower end, 1 at its upper end
/// (within 1e-9 of the box's smallest side).
inline std::vector<std::array<int8_t, 3>> node_ends(const TetMesh& mesh) {
  const Box& box = mesh.box;
  const double tol = 1e-9 * box.size.minCoeff();
  std::vector<std::array<int8_t, 3>> at(mesh.nodes.size());
  for (size_t i = 0; i < mesh.nodes.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      const double x = mesh.nodes[i][a] - box.origin[a];
      at[i][a] = std::abs(x) <= tol ? 0 : (std::abs(x - box.size[a]) <= tol ? 1 : -1);
    }
  }
  return at;
}

/// Refuses (InputError naming the family) a set tet_mesh cannot mesh.
void check_tet_meshable(const InclusionSet& set);

/// Called with the share done (0 to 1) and, at each stage, a line naming it (empty between
/// stages); returning false stops the mesher (tet_mesh then throws Cancelled).
using TetMeshProgress = std::function<bool(double fraction, const std::string& line)>;

/// Meshes the set. Throws InputError for what check_tet_meshable refuses, MeshError when the
/// mesher fails (with its message) or when the faces do not match or the mesh does not
/// conform, and Cancelled when `progress` returned false: at the end of the stage under way
/// (Gmsh cannot be interrupted inside one; stages: fragments, surfaces, volumes, node moves).
TetMesh tet_mesh(const InclusionSet& set, const TetMeshOptions& options = {},
                 const TetMeshProgress& progress = {});

/// The elements tet_mesh makes of the set with these sizes, estimated before it runs: its size
/// field h (gaps, curvature, growth away from surfaces, the least and largest sizes) integrated
/// as a constant times the integral of 1 / h^3 over the box (an octree refined to the local
/// size), the constant fitted on meshes of spheres, fibres and the default scene. The work grows
/// with the count (an evaluation of the size field per few elements): past `cap` it stops
/// and returns a count above the cap (the memory check asks no more than whether it fits).
inline constexpr double kTetEstimateCap = 1e8;  // elements: about 90 GB of mesh
double tet_elements_estimate(const InclusionSet& set, const TetMeshSpec& spec,
                             double cap = kTetEstimateCap);

/// What meshing the set needs: tet_elements_estimate's elements, stopped once they pass what
/// `limit` bytes can hold (0: no limit; `capped` then says the count is only a lower bound), and
/// their peak bytes (tet_mesh_bytes, OpenCASCADE's solids included).
struct TetMeshNeed {
  double elements = 0.0;
  double bytes = 0.0;
  bool capped = false;
};
TetMeshNeed tet_mesh_need(const InclusionSet& set, const TetMeshSpec& spec, double limit);

/// The first of coarser_tet_meshes(spec) (resources.hpp: the least loss of accuracy first)
/// whose need on the set (tet_mesh_need, stopped past `limit` bytes) `fits` accepts; false when
/// none does. A mesh refused for its memory is refused with a setting that would be taken.
bool coarser_tet_mesh_that_fits(const InclusionSet& set, const TetMeshSpec& spec, double limit,
                                const std::function<bool(const TetMeshNeed&)>& fits,
                                TetMeshSpec* fit, TetMeshNeed* need);

/// The face clearance of a cell with lower corner `origin` (and the box's size): the least
/// distance from a box face (any periodic copy of it) to an extreme point along the face's
/// normal of a sphere or ellipsoid, over its least size (Shape::min_size), or of a cylinder's
/// rim, over its radius, and to the span of a cylinder's end disk within 30 degrees of parallel
/// to the face, over the radius. A face that cuts a sphere at distance c r inside its extreme
/// leaves a cap with an edge angle of acos(1 - c); one that crosses an end disk at angle phi, a
/// wedge of phi. Also from the span along the face's normal of the two lines of a cylinder's
/// mantle furthest along it, where the cylinder's axis lies within 8 degrees of the face: a face
/// within that span is tangent to the mantle where it crosses the line, a wedge as thin as the
/// tilt.
double face_clearance(const InclusionSet& set, const Vec3& origin);

/// The edge clearance of a cell with lower corner `origin`: how far, in the same units, the
/// cell's edges (any periodic copy) are from grazing an inclusion's surface (from the outline of
/// its shadow along the edge; for cylinders, from the mantle and the rims), and its corners from
/// the surface.
double edge_clearance(const InclusionSet& set, const Vec3& origin);

/// Where tet_mesh puts the cell's lower corner when options.shift_cell: the box's when its face
/// and edge clearances are at least kGoodClearance; otherwise, of a few positions per axis with
/// the largest face clearance (the box's among them), the combination with the largest least
/// clearance of faces and edges, and of those the one with the clearest edges. Where the spans
/// of shallow mantles cover an axis (long fibres nearly along the faces), the least shallow are
/// let go first: the tilt below which spans count falls from 8 to 6, 4, 2 and 0 degrees until
/// some position misses them all; then the spans of steep disks are let go. The same medium:
/// the cell is a window on the periodic RVE.
Vec3 cell_origin(const InclusionSet& set);
inline constexpr double kGoodClearance = 0.05;  // caps of 18 degrees or more

/// What nudge_off_cell did: inclusions moved (each counted once), and those that graze the cell
/// and found no room.
struct Nudged {
  int moved = 0;
  int stuck = 0;
};
/// Moves each inclusion whose own face or edge clearance at the cell with lower corner `origin`
/// is under kGoodClearance off the cell's faces, keeping it at least `min_gap` from every other
/// inclusion (exact tests on the envelopes, periodic images):
/// - first by the least translation along one axis that does it (at most 1.5 of its least size,
///   a cylinder's radius, in steps of a sixteenth);
/// - else by the least in any of 26 directions (at most 4 sizes);
/// - else by one of those (the 24 least) that pushes the inclusions it meets: they are moved
///   off it along their contacts' normals, and those they meet in turn, in sweeps until no two
///   are within 1.2 min_gap. Accepted when at most 64 moved, none by more than 2 of its sizes,
///   and none grazes the faces more than before (or under kGoodClearance).
/// The inclusions stay as drawn otherwise (sizes and orientations, hence the volume fractions
/// and the orientation tensor). In the index order, so the same set gives the same result.
Nudged nudge_off_cell(InclusionSet* set, const Vec3& origin, double min_gap);
/// Rounds of nudge_off_cell at cell_origin(*set) until one moves nothing (at most four), so that
/// the cell tet_mesh chooses for the moved set is the one the last round cleared; `moved` counts
/// the inclusions that any round moved, `stuck` the last round's.
Nudged nudge_off_chosen_cell(InclusionSet* set, double min_gap);

/// Puts each node that lies on an upper box face (within 1e-9 of the box's least side, the
/// tolerance of the periodic pairs) exactly at the translate of its image on the lower faces,
/// where one lies within 1e-6 of that side of where the image should be. Gmsh places the nodes
/// of a curve it meshes as the copy of its periodic image on the curve itself: rarely, one
/// lands further off the translate of its image's than the pairs' tolerance. Returns the number
/// of nodes moved by more than 1e-9 of the side (those the pairs would miss; most others move
/// by a rounding error).
long long snap_periodic_nodes(TetMesh* mesh);

/// Merges nodes at one position (each element then uses the lowest-numbered one), drops nodes
/// no element uses and renumbers the rest in order. Throws MeshError if an element is left with
/// two nodes at one position. tet_mesh calls it: the volume mesher rarely leaves a second node
/// where one is, which cracks the mesh.
/// Returns the number of nodes merged into others.
long long merge_coincident_nodes(TetMesh* mesh);

/// Moves the nodes inside each curved interface (between the matrix and a core or a shell, or a
/// core and its shell: spheres, cylinders' mantles, ellipsoids, shells' outer surfaces) along the
/// surface's normal by the area-weighted mean gap between its triangles and the exact surface, so
/// that the volume the chords cut off is given back: each phase's volume is then exact to second
/// order in the chord error. Nodes on box faces, on flat ends, on two surfaces, or on an
/// interface between two inclusions stay. A move that would invert an element, or leave one with
/// a least dihedral angle under 5 degrees and smaller than before, is undone. tet_mesh calls it
/// when options.keep_volumes. Returns the number of nodes moved.
long long keep_phase_volumes(TetMesh* mesh, const InclusionSet& set);

/// Makes the mesh second order: a node at the middle of every edge (one per edge, shared by the
/// elements around it), appended after the corners, and mesh->mid. The edges stay straight, so
/// the elements keep their volumes and angles, and the middle of an edge on an upper box face is
/// the image of the middle of its translate on the lower face. tet_mesh calls it when
/// options.order is 2, before it pairs the periodic nodes.
void add_midside_nodes(TetMesh* mesh);

/// Removes the flat elements that lie in a box face (all four nodes on one face: the volume
/// mesher leaves one now and then where a thin piece of an inclusion meets the face). Such an
/// element's two faces on the box face are one diagonal of their quadrilateral, its two other
/// faces (shared with the elements above) the other diagonal: without it, the box face takes the
/// other diagonal, and the opposite face, whose triangles must stay their translates, takes it
/// too by a flip of the two elements on its triangles (when they share their fourth node, lie in
/// one region and come out positive; otherwise the flat element stays, as do flat elements with
/// one node inside the triangle of the three others). No node moves, the volumes and interfaces
/// stay. tet_mesh calls it before lift_slivers. Returns the number of elements removed.
long long remove_flat_face_elements(TetMesh* mesh);

/// Moves nodes of the elements whose least dihedral angle is under `angle` degrees to raise the
/// least angle of the elements around them: nodes inside one region (inclusion and phase) move
/// freely, nodes on one curved interface of `set`'s inclusions slide along it at their distance
/// from the exact surface; a node on one box face (not an edge) whose image is on the opposite
/// face moves with it, in the face or along the face's cut of one curved interface; nodes on
/// box edges, flat ends, two interfaces or between two inclusions stay. So no interface moves off
/// its surface, the faces' triangulations stay translates of each other, and the phases' volumes
/// change only by the surfaces' curvature over a step. A move is taken only when
/// it raises the least angle of the elements around the node, all positive. tet_mesh calls it on
/// every mesh, after keep_phase_volumes. Returns the number of nodes moved.
long long lift_slivers(TetMesh* mesh, const InclusionSet& set, double angle = 5.0);

/// Remakes each element whose least dihedral angle is under `angle` degrees with its
/// neighbours, where that lifts it, in one of three ways, the best by least angle:
/// - the elements around one of its edges replaced by a triangulation of their ring (the best by
///   least angle), no node added;
/// - the element and its neighbour across a face, in one region, made three about the line
///   between their other nodes;
/// - one of its edges collapsed into one node u (its other node v goes, v's other elements take
///   u), where v lies inside the box and in one region, or on one interface that the edge lies
///   in with u within a tenth of the mean length of v's other edges of the plane of each of
///   v's interface triangles (a short edge, or one along a flat interface).
/// An edge on an interface (its ring in two regions) is flipped with the interface where the
/// interface's two triangles at it nearly lie in one plane (their diagonals apart by at most a
/// tenth of the shorter): the interface then moves by the flat element between them; a
/// collapse moves it by no more than u's distance from those planes. Edges in box faces, nodes on
/// them and edges where three regions meet stay; so do the faces' triangulations. At a tie in least
/// angle, what keeps the interfaces is taken. Taken when every new element is positive and their
/// least angle is at least `angle`, or higher than the old ones' with fewer under `angle`. Nodes
/// left in no element go (the others keep their order). tet_mesh calls it after lift_slivers.
/// Returns the number of remakes.
long long remake_slivers(TetMesh* mesh, double angle = 5.0);

/// Adds a node inside one region (inclusion and phase) at each element whose least dihedral
/// angle is under `angle` degrees, where that lifts it: at the element's circumcentre, its
/// centroid or the centroid of its neighbours in the region, the one that does best. The
/// elements of the region whose circumscribed spheres hold the node (a Delaunay cavity, connected
/// to the element; those with a boundary face the node does not see leave it) are replaced by
/// the node joined to the cavity's boundary faces; taken when
/// every new element is positive, they fill the cavity's volume exactly, and their least angle is
/// at least `angle`, or higher than the cavity's with fewer elements under `angle`. The boundary
/// faces stay, so no interface, box face or phase volume changes. For elements whose nodes all
/// lie on surfaces, which lift_slivers cannot move. tet_mesh calls it after lift_slivers.
/// Returns the number of nodes added.
long long insert_nodes_in_slivers(TetMesh* mesh, double angle = 5.0);

/// Throws MeshError unless the mesh conforms (every face of an element is a face of another
/// element or lies in a box face) and fills the box (every element positive, their volumes
/// adding up to the box's to 1e-9). tet_mesh calls it on every mesh.
/// Lifts the elements under `angle` degrees by rounds of lift_slivers, remake_slivers and
/// insert_nodes_in_slivers, each round on what the one before left (a remake or an inserted node
/// can give a node room that it lacked), until none is left under `angle`, a round changes
/// nothing, or 4 rounds; the three passes' counts add to the mesh's relocated_nodes,
/// remade_slivers and inserted_nodes. tet_mesh calls it after keep_phase_volumes. Returns the
/// rounds run (0: none was under `angle`).
int repair_slivers(TetMesh* mesh, const InclusionSet& set, double angle = 5.0);

void check_conforming(const TetMesh& mesh);

/// What the mesh is worth: element volumes and their sum per phase label, the least dihedral
/// angle of every element.
struct TetQuality {
  double min_volume = 0.0;                 // least element volume (positive: no inverted element)
  std::vector<double> phase_volume;        // per phase label
  double min_dihedral = 0.0;               // degrees
  std::array<double, 3> quantiles = {};    // 1 %, 5 %, 50 % of the elements' least angles
  std::vector<long long> dihedral_counts;  // elements whose least angle lies in each bin
  static constexpr std::array<double, 7> kBins = {0, 5, 10, 15, 20, 30, 45};  // bin lower ends
  long long below_5_degrees = 0;
};
TetQuality tet_quality(const TetMesh& mesh);

}  // namespace rvegen
