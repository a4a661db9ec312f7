#include "rvegen/femesh/tet_mesh.hpp"

#include <gmsh.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <unordered_map>

#include "rvegen/femesh/mesh_parts.hpp"
#include "rvegen/femesh/mesh_tolerances.hpp"
#include "rvegen/femesh/offset_solid.hpp"
#include "rvegen/femesh/periodic_faces.hpp"
#include "rvegen/femesh/size_field.hpp"
#include "rvegen/geometry/pair.hpp"
#include "rvegen/model/body.hpp"
#include "rvegen/model/errors.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/model/parallel.hpp"
#include "rvegen/model/resources.hpp"

namespace rvegen {

using namespace mesh_parts;

namespace {

// Gmsh holds one model per process: one mesh at a time.
std::mutex gmsh_mutex;

// Initialises Gmsh for one mesh and finalises it on every way out.
struct GmshSession {
  GmshSession() {
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::model::add("rve");
  }
  ~GmshSession() { gmsh::finalize(); }
};

std::string last_gmsh_error() {
  std::string e;
  gmsh::logger::getLastError(e);
  return e.empty() ? "no message" : e;
}

}  // namespace

void check_tet_meshable(const InclusionSet& set) {
  if (!set.box.periodic) {
    throw InputError("outputs: mesh_tet needs a periodic box (box.periodic false)");
  }
  for (const Inclusion& inc : set.inclusions) {
    const std::string name = inc.family < static_cast<int>(set.family_names.size())
                                 ? set.family_names[inc.family]
                                 : "family " + std::to_string(inc.family);
    const Modifiers& m = inc.mod;
    if (m.curved() || m.deformed()) {
      throw InputError(
          "outputs: mesh_tet meshes spheres, cylinders and ellipsoids, plain, coated or (spheres) "
          "debonded; family \"" +
          name + "\" has wavy, bent or deformed inclusions (use mesh_voxel for them)");
    }
  }
}

namespace {

// The surface mesher failed, or HXT refused the surface mesh (see mesh_with): what() says which,
// after "mesh_tet: ". tet_mesh meshes again from the start, another way.
struct SurfacesRefused : MeshError {
  using MeshError::MeshError;
  SurfacesRefused(const std::string& what, std::vector<int> at)
      : MeshError(what), inclusions(std::move(at)) {}
  // The inclusions (indices in the set) whose surfaces bound the curves the message names.
  std::vector<int> inclusions;
};

// The chord error of the curves in the last attempt (tet_mesh).
constexpr double kFinerCurveChord = 0.01;
// How many times tet_mesh builds the inclusions about a failed surface in another frame.
constexpr int kFrameTurns = 2;

// Whether the volume mesher, not the surface mesher, refused (mesh_with's words).
bool refused_volumes(const SurfacesRefused& e) {
  return std::string(e.what()).rfind("the volume mesher refused", 0) == 0;
}
constexpr const char* kDelaunayRetry =
    "meshing the volumes again with Gmsh's Delaunay mesher (one thread, several times slower)";

// The matrix's volume, made of the faces after the box's faces (the first `box_faces` maps of
// `pieces`) were fragmented against the inclusions' pieces (`owner`'s volumes): the faces of the
// box that bound no piece and the pieces' faces that bound one piece only and lie in no box
// face. Its shells are the sets of those faces joined by their curves: the one that holds box
// faces is the outer shell, each other one a hole (an inclusion inside the box). Returns its tag.
int add_matrix(size_t box_faces, const std::vector<gmsh::vectorpair>& pieces,
               const std::map<int, std::pair<int, int32_t>>& owner) {
  std::set<int> on_box;
  for (size_t k = 0; k < box_faces && k < pieces.size(); ++k) {
    for (const auto& dt : pieces[k]) on_box.insert(dt.second);
  }
  std::map<int, int> uses;
  for (const auto& [volume, who] : owner) {
    gmsh::vectorpair faces;
    gmsh::model::getBoundary({{3, volume}}, faces, false, false, false);
    for (const auto& f : faces) ++uses[std::abs(f.second)];
  }
  std::vector<int> faces;
  for (const int f : on_box) {
    if (!uses.count(f)) faces.push_back(f);
  }
  const size_t box_patches = faces.size();
  for (const auto& [f, n] : uses) {
    if (n == 1 && !on_box.count(f)) faces.push_back(f);
  }
  // Shells: faces joined through the curves they share.
  std::vector<int> parent(faces.size());
  for (size_t i = 0; i < faces.size(); ++i) parent[i] = static_cast<int>(i);
  auto root = [&parent](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  std::unordered_map<int, int> face_of_curve;
  for (size_t i = 0; i < faces.size(); ++i) {
    gmsh::vectorpair curves;
    gmsh::model::getBoundary({{2, faces[i]}}, curves, false, false, false);
    for (const auto& c : curves) {
      const auto [it, fresh] = face_of_curve.emplace(std::abs(c.second), static_cast<int>(i));
      if (!fresh) parent[root(static_cast<int>(i))] = root(it->second);
    }
  }
  std::map<int, std::vector<int>> shells;
  for (size_t i = 0; i < faces.size(); ++i) shells[root(static_cast<int>(i))].push_back(faces[i]);
  if (box_patches == 0) throw MeshError("mesh_tet: the inclusions cover the box's faces");
  const int outer = root(0);
  // As they are: Gmsh's fixes would make new faces, and keep one shell of a loop.
  gmsh::option::setNumber("Geometry.OCCAutoFix", 0);
  // (Tagged here: Gmsh 4.8 returns -1 for a loop it numbers itself, and binds it as -1.)
  std::vector<int> loops;
  auto add_loop = [&loops](const std::vector<int>& shell) {
    loops.push_back(gmsh::model::occ::addSurfaceLoop(shell, gmsh::model::occ::getMaxTag(-2) + 1));
  };
  add_loop(shells[outer]);
  for (const auto& [r, shell] : shells) {
    if (r != outer) add_loop(shell);
  }
  const int matrix = gmsh::model::occ::addVolume(loops);
  gmsh::option::setNumber("Geometry.OCCAutoFix", 1);
  gmsh::model::occ::synchronize();
  return matrix;
}

// Gmsh's volume meshers: HXT (parallel, with its own optimiser) and Delaunay (one volume after
// another on one thread, Gmsh's optimiser).
constexpr int kHxt = 10, kDelaunay3d = 1;

// One attempt, with Gmsh's 2D algorithm `surface_algorithm` (6: Frontal-Delaunay, 5: Delaunay)
// and 3D algorithm `volume_algorithm` (kHxt or kDelaunay3d). With curve_chord > 0, the curves
// (the faces' cuts and the shells' rims) are divided as that chord error asks, where it is less
// than options.chord_error; the surfaces and volumes as options ask.
TetMesh mesh_with(const InclusionSet& set, const TetMeshOptions& options,
                  const TetMeshProgress& progress, int surface_algorithm, double curve_chord,
                  const std::vector<int>& frame_rank, int volume_algorithm = kHxt) {
  // Progress by stages, each a span of the whole; inside a long stage the size callback reports
  // too (every 2^16 calls, from the calling thread only: the volume mesher calls it from its
  // own threads as well), creeping towards the stage's end. Once progress returns false the
  // next stage does not start. (Gmsh cannot be interrupted inside a stage: answering the
  // largest size from then on, to end the stage sooner, made the volume stage three times
  // longer.)
  const std::thread::id caller = std::this_thread::get_id();
  std::atomic<bool> stop{false};
  std::atomic<long long> calls{0};
  double stage_from = 0.0, stage_to = 0.0;
  long long stage_calls = 0;
  auto report = [&](double fraction, const std::string& line) {
    if (progress && !progress(fraction, line)) stop = true;
  };
  auto stage = [&](double from, double to, const std::string& line) {
    if (stop) throw Cancelled();
    stage_from = from;
    stage_to = to;
    stage_calls = calls;
    report(from, line);
    if (stop) throw Cancelled();
  };
  const Box& box = set.box;
  const double side = box.size.minCoeff();
  const double max_size = options.largest_size(set.box), min_size = least_size(set, options);

  const int threads =
      std::max(1, options.threads > 0 ? options.threads
                                      : static_cast<int>(std::thread::hardware_concurrency()));

  std::lock_guard<std::mutex> lock(gmsh_mutex);
  GmshSession session;
  TetMesh mesh;
  mesh.box = box;
  mesh.phases = phase_table(set);
  try {
    // OpenCASCADE's boolean operations (the cuts by the cells and the fragment against the box)
    // in parallel when more than one thread is allowed; OpenCASCADE then uses its own pool of
    // all cores, not `threads`.
    // Not with coated ellipsoids: their shells' offset surfaces are evaluated through a cache
    // that OpenCASCADE's parallel booleans share between threads (a crash in
    // Geom_OsculatingSurface while 44 coated ellipsoids were cut by the cells on two threads;
    // made splines, the offsets crashed no more but the cut faces no longer matched their images).
    const bool offsets =
        std::any_of(set.inclusions.begin(), set.inclusions.end(), [](const Inclusion& in) {
          return in.mod.coated() && in.shape.kind == ShapeKind::Ellipsoid;
        });
    gmsh::option::setNumber("Geometry.OCCParallel", threads > 1 && !offsets ? 1 : 0);
    const Vec3 o = box.origin, len = box.size;
    // The box enters the fragment against the pieces as its six faces, not as a solid, and the
    // matrix is made of the faces afterwards: OpenCASCADE classifies every face of the other
    // arguments against each solid argument, and each test against the box, split by the pieces
    // into thousands of faces, explores all of them (2,484 fibres: 173 s, against 21 s for the
    // faces).
    gmsh::vectorpair box_faces;
    {
      const int box_tag = gmsh::model::occ::addBox(o[0], o[1], o[2], len[0], len[1], len[2]);
      gmsh::model::occ::synchronize();
      gmsh::model::getBoundary({{3, box_tag}}, box_faces, false, false, false);
      gmsh::model::occ::remove({{3, box_tag}}, false);
    }
    // Each inclusion's solid is cut by the box and by its shifted copies, and every piece is
    // brought into the box by its shift. A face cut by a box face then lies on both opposite faces
    // as one face and its exact translate, whatever the surface (OpenCASCADE makes spline
    // surfaces of ellipsoids, and the cuts of two translated images by opposite box faces,
    // computed apart, differed by 3 % of their area). Inclusions without a shell that have one
    // image, inside the box, go in as that image. All the others are cut in one boolean operation:
    // the solids (cores, and shells' outer surfaces) against the planes of the cells' faces, a
    // cell being the box moved by minus a shift (Gmsh's bookkeeping of OpenCASCADE's shapes costs
    // in proportion to the shapes it holds at each operation: cut one inclusion at a time, the
    // default scene's 1,269 pieces took 179 s).
    const std::vector<Image> images = images_near(set, 0.0);
    std::map<int, std::vector<Vec3>> shifts_of;
    for (const Image& im : images) shifts_of[im.inc].push_back(im.shift);
    gmsh::vectorpair tools;
    std::vector<int> tool_inc;
    std::vector<int32_t> tool_label;  // the phase of each piece
    const std::vector<int> shell_label =
        interphase_labels(mesh.phases, static_cast<int>(set.family_names.size()));
    const std::vector<int> void_label =
        void_labels(mesh.phases, static_cast<int>(set.family_names.size()));
    gmsh::vectorpair objects;
    std::vector<int> object_inc;
    std::vector<char> object_core;
    std::vector<Vec3> cell_shift;
    std::vector<Image> inside_images;         // made after the cut (see below)
    std::vector<std::pair<int, int>> to_cut;  // (inclusion, bit a: it crosses planes normal to a)
    for (const auto& [inc, shifts] : shifts_of) {
      const Inclusion& in = set.inclusions[inc];
      // (The cell is the box moved off the inclusions it would graze, so many of those inside
      // it are images.)
      Vec3 lo, hi;
      outer_aabb(in, &lo, &hi);
      const Vec3& t0 = shifts.front();
      const bool inside = shifts.size() == 1 && (lo + t0 - o).minCoeff() > 0.0 &&
                          (o + len - hi - t0).minCoeff() > 0.0;
      if (inside && !in.mod.coated() && !in.mod.debonded()) {
        inside_images.push_back({inc, t0});
        continue;
      }
      // The axes along which its images lie in more than one cell: the planes it crosses.
      int axes = 0;
      for (const Vec3& t : shifts) {
        for (int a = 0; a < 3; ++a) axes |= t[a] != t0[a] ? 1 << a : 0;
        if (std::find(cell_shift.begin(), cell_shift.end(), t) == cell_shift.end()) {
          cell_shift.push_back(t);
        }
      }
      to_cut.push_back({inc, axes});
    }
    if (!to_cut.empty()) {
      // The solids are cut by the planes of the cells' faces, entered as faces (squares wider
      // than the cells): with the cells as solids, OpenCASCADE classified every face of the
      // solids against each cell, split by the solids into hundreds of faces. Each piece goes to
      // the cell that holds its centre of mass (a piece lies in one cell, and its centre of mass
      // inside its convex hull).
      std::set<std::pair<int, long>> plane_at;  // (axis, k): the plane x_axis = o + k len
      for (const Vec3& t : cell_shift) {
        for (int a = 0; a < 3; ++a) {
          const long k = std::lround(-t[a] / len[a]);
          plane_at.insert({a, k});
          plane_at.insert({a, k + 1});
        }
      }
      // The solids of an inclusion (its core, and its shell's outer surface and its void);
      // map[k]: the pieces of objects[k] so far.
      std::vector<gmsh::vectorpair> map;
      auto make_solids = [&](int inc) {
        const Inclusion& in = set.inclusions[inc];
        const bool cone = in.mod.debonded() && in.mod.debond_fraction < 1.0;
        const Mat3 axis_frame = cone ? void_frame(in, box) : Mat3::Identity();
        objects.push_back(
            {3, add_solid(in.shape, box, 0.0, cone ? &axis_frame : nullptr, frame_rank[inc])});
        object_inc.push_back(inc);
        object_core.push_back(1);
        if (in.mod.coated()) {
          objects.push_back(
              {3, add_solid(in.shape, box, in.mod.coating, nullptr, frame_rank[inc])});
          object_inc.push_back(inc);
          object_core.push_back(0);
        }
        if (in.mod.debonded()) {
          objects.push_back({3, add_void_solid(in, box)});
          object_inc.push_back(inc);
          object_core.push_back(2);
        }
        while (map.size() < objects.size()) map.push_back({objects[map.size()]});
      };
      // Fragments the present pieces of objects[from, to) against the planes normal to the
      // axes of `axes` (bits).
      auto cut = [&](size_t from, size_t to, int axes) {
        gmsh::vectorpair present;  // each once (a shell's pieces hold its core's)
        std::set<int> seen;
        for (size_t k = from; k < to; ++k) {
          for (const auto& dt : map[k]) {
            if (seen.insert(dt.second).second) present.push_back(dt);
          }
        }
        if (present.empty()) return;
        gmsh::vectorpair planes;
        for (const auto& [a, k] : plane_at) {
          if (!(axes & (1 << a))) continue;
          const int b = (a + 1) % 3, c = (a + 2) % 3;
          int corner[4];
          for (int q = 0; q < 4; ++q) {
            Vec3 p;
            p[a] = o[a] + static_cast<double>(k) * len[a];
            p[b] = o[b] + ((q == 1 || q == 2) ? 3.0 : -2.0) * len[b];
            p[c] = o[c] + (q >= 2 ? 3.0 : -2.0) * len[c];
            corner[q] = gmsh::model::occ::addPoint(p[0], p[1], p[2]);
          }
          std::vector<int> sides;
          for (int q = 0; q < 4; ++q) {
            sides.push_back(gmsh::model::occ::addLine(corner[q], corner[(q + 1) % 4]));
          }
          planes.push_back(
              {2, gmsh::model::occ::addPlaneSurface({gmsh::model::occ::addCurveLoop(sides)})});
        }
        gmsh::vectorpair out;
        std::vector<gmsh::vectorpair> out_map;
        gmsh::model::occ::fragment(present, planes, out, out_map);
        std::map<int, const gmsh::vectorpair*> became;
        for (size_t i = 0; i < present.size() && i < out_map.size(); ++i) {
          became[present[i].second] = &out_map[i];
        }
        for (size_t k = from; k < to; ++k) {
          gmsh::vectorpair now;
          for (const auto& dt : map[k]) {
            for (const auto& n : *became.at(dt.second)) {
              if (std::find(now.begin(), now.end(), n) == now.end()) now.push_back(n);
            }
          }
          map[k] = std::move(now);
        }
        // The planes' pieces (those that bound a piece stay, as its faces): a later fragment
        // forgets the faces of the pieces it cuts.
        gmsh::vectorpair rest;
        for (const auto& dt : out) {
          if (dt.first == 2) rest.push_back(dt);
        }
        gmsh::model::occ::remove(rest, false);
      };
      // With the planes of two axes in one fragment, OpenCASCADE left an ellipsoid (a spline
      // surface) through which the line where two planes meet passes split by one of them only
      // (the default scene's cell, an ellipsoid across its x and z faces: its cap stood out of
      // the cell). The solids that cross planes of two or three axes are cut one axis at a time
      // (parallel planes never meet), and first, while the model holds little (each fragment
      // costs about 3 s for 2,484 fibres whatever it cuts, in Gmsh's bookkeeping of the
      // shapes it holds); the others are cut by all the planes at once.
      auto across = [](int axes) { return (axes & (axes - 1)) != 0; };
      for (const auto& [inc, axes] : to_cut) {
        if (across(axes)) make_solids(inc);
      }
      const size_t first = objects.size();
      for (int a = 0; a < 3; ++a) {
        // (Each pass takes every one of them: a solid it does not cut keeps its pieces.)
        cut(0, first, 1 << a);
      }
      for (const auto& [inc, axes] : to_cut) {
        if (!across(axes)) make_solids(inc);
      }
      cut(first, objects.size(), 7);
      // Each piece of a solid belongs to the first inclusion whose solids hold it (where shells
      // that may touch overlap), and is a core's when one of that inclusion's cores holds it.
      std::map<int, int> piece_inc;
      std::set<int> core_piece, void_piece;
      for (size_t k = 0; k < objects.size() && k < map.size(); ++k) {
        for (const auto& dt : map[k]) {
          const int owner_inc = piece_inc.emplace(dt.second, object_inc[k]).first->second;
          if (owner_inc != object_inc[k]) continue;
          if (object_core[k] == 1) core_piece.insert(dt.second);
          if (object_core[k] == 2) void_piece.insert(dt.second);
        }
      }
      std::map<std::array<long, 3>, gmsh::vectorpair> to_move;  // by the cell's index
      for (const auto& [piece, inc] : piece_inc) {
        double com[3];
        gmsh::model::occ::getCenterOfMass(3, piece, com[0], com[1], com[2]);
        std::array<long, 3> cell;
        for (int a = 0; a < 3; ++a) cell[a] = std::lround(std::floor((com[a] - o[a]) / len[a]));
        const Inclusion& in = set.inclusions[inc];
        to_move[cell].push_back({3, piece});
        tools.push_back({3, piece});
        tool_inc.push_back(inc);
        tool_label.push_back(core_piece.count(piece)   ? core_label(in.family)
                             : void_piece.count(piece) ? void_label[in.family]
                                                       : shell_label[in.family]);
      }
      for (const auto& [cell, mine] : to_move) {
        const Vec3 t(-cell[0] * len[0], -cell[1] * len[1], -cell[2] * len[2]);
        if (!t.isZero()) gmsh::model::occ::translate(mine, t[0], t[1], t[2]);
      }
      // The curves and points the planes' pieces left unused (removed with their curves, the
      // planes' pieces took 17 s: for each curve and point of them, Gmsh scans every face and
      // curve it holds).
      gmsh::model::occ::synchronize();
      gmsh::vectorpair curves, unused;
      gmsh::model::getEntities(curves, 1);
      for (const auto& e : curves) {
        std::vector<int> up, down;
        gmsh::model::getAdjacencies(e.first, e.second, up, down);
        if (up.empty()) unused.push_back(e);
      }
      gmsh::model::occ::remove(unused, true);
    }
    // Gmsh's bookkeeping after a boolean operation scans, for each shape of its inputs, every
    // shape it holds: the inclusions inside the box are made after the cut (2,484 fibres: the
    // cut's fragment took 76 s with the 1,699 made before, 11 s after).
    for (const Image& im : inside_images) {
      const Inclusion& in = set.inclusions[im.inc];
      Shape image = in.shape;
      image.center += im.shift;
      tools.push_back({3, add_inside_solid(image, box, frame_rank[im.inc])});
      tool_inc.push_back(im.inc);
      tool_label.push_back(core_label(in.family));
    }
    stage(0.0, 0.15,
          "mesh_tet: fragmenting " + std::to_string(tools.size()) +
              " inclusion pieces against the box");
    gmsh::vectorpair out;
    std::vector<gmsh::vectorpair> pieces;
    gmsh::model::occ::fragment(box_faces, tools, out, pieces);
    gmsh::model::occ::synchronize();
    // Which inclusion and phase each volume belongs to (the pieces of tool k; where shells
    // that may touch overlap, the first).
    const size_t first_tool = box_faces.size();
    std::map<int, std::pair<int, int32_t>> owner;
    for (size_t k = 0; k < tools.size() && first_tool + k < pieces.size(); ++k) {
      for (const auto& dt : pieces[first_tool + k]) {
        owner.emplace(dt.second, std::make_pair(tool_inc[k], tool_label[k]));
      }
    }
    add_matrix(box_faces.size(), pieces, owner);
    // The faces at the upper end of each axis mesh as translated copies of those at the lower
    // end (tie_face_curves, copy_face_meshes): matched by bounding box and area. The patches of a
    // box face are the planes whose normal is the axis and whose centre of mass lies in the face
    // (OpenCASCADE's bounding boxes of patches bounded by spline curves stand out of the plane by
    // the curves' tolerance).
    const double tol = kPatchTolerance * side;
    gmsh::vectorpair surfaces;
    gmsh::model::getEntities(surfaces, 2);
    std::vector<FacePair> face_pairs;
    for (int a = 0; a < 3; ++a) {
      std::vector<std::pair<int, std::array<double, 7>>> lower, upper;
      for (const auto& s : surfaces) {
        std::string type;
        gmsh::model::getType(2, s.second, type);
        if (type != "Plane") continue;
        double com[3];
        gmsh::model::occ::getCenterOfMass(2, s.second, com[0], com[1], com[2]);
        for (int end = 0; end < 2; ++end) {
          const double v = o[a] + (end ? len[a] : 0.0);
          if (std::abs(com[a] - v) > tol) continue;
          std::vector<double> lo, hi, normal;
          gmsh::model::getParametrizationBounds(2, s.second, lo, hi);
          gmsh::model::getNormal(s.second, {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])}, normal);
          if (normal.size() < 3 || std::abs(std::abs(normal[a]) - 1.0) > kOnFace) continue;
          double b[6];
          gmsh::model::getBoundingBox(2, s.second, b[0], b[1], b[2], b[3], b[4], b[5]);
          std::array<double, 7> key;
          for (int k = 0; k < 6; ++k) key[k] = b[k];
          gmsh::model::occ::getMass(2, s.second, key[6]);
          (end ? upper : lower).push_back({s.second, key});
        }
      }
      if (upper.size() != lower.size()) {
        throw MeshError("mesh_tet: the box faces normal to " + std::string(1, "xyz"[a]) +
                        " were cut into " + std::to_string(lower.size()) + " and " +
                        std::to_string(upper.size()) + " patches");
      }
      std::set<int> used;
      for (const auto& [tag, key] : upper) {
        // The lower patch nearest to this one's image, each taken once (OpenCASCADE's centres of
        // mass and areas of small patches differ from their images' by up to about 1e-5 of the
        // box and of their area: matched within 1e-3).
        int match = -1;
        double best = 1e300;
        for (const auto& [ltag, lkey] : lower) {
          double d = 0.0;
          for (int k = 0; k < 6; ++k) {
            d = std::max(d, std::abs(key[k] - (k % 3 == a ? len[a] : 0.0) - lkey[k]) / side);
          }
          d = std::max(
              d, std::abs(key[6] - lkey[6]) / std::max(key[6], kPatchTolerance * side * side));
          if (d < best) {
            best = d;
            match = ltag;
          }
        }
        if (best > kPatchKeyMatch || !used.insert(match).second) match = -1;
        if (match < 0) {
          throw MeshError("mesh_tet: a patch of the upper box face normal to " +
                          std::string(1, "xyz"[a]) + " has no image on the lower face");
        }
        face_pairs.push_back({tag, match, a});
      }
    }
    tie_face_curves(face_pairs, len, tol);
    // The fragment can leave a curve inside a box face's patch, not on its boundary, which Gmsh
    // then meshes with the patch as an edge its triangles must follow: a line of 8.8e-6 that
    // continued a face's cut of a fibre's end disk past the mantle's cut (the face met the disk
    // near its rim). Inside an upper patch, whose triangles are the lower one's translate, it
    // was a line the volume mesher could not recover ("failed to recover constrained
    // lines/triangles") or, recovered, a node with no image on the lower face. The patches
    // follow their boundaries only.
    for (const FacePair& fp : face_pairs) {
      gmsh::model::mesh::removeEmbedded({{2, fp.upper}, {2, fp.lower}});
    }

    const SizeField size(set, options, max_size, min_size);
    TetMeshOptions curve_options = options;
    std::optional<SizeField> curve_size;
    if (curve_chord > 0.0 && curve_chord < options.chord_error) {
      curve_options.chord_error = curve_chord;
      curve_size.emplace(set, curve_options, max_size, min_size);
    }
    gmsh::model::mesh::setSizeCallback([&](int dim, int, double x, double y, double z) {
      const long long n = ++calls;
      if (n % 65536 == 0 && !stop && std::this_thread::get_id() == caller) {
        const double done = static_cast<double>(n - stage_calls);
        report(stage_from + (stage_to - stage_from) * done / (done + 4e6), "");
      }
      return dim == 1 && curve_size ? (*curve_size)(Vec3(x, y, z)) : size(Vec3(x, y, z));
    });
    gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
    // Gmsh places a curve's nodes by integrating 1 / size along it, splitting each interval
    // until two estimates agree within this precision (in elements; Gmsh's default 1e-9). At
    // the default the curves of 2,484 fibres took 21 s, nearly all of it in the size callback;
    // at 1e-5, 2.4 s, with 983,491 surface nodes against 983,863.
    gmsh::option::setNumber("Mesh.LcIntegrationPrecision", kSizeIntegrationPrecision);
    gmsh::option::setNumber("Mesh.MeshSizeMax", max_size);
    gmsh::option::setNumber("Mesh.MeshSizeMin", min_size);
    gmsh::option::setNumber("Mesh.Algorithm", surface_algorithm);
    gmsh::option::setNumber("Mesh.Algorithm3D", volume_algorithm);
    gmsh::option::setNumber("Mesh.Optimize", options.optimize_threshold > 0.0 ? 1 : 0);
    gmsh::option::setNumber("Mesh.OptimizeThreshold", options.optimize_threshold);
    gmsh::option::setNumber("General.NumThreads", threads);
    gmsh::option::setNumber("Mesh.MeshOnlyVisible", 0);
    gmsh::option::setNumber("Mesh.MeshOnlyEmpty", 0);
    // Gmsh's errors are logged, not thrown, while it meshes: thrown inside its parallel loops
    // (a surface whose periodic copy fails), they would end the process. The log is read after
    // each stage.
    gmsh::option::setNumber("General.AbortOnError", 0);
    // (Gmsh's logger is not safe from its threads, so the last error is compared instead; Gmsh
    // clears it when it starts meshing.)
    std::string known;
    gmsh::logger::getLastError(known);
    auto logged_error = [&known] {
      std::string e;
      gmsh::logger::getLastError(e);
      if (e.empty() || e == known) return std::string();
      known = e;
      return e;
    };
    stage(0.15, 0.35, "mesh_tet: meshing the surfaces");
    // The curves and the lower box-face patches first, then their copies on the upper patches,
    // then the other surfaces. Each copy adds its triangles through Gmsh's API, which looks
    // their nodes up in a cache of the model's nodes, rebuilt after each call by walking every
    // entity and node: made with every surface meshed, the 934 copies of 2,484 fibres took
    // 18 s; made before the other surfaces, 12 s (the entities' walk is what is left).
    // Gmsh meshes only the visible surfaces in the first pass, and only those without elements
    // afterwards: the patches are left pending, so the volume stage runs the surface mesher
    // again, which must leave them too.
    std::set<int> lower_patches;
    for (const FacePair& fp : face_pairs) lower_patches.insert(fp.lower);
    gmsh::vectorpair hidden;
    for (const auto& s : surfaces) {
      if (!lower_patches.count(s.second)) hidden.push_back(s);
    }
    gmsh::model::setVisibility(hidden, 0, false);
    gmsh::option::setNumber("Mesh.MeshOnlyVisible", 1);
    gmsh::model::mesh::generate(2);
    gmsh::option::setNumber("Mesh.MeshOnlyVisible", 0);
    gmsh::model::setVisibility(hidden, 1, false);
    std::string surface_error = logged_error();
    if (surface_error.empty()) {
      copy_face_meshes(face_pairs, len, tol);
      gmsh::option::setNumber("Mesh.MeshOnlyEmpty", 1);
      gmsh::model::mesh::generate(2);
      surface_error = logged_error();
    }
    // The inclusions whose surfaces bound the curves a message names ("curve N"): the
    // surfaces about a curve's mesh that has no periodic counterpart.
    auto named_inclusions = [&owner](const std::string& e) {
      std::set<int> at;
      for (size_t k = e.find("curve "); k != std::string::npos; k = e.find("curve ", k + 6)) {
        const char* digits = e.c_str() + k + 6;
        char* end = nullptr;
        const long curve = std::strtol(digits, &end, 10);
        if (end == digits || curve <= 0) continue;
        std::vector<int> faces, ends;
        gmsh::model::getAdjacencies(1, static_cast<int>(curve), faces, ends);
        for (const int f : faces) {
          std::vector<int> volumes, edges;
          gmsh::model::getAdjacencies(2, f, volumes, edges);
          for (const int v : volumes) {
            const auto it = owner.find(v);
            if (it != owner.end()) at.insert(it->second.first);
          }
        }
      }
      return std::vector<int>(at.begin(), at.end());
    };
    if (const std::string& e = surface_error; !e.empty()) {
      // Where Gmsh fails on a curved surface it refines every curve around it and meshes it
      // again; a curve tied to its image on the opposite face then has nodes its image lacks.
      const bool refined_copy = e.find("periodic counterpart") != std::string::npos &&
                                e.find("curve") != std::string::npos;
      throw SurfacesRefused(
          "the surface mesher failed: " + e +
              (refined_copy ? " (Gmsh refined the curves of a curved surface it could not "
                              "mesh, one of them a copy of a curve on the opposite box "
                              "face: try a smaller mesh_tet.chord_error)"
                            : ""),
          named_inclusions(e));
    }
    mesh.raised_triangles = raise_flat_triangles(box, tol, &mesh.flipped_chords);
    stage(0.35, 0.85, "mesh_tet: meshing the volumes");
    gmsh::model::mesh::generate(3);
    gmsh::option::setNumber("Mesh.MeshOnlyEmpty", 0);
    // A volume left without elements is a failure even when the last error reads as the one
    // before (the second attempt's refusal repeats the first's words).
    std::string refused = logged_error();
    gmsh::vectorpair volumes_meshed;
    gmsh::model::getEntities(volumes_meshed, 3);
    for (const auto& v : volumes_meshed) {
      std::vector<int> types;
      gmsh::model::mesh::getElementTypes(types, 3, v.second);
      if (refused.empty() && types.empty()) refused = last_gmsh_error();
    }
    if (const std::string& e = refused; !e.empty()) {
      throw SurfacesRefused("the volume mesher refused the surfaces: " + e, named_inclusions(e));
    }
    // (The elements HXT's optimiser leaves under 5 degrees are lifted by repair_slivers below.
    // Gmsh's node relocation (Relocate3D) before it changed nothing it leaves: the same least
    // angle before the repair, the same 1, 5 and 50 % quantiles after it, for 12 s on 2,484
    // fibres and 5.6 s on the default scene.)

    // Nodes (renumbered from 0), then the tetrahedra of every volume with its phase.
    std::vector<std::size_t> tags;
    std::vector<double> xyz, param;
    gmsh::model::mesh::getNodes(tags, xyz, param);
    std::unordered_map<std::size_t, int32_t> index;
    index.reserve(tags.size());
    mesh.nodes.resize(tags.size());
    for (size_t i = 0; i < tags.size(); ++i) {
      index[tags[i]] = static_cast<int32_t>(i);
      mesh.nodes[i] = Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    }
    gmsh::vectorpair volumes;
    gmsh::model::getEntities(volumes, 3);
    for (const auto& v : volumes) {
      const auto it = owner.find(v.second);
      const int inc = it == owner.end() ? -1 : it->second.first;
      const int32_t label = inc < 0 ? 0 : it->second.second;
      const int32_t id = inc < 0 ? -1 : set.inclusions[inc].id;
      std::vector<int> types;
      std::vector<std::vector<std::size_t>> etags, enodes;
      gmsh::model::mesh::getElements(types, etags, enodes, 3, v.second);
      for (size_t b = 0; b < types.size(); ++b) {
        if (types[b] != 4)
          throw MeshError("mesh_tet: the mesher gave elements other than tetrahedra");
        for (size_t e = 0; e < etags[b].size(); ++e) {
          std::array<int32_t, 4> t;
          for (int c = 0; c < 4; ++c) t[c] = index.at(enodes[b][4 * e + c]);
          if (tet_volume(mesh.nodes, t) < 0.0) std::swap(t[2], t[3]);
          mesh.tets.push_back(t);
          mesh.phase.push_back(label);
          mesh.inclusion_id.push_back(id);
        }
      }
    }
  } catch (const MeshError&) {
    throw;
  } catch (const Cancelled&) {
    throw;
  } catch (const std::exception& e) {
    // Ours (a callback's) or Gmsh's: the message says which.
    throw MeshError(std::string("mesh_tet: the mesher failed: ") + e.what());
  } catch (...) {
    throw MeshError("mesh_tet: the mesher failed: " + last_gmsh_error());
  }

  stage(0.85, 1.0, "mesh_tet: checking the mesh");
  if (mesh.tets.empty()) throw MeshError("mesh_tet: the volume mesher made no elements");
  mesh.snapped_nodes = snap_periodic_nodes(&mesh);
  mesh.merged_nodes = merge_coincident_nodes(&mesh);
  mesh.flat_elements_removed = remove_flat_face_elements(&mesh);
  if (options.keep_volumes) mesh.moved_nodes = keep_phase_volumes(&mesh, set);
  mesh.sliver_rounds = repair_slivers(&mesh, set);
  check_conforming(mesh);
  if (options.order == 2) add_midside_nodes(&mesh);

  // Periodic pairs by coordinates: every node with a coordinate at an upper end, and the node
  // at its coordinates brought to the lower ends, within 3e-9 of the side (the reach of the
  // rounded keys that found it before; snap_periodic_nodes has put the corners exactly).
  for (const auto& [i, master] : lower_images(mesh, kOnFace * side, kImageReach * side)) {
    if (master < 0) {
      const Vec3& y = mesh.nodes[i];
      throw MeshError("mesh_tet: the node at (" + std::to_string(y[0]) + ", " +
                      std::to_string(y[1]) + ", " + std::to_string(y[2]) +
                      "), on an upper box face, has no image on the lower faces");
    }
    mesh.periodic.push_back({i, master});
  }
  report(1.0, "mesh_tet: " + std::to_string(mesh.tets.size()) +
                  (mesh.mid.empty() ? " tetrahedra, " : " 10-node tetrahedra, ") +
                  std::to_string(mesh.nodes.size()) + " nodes" +
                  (mesh.merged_nodes
                       ? " (" + std::to_string(mesh.merged_nodes) + " coincident nodes merged)"
                       : ""));
  return mesh;
}

}  // namespace

TetMesh tet_mesh(const InclusionSet& set_in, const TetMeshOptions& options,
                 const TetMeshProgress& progress) {
  check_tet_meshable(set_in);
  InclusionSet moved;
  if (options.shift_cell) {
    moved = set_in;
    moved.box.origin = cell_origin(set_in);
  }
  const InclusionSet& set = options.shift_cell ? moved : set_in;
  // The share shown never falls, through a second attempt too.
  double shown = 0.0;
  const TetMeshProgress steady = [&](double f, const std::string& line) {
    shown = std::max(shown, f);
    return progress ? progress(shown, line) : true;
  };
  // Gmsh's Frontal-Delaunay fails on some spline surfaces of ellipsoids cut by a box face, in
  // one frame of the ellipsoid and not in others (three ellipsoids of a packing at 0.4: one
  // frame of 32 failed), refines the curves around the surface and leaves a curve and its image
  // on the opposite face with other nodes ("Can't find periodic counterpart of mesh edge ... on
  // curve ..."). The inclusions about the curves named are built again in their next frame,
  // up to kFrameTurns times.
  std::vector<int> rank(set.inclusions.size(), 0);
  // Each failure and what comes next: said as progress, and kept in the mesh made at last.
  std::vector<std::string> retries;
  auto retry = [&](const std::string& line) {
    retries.push_back(line);
    if (!steady(shown, "mesh_tet: " + line)) throw Cancelled();
  };
  auto made = [&](TetMesh mesh) {
    mesh.retries = retries;
    return mesh;
  };
  for (int turn = 0;; ++turn) {
    try {
      return made(mesh_with(set, options, steady, 6, 0.0, rank));
    } catch (const SurfacesRefused& e) {
      if (turn < kFrameTurns && !e.inclusions.empty()) {
        std::string ids;
        for (const int i : e.inclusions) {
          ++rank[i];
          ids += (ids.empty() ? "" : ", ") + std::to_string(set.inclusions[i].id);
        }
        retry(std::string(e.what()) + "; meshing again with " +
              (e.inclusions.size() > 1 ? "inclusions " : "inclusion ") + ids +
              " built in another frame");
        continue;
      }
      // HXT refuses some surface meshes of Gmsh's default surface mesher (Frontal-Delaunay):
      // "Found two exactly self-intersecting facets", in 3 of 12 sphere scenes of the benchmark.
      // Meshed from the start with Gmsh's Delaunay surface mesher, all three went through.
      // (Meshing the surfaces again in the same model gave no elements; Gmsh's Delaunay volume
      // mesher on the first surfaces gave none either.) The surface mesher's own failures that
      // other frames do not end go the same way.
      retry(std::string(e.what()) + "; meshing the surfaces again with Delaunay");
      break;
    }
  }
  try {
    return made(mesh_with(set, options, steady, 5, 0.0, rank));
  } catch (const SurfacesRefused& e) {
    // Where two curves of a face meet at a small angle (a face cutting a fibre nearly along it
    // and its end disk), segments as long as a coarse chord error allows cross each other
    // ("PLC Error: Two segments intersect", with either surface mesher: seen in 2 of 8 packings
    // of 311 fibres of L/D 10 at chord error 0.1). Curves divided as a chord error of
    // kFinerCurveChord asks do not cross there; the surfaces keep the sizes asked. (The one of
    // them kept as a test was a flat triangle's chord in the face, which raise_flat_triangles
    // now flips: it meshes at the first attempt. The other was not kept.)
    // A refusal of the volume mesher goes on to the Delaunay volume mesher (below); any other
    // failure ends here.
    auto to_delaunay = [&](const SurfacesRefused& refusal) {
      if (!refused_volumes(refusal)) throw MeshError("mesh_tet: " + std::string(refusal.what()));
      retry("again, " + std::string(refusal.what()) + "; " + kDelaunayRetry);
    };
    if (options.chord_error > kFinerCurveChord) {
      retry("again, " + std::string(e.what()) + "; meshing them again with curves divided finer");
      try {
        return made(mesh_with(set, options, steady, 6, kFinerCurveChord, rank));
      } catch (const SurfacesRefused& again) {
        to_delaunay(again);
      }
    } else {
      to_delaunay(e);
    }
  }
  // Where HXT refuses the surfaces of all three attempts, Gmsh's Delaunay volume mesher takes
  // the first attempt's surfaces, in several times HXT's time (one thread). It meshed the two
  // refusals seen: a packing of 429 fibres at 0.2 ("failed to recover constrained
  // lines/triangles"; 3.6 M elements in 189 s against HXT's 10 s, least angle 5.04 degrees),
  // since meshed at once with HXT (its cause, a curve inside a box face, is no longer meshed),
  // and fibres pushed to exactly min_gap apart by a move off the cell's faces that was not
  // kept ("No elements in volume"). So it comes last.
  try {
    TetMesh mesh = made(mesh_with(set, options, steady, 6, 0.0, rank, kDelaunay3d));
    mesh.volume_mesher = "Delaunay";
    return mesh;
  } catch (const SurfacesRefused& e) {
    throw MeshError("mesh_tet: " + std::string(e.what()));
  }
}

TetQuality tet_quality(const TetMesh& mesh) {
  TetQuality q;
  q.phase_volume.assign(mesh.phases.size(), 0.0);
  q.dihedral_counts.assign(TetQuality::kBins.size(), 0);
  q.min_volume = mesh.tets.empty() ? 0.0 : 1e300;
  std::vector<double> least(mesh.tets.size());
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    Vec3 p[4];
    for (int c = 0; c < 4; ++c) p[c] = mesh.nodes[mesh.tets[e][c]];
    const double v = tet_volume(mesh.nodes, mesh.tets[e]);
    q.min_volume = std::min(q.min_volume, v);
    const int label = mesh.phase[e];
    if (label >= 0 && label < static_cast<int>(q.phase_volume.size())) q.phase_volume[label] += v;
    const double m = least_dihedral(p);
    least[e] = m;
    size_t bin = 0;
    while (bin + 1 < TetQuality::kBins.size() && m >= TetQuality::kBins[bin + 1]) ++bin;
    ++q.dihedral_counts[bin];
    q.below_5_degrees += m < 5.0;
  }
  if (!least.empty()) {
    std::sort(least.begin(), least.end());
    q.min_dihedral = least.front();
    const double at[3] = {0.01, 0.05, 0.5};
    for (int k = 0; k < 3; ++k)
      q.quantiles[k] = least[static_cast<size_t>(at[k] * (least.size() - 1))];
  }
  return q;
}

}  // namespace rvegen
