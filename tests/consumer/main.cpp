// Packs the built-in default scene's spheres with an installed rvegen and prints the count.
#include <cstdio>

#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/packing/packing.hpp"

int main() {
  rvegen::Scene scene = rvegen::default_scene();
  scene.families.resize(1);
  const rvegen::PackingResult r = rvegen::generate(scene);
  std::printf("%zu inclusions, %zu bytes of JSON\n", r.set.inclusions.size(),
              rvegen::write_inclusions_json(r.set).size());
  return r.status == rvegen::PackingStatus::kOk && !r.set.inclusions.empty() ? 0 : 1;
}
