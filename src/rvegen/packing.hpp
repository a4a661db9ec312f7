// Packing engines: turn a validated Scene into an InclusionSet with no overlapping pair.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "rvegen/random.hpp"
#include "rvegen/scene.hpp"

namespace rvegen {

struct PackingResult {
  InclusionSet set;
  /// "ok" or "target_not_reached" (the best non-overlapping configuration is still in `set`).
  std::string status = "ok";
  std::vector<int> target_count;  // per family
  std::vector<int> placed_count;  // per family
  double seconds = 0.0;
  long long attempts = 0;
};

/// Progress callback: receives one human-readable line at a time.
using ProgressFn = std::function<void(const std::string&)>;

/// Draws one inclusion of family `f` centred at `center` (orientation from its law).
Shape draw_inclusion(const Family& f, const Vec3& center, Random& rng);

/// Random sequential adsorption: inclusions are drawn one at a time (largest first) at uniform
/// random positions and kept when clear of every placed one (and their periodic images) by
/// scene.min_gap. Each inclusion gets at most scene.rsa_max_attempts draws; when one fails the
/// run stops with status "target_not_reached".
PackingResult pack_rsa(const Scene& scene, const ProgressFn& progress = nullptr);

/// Runs the scene's method.
PackingResult generate(const Scene& scene, const ProgressFn& progress = nullptr);

}  // namespace rvegen
