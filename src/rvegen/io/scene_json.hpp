// Scene files: JSON text to Scene (strict: unknown and repeated keys are errors) and back.
#pragma once

#include <string>
#include <vector>

#include "rvegen/model/scene.hpp"

namespace rvegen {

/// Reads a scene (see README for the schema): known keys, JSON types, integers that fit; every
/// range and cross-field rule is then validate_scene's, the one place that checks a scene however
/// it was built. Throws InputError naming the key.
Scene parse_scene(const std::string& json_text);
/// Reads a "materials" object ({"matrix": {...}, "<family>": {...}, ...}, the scene's syntax)
/// into scene->materials (replacing them); names and ranges are validate_homogenization's.
void read_materials_json(const std::string& json_text, Scene* scene);
/// The outputs named in `names` (inclusions, voxels, h5, amitex, levelsets, mesh), nothing
/// else; `mesh` as given unless "mesh" is named. `where` names the list in errors (InputError).
Outputs outputs_from_names(const std::vector<std::string>& names, bool mesh,
                           const std::string& where);
/// JSON text of a scene (what parse_scene reads).
std::string scene_to_json(const Scene& scene);
/// JSON text of the packing part alone (the scene's keys that the packing depends on): equal
/// texts give equal packings.
std::string packing_to_json(const PackingSpec& spec);

}  // namespace rvegen
