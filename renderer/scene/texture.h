// SPDX-License-Identifier: Apache-2.0
#pragma once
// Textures of the scene model: decoded RGBA8 images with their mip chain, and the one sampler both
// backends agree on. The Embree backend samples here (trilinear, at the level of detail of a ray
// cone, Akenine-Möller et al. 2019); the OpenGL backend uploads the same levels (GL_SRGB8_ALPHA8 or
// GL_RGBA8) and samples them with GL_LINEAR_MIPMAP_LINEAR, so the two differ only in how they pick
// the level (screen derivatives against the ray cone) and in the GPU's filtering precision.
#include <cstddef>
#include <cstdint>
#include <glm/glm.hpp>
#include <memory>
#include <string>
#include <vector>

namespace fovea::render {

enum class TextureWrap : std::uint8_t { Repeat, ClampToEdge, MirroredRepeat };

struct TextureSampler {
  TextureWrap wrap_s = TextureWrap::Repeat, wrap_t = TextureWrap::Repeat;
  bool mag_nearest = false;  // magnification picks the nearest texel instead of bilinear
  bool operator==(const TextureSampler&) const = default;
};

struct TextureLevel {
  std::uint32_t width = 0, height = 0;
  std::vector<std::uint8_t> rgba;  // 4 bytes per texel, row 0 at v = 0 (glTF's top of the image)
};

// An image as the renderer samples it. Colour images (base colour, emissive) are sRGB-encoded and
// sampled as linear RGB; data images (metallic-roughness, normal, occlusion) are linear.
struct TextureImage {
  std::string name;  // the file or "image N of FILE", for messages
  bool srgb = false;
  std::vector<TextureLevel> levels;  // level 0 full size; level k max(1, size >> k); down to 1x1
  std::size_t bytes() const;
};

// A texture as a material uses it.
struct TextureBinding {
  std::uint32_t texture = 0;    // index into Scene::textures
  std::uint32_t tex_coord = 0;  // 0: Mesh::texcoords0, 1: Mesh::texcoords1
  TextureSampler sampler;
};

// sRGB transfer function (IEC 61966-2-1), per channel; alpha is always linear.
float srgb_to_linear(float c);
float linear_to_srgb(float c);

// The image with its whole mip chain. Each level is a 2x2 box filter of the one above (odd sizes:
// the last row or column counted twice), averaged in linear light for sRGB images. `rgba` holds
// width * height * 4 bytes. When the chain is larger than max_bytes, the largest levels are left
// out until it fits (the image is then as if it had been smaller); `dropped_levels` says how many.
struct MipChainResult {
  std::shared_ptr<const TextureImage> image;
  std::uint32_t dropped_levels = 0;
};
MipChainResult make_texture_image(std::string name, std::uint32_t width, std::uint32_t height,
                                  std::vector<std::uint8_t> rgba, bool srgb, std::size_t max_bytes = SIZE_MAX);

// Bytes a full chain of a width x height RGBA8 image takes (the 4/3 of level 0, exactly).
std::size_t mip_chain_bytes(std::uint32_t width, std::uint32_t height);

// Trilinear sample at uv (u right, v down, the image covering [0, 1]^2) and level of detail `lod`
// (0 = level 0; past the last level it stays on the last). Magnification (lod <= 0) uses level 0
// with the sampler's filter. Returns linear RGBA (sRGB decoded). Never NaN: a non-finite uv or lod
// samples texel (0, 0) of level 0.
glm::vec4 sample_texture(const TextureImage& image, const TextureSampler& sampler, glm::vec2 uv, float lod);

// The texture's half log2 area in texels, 0.5 log2(w h): the term a ray cone's level adds for the
// texture's resolution (Akenine-Möller et al. 2019, eq. 34).
float texel_area_lod(const TextureImage& image);

}  // namespace fovea::render
