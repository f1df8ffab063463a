// SPDX-License-Identifier: Apache-2.0
#pragma once
// The scene builder for glTF assets (Falcor's importer -> SceneBuilder split): turns a gltf::Asset
// (read and checked by read_gltf) into fovea's scene model. It fills the model only; passes never
// see glTF. The rules (renderer/SCENES.md, "glTF 2.0 assets"):
//   objects    one per (mesh node, primitive), ids 1-based in gltf::flatten order; named as the
//              instance ("node") for a one-primitive mesh, "node/p<k>" for several. Nodes sharing
//              a glTF mesh share its fovea Mesh (one std::shared_ptr per primitive).
//   lod        each object asks for a default level-of-detail chain (LodChainRequest::implicit:
//              lod::attach_chains builds it through the cache, or leaves a mesh it cannot reduce
//              without levels); instances share their mesh's levels.
//   transform  the node's exact world matrix (Transform::matrix_override); a matrix that is not
//              finite or not invertible is refused by the node's JSON path.
//   materials  MetallicRoughness with the file's factors, textures (decoded by gltf_textures.h;
//              a missing or broken image is a warning and the factor alone), alpha mode and
//              double-sidedness; BLEND is drawn as MASK at 0.5. Tangents the file lacks are
//              generated for normal-mapped primitives by MikkTSpace's rules (scene/tangents.h),
//              which splits a vertex whose corners lie on both sides of a mirrored UV seam.
//   camera     the first perspective camera node (or options.camera_name), else one framing the
//              scene's bounds from +Z.
//   lights     KHR_lights_punctual point and spot with Phi = 4 pi I colour (the file's units taken
//              as fovea's), directional as a distant point light; none: a two-light default rig.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "scene/gltf/gltf_asset.h"
#include "scene/gltf/gltf_textures.h"
#include "scene/scene.h"
#include "scene/scene_error.h"
#include "scene/scene_loader.h"

namespace fovea::render {

struct GltfSceneOptions {
  std::string camera_name;  // a camera node's name; empty: the first camera node
  std::uint32_t width = 640, height = 480;
  gltf::TextureOptions textures;
};

// Throws SceneError naming asset.source and the JSON path. Appends what it approximated or left out
// (textures, directional lights, orthographic cameras, ...) to `warnings` when given.
// `report`, when given, gets the "textures" phase (decoding and mip chains).
Scene scene_from_gltf(const gltf::Asset& asset, const GltfSceneOptions& options,
                      std::vector<std::string>* warnings = nullptr, LoadReport* report = nullptr);

// .gltf or .glb, by the extension in any case.
bool is_gltf_file(const std::filesystem::path& path);

// load_scene for a glTF file: read_gltf, then scene_from_gltf; warnings go to stderr. A built scene
// has no JSON document to override: `overrides` may set only camera.width and camera.height.
Scene load_gltf_scene(const std::filesystem::path& path, const std::vector<SceneOverride>& overrides,
                      const std::string& camera, LoadReport* report = nullptr);

// A glTF material's factors as a MetallicRoughness material, without its textures (bound by the
// builder). kd, ks and shininess get the factors' nearest Blinn-Phong for the GI pass: kd = base x
// (1 - metallic), ks = mix(0.04, base, metallic), n = 2/alpha^2 - 2 (alpha = roughness^2, n in
// [1, 10000]).
Material material_from_gltf(const gltf::Material& m, const std::string& name);

}  // namespace fovea::render
