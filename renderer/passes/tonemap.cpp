#include "passes/tonemap.h"

#include <algorithm>
#include <cmath>

namespace fovea::render {

void tonemap(const std::vector<glm::vec3>& hdr, std::uint32_t width, std::uint32_t height, const TonemapParams& p,
             Image8& out) {
  out.resize(width, height);
  const bool reinhard = p.op == "reinhard";
  for (std::uint32_t y = 0; y < height; ++y) {
    for (std::uint32_t x = 0; x < width; ++x) {
      glm::vec3 c = hdr[std::size_t{y} * width + x] * p.exposure;
      for (int k = 0; k < 3; ++k) {
        float v = std::isfinite(c[k]) ? std::max(c[k], 0.0f) : 0.0f;
        v = reinhard ? v / (1.0f + v) : std::min(v, 1.0f);
        c[k] = linear_to_srgb(v);
      }
      out.set(x, y, c);
    }
  }
}

}  // namespace fovea::render
