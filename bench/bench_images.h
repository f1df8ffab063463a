// SPDX-License-Identifier: Apache-2.0
#pragma once
// What the benchmarks hand to image-based peers (OpenCV saliency): the display image.
#include <cstdint>
#include <glm/glm.hpp>
#include <opencv2/core.hpp>

#include "backend/gbuffer.h"

namespace fovea::bench {

// The G-buffer's HDR colour clamped to [0, 1] and quantised to 8-bit BGR (like the attention
// tracker's own clamp); it stands for the renderer's tone-mapped output.
inline cv::Mat to_bgr8(const render::GBuffer& g) {
  cv::Mat img(static_cast<int>(g.height), static_cast<int>(g.width), CV_8UC3);
  for (std::uint32_t y = 0; y < g.height; ++y) {
    auto* row = img.ptr<cv::Vec3b>(static_cast<int>(y));
    for (std::uint32_t x = 0; x < g.width; ++x) {
      const glm::vec3 c = glm::clamp(g.color[g.index(x, y)], 0.0f, 1.0f) * 255.0f + 0.5f;
      row[x] = cv::Vec3b(static_cast<std::uint8_t>(c.b), static_cast<std::uint8_t>(c.g), static_cast<std::uint8_t>(c.r));
    }
  }
  return img;
}

}  // namespace fovea::bench
