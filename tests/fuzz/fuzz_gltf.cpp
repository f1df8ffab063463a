// SPDX-License-Identifier: Apache-2.0
// libFuzzer entry point for the glTF reader and scene builder (renderer/scene/gltf/): whatever the
// bytes, read_gltf_bytes must return an asset or throw SceneError, and scene_from_gltf (materials,
// texture decoding of embedded images, tangents) a scene or SceneError, never crash, read out of
// bounds or allocate without bound. Each input is read as a .glb and as a .gltf (a "glTF" magic makes
// both GLB); with no folder, external URIs are refused, so no file is opened. The budgets keep a run
// far below libFuzzer's 2 GB RSS limit: 1 MiB of input, 4 MiB of buffers, 64 MiB of decoded vertex
// data, images of at most 256x256 declared pixels and 4 MiB of textures.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "scene/gltf/gltf_flatten.h"
#include "scene/gltf/gltf_reader.h"
#include "scene/gltf/gltf_scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  fovea::render::gltf::ReadOptions options;
  options.max_file_bytes = 1u << 20;
  options.max_buffer_file_bytes = 1u << 20;
  options.max_total_buffer_bytes = 4u << 20;
  options.max_data_uri_bytes = 1u << 20;
  options.max_decoded_bytes = 64u << 20;
  for (const char* name : {"fuzz.glb", "fuzz.gltf"}) {
    try {
      const auto asset = fovea::render::gltf::read_gltf_bytes(bytes, name, {}, options);
      (void)fovea::render::gltf::flatten(asset);
      fovea::render::GltfSceneOptions scene_options;
      scene_options.textures.max_image_pixels = 256 * 256;
      scene_options.textures.budget_bytes = 4u << 20;
      std::vector<std::string> warnings;
      (void)fovea::render::scene_from_gltf(asset, scene_options, &warnings);
    } catch (const fovea::render::SceneError&) {
      // the expected outcome for nearly every input
    }
  }
  return 0;
}
