// SPDX-License-Identifier: Apache-2.0
#pragma once
// Decoding a glTF asset's images into textures (scene/texture.h). Images are data from strangers:
// each is read bounded (an external file at most max_image_file_bytes), its header checked before
// decoding (a PNG or JPEG declaring more than max_image_pixels is refused before OpenCV allocates:
// trackerd/source_api/image_header.h, the hardening's decompression-bomb check), and all of them
// together kept within a memory budget by loading every image at a lower mip level when the full
// chains would not fit. A missing or broken image is a warning naming the image and the material
// slot that uses it, and that texture is left out (the material's factors stand alone); it never
// throws. Decoding runs in parallel (TBB), one image per task.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "scene/gltf/gltf_asset.h"
#include "scene/texture.h"

namespace fovea::render::gltf {

struct TextureRequest {
  std::uint32_t image = 0;
  bool srgb = false;     // colour (base colour, emissive) or data (metallic-roughness, normal, occlusion)
  std::string used_by;   // "material \"Brick\" baseColorTexture", for the warning
};

struct TextureOptions {
  std::size_t budget_bytes = std::size_t{3} << 29;               // 1.5 GiB of mip chains, all textures
  std::uint64_t max_image_pixels = std::uint64_t{8192} * 8192;   // each image, as its header declares
  std::size_t max_image_file_bytes = std::size_t{256} << 20;     // each external image file
};

struct DecodedTextures {
  std::vector<std::shared_ptr<const TextureImage>> images;  // one per request; null where it failed
  std::vector<std::string> warnings;
  std::size_t bytes = 0;               // resident, all chains
  std::uint32_t dropped_levels = 0;    // levels left out of every image for the budget
};

DecodedTextures decode_textures(const Asset& asset, const std::vector<TextureRequest>& requests,
                                const TextureOptions& options = {});

}  // namespace fovea::render::gltf
