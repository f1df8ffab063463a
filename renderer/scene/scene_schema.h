// SPDX-License-Identifier: Apache-2.0
#pragma once
// The scene file's schema (renderer/SCENES.md): which keys each kind of JSON object may hold.
// Validation (scene_loader.cpp) and overrides (scene_overrides.h) share it.
#include <string_view>

#include "scene/json_path.h"

namespace fovea::render::schema {

using json::Keys;

enum class Kind {
  Scene, Camera, Lens, Animation, AnimationKeys, AnimationKey, Materials, Material, Objects, Object, Geometry,
  Sphere, Cylinder, Transform, Lod, LodLevel, Lights, Light, Display, Value
};


inline const Keys kSceneKeys{"name",    "camera",     "materials", "objects", "lights",
                      "ambient", "background", "display",   "gltf",    "comment"};
inline const Keys kCameraKeys{"position", "target", "up", "vertical_fov_deg", "width", "height",
                       "near", "far", "lens", "animation", "stereo", "ipd_m", "comment"};
inline const Keys kLensKeys{"type", "focal_length_mm", "f_number", "aperture_mm", "focus_distance_m", "image_distance_mm",
                     "comment"};
inline const Keys kPinholeKeys{"type", "comment"};
inline const Keys kThinLensKeys{"type", "focal_length_mm", "f_number", "aperture_mm", "focus_distance_m",
                         "image_distance_mm", "comment"};
inline const Keys kHumanEyeKeys{"type", "focus_distance_m", "comment"};
inline const Keys kAnimationKeys{"loop", "keys", "comment"};
inline const Keys kObjectKeyframeKeys{"t", "translation", "rotation_deg", "comment"};
inline const Keys kCameraKeyframeKeys{"t", "translation", "comment"};
inline const Keys kMaterialKeys{"name", "type", "kd", "ks", "shininess", "reflectance", "ior", "emission", "comment"};
inline const Keys kObjectKeys{"name", "geometry", "material", "transform", "animation", "task_importance", "lod", "comment"};
inline const Keys kGeometryKeys{"mesh", "box", "sphere", "plane", "cylinder", "comment"};
inline const Keys kShapeKeys{"mesh", "box", "sphere", "plane", "cylinder"};
inline const Keys kSphereKeys{"radius", "rings", "segments", "comment"};
inline const Keys kCylinderKeys{"radius", "height", "segments", "comment"};
inline const Keys kTransformKeys{"translation", "rotation_deg", "scale", "comment"};
inline const Keys kLodSimplifyKeys{"simplify", "chain", "comment"};
inline const Keys kLodChainKeys{"levels", "base", "attributes", "comment"};
inline const Keys kLodLevelKeys{"mesh", "max_error_m", "comment"};
inline const Keys kLightKeys{"type", "position", "power", "direction", "cutoff_deg", "falloff_deg", "normal", "size",
                      "samples", "comment"};
inline const Keys kPointLightKeys{"type", "position", "power", "comment"};
inline const Keys kSpotLightKeys{"type", "position", "direction", "power", "cutoff_deg", "falloff_deg", "comment"};
inline const Keys kAreaLightKeys{"type", "position", "normal", "size", "power", "samples", "comment"};
inline const Keys kDisplayKeys{"width_px", "height_px", "width_mm", "height_mm", "viewing_distance_mm", "comment"};
inline const Keys kNoKeys{};


// The keys an object of kind `k` may hold (none for arrays, maps of user-chosen names and values).
const Keys& keys_of(Kind k);
// The kind of the value at `key` inside an object of kind `parent`.
Kind child_kind(Kind parent, std::string_view key);
// The kind of an element of an array (or of a map of user-chosen names) of kind `parent`.
Kind element_kind(Kind parent);

}  // namespace fovea::render::schema
