// SPDX-License-Identifier: Apache-2.0
#include "scene/texture.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

namespace fovea::render {

namespace {

const std::array<float, 256>& srgb_table() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[static_cast<std::size_t>(i)] = srgb_to_linear(static_cast<float>(i) / 255.0f);
    return t;
  }();
  return table;
}

std::uint8_t to_byte(float v) { return static_cast<std::uint8_t>(std::clamp(std::lround(v * 255.0f), 0L, 255L)); }

// lround(linear_to_srgb(x) * 255) without a pow per call: the byte whose interval of linear values
// holds x, by binary search over the 255 boundaries (the sRGB values k + 0.5 of 255 in linear light).
// Building a 2k texture's mip chain encodes ~4 M values: pow made it most of the texture load time.
std::uint8_t to_srgb_byte(float x) {
  static const std::array<float, 255> bounds = [] {
    std::array<float, 255> b{};
    for (int k = 0; k < 255; ++k) b[static_cast<std::size_t>(k)] = srgb_to_linear((static_cast<float>(k) + 0.5f) / 255.0f);
    return b;
  }();
  return static_cast<std::uint8_t>(std::upper_bound(bounds.begin(), bounds.end(), x) - bounds.begin());
}

// One level from the one above: each texel the mean of its 2x2 parents (clamped at an odd edge).
TextureLevel downsample(const TextureLevel& src, bool srgb) {
  TextureLevel dst;
  dst.width = std::max(1u, src.width / 2);
  dst.height = std::max(1u, src.height / 2);
  dst.rgba.resize(std::size_t{dst.width} * dst.height * 4);
  const auto& lut = srgb_table();
  for (std::uint32_t y = 0; y < dst.height; ++y) {
    for (std::uint32_t x = 0; x < dst.width; ++x) {
      float sum[4] = {0, 0, 0, 0};
      for (std::uint32_t dy = 0; dy < 2; ++dy) {
        for (std::uint32_t dx = 0; dx < 2; ++dx) {
          const std::uint32_t sx = std::min(2 * x + dx, src.width - 1), sy = std::min(2 * y + dy, src.height - 1);
          const std::uint8_t* t = &src.rgba[(std::size_t{sy} * src.width + sx) * 4];
          for (int c = 0; c < 3; ++c) sum[c] += srgb ? lut[t[c]] : static_cast<float>(t[c]) / 255.0f;
          sum[3] += static_cast<float>(t[3]) / 255.0f;
        }
      }
      std::uint8_t* out = &dst.rgba[(std::size_t{y} * dst.width + x) * 4];
      for (int c = 0; c < 3; ++c) out[c] = srgb ? to_srgb_byte(sum[c] / 4) : to_byte(sum[c] / 4);
      out[3] = to_byte(sum[3] / 4);
    }
  }
  return dst;
}

std::uint32_t wrap(std::int64_t i, std::uint32_t n, TextureWrap mode) {
  const auto size = static_cast<std::int64_t>(n);
  switch (mode) {
    case TextureWrap::ClampToEdge: return static_cast<std::uint32_t>(std::clamp<std::int64_t>(i, 0, size - 1));
    case TextureWrap::MirroredRepeat: {
      std::int64_t m = i % (2 * size);
      if (m < 0) m += 2 * size;
      return static_cast<std::uint32_t>(m < size ? m : 2 * size - 1 - m);
    }
    case TextureWrap::Repeat: break;
  }
  std::int64_t m = i % size;
  return static_cast<std::uint32_t>(m < 0 ? m + size : m);
}

glm::vec4 texel(const TextureLevel& l, std::uint32_t x, std::uint32_t y, bool srgb) {
  const std::uint8_t* t = &l.rgba[(std::size_t{y} * l.width + x) * 4];
  const auto& lut = srgb_table();
  constexpr float k = 1.0f / 255.0f;
  if (srgb) return {lut[t[0]], lut[t[1]], lut[t[2]], t[3] * k};
  return {t[0] * k, t[1] * k, t[2] * k, t[3] * k};
}

// Texel coordinates of uv on a level of size n (texel centres at i + 0.5), kept in a range whose
// floor an int64 holds: a uv of 1e30 (a stranger's mesh) must not overflow, and wrapping makes a
// huge coordinate's position inside the texture meaningless anyway.
double texel_coordinate(float uv, std::uint32_t n) {
  const double x = static_cast<double>(uv) * n - 0.5;
  return std::clamp(x, -1e15, 1e15);
}

glm::vec4 bilinear(const TextureLevel& l, const TextureSampler& s, glm::vec2 uv, bool srgb) {
  const double x = texel_coordinate(uv.x, l.width), y = texel_coordinate(uv.y, l.height);
  const double x0 = std::floor(x), y0 = std::floor(y);
  const auto fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const auto ix = static_cast<std::int64_t>(x0), iy = static_cast<std::int64_t>(y0);
  const std::uint32_t xa = wrap(ix, l.width, s.wrap_s), xb = wrap(ix + 1, l.width, s.wrap_s);
  const std::uint32_t ya = wrap(iy, l.height, s.wrap_t), yb = wrap(iy + 1, l.height, s.wrap_t);
  const glm::vec4 top = glm::mix(texel(l, xa, ya, srgb), texel(l, xb, ya, srgb), fx);
  const glm::vec4 bottom = glm::mix(texel(l, xa, yb, srgb), texel(l, xb, yb, srgb), fx);
  return glm::mix(top, bottom, fy);
}

glm::vec4 nearest(const TextureLevel& l, const TextureSampler& s, glm::vec2 uv, bool srgb) {
  const auto ix = static_cast<std::int64_t>(std::floor(texel_coordinate(uv.x, l.width) + 0.5));
  const auto iy = static_cast<std::int64_t>(std::floor(texel_coordinate(uv.y, l.height) + 0.5));
  return texel(l, wrap(ix, l.width, s.wrap_s), wrap(iy, l.height, s.wrap_t), srgb);
}

}  // namespace

float srgb_to_linear(float c) {
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

float linear_to_srgb(float c) {
  c = std::clamp(c, 0.0f, 1.0f);
  return c <= 0.0031308f ? c * 12.92f : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

std::size_t TextureImage::bytes() const {
  std::size_t n = 0;
  for (const TextureLevel& l : levels) n += l.rgba.size();
  return n;
}

std::size_t mip_chain_bytes(std::uint32_t width, std::uint32_t height) {
  std::size_t n = 0;
  for (;;) {
    n += std::size_t{width} * height * 4;
    if (width == 1 && height == 1) return n;
    width = std::max(1u, width / 2);
    height = std::max(1u, height / 2);
  }
}

MipChainResult make_texture_image(std::string name, std::uint32_t width, std::uint32_t height,
                                  std::vector<std::uint8_t> rgba, bool srgb, std::size_t max_bytes) {
  auto image = std::make_shared<TextureImage>();
  image->name = std::move(name);
  image->srgb = srgb;
  MipChainResult result;
  if (width == 0 || height == 0 || rgba.size() != std::size_t{width} * height * 4) return result;
  TextureLevel level{width, height, std::move(rgba)};
  // Levels past the budget are built and dropped: each is a quarter of the one above, so the work
  // for a chain that fits is at most 1/3 more than building it whole.
  while (mip_chain_bytes(level.width, level.height) > max_bytes && (level.width > 1 || level.height > 1)) {
    level = downsample(level, srgb);
    ++result.dropped_levels;
  }
  if (mip_chain_bytes(level.width, level.height) > max_bytes) return result;
  image->levels.push_back(std::move(level));
  while (image->levels.back().width > 1 || image->levels.back().height > 1) {
    image->levels.push_back(downsample(image->levels.back(), srgb));
  }
  result.image = std::move(image);
  return result;
}

float texel_area_lod(const TextureImage& image) {
  if (image.levels.empty()) return 0;
  const TextureLevel& l = image.levels.front();
  return 0.5f * std::log2(static_cast<float>(l.width) * static_cast<float>(l.height));
}

glm::vec4 sample_texture(const TextureImage& image, const TextureSampler& sampler, glm::vec2 uv, float lod) {
  if (image.levels.empty()) return glm::vec4(1.0f);
  if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) uv = glm::vec2(0.0f);
  if (!std::isfinite(lod)) lod = 0;
  if (lod <= 0) {
    const TextureLevel& l = image.levels.front();
    return sampler.mag_nearest ? nearest(l, sampler, uv, image.srgb) : bilinear(l, sampler, uv, image.srgb);
  }
  const float last = static_cast<float>(image.levels.size() - 1);
  if (lod >= last) return bilinear(image.levels.back(), sampler, uv, image.srgb);
  const auto k = static_cast<std::size_t>(lod);
  const float f = lod - static_cast<float>(k);
  const glm::vec4 a = bilinear(image.levels[k], sampler, uv, image.srgb);
  if (f <= 0) return a;
  return glm::mix(a, bilinear(image.levels[k + 1], sampler, uv, image.srgb), f);
}

}  // namespace fovea::render
