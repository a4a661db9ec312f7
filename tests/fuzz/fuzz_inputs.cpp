// Fuzz target for what rvegen reads: the scene parser and the inclusion reader, each input tried
// as both, and an RVE handed in with its scene ({"scene": ..., "inclusions": ...}, as
// `rvegen homogenize DIR SCENE` reads them). Inputs that pass are taken further (a scene is
// packed under a short time budget and voxelized; an inclusion list is audited and voxelized;
// an RVE that its scene accepts is voxelized), so what validation lets through is exercised
// too. Any crash, sanitizer report, uncaught exception or hang is a defect: input
// errors must come out as InputError, and a packed RVE must pass the audit (AuditFailure is
// not caught here).
//
// Built with clang's libFuzzer (RVEGEN_FUZZ=ON and clang) as rvegen_fuzz; fuzz_replay.cpp runs
// the same function over the checked-in corpus in the ordinary test suite.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/resources.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/packing/audit.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace {

void try_scene(const std::string& text) {
  rvegen::Scene scene;
  try {
    scene = rvegen::parse_scene(text);
  } catch (const rvegen::InputError&) {
    return;
  }
  const rvegen::ResourceEstimate need = rvegen::estimate_resources(scene);
  if (need.inclusions > 300) return;  // keep each input fast
  scene.md.max_seconds = std::min(scene.md.max_seconds, 0.3);
  scene.rsa_max_seconds = std::min(scene.rsa_max_seconds, 0.3);
  rvegen::PackingResult result;
  try {
    result = rvegen::generate(scene);
  } catch (const rvegen::InputError&) {
    return;  // e.g. an unlucky draw past the count limit
  } catch (const rvegen::NothingPlaced&) {
    return;  // entangled within the budget: no RVE, reported as such
  }
  rvegen::voxelize(result.set, {6, 5, 4});
}

void try_inclusions(const std::string& text) {
  rvegen::InclusionSet set;
  try {
    set = rvegen::read_inclusions_json(text);
  } catch (const rvegen::InputError&) {
    return;
  }
  if (set.inclusions.size() > 2000) return;
  rvegen::audit(set, 100);
  try {
    rvegen::voxelize(set, {6, 5, 4});
  } catch (const rvegen::InputError&) {
    // too many phases for 8-bit labels: refused, as it should be
  }
}

// An RVE handed in with its scene: the check that homogenize makes before any work. What it
// lets through must be an RVE of the scene, so its image has the scene's phases.
void try_rve_with_scene(const std::string& text) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object() || j.size() != 2 || !j.contains("scene") ||
      !j.contains("inclusions"))
    return;
  rvegen::Scene scene;
  rvegen::InclusionSet set;
  try {
    scene = rvegen::parse_scene(j["scene"].dump());
    set = rvegen::read_inclusions_json(j["inclusions"].dump());
    if (set.inclusions.size() > 2000) return;
    rvegen::check_rve_for_scene(set, scene, "fuzz");
  } catch (const rvegen::InputError&) {
    return;
  }
  try {
    rvegen::voxelize(set, {6, 5, 4});
  } catch (const rvegen::InputError&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try_scene(text);
  try_inclusions(text);
  try_rve_with_scene(text);
  return 0;
}
