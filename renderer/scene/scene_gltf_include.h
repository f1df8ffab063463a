// SPDX-License-Identifier: Apache-2.0
#pragma once
// A JSON scene that includes a glTF 2.0 asset ($.gltf, renderer/SCENES.md "A JSON scene around a
// glTF asset"): the asset is built as `fovea-render --scene FILE.gltf` would build it, then the
// per-object overrides of $.gltf.objects apply to the objects whose names match their patterns
// (task_importance, lod). The scene loader merges the rest (camera, lights, display, extra objects).
#include <filesystem>
#include <string>
#include <string_view>

#include "scene/json_path.h"
#include "scene/scene.h"
#include "scene/scene_loader.h"

namespace fovea::render {

// Reads $.gltf ({"file", "camera", "objects": [{"match", "task_importance", "lod"}]}) through
// `r` (errors by JSON path), loads the file relative to base_dir and applies the object overrides.
// A pattern that matches no object is an error naming it and some of the objects' names. The
// asset's warnings go to stderr.
Scene read_gltf_include(const json::Reader& r, const json::Node& n, const std::filesystem::path& base_dir,
                        LoadReport* report = nullptr);

// Shell-style glob: '*' any run of characters, '?' one character, everything else itself.
bool glob_match(std::string_view pattern, std::string_view name);

}  // namespace fovea::render
