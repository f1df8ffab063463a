// SPDX-License-Identifier: Apache-2.0
#pragma once
// Scene overrides (fovea-render --scene-set PATH=VALUE): set a value of the JSON document before it
// is validated, by a dotted path ("camera.width", "lights.0.power"). The value is parsed as JSON if
// it can be, else taken as a string. A path that does not exist in the document and is not a known
// optional field (scene_schema.h) is an error naming the override.
#include "scene/json_path.h"
#include "scene/scene_loader.h"

namespace fovea::render {

// Sets `o` in `doc` and notes it in `reader`, so later errors at that path say the override set it.
// Throws SceneError.
void apply_override(json::Json& doc, const SceneOverride& o, json::Reader& reader);

}  // namespace fovea::render
