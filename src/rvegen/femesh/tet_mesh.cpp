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

#include "rvegen/femesh/cell_pieces.hpp"
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

// Which inclusion (index in the set) and phase each volume of the model belongs to.
using VolumeOwners = std::map<int, std::pair<int, int32_t>>;

// The size callback reports progress once per this many calls, and after this many calls a
// stage is shown half done (the share creeps towards the stage's end).
constexpr long long kSizeCallsPerReport = 65536;
constexpr double kSizeCallsToHalfStage = 4e6;

// Progress by stages, each a span of the whole; inside a long stage the size callback reports
// too (from the calling thread only: the volume mesher calls it from its own threads as well).
// Once progress returns false the next stage does not start. (Gmsh cannot be interrupted inside
// a stage: answering the largest size from then on, to end the stage sooner, made the volume
// stage longer, not shorter.)
class Stages {
 public:
  explicit Stages(const TetMeshProgress& progress)
      : progress_(progress), caller_(std::this_thread::get_id()) {}

  void report(double fraction, const std::string& line) {
    if (progress_ && !progress_(fraction, line)) stop_ = true;
  }
  // Starts the stage from `from` to `to` of the whole; throws Cancelled once stopped.
  void begin(double from, double to, const std::string& line) {
    if (stop_) throw Cancelled();
    from_ = from;
    to_ = to;
    stage_calls_ = calls_;
    report(from, line);
    if (stop_) throw Cancelled();
  }
  // The size callback's call, from any thread.
  void size_called() {
    const long long n = ++calls_;
    if (n % kSizeCallsPerReport == 0 && !stop_ && std::this_thread::get_id() == caller_) {
      const double done = static_cast<double>(n - stage_calls_);
      report(from_ + (to_ - from_) * done / (done + kSizeCallsToHalfStage), "");
    }
  }

 private:
  const TetMeshProgress& progress_;
  const std::thread::id caller_;
  std::atomic<bool> stop_{false};
  std::atomic<long long> calls_{0};
  double from_ = 0.0, to_ = 0.0;
  long long stage_calls_ = 0;
};

// Gmsh's errors while it meshes are logged, not thrown (see set_mesh_options). Its logger is
// not safe from its threads, so the last error is compared with the one seen before (Gmsh
// clears it when it starts meshing).
class GmshLog {
 public:
  GmshLog() { gmsh::logger::getLastError(known_); }
  // The error logged since the last call; empty when none.
  std::string new_error() {
    std::string e;
    gmsh::logger::getLastError(e);
    if (e.empty() || e == known_) return std::string();
    known_ = e;
    return e;
  }

 private:
  std::string known_;
};

// The box, entered as its six faces, not as a solid (the matrix is made of the faces
// afterwards): OpenCASCADE classifies every face of the other arguments of a fragment against
// each solid argument, and each test against the box, split by the pieces into thousands of
// faces, would explore all of them.
gmsh::vectorpair add_box_faces(const Box& box) {
  const Vec3 o = box.origin, len = box.size;
  gmsh::vectorpair box_faces;
  const int box_tag = gmsh::model::occ::addBox(o[0], o[1], o[2], len[0], len[1], len[2]);
  gmsh::model::occ::synchronize();
  gmsh::model::getBoundary({{3, box_tag}}, box_faces, false, false, false);
  gmsh::model::occ::remove({{3, box_tag}}, false);
  return box_faces;
}

// Fragments the box's faces against the inclusions' pieces and makes the matrix; returns the
// inclusion and phase of every volume (the pieces of a solid; where shells that may touch
// overlap, the first solid's).
VolumeOwners fragment_with_box(const gmsh::vectorpair& box_faces, const CellPieces& pieces) {
  gmsh::vectorpair out;
  std::vector<gmsh::vectorpair> made;
  gmsh::model::occ::fragment(box_faces, pieces.solids, out, made);
  gmsh::model::occ::synchronize();
  const size_t first = box_faces.size();
  VolumeOwners owner;
  for (size_t k = 0; k < pieces.solids.size() && first + k < made.size(); ++k) {
    for (const auto& dt : made[first + k]) {
      owner.emplace(dt.second, std::make_pair(pieces.inclusion[k], pieces.label[k]));
    }
  }
  add_matrix(box_faces.size(), made, owner);
  return owner;
}

void set_mesh_options(const TetMeshOptions& options, int surface_algorithm, int volume_algorithm,
                      double max_size, double min_size, int threads) {
  gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 0);
  gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
  gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
  // Gmsh places a curve's nodes by integrating 1 / size along it, splitting each interval
  // until two estimates agree within this precision (in elements). At Gmsh's default (1e-9)
  // the size callback takes most of the curves' time, for nearly the same nodes
  // (docs/benchmarks.md).
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
  // each stage (GmshLog).
  gmsh::option::setNumber("General.AbortOnError", 0);
}

// The inclusions whose surfaces bound the curves a message names ("curve N"): the surfaces
// about a curve's mesh that has no periodic counterpart.
std::vector<int> named_inclusions(const VolumeOwners& owner, const std::string& e) {
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
}

// Meshes the surfaces: the curves and the lower box-face patches first, then their copies on
// the upper patches, then the other surfaces. Each copy adds its triangles through Gmsh's API,
// which looks their nodes up in a cache of the model's nodes, rebuilt after each call by
// walking every entity and node: made before the other surfaces are meshed, each walk costs
// less. Gmsh meshes only the visible surfaces in the first pass, and only those without
// elements afterwards: the patches are left pending, so the volume stage runs the surface
// mesher again, which must leave them too. Throws SurfacesRefused when Gmsh logs an error.
void mesh_surfaces(const std::vector<FacePair>& face_pairs, const Vec3& len, double tol,
                   const VolumeOwners& owner, GmshLog* log) {
  gmsh::vectorpair surfaces;
  gmsh::model::getEntities(surfaces, 2);
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
  std::string e = log->new_error();
  if (e.empty()) {
    copy_face_meshes(face_pairs, len, tol);
    gmsh::option::setNumber("Mesh.MeshOnlyEmpty", 1);
    gmsh::model::mesh::generate(2);
    e = log->new_error();
  }
  if (e.empty()) return;
  // Where Gmsh fails on a curved surface it refines every curve around it and meshes it
  // again; a curve tied to its image on the opposite face then has nodes its image lacks.
  const bool refined_copy =
      e.find("periodic counterpart") != std::string::npos && e.find("curve") != std::string::npos;
  throw SurfacesRefused("the surface mesher failed: " + e +
                            (refined_copy ? " (Gmsh refined the curves of a curved surface it "
                                            "could not mesh, one of them a copy of a curve on "
                                            "the opposite box face: try a smaller "
                                            "mesh_tet.chord_error)"
                                          : ""),
                        named_inclusions(owner, e));
}

// Meshes the volumes; throws SurfacesRefused when Gmsh logs an error or leaves a volume
// without elements (a failure even when the last error reads as the one before: the second
// attempt's refusal repeats the first's words). (The elements HXT's optimiser leaves under 5
// degrees are lifted by repair_slivers; Gmsh's node relocation before it changed nothing of
// what it leaves.)
void mesh_volumes(const VolumeOwners& owner, GmshLog* log) {
  gmsh::model::mesh::generate(3);
  gmsh::option::setNumber("Mesh.MeshOnlyEmpty", 0);
  std::string refused = log->new_error();
  gmsh::vectorpair volumes;
  gmsh::model::getEntities(volumes, 3);
  for (const auto& v : volumes) {
    std::vector<int> types;
    gmsh::model::mesh::getElementTypes(types, 3, v.second);
    if (refused.empty() && types.empty()) refused = last_gmsh_error();
  }
  if (!refused.empty()) {
    throw SurfacesRefused("the volume mesher refused the surfaces: " + refused,
                          named_inclusions(owner, refused));
  }
}

// Gmsh's nodes (renumbered from 0), then the tetrahedra of every volume with its phase and
// inclusion id, each positively oriented.
void read_tetrahedra(const InclusionSet& set, const VolumeOwners& owner, TetMesh* mesh) {
  std::vector<std::size_t> tags;
  std::vector<double> xyz, param;
  gmsh::model::mesh::getNodes(tags, xyz, param);
  std::unordered_map<std::size_t, int32_t> index;
  index.reserve(tags.size());
  mesh->nodes.resize(tags.size());
  for (size_t i = 0; i < tags.size(); ++i) {
    index[tags[i]] = static_cast<int32_t>(i);
    mesh->nodes[i] = Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
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
      if (types[b] != 4) {
        throw MeshError("mesh_tet: the mesher gave elements other than tetrahedra");
      }
      for (size_t e = 0; e < etags[b].size(); ++e) {
        std::array<int32_t, 4> t;
        for (int c = 0; c < 4; ++c) t[c] = index.at(enodes[b][4 * e + c]);
        if (tet_volume(mesh->nodes, t) < 0.0) std::swap(t[2], t[3]);
        mesh->tets.push_back(t);
        mesh->phase.push_back(label);
        mesh->inclusion_id.push_back(id);
      }
    }
  }
}

// Gmsh's mesh made whole: periodic nodes snapped and paired, coincident nodes merged, flat
// elements in the box faces removed, the phases' volumes kept, slivers repaired, conformity
// checked, midside nodes added for order 2.
void finish_mesh(const InclusionSet& set, const TetMeshOptions& options, TetMesh* mesh) {
  if (mesh->tets.empty()) throw MeshError("mesh_tet: the volume mesher made no elements");
  mesh->snapped_nodes = snap_periodic_nodes(mesh);
  mesh->merged_nodes = merge_coincident_nodes(mesh);
  mesh->flat_elements_removed = remove_flat_face_elements(mesh);
  if (options.keep_volumes) mesh->moved_nodes = keep_phase_volumes(mesh, set);
  mesh->sliver_rounds = repair_slivers(mesh, set);
  check_conforming(*mesh);
  if (options.order == 2) add_midside_nodes(mesh);
  // Periodic pairs by coordinates: every node with a coordinate at an upper end, and the node
  // at its coordinates brought to the lower ends, within kImageReach of the side
  // (snap_periodic_nodes has put the corners exactly).
  const double side = set.box.size.minCoeff();
  for (const auto& [i, master] : lower_images(*mesh, kOnFace * side, kImageReach * side)) {
    if (master < 0) {
      const Vec3& y = mesh->nodes[i];
      throw MeshError("mesh_tet: the node at (" + std::to_string(y[0]) + ", " +
                      std::to_string(y[1]) + ", " + std::to_string(y[2]) +
                      "), on an upper box face, has no image on the lower faces");
    }
    mesh->periodic.push_back({i, master});
  }
}

// One attempt, with Gmsh's 2D algorithm `surface_algorithm` (6: Frontal-Delaunay, 5: Delaunay)
// and 3D algorithm `volume_algorithm` (kHxt or kDelaunay3d). With curve_chord > 0, the curves
// (the faces' cuts and the shells' rims) are divided as that chord error asks, where it is less
// than options.chord_error; the surfaces and volumes as options ask.
TetMesh mesh_with(const InclusionSet& set, const TetMeshOptions& options,
                  const TetMeshProgress& progress, int surface_algorithm, double curve_chord,
                  const std::vector<int>& frame_rank, int volume_algorithm = kHxt) {
  Stages stages(progress);
  const Box& box = set.box;
  const double max_size = options.largest_size(set.box), min_size = least_size(set, options);
  // One thread for a reproducible mesh: Gmsh's and OpenCASCADE's parallel passes give other
  // meshes from run to run.
  const int threads =
      options.reproducible
          ? 1
          : std::max(1, options.threads > 0
                            ? options.threads
                            : static_cast<int>(std::thread::hardware_concurrency()));

  std::lock_guard<std::mutex> lock(gmsh_mutex);
  GmshSession session;
  TetMesh mesh;
  mesh.box = box;
  mesh.phases = phase_table(set);
  try {
    // OpenCASCADE's boolean operations (the cuts by the cells and the fragment against the box)
    // in parallel when more than one thread is allowed; OpenCASCADE then uses its own pool of
    // all cores, not `threads`. Not with coated ellipsoids: their shells' offset surfaces are
    // evaluated through a cache that OpenCASCADE's parallel booleans share between threads (a
    // crash in Geom_OsculatingSurface while coated ellipsoids were cut by the cells on two
    // threads; made splines, the offsets crashed no more but the cut faces no longer matched
    // their images).
    const bool offsets =
        std::any_of(set.inclusions.begin(), set.inclusions.end(), [](const Inclusion& in) {
          return in.mod.coated() && in.shape.kind == ShapeKind::Ellipsoid;
        });
    gmsh::option::setNumber("Geometry.OCCParallel", threads > 1 && !offsets ? 1 : 0);
    const gmsh::vectorpair box_faces = add_box_faces(box);
    const CellPieces pieces = cut_into_box(set, mesh.phases, frame_rank);
    stages.begin(0.0, 0.15,
                 "mesh_tet: fragmenting " + std::to_string(pieces.solids.size()) +
                     " inclusion pieces against the box");
    const VolumeOwners owner = fragment_with_box(box_faces, pieces);
    // The faces at the upper end of each axis mesh as translated copies of those at the lower
    // end, their curves tied to their images first.
    const double tol = kPatchTolerance * box.size.minCoeff();
    const std::vector<FacePair> face_pairs = pair_box_patches(box, tol);
    tie_face_curves(face_pairs, box.size, tol);
    // The fragment can leave a curve inside a box face's patch, not on its boundary, which Gmsh
    // then meshes with the patch as an edge its triangles must follow (a short line continuing
    // a face's cut of a fibre's end disk past the mantle's cut, where the face met the disk
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
      stages.size_called();
      return dim == 1 && curve_size ? (*curve_size)(Vec3(x, y, z)) : size(Vec3(x, y, z));
    });
    set_mesh_options(options, surface_algorithm, volume_algorithm, max_size, min_size, threads);
    GmshLog log;
    stages.begin(0.15, 0.35, "mesh_tet: meshing the surfaces");
    mesh_surfaces(face_pairs, box.size, tol, owner, &log);
    mesh.raised_triangles = raise_flat_triangles(box, tol, &mesh.flipped_chords);
    stages.begin(0.35, 0.85, "mesh_tet: meshing the volumes");
    mesh_volumes(owner, &log);
    read_tetrahedra(set, owner, &mesh);
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

  stages.begin(0.85, 1.0, "mesh_tet: checking the mesh");
  finish_mesh(set, options, &mesh);
  stages.report(1.0, "mesh_tet: " + std::to_string(mesh.tets.size()) +
                         (mesh.mid.empty() ? " tetrahedra, " : " 10-node tetrahedra, ") +
                         std::to_string(mesh.nodes.size()) + " nodes" +
                         (mesh.merged_nodes ? " (" + std::to_string(mesh.merged_nodes) +
                                                  " coincident nodes merged)"
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
  // one frame of the ellipsoid and not in others, refines the curves around the surface and
  // leaves a curve and its image on the opposite face with other nodes ("Can't find periodic
  // counterpart of mesh edge ... on curve ..."). The inclusions about the curves named are
  // built again in their next frame, up to kFrameTurns times.
  std::vector<int> rank(set.inclusions.size(), 0);
  // Each failure and what comes next: said as progress, and kept in the mesh made at last.
  std::vector<std::string> retries;
  auto retry = [&](const std::string& line) {
    retries.push_back(line);
    if (!steady(shown, "mesh_tet: " + line)) throw Cancelled();
  };
  auto made = [&](TetMesh mesh) {
    mesh.retries = retries;
    if (options.reproducible) mesh.volume_mesher = "Delaunay";
    return mesh;
  };
  // HXT, or with options.reproducible Gmsh's Delaunay volume mesher in every attempt.
  const int volumes = options.reproducible ? kDelaunay3d : kHxt;
  for (int turn = 0;; ++turn) {
    try {
      return made(mesh_with(set, options, steady, 6, 0.0, rank, volumes));
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
      // "Found two exactly self-intersecting facets", in some sphere scenes of the benchmark.
      // Meshed from the start with Gmsh's Delaunay surface mesher, they all went through.
      // (Meshing the surfaces again in the same model gave no elements; Gmsh's Delaunay volume
      // mesher on the first surfaces gave none either.) The surface mesher's own failures that
      // other frames do not end go the same way.
      retry(std::string(e.what()) + "; meshing the surfaces again with Delaunay");
      break;
    }
  }
  try {
    return made(mesh_with(set, options, steady, 5, 0.0, rank, volumes));
  } catch (const SurfacesRefused& e) {
    // Where two curves of a face meet at a small angle (a face cutting a fibre nearly along it
    // and its end disk), segments as long as a coarse chord error allows cross each other
    // ("PLC Error: Two segments intersect", with either surface mesher: seen in packings of
    // fibres at a coarse chord error). Curves divided as a chord error of
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
        return made(mesh_with(set, options, steady, 6, kFinerCurveChord, rank, volumes));
      } catch (const SurfacesRefused& again) {
        to_delaunay(again);
      }
    } else {
      to_delaunay(e);
    }
  }
  // Where HXT refuses the surfaces of all three attempts, Gmsh's Delaunay volume mesher takes
  // the first attempt's surfaces, far more slowly than HXT (one thread). It meshed the two
  // refusals seen: a packing of fibres ("failed to recover constrained lines/triangles"),
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

}  // namespace rvegen
