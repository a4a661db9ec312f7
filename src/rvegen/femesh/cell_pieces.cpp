#include "rvegen/femesh/cell_pieces.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <utility>

#include "rvegen/femesh/mesh_parts.hpp"

namespace rvegen::mesh_parts {

namespace {

// What cut_into_box does with each inclusion.
struct CutPlan {
  // Images kept whole: one image, inside the box, no shell or void.
  std::vector<Image> inside;
  // (inclusion, bit a set: its images lie in more than one cell along axis a).
  std::vector<std::pair<int, int>> to_cut;
  // The planes of the cells' faces that the images to cut lie between: (axis, k) for the plane
  // x_axis = origin + k size.
  std::set<std::pair<int, long>> planes;
};

CutPlan plan_cuts(const InclusionSet& set) {
  const Vec3 o = set.box.origin, len = set.box.size;
  std::map<int, std::vector<Vec3>> shifts_of;
  for (const Image& im : images_near(set, 0.0)) shifts_of[im.inc].push_back(im.shift);
  CutPlan plan;
  std::vector<Vec3> cell_shift;
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
      plan.inside.push_back({inc, t0});
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
    plan.to_cut.push_back({inc, axes});
  }
  for (const Vec3& t : cell_shift) {
    for (int a = 0; a < 3; ++a) {
      const long k = std::lround(-t[a] / len[a]);
      plan.planes.insert({a, k});
      plan.planes.insert({a, k + 1});
    }
  }
  return plan;
}

// The solids of the inclusions to cut, and the pieces each has become so far.
class PlaneCutter {
 public:
  PlaneCutter(const InclusionSet& set, const std::vector<int>& frame_rank,
              const std::set<std::pair<int, long>>& planes)
      : set_(set), frame_rank_(frame_rank), planes_(planes) {}

  size_t count() const { return objects_.size(); }

  // An inclusion's solids: its core, and its shell's outer surface or its void.
  void add_solids(int inc) {
    const Inclusion& in = set_.inclusions[inc];
    const Box& box = set_.box;
    const bool cone = in.mod.debonded() && in.mod.debond_fraction < 1.0;
    const Mat3 axis_frame = cone ? void_frame(in, box) : Mat3::Identity();
    add({3, add_solid(in.shape, box, 0.0, cone ? &axis_frame : nullptr, frame_rank_[inc])}, inc,
        kCore);
    if (in.mod.coated()) {
      add({3, add_solid(in.shape, box, in.mod.coating, nullptr, frame_rank_[inc])}, inc, kShell);
    }
    if (in.mod.debonded()) add({3, add_void_solid(in, box)}, inc, kVoid);
  }

  // Fragments the present pieces of solids [from, to) against the planes normal to the axes of
  // `axes` (bits).
  void cut(size_t from, size_t to, int axes) {
    gmsh::vectorpair present;  // each once (a shell's pieces hold its core's)
    std::set<int> seen;
    for (size_t k = from; k < to; ++k) {
      for (const auto& dt : pieces_[k]) {
        if (seen.insert(dt.second).second) present.push_back(dt);
      }
    }
    if (present.empty()) return;
    gmsh::vectorpair out;
    std::vector<gmsh::vectorpair> out_map;
    gmsh::model::occ::fragment(present, planes(axes), out, out_map);
    std::map<int, const gmsh::vectorpair*> became;
    for (size_t i = 0; i < present.size() && i < out_map.size(); ++i) {
      became[present[i].second] = &out_map[i];
    }
    for (size_t k = from; k < to; ++k) {
      gmsh::vectorpair now;
      for (const auto& dt : pieces_[k]) {
        for (const auto& n : *became.at(dt.second)) {
          if (std::find(now.begin(), now.end(), n) == now.end()) now.push_back(n);
        }
      }
      pieces_[k] = std::move(now);
    }
    // The planes' pieces (those that bound a piece stay, as its faces): a later fragment
    // forgets the faces of the pieces it cuts.
    gmsh::vectorpair rest;
    for (const auto& dt : out) {
      if (dt.first == 2) rest.push_back(dt);
    }
    gmsh::model::occ::remove(rest, false);
  }

  // Each piece, with its inclusion and phase, brought into the box by its cell's shift. A piece
  // belongs to the first inclusion whose solids hold it (where shells that may touch overlap),
  // and is a core's when one of that inclusion's cores holds it. A piece lies in one cell, and
  // its centre of mass inside its convex hull: the cell that holds that centre is its own.
  void move_into_box(const std::vector<Phase>& phases, CellPieces* out) const {
    const int families = static_cast<int>(set_.family_names.size());
    const std::vector<int> shell_label = interphase_labels(phases, families);
    const std::vector<int> void_label = void_labels(phases, families);
    std::map<int, int> piece_inc;
    std::set<int> core_piece, void_piece;
    for (size_t k = 0; k < objects_.size() && k < pieces_.size(); ++k) {
      for (const auto& dt : pieces_[k]) {
        const int owner_inc = piece_inc.emplace(dt.second, object_inc_[k]).first->second;
        if (owner_inc != object_inc_[k]) continue;
        if (object_kind_[k] == kCore) core_piece.insert(dt.second);
        if (object_kind_[k] == kVoid) void_piece.insert(dt.second);
      }
    }
    const Vec3 o = set_.box.origin, len = set_.box.size;
    std::map<std::array<long, 3>, gmsh::vectorpair> to_move;  // by the cell's index
    for (const auto& [piece, inc] : piece_inc) {
      double com[3];
      gmsh::model::occ::getCenterOfMass(3, piece, com[0], com[1], com[2]);
      std::array<long, 3> cell;
      for (int a = 0; a < 3; ++a) cell[a] = std::lround(std::floor((com[a] - o[a]) / len[a]));
      const Inclusion& in = set_.inclusions[inc];
      to_move[cell].push_back({3, piece});
      out->solids.push_back({3, piece});
      out->inclusion.push_back(inc);
      out->label.push_back(core_piece.count(piece)   ? core_label(in.family)
                           : void_piece.count(piece) ? void_label[in.family]
                                                     : shell_label[in.family]);
    }
    for (const auto& [cell, mine] : to_move) {
      const Vec3 t(-cell[0] * len[0], -cell[1] * len[1], -cell[2] * len[2]);
      if (!t.isZero()) gmsh::model::occ::translate(mine, t[0], t[1], t[2]);
    }
  }

 private:
  enum Kind : char { kShell = 0, kCore = 1, kVoid = 2 };

  void add(const std::pair<int, int>& solid, int inc, Kind kind) {
    objects_.push_back(solid);
    object_inc_.push_back(inc);
    object_kind_.push_back(kind);
    pieces_.push_back({solid});
  }

  // The planes normal to the axes of `axes` (bits), as squares wider than the cells: with the
  // cells as solids, OpenCASCADE would classify every face of the solids, split by them into
  // hundreds of faces, against each cell.
  gmsh::vectorpair planes(int axes) const {
    const Vec3 o = set_.box.origin, len = set_.box.size;
    gmsh::vectorpair planes;
    for (const auto& [a, k] : planes_) {
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
    return planes;
  }

  const InclusionSet& set_;
  const std::vector<int>& frame_rank_;
  const std::set<std::pair<int, long>>& planes_;
  gmsh::vectorpair objects_;
  std::vector<int> object_inc_;
  std::vector<Kind> object_kind_;
  std::vector<gmsh::vectorpair> pieces_;  // pieces_[k]: what objects_[k] has become
};

// Removes the curves and points that the planes' pieces left bounding nothing. (Removed with
// their planes' pieces instead, each would make Gmsh scan every face and curve it holds.)
void remove_unused_curves() {
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

}  // namespace

CellPieces cut_into_box(const InclusionSet& set, const std::vector<Phase>& phases,
                        const std::vector<int>& frame_rank) {
  const CutPlan plan = plan_cuts(set);
  CellPieces out;
  if (!plan.to_cut.empty()) {
    PlaneCutter cutter(set, frame_rank, plan.planes);
    // With the planes of two axes in one fragment, OpenCASCADE left an ellipsoid (a spline
    // surface) through which the line where two planes meet passes split by one of them only
    // (the default scene's cell, an ellipsoid across its x and z faces: its cap stood out of
    // the cell). The solids that cross planes of two or three axes are cut one axis at a time
    // (parallel planes never meet), and first, while the model holds little (each fragment
    // costs in proportion to the shapes the model holds, whatever it cuts); the others are cut
    // by all the planes at once.
    auto across = [](int axes) { return (axes & (axes - 1)) != 0; };
    for (const auto& [inc, axes] : plan.to_cut) {
      if (across(axes)) cutter.add_solids(inc);
    }
    const size_t first = cutter.count();
    for (int a = 0; a < 3; ++a) {
      // (Each pass takes every one of them: a solid it does not cut keeps its pieces.)
      cutter.cut(0, first, 1 << a);
    }
    for (const auto& [inc, axes] : plan.to_cut) {
      if (!across(axes)) cutter.add_solids(inc);
    }
    cutter.cut(first, cutter.count(), 7);
    cutter.move_into_box(phases, &out);
    remove_unused_curves();
  }
  // Gmsh's bookkeeping after a boolean operation scans, for each shape of its inputs, every
  // shape it holds: the inclusions inside the box are made after the cut.
  for (const Image& im : plan.inside) {
    const Inclusion& in = set.inclusions[im.inc];
    Shape image = in.shape;
    image.center += im.shift;
    out.solids.push_back({3, add_inside_solid(image, set.box, frame_rank[im.inc])});
    out.inclusion.push_back(im.inc);
    out.label.push_back(core_label(in.family));
  }
  return out;
}

}  // namespace rvegen::mesh_parts
