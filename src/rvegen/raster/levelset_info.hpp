// What a set of level sets holds (names, kinds, sizes), without OpenVDB: the report and the
// command line read it; building the grids is levelset.hpp's (the rvegen_levelset library).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "rvegen/model/phases.hpp"

namespace rvegen {

struct LevelSetOptions {
  /// Voxel size of the grids; 0 picks the smallest box size / 256.
  double voxel_size = 0.0;
  /// Half width of the narrow band, in voxels.
  double half_width = 3.0;
  /// Grids for the shells of straight coated inclusions too (Modifiers::exact_shape: their
  /// shell is exact in closed form, so by default they get none).
  bool exact_shapes = false;
};

/// One grid: the union of one family's wavy or deformed cores ("<family>_core") or of its
/// interphase shells ("<family>_interphase"), periodic images that reach into the box included.
struct LevelSetInfo {
  std::string name;
  PhaseKind kind = PhaseKind::kCore;  // kCore or kInterphase
  int family = 0;
  int phase = 0;  // label in phase_table(set)
  int inclusions = 0;
  long long active_voxels = 0;
  long long memory_bytes = 0;  // of the sparse tree
};

struct LevelSets {
  std::vector<LevelSetInfo> grids;
  double voxel_size = 0.0;
  double half_width = 0.0;
  /// Bytes of dense float grids of the same voxel size over the box (one per named grid), for
  /// comparison.
  long long dense_bytes = 0;
  long long memory_bytes = 0;  // all sparse grids
  std::shared_ptr<void> data;  // the OpenVDB grids
  bool empty() const { return grids.empty(); }
};

}  // namespace rvegen
