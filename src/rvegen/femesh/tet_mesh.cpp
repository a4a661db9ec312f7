#include "rvegen/femesh/tet_mesh.hpp"

#include <gmsh.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <unordered_map>

#include "rvegen/model/body.hpp"
#include "rvegen/model/errors.hpp"

namespace rvegen {

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

// An inclusion's periodic image: the inclusion and its shift.
struct Image {
  int inc;
  Vec3 shift;
};

// The images of the set's inclusions whose box, grown by `margin`, meets the box.
std::vector<Image> images_near(const InclusionSet& set, double margin) {
  const Vec3 o = set.box.origin, len = set.box.size;
  std::vector<Image> out;
  for (size_t m = 0; m < set.inclusions.size(); ++m) {
    Vec3 lo, hi;
    set.inclusions[m].shape.aabb(&lo, &hi);
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

// The element size wanted at a point: the gap between the two nearest surfaces (two
// inclusions, or an inclusion and a box face it does not cross) over gap_elements, the chord
// bound near a surface, between min_size and max_size. A cell list of the images.
class SizeField {
 public:
  SizeField(const InclusionSet& set, const TetMeshOptions& opt, double max_size, double min_size)
      : set_(set), opt_(opt), max_(max_size), min_(min_size) {
    for (const Inclusion& inc : set.inclusions) query_.emplace_back(inc);
    images_ = images_near(set, max_);
    const double side = set.box.size.minCoeff();
    n_ = std::clamp(static_cast<int>(side / max_), 1, 64);
    for (int a = 0; a < 3; ++a) cell_[a] = set.box.size[a] / n_;
    grid_.resize(static_cast<size_t>(n_) * n_ * n_);
    lo_.resize(images_.size());
    hi_.resize(images_.size());
    for (size_t id = 0; id < images_.size(); ++id) {
      Vec3& lo = lo_[id];
      Vec3& hi = hi_[id];
      set.inclusions[images_[id].inc].shape.aabb(&lo, &hi);
      lo += images_[id].shift;
      hi += images_[id].shift;
      int c0[3], c1[3];
      for (int a = 0; a < 3; ++a) {
        const double o = set.box.origin[a];
        c0[a] = std::clamp(static_cast<int>(std::floor((lo[a] - max_ - o) / cell_[a])), 0, n_ - 1);
        c1[a] = std::clamp(static_cast<int>(std::floor((hi[a] + max_ - o) / cell_[a])), 0, n_ - 1);
      }
      for (int k = c0[2]; k <= c1[2]; ++k) {
        for (int j = c0[1]; j <= c1[1]; ++j) {
          for (int i = c0[0]; i <= c1[0]; ++i)
            grid_[index(i, j, k)].push_back(static_cast<int>(id));
        }
      }
    }
  }

  double operator()(const Vec3& p) const {
    int c[3];
    for (int a = 0; a < 3; ++a) {
      c[a] = std::clamp(static_cast<int>((p[a] - set_.box.origin[a]) / cell_[a]), 0, n_ - 1);
    }
    double d1 = 1e300, d2 = 1e300, rho1 = 0.0, gap_face = 1e300;
    for (int id : grid_[index(c[0], c[1], c[2])]) {
      const Image& im = images_[id];
      const Vec3 x = p - im.shift;
      const double d = std::abs(query_[im.inc].core_distance(x));
      const Shape& s = set_.inclusions[im.inc].shape;
      if (d < d1) {
        d2 = d1;
        d1 = d;
        rho1 = s.radius;  // spheres and cylinders: their least radius of curvature
      } else if (d < d2) {
        d2 = d;
      }
      // A thin layer of matrix between this image and a box face it does not cross.
      const Vec3 &lo = lo_[id], &hi = hi_[id];
      for (int a = 0; a < 3; ++a) {
        const double f0 = set_.box.origin[a], f1 = f0 + set_.box.size[a];
        const double below = lo[a] - f0, above = f1 - hi[a];
        if (below > 0.0 && below < max_ * opt_.gap_elements && p[a] - f0 <= below + d) {
          gap_face = std::min(gap_face, d + p[a] - f0);
        }
        if (above > 0.0 && above < max_ * opt_.gap_elements && f1 - p[a] <= above + d) {
          gap_face = std::min(gap_face, d + f1 - p[a]);
        }
      }
    }
    double h = std::min(d1 + d2, gap_face) / opt_.gap_elements;
    if (d1 < max_) h = std::min(h, rho1 * std::sqrt(8.0 * opt_.chord_error));
    return std::clamp(h, min_, max_);
  }

 private:
  size_t index(int i, int j, int k) const { return (static_cast<size_t>(k) * n_ + j) * n_ + i; }
  const InclusionSet& set_;
  const TetMeshOptions& opt_;
  double max_, min_;
  std::vector<BodyQuery> query_;
  std::vector<Image> images_;
  std::vector<Vec3> lo_, hi_;  // each image's bounding box, shifted
  int n_ = 1;
  double cell_[3] = {1, 1, 1};
  std::vector<std::vector<int>> grid_;
};

// The OCC solid of a shape; its tag.
int add_solid(const Shape& s) {
  const Vec3 c = s.center;
  switch (s.kind) {
    case ShapeKind::Sphere:
      return gmsh::model::occ::addSphere(c[0], c[1], c[2], s.radius);
    case ShapeKind::Cylinder: {
      const Vec3 b = c - s.half_axis, d = 2.0 * s.half_axis;
      return gmsh::model::occ::addCylinder(b[0], b[1], b[2], d[0], d[1], d[2], s.radius);
    }
    case ShapeKind::Ellipsoid:
      break;  // refused by check_tet_meshable
  }
  return -1;
}

// A face's key: its three node numbers in any order, mixed into 64 bits.
uint64_t face_key(int32_t a, int32_t b, int32_t c) {
  if (a > b) std::swap(a, b);
  if (b > c) std::swap(b, c);
  if (a > b) std::swap(a, b);
  auto mix = [](uint64_t x) {  // splitmix64's finaliser
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
  };
  return mix(mix(mix(static_cast<uint64_t>(a)) + static_cast<uint32_t>(b)) +
             static_cast<uint32_t>(c));
}

}  // namespace

// The volume mesher rarely leaves two nodes at one position, each used by elements on its own
// side (a crack in the mesh: seen in 3 runs in 10 of the test scene). Such nodes are merged
// (the lowest number kept); nodes no element uses are dropped and the rest renumbered in order.
long long merge_coincident_nodes(TetMesh* mesh) {
  std::vector<int32_t> order(mesh->nodes.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int32_t>(i);
  auto less = [&](int32_t a, int32_t b) {
    const Vec3 &p = mesh->nodes[a], &q = mesh->nodes[b];
    if (p[0] != q[0]) return p[0] < q[0];
    if (p[1] != q[1]) return p[1] < q[1];
    if (p[2] != q[2]) return p[2] < q[2];
    return a < b;
  };
  std::sort(order.begin(), order.end(), less);
  std::vector<int32_t> same(mesh->nodes.size());
  long long merged = 0;
  for (size_t k = 0; k < order.size(); ++k) {
    const bool repeat = k > 0 && mesh->nodes[order[k]] == mesh->nodes[order[k - 1]];
    same[order[k]] = repeat ? same[order[k - 1]] : order[k];
    merged += repeat;
  }
  std::vector<int32_t> number(mesh->nodes.size(), -1);
  for (auto& t : mesh->tets) {
    for (int32_t& n : t) n = same[n];
    for (int c = 0; c < 4; ++c) number[t[c]] = 0;
  }
  std::vector<Vec3> kept;
  for (size_t i = 0; i < number.size(); ++i) {
    if (number[i] < 0) continue;
    number[i] = static_cast<int32_t>(kept.size());
    kept.push_back(mesh->nodes[i]);
  }
  mesh->nodes.swap(kept);
  for (auto& t : mesh->tets) {
    for (int32_t& n : t) n = number[n];
    for (int c = 0; c < 4; ++c) {
      for (int d = c + 1; d < 4; ++d) {
        if (t[c] == t[d]) throw MeshError("mesh_tet: an element with two nodes at one position");
      }
    }
  }
  return merged;
}

// A conforming mesh of the box: every face of an element is the face of one other element, or
// lies in a box face. Checked without storing the faces: interior faces come in pairs, so the
// XOR of the keys of all elements' faces equals the XOR of those of the faces in box faces;
// a face left alone (a crack, a hole) breaks the equality (but for a 2^-64 chance).
void check_conforming(const TetMesh& mesh) {
  // Per node, bits of the box faces it lies on.
  const std::vector<std::array<int8_t, 3>> ends = node_ends(mesh);
  std::vector<uint8_t> plane(ends.size(), 0);
  for (size_t n = 0; n < ends.size(); ++n) {
    for (int a = 0; a < 3; ++a) {
      if (ends[n][a] >= 0) plane[n] |= static_cast<uint8_t>(1 << (2 * a + ends[n][a]));
    }
  }
  uint64_t all = 0, outer = 0;
  for (const auto& t : mesh.tets) {
    for (int skip = 0; skip < 4; ++skip) {
      int32_t f[3], n = 0;
      for (int c = 0; c < 4; ++c) {
        if (c != skip) f[n++] = t[c];
      }
      const uint64_t k = face_key(f[0], f[1], f[2]);
      all ^= k;
      if (plane[f[0]] & plane[f[1]] & plane[f[2]]) outer ^= k;
    }
  }
  if (all != outer) {
    throw MeshError(
        "mesh_tet: the mesh is not conforming (an element face is shared by no other "
        "element and lies in no box face)");
  }
  // And the elements fill the box: their volumes (each positive) add up to it.
  double total = 0.0, least = 1e300;
  for (const auto& t : mesh.tets) {
    const double v = tet_volume(mesh.nodes, t);
    total += v;
    least = std::min(least, v);
  }
  if (!(least > 0.0) || std::abs(total / mesh.box.volume() - 1.0) > 1e-9) {
    throw MeshError("mesh_tet: the elements do not fill the box (their volume " +
                    std::to_string(total) + ", the box " + std::to_string(mesh.box.volume()) +
                    ", least element " + std::to_string(mesh.tets.empty() ? 0.0 : least) + ")");
  }
}

void check_tet_meshable(const InclusionSet& set) {
  if (!set.box.periodic) {
    throw InputError("outputs: mesh_tet needs a periodic box (box.periodic false)");
  }
  for (const Inclusion& inc : set.inclusions) {
    const std::string name = inc.family < static_cast<int>(set.family_names.size())
                                 ? set.family_names[inc.family]
                                 : "family " + std::to_string(inc.family);
    if (inc.mod.any()) {
      throw InputError("outputs: mesh_tet meshes plain spheres and cylinders; family \"" + name +
                       "\" has coated, wavy, bent, deformed or debonded inclusions (use "
                       "mesh_voxel for them)");
    }
    if (inc.shape.kind == ShapeKind::Ellipsoid) {
      // OpenCASCADE has no ellipsoid: a scaled sphere becomes a spline surface, and its cuts
      // by opposite box faces came out different (areas 3 % apart), so the faces' meshes could
      // not be made periodic.
      throw InputError("outputs: mesh_tet meshes plain spheres and cylinders; family \"" + name +
                       "\" has ellipsoids, which it cannot mesh periodically yet (use mesh_voxel "
                       "for them)");
    }
  }
}

namespace {

// HXT refused the surface mesh (see mesh_with).
struct SurfacesRefused : MeshError {
  using MeshError::MeshError;
};

// One attempt, with Gmsh's 2D algorithm `surface_algorithm` (6: Frontal-Delaunay, 5: Delaunay).
TetMesh mesh_with(const InclusionSet& set, const TetMeshOptions& options,
                  const TetMeshProgress& progress, int surface_algorithm) {
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
  const double max_size = options.max_size > 0.0 ? options.max_size : side / 10.0;
  double least = side;
  for (const Inclusion& inc : set.inclusions) least = std::min(least, inc.shape.min_size());
  const double min_size = options.min_size > 0.0 ? options.min_size : least / 50.0;

  std::lock_guard<std::mutex> lock(gmsh_mutex);
  GmshSession session;
  TetMesh mesh;
  mesh.box = box;
  mesh.phases = phase_table(set);
  try {
    const Vec3 o = box.origin, len = box.size;
    const int box_tag = gmsh::model::occ::addBox(o[0], o[1], o[2], len[0], len[1], len[2]);
    const std::vector<Image> images = images_near(set, 0.0);
    // Each inclusion's solid is built once and its images are translated copies of it.
    gmsh::vectorpair tools;
    std::map<int, int> base;  // inclusion -> its solid at shift 0 (removed after the copies)
    for (const Image& im : images) {
      if (!base.count(im.inc)) base[im.inc] = add_solid(set.inclusions[im.inc].shape);
    }
    for (const Image& im : images) {
      gmsh::vectorpair copy;
      gmsh::model::occ::copy({{3, base[im.inc]}}, copy);
      gmsh::model::occ::translate(copy, im.shift[0], im.shift[1], im.shift[2]);
      tools.push_back(copy.front());
    }
    gmsh::vectorpair originals;
    for (const auto& [inc, tag] : base) originals.push_back({3, tag});
    gmsh::model::occ::remove(originals, true);
    stage(0.0, 0.15,
          "mesh_tet: fragmenting " + std::to_string(images.size()) +
              " inclusion images against the box");
    gmsh::vectorpair out;
    std::vector<gmsh::vectorpair> pieces;
    gmsh::model::occ::fragment({{3, box_tag}}, tools, out, pieces);
    gmsh::model::occ::synchronize();
    // Which inclusion each volume belongs to (the pieces of tool k); the parts outside the box
    // are removed.
    std::map<int, int> owner;
    for (size_t k = 0; k < images.size() && k + 1 < pieces.size(); ++k) {
      for (const auto& dt : pieces[k + 1]) owner[dt.second] = images[k].inc;
    }
    // The pieces of the box (the fragment's map of its first solid) are the matrix and the
    // parts of the inclusions inside it; every other piece lies outside. (No geometric test:
    // OpenCASCADE's bounding boxes of curved pieces are loose, and the part of an inclusion
    // beyond a box edge wraps around the edge, so its centre of mass can lie inside.)
    std::set<int> in_box;
    if (!pieces.empty()) {
      for (const auto& dt : pieces[0]) in_box.insert(dt.second);
    }
    gmsh::vectorpair outside;
    for (const auto& dt : out) {
      if (!in_box.count(dt.second)) outside.push_back(dt);
    }
    gmsh::model::occ::remove(outside, true);
    gmsh::model::occ::synchronize();

    // The faces at the upper end of each axis mesh as translated copies of those at the lower
    // end: matched by centre of mass and area.
    const double tol = 1e-6 * side;
    gmsh::vectorpair surfaces;
    gmsh::model::getEntities(surfaces, 2);
    for (int a = 0; a < 3; ++a) {
      std::vector<std::pair<int, std::array<double, 7>>> lower, upper;
      for (const auto& s : surfaces) {
        double b[6];
        gmsh::model::getBoundingBox(2, s.second, b[0], b[1], b[2], b[3], b[4], b[5]);
        for (int end = 0; end < 2; ++end) {
          const double v = o[a] + (end ? len[a] : 0.0);
          if (std::abs(b[a] - v) > 10 * tol || std::abs(b[a + 3] - v) > 10 * tol) continue;
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
      std::vector<double> T = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
      T[4 * a + 3] = len[a];
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
          d = std::max(d, std::abs(key[6] - lkey[6]) / std::max(key[6], 1e-6 * side * side));
          if (d < best) {
            best = d;
            match = ltag;
          }
        }
        if (best > 1e-3 || !used.insert(match).second) match = -1;
        if (match < 0) {
          throw MeshError("mesh_tet: a patch of the upper box face normal to " +
                          std::string(1, "xyz"[a]) + " has no image on the lower face");
        }
        gmsh::model::mesh::setPeriodic(2, {tag}, {match}, T);
      }
    }

    const SizeField size(set, options, max_size, min_size);
    gmsh::model::mesh::setSizeCallback([&](int, int, double x, double y, double z) {
      const long long n = ++calls;
      if (n % 65536 == 0 && !stop && std::this_thread::get_id() == caller) {
        const double done = static_cast<double>(n - stage_calls);
        report(stage_from + (stage_to - stage_from) * done / (done + 4e6), "");
      }
      return size(Vec3(x, y, z));
    });
    gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
    gmsh::option::setNumber("Mesh.MeshSizeMax", max_size);
    gmsh::option::setNumber("Mesh.MeshSizeMin", min_size);
    gmsh::option::setNumber("Mesh.Algorithm", surface_algorithm);
    gmsh::option::setNumber("Mesh.Algorithm3D", 10);  // HXT: parallel, with its optimiser
    gmsh::option::setNumber("Mesh.Optimize", 1);
    const int threads = options.threads > 0 ? options.threads
                                            : static_cast<int>(std::thread::hardware_concurrency());
    gmsh::option::setNumber("General.NumThreads", std::max(1, threads));
    stage(0.15, 0.35, "mesh_tet: meshing the surfaces");
    gmsh::model::mesh::generate(2);
    stage(0.35, 0.85, "mesh_tet: meshing the volumes");
    try {
      gmsh::model::mesh::generate(3);
    } catch (...) {
      if (surface_algorithm == 5) throw;
      throw SurfacesRefused(last_gmsh_error());
    }
    stage(0.85, 0.95, "mesh_tet: moving nodes of the worst elements");
    // HXT's own optimiser left a few elements under 5 degrees; moving their nodes (Gmsh's
    // Relocate3D) lifted them (test scene: 4.98 to 5.38 degrees, the least angle now at a
    // surface).
    gmsh::model::mesh::optimize("Relocate3D", false, 3);

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
      const int inc = it == owner.end() ? -1 : it->second;
      const int32_t label = inc < 0 ? 0 : core_label(set.inclusions[inc].family);
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

  stage(0.95, 1.0, "mesh_tet: checking the mesh");
  if (mesh.tets.empty()) throw MeshError("mesh_tet: the volume mesher made no elements");
  mesh.merged_nodes = merge_coincident_nodes(&mesh);
  check_conforming(mesh);

  // Periodic pairs by coordinates: every node with a coordinate at an upper end, and the node
  // at its coordinates brought to the lower ends.
  const double tol = 1e-9 * side;
  auto key_of = [&](const Vec3& x) {
    std::array<long long, 3> k;
    for (int a = 0; a < 3; ++a) k[a] = std::llround((x[a] - box.origin[a]) / tol);
    return k;
  };
  struct KeyHash {
    size_t operator()(const std::array<long long, 3>& k) const {
      return std::hash<long long>()(k[0] * 73856093LL ^ k[1] * 19349663LL ^ k[2] * 83492791LL);
    }
  };
  std::unordered_map<std::array<long long, 3>, int32_t, KeyHash> at;
  std::vector<int32_t> dependent;
  for (size_t i = 0; i < mesh.nodes.size(); ++i) {
    const Vec3& x = mesh.nodes[i];
    bool upper = false;
    for (int a = 0; a < 3; ++a)
      upper = upper || std::abs(x[a] - box.origin[a] - box.size[a]) <= tol;
    if (upper) {
      dependent.push_back(static_cast<int32_t>(i));
    } else {
      at[key_of(x)] = static_cast<int32_t>(i);
    }
  }
  for (int32_t i : dependent) {
    Vec3 x = mesh.nodes[i];
    for (int a = 0; a < 3; ++a) {
      if (std::abs(x[a] - box.origin[a] - box.size[a]) <= tol) x[a] = box.origin[a];
    }
    // Within the tolerance of the key's rounding: the neighbouring keys too.
    const auto k = key_of(x);
    int32_t master = -1;
    for (int dx = -1; dx <= 1 && master < 0; ++dx) {
      for (int dy = -1; dy <= 1 && master < 0; ++dy) {
        for (int dz = -1; dz <= 1 && master < 0; ++dz) {
          const auto it = at.find({k[0] + dx, k[1] + dy, k[2] + dz});
          if (it != at.end()) master = it->second;
        }
      }
    }
    if (master < 0) {
      throw MeshError("mesh_tet: a node on an upper box face has no image on the lower faces");
    }
    mesh.periodic.push_back({i, master});
  }
  report(1.0, "mesh_tet: " + std::to_string(mesh.tets.size()) + " tetrahedra, " +
                  std::to_string(mesh.nodes.size()) + " nodes" +
                  (mesh.merged_nodes
                       ? " (" + std::to_string(mesh.merged_nodes) + " coincident nodes merged)"
                       : ""));
  return mesh;
}

}  // namespace

TetMesh tet_mesh(const InclusionSet& set, const TetMeshOptions& options,
                 const TetMeshProgress& progress) {
  check_tet_meshable(set);
  // The share shown never falls, through a second attempt too.
  double shown = 0.0;
  const TetMeshProgress steady = [&](double f, const std::string& line) {
    shown = std::max(shown, f);
    return progress ? progress(shown, line) : true;
  };
  try {
    return mesh_with(set, options, steady, 6);
  } catch (const SurfacesRefused& e) {
    // HXT refuses some surface meshes of Gmsh's default surface mesher (Frontal-Delaunay):
    // "Found two exactly self-intersecting facets", in 3 of 12 sphere scenes of the benchmark.
    // Meshed from the start with Gmsh's Delaunay surface mesher, all three went through.
    // (Meshing the surfaces again in the same model gave no elements; Gmsh's Delaunay volume
    // mesher on the first surfaces gave none either.)
    if (!steady(shown, std::string("mesh_tet: the volume mesher refused the surfaces (") +
                           e.what() + "); meshing them again with Delaunay"))
      throw Cancelled();
    return mesh_with(set, options, steady, 5);
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
    // The dihedral angle at each edge: the angle between the other two vertices seen across it.
    double m = 180.0;
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) {
        int other[2], n = 0;
        for (int k = 0; k < 4; ++k) {
          if (k != i && k != j) other[n++] = k;
        }
        const Vec3 axis = (p[j] - p[i]).normalized();
        Vec3 u = p[other[0]] - p[i], w = p[other[1]] - p[i];
        u -= u.dot(axis) * axis;
        w -= w.dot(axis) * axis;
        const double c = std::clamp(u.normalized().dot(w.normalized()), -1.0, 1.0);
        m = std::min(m, std::acos(c) * 180.0 / M_PI);
      }
    }
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
