#include "rvegen/raster/levelset.hpp"

#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/Prune.h>
#include <openvdb/tools/SignedFloodFill.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <mutex>
#include <sstream>

#include "rvegen/model/body.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen {
namespace {

struct Grids {
  std::vector<openvdb::FloatGrid::Ptr> grids;
};

void init_openvdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

const Grids& grids_of(const LevelSets& ls) {
  return *static_cast<const Grids*>(ls.data.get());
}

}  // namespace

LevelSets build_level_sets(const InclusionSet& set, const LevelSetOptions& opt) {
  init_openvdb();
  LevelSets ls;
  auto data = std::make_shared<Grids>();
  const Box& box = set.box;
  const double vs = opt.voxel_size > 0.0 ? opt.voxel_size : box.size.minCoeff() / 256.0;
  const double band = opt.half_width * vs;
  ls.voxel_size = vs;
  ls.half_width = opt.half_width;
  long long dense = 4;
  for (int a = 0; a < 3; ++a) dense *= static_cast<long long>(std::ceil(box.size[a] / vs));

  const std::vector<Phase> phases = phase_table(set);
  int nf = 0;
  for (const auto& p : phases) nf = std::max(nf, p.family + 1);
  // Grid names: family names with spaces as underscores, made unique (families "a b" and
  // "a_b", or two of the same name, get the family index appended).
  std::vector<std::string> names(nf);
  for (int f = 0; f < nf; ++f) {
    std::string n = f < static_cast<int>(set.family_names.size()) ? set.family_names[f]
                                                                  : "family" + std::to_string(f);
    std::replace(n.begin(), n.end(), ' ', '_');
    names[f] = n;
  }
  for (bool clash = true; clash;) {
    clash = false;
    for (int f = 0; f < nf; ++f) {
      if (std::count(names.begin(), names.end(), names[f]) > 1) {
        const std::string dup = names[f];
        for (int g = 0; g < nf; ++g) {
          if (names[g] == dup) names[g] += "_" + std::to_string(g);
        }
        clash = true;
      }
    }
  }
  auto family_name = [&](int f) { return names[f]; };
  for (int kind = 0; kind < 2; ++kind) {  // 0: wavy / deformed cores, 1: interphase shells
    for (int f = 0; f < nf; ++f) {
      std::vector<const Inclusion*> members;
      for (const auto& inc : set.inclusions) {
        if (inc.family != f) continue;
        const bool wanted = kind == 0
                                ? (inc.mod.curved() || inc.mod.deformed())
                                : inc.mod.coated() && (opt.exact_shapes || !inc.mod.exact_shape());
        if (wanted) members.push_back(&inc);
      }
      if (members.empty()) continue;
      auto grid = openvdb::FloatGrid::create(static_cast<float>(band));
      grid->setTransform(openvdb::math::Transform::createLinearTransform(vs));
      grid->setGridClass(openvdb::GRID_LEVEL_SET);
      // Narrow-band values of each inclusion, computed in parallel, then written in inclusion
      // order taking the minimum (the union: merged shells, self images): the same grid
      // whatever the number of threads.
      std::vector<std::vector<std::pair<openvdb::Coord, float>>> values(members.size());
      tbb::parallel_for(size_t(0), members.size(), [&](size_t m) {
        const Inclusion* inc = members[m];
        const BodyQuery body(*inc);
        Vec3 lo, hi;
        outer_bound(*inc).aabb(&lo, &hi);
        lo.array() -= band;
        hi.array() += band;
        // Periodic images whose bounding box meets the box.
        int k0[3] = {0, 0, 0}, k1[3] = {0, 0, 0};
        if (box.periodic) {
          for (int a = 0; a < 3; ++a) {
            k0[a] = static_cast<int>(std::ceil((box.origin[a] - hi[a]) / box.size[a]));
            k1[a] =
                static_cast<int>(std::floor((box.origin[a] + box.size[a] - lo[a]) / box.size[a]));
          }
        }
        for (int si = k0[0]; si <= k1[0]; ++si) {
          for (int sj = k0[1]; sj <= k1[1]; ++sj) {
            for (int sk = k0[2]; sk <= k1[2]; ++sk) {
              const Vec3 shift(si * box.size[0], sj * box.size[1], sk * box.size[2]);
              openvdb::Coord c0, c1;
              for (int a = 0; a < 3; ++a) {
                c0[a] = static_cast<int>(std::floor((lo[a] + shift[a]) / vs));
                c1[a] = static_cast<int>(std::ceil((hi[a] + shift[a]) / vs));
              }
              for (int z = c0[2]; z <= c1[2]; ++z) {
                for (int y = c0[1]; y <= c1[1]; ++y) {
                  for (int x = c0[0]; x <= c1[0]; ++x) {
                    // Voxel centres of the grid sit at integer coordinates times vs.
                    const Vec3 p = Vec3(x, y, z) * vs - shift;
                    const double d = kind == 0 ? body.core_distance(p) : body.shell_distance(p);
                    if (std::abs(d) < band) {
                      values[m].emplace_back(openvdb::Coord(x, y, z), static_cast<float>(d));
                    }
                  }
                }
              }
            }
          }
        }
      });
      auto acc = grid->getAccessor();
      for (const auto& list : values) {
        for (const auto& [ijk, d] : list) {
          float v;
          if (acc.probeValue(ijk, v) && v <= d) continue;
          acc.setValue(ijk, d);
        }
      }
      openvdb::tools::signedFloodFill(grid->tree());
      openvdb::tools::pruneLevelSet(grid->tree());
      LevelSetInfo info;
      info.family = f;
      info.kind = kind == 0 ? PhaseKind::kCore : PhaseKind::kInterphase;
      info.name = family_name(f) + "_" + phase_kind_name(info.kind);
      info.phase = f + 1;
      for (const auto& p : phases) {
        if (kind == 1 && p.family == f && p.kind == PhaseKind::kInterphase) info.phase = p.label;
      }
      info.inclusions = static_cast<int>(members.size());
      info.active_voxels = static_cast<long long>(grid->activeVoxelCount());
      info.memory_bytes = static_cast<long long>(grid->memUsage());
      grid->setName(info.name);
      grid->insertMeta("family", openvdb::Int32Metadata(f));
      grid->insertMeta("kind", openvdb::StringMetadata(phase_kind_name(info.kind)));
      grid->insertMeta("inclusions", openvdb::Int32Metadata(info.inclusions));
      grid->insertMeta("half_width_voxels",
                       openvdb::FloatMetadata(static_cast<float>(opt.half_width)));
      ls.memory_bytes += info.memory_bytes;
      ls.grids.push_back(info);
      data->grids.push_back(grid);
    }
  }
  // The dense equivalent: one float grid of the same voxel size over the box per named grid.
  ls.dense_bytes = dense * static_cast<long long>(ls.grids.size());
  ls.data = data;
  return ls;
}

double level_set_value(const LevelSets& ls, size_t g, const Vec3& x) {
  const auto& grid = grids_of(ls).grids.at(g);
  openvdb::tools::GridSampler<openvdb::FloatGrid, openvdb::tools::BoxSampler> sampler(*grid);
  return sampler.wsSample(openvdb::Vec3d(x[0], x[1], x[2]));
}

std::string vdb_bytes(const LevelSets& ls, const InclusionSet& set) {
  init_openvdb();
  openvdb::GridPtrVec grids;
  if (ls.data) {
    for (const auto& g : grids_of(ls).grids) grids.push_back(g);
  }
  openvdb::MetaMap meta;
  meta.insertMeta("format", openvdb::StringMetadata("rvegen.levelsets/1"));
  meta.insertMeta("box_origin", openvdb::Vec3DMetadata(openvdb::Vec3d(
                                    set.box.origin[0], set.box.origin[1], set.box.origin[2])));
  meta.insertMeta("box_size", openvdb::Vec3DMetadata(openvdb::Vec3d(
                                  set.box.size[0], set.box.size[1], set.box.size[2])));
  meta.insertMeta("periodic", openvdb::BoolMetadata(set.box.periodic));
  meta.insertMeta("voxel_size", openvdb::DoubleMetadata(ls.voxel_size));
  std::ostringstream out(std::ios::binary);
  openvdb::io::Stream(out).write(grids, meta);
  return out.str();
}

std::vector<std::pair<std::string, long long>> read_vdb_summary(const std::string& path) {
  init_openvdb();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  openvdb::io::Stream stream(in);
  std::vector<std::pair<std::string, long long>> out;
  for (const auto& g : *stream.getGrids()) {
    out.emplace_back(g->getName(), static_cast<long long>(g->activeVoxelCount()));
  }
  return out;
}

SurfaceMesh level_set_surfaces(const LevelSets& ls) {
  SurfaceMesh m;
  if (!ls.data) return m;
  const auto& grids = grids_of(ls).grids;
  for (size_t g = 0; g < grids.size(); ++g) {
    std::vector<openvdb::Vec3s> pts;
    std::vector<openvdb::Vec3I> tris;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(*grids[g], pts, tris, quads, 0.0, 0.0);
    const int64_t base = static_cast<int64_t>(m.points.size());
    for (const auto& p : pts) m.points.emplace_back(p[0], p[1], p[2]);
    const LevelSetInfo& info = ls.grids[g];
    auto add = [&](int64_t a, int64_t b, int64_t c) {
      // OpenVDB winds faces inward for VTK's convention: reversed here.
      m.triangles.push_back({base + a, base + c, base + b});
      m.inclusion_id.push_back(-1);
      m.family.push_back(info.family);
      m.shape.push_back(-1);
      m.phase.push_back(info.phase);
      m.axis.push_back({0.0f, 0.0f, 0.0f});
    };
    for (const auto& t : tris) add(t[0], t[1], t[2]);
    for (const auto& q : quads) {
      add(q[0], q[1], q[2]);
      add(q[0], q[2], q[3]);
    }
  }
  return m;
}

}  // namespace rvegen
