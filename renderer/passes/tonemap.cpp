// SPDX-License-Identifier: Apache-2.0
#include "passes/tonemap.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "scene/texture.h"

namespace fovea::render {

namespace {

// The display value of a tone-mapped linear value v in [0, 1], quantised to 8 bits: a table of
// kLutSize entries replaces pow() per channel. With 16384 entries the table differs from the exact
// sRGB encoding by at most one 8-bit level (tested), at a fraction of the cost (bench/RESULTS.md).
constexpr std::size_t kLutSize = 16384;

const std::array<std::uint8_t, kLutSize + 1>& srgb_lut() {
  static const auto lut = [] {
    std::array<std::uint8_t, kLutSize + 1> t{};
    for (std::size_t i = 0; i <= kLutSize; ++i) {
      const float v = static_cast<float>(i) / static_cast<float>(kLutSize);
      t[i] = static_cast<std::uint8_t>(std::lround(linear_to_srgb(v) * 255.0f));
    }
    return t;
  }();
  return lut;
}

enum class Operator { Reinhard, Clamp, Exponential };

float map_operator(float v, Operator op) {
  v = std::isfinite(v) ? std::max(v, 0.0f) : 0.0f;
  switch (op) {
    case Operator::Reinhard: return v / (1.0f + v);
    case Operator::Exponential: return 1.0f - std::exp(-v);  // Jensen & Pedersen 2009, eq. 8.7 (exposure applied before)
    case Operator::Clamp: break;
  }
  return std::min(v, 1.0f);
}

}  // namespace

void tonemap(const std::vector<glm::vec3>& hdr, std::uint32_t width, std::uint32_t height, const TonemapParams& p,
             Image8& out) {
  out.resize(width, height);
  const Operator op = p.op == "reinhard" ? Operator::Reinhard : p.op == "exponential" ? Operator::Exponential : Operator::Clamp;
  const auto& lut = srgb_lut();
  const std::size_t n = std::size_t{width} * height;
  for (std::size_t i = 0; i < n; ++i) {
    const glm::vec3 c = hdr[i] * p.exposure;
    for (int k = 0; k < 3; ++k) {
      const float v = map_operator(c[k], op);
      if (p.exact) {
        out.rgb[3 * i + static_cast<std::size_t>(k)] =
            static_cast<std::uint8_t>(std::lround(linear_to_srgb(v) * 255.0f));
      } else {
        out.rgb[3 * i + static_cast<std::size_t>(k)] =
            lut[static_cast<std::size_t>(v * static_cast<float>(kLutSize) + 0.5f)];
      }
    }
  }
}

}  // namespace fovea::render
