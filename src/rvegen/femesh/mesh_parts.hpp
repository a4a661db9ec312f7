// What the rooms of the tetrahedral mesher share (not for use outside femesh/): the inclusions'
// periodic images near the box and their outer surfaces (a shell or a void around the core),
// and the mesh topology's helpers.
#pragma once

#include <array>
#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/model/inclusion_set.hpp"

namespace rvegen::mesh_parts {

// An inclusion's periodic image: the inclusion and its shift.
struct Image {
  int inc;
  Vec3 shift;
};

// How far an inclusion's outer surface lies out from its core: its interphase shell's thickness,
// or its debonding void's gap (over the cap; a sphere can have one or the other).
inline double outer_offset(const Modifiers& m) {
  return m.coated() ? m.coating : (m.debonded() ? m.debond_gap : 0.0);
}

// An inclusion's bounding box, its interphase shell or debonding void included.
inline void outer_aabb(const Inclusion& inc, Vec3* lo, Vec3* hi) {
  inc.shape.aabb(lo, hi);
  *lo -= Vec3::Constant(outer_offset(inc.mod));
  *hi += Vec3::Constant(outer_offset(inc.mod));
}

// The images of the set's inclusions whose box, grown by `margin`, meets the box.
inline std::vector<Image> images_near(const InclusionSet& set, double margin) {
  const Vec3 o = set.box.origin, len = set.box.size;
  std::vector<Image> out;
  for (size_t m = 0; m < set.inclusions.size(); ++m) {
    Vec3 lo, hi;
    outer_aabb(set.inclusions[m], &lo, &hi);
    for (int ox = -1; ox <= 1; ++ox) {
      for (int oy = -1; oy <= 1; ++oy) {
        for (int oz = -1; oz <= 1; ++oz) {
          const Vec3 t(ox * len[0], oy * len[1], oz * len[2]);
          bool meets = true;
          for (int a = 0; a < 3; ++a) {
            meets = meets && hi[a] + t[a] + margin > o[a] && lo[a] + t[a] - margin < o[a] + len[a];
          }
          if (meets) out.push_back({static_cast<int>(m), t});
        }
      }
    }
  }
  return out;
}

// mesh_topology.cpp: a face's key (its three node numbers in any order, mixed into 64 bits);
// the nodes in no element dropped (the others keep their order); each node on an upper box
// face (within `on` of it) with the node on the lower faces nearest its translate there,
// within `reach` (-1 when none); the least dihedral angle of a tetrahedron, in degrees.
uint64_t face_key(int32_t a, int32_t b, int32_t c);
void drop_unused_nodes(TetMesh* mesh);
std::vector<std::pair<int32_t, int32_t>> lower_images(const TetMesh& mesh, double on, double reach);
double least_dihedral(const Vec3 (&p)[4]);
double least_dihedral(const TetMesh& mesh, const std::array<int32_t, 4>& t);

// phase_volumes.cpp: the signed distance of x from the surface of shape s grown by t
// (negative inside) and the outward normal there (exact for spheres, cylinders and grown
// ellipsoids outside the ellipsoid, to first order for ellipsoids; `feature`: x on a flat end's
// plane of an ungrown cylinder); an element's region (its inclusion and phase as one number);
// the index in set.inclusions of each inclusion id; the exact surface an interface between two
// regions belongs to (-1: none); the periodic image of a grown shape nearest x; whether a
// triangle or a point of a debonded sphere's void lies on the void's cone.
double surface_distance(const Shape& s, double t, const Vec3& x, Vec3* normal, bool* feature);
uint64_t region_of(const TetMesh& mesh, size_t e);
std::unordered_map<int32_t, int> index_by_id(const InclusionSet& set);
int interface_surface(const std::unordered_map<int32_t, int>& by_id, int id1, PhaseKind k1, int id2,
                      PhaseKind k2);
Vec3 nearest_image(const Shape& shape, double grown, const Vec3& size, const Vec3& x,
                   double* distance, bool* feature);
bool on_void_cone(const Inclusion& in, const Vec3& shift, const Vec3& p0, const Vec3& p1,
                  const Vec3& p2);
bool on_void_cone(const Inclusion& in, const Vec3& shift, const Vec3& x);

// solids.cpp (through Gmsh's OpenCASCADE kernel; tags of the solids made): the solid of shape
// s grown by `offset` (a shell's outer surface), built in the frame that keeps its seam and
// poles off the faces of `box` it crosses, or in `given`, or in the frame of rank `rank` by
// that measure; the piece inside the box of an image cut by its faces; the frame of a debonded
// sphere's void and core; the solid of that void.
int add_solid(const Shape& s, const Box& box, double offset = 0.0, const Mat3* given = nullptr,
              int rank = 0);
int add_inside_solid(const Shape& s, const Box& box, int rank);
Mat3 void_frame(const Inclusion& in, const Box& box);
int add_void_solid(const Inclusion& in, const Box& box);

// slivers.cpp: the elements marked in `gone` dropped (the rest keep their order); the elements
// whose least dihedral angle is under `angle` degrees, in order (*least: every element's);
// the elements around each node n, (*around)[(*start)[n]] to (*around)[(*start)[n + 1] - 1];
// the element other than `except` on face (a, b, c), -1 if none; the centre of a
// tetrahedron's circumscribed sphere (its centroid when flat to rounding).
void drop_elements(TetMesh* mesh, const std::vector<uint8_t>& gone);
std::vector<int32_t> elements_under(const TetMesh& mesh, double angle, std::vector<double>* least);
void elements_around(const TetMesh& mesh, std::vector<int32_t>* start,
                     std::vector<int32_t>* around);
int32_t element_on(const TetMesh& mesh, const std::vector<int32_t>& start,
                   const std::vector<int32_t>& around, int32_t a, int32_t b, int32_t c,
                   int32_t except);
Vec3 circumcentre(const Vec3 (&p)[4]);

}  // namespace rvegen::mesh_parts
