// SPDX-License-Identifier: Apache-2.0
#pragma once
// Eye rays of a pinhole camera through pixel centres, the same rays as the Embree G-buffer
// (backend/embree): direction scaled to unit length along the view axis, so t is view depth.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/glm.hpp>

#include "scene/scene.h"

namespace fovea::render::gi {

struct EyeRays {
  static bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
  glm::vec3 eye{0.0f}, right{1, 0, 0}, up{0, 1, 0}, back{0, 0, 1};
  float tan_x = 1, tan_y = 1;
  std::uint32_t width = 0, height = 0;
  bool ok = false;
  EyeRays(const Camera& cam, double t) : width(cam.width), height(cam.height) {
    const glm::mat4 to_world = glm::inverse(cam.view_at(t));
    eye = glm::vec3(to_world[3]);
    right = glm::vec3(to_world[0]);
    up = glm::vec3(to_world[1]);
    back = glm::vec3(to_world[2]);
    tan_y = std::tan(glm::radians(cam.vertical_fov_deg) * 0.5f);
    tan_x = tan_y * static_cast<float>(cam.width) / static_cast<float>(std::max(1u, cam.height));
    ok = finite(eye) && finite(right) && finite(up) && finite(back) && std::isfinite(tan_x) && tan_y > 0 &&
         width > 0 && height > 0;
  }
  // Through image point (px, py) in pixels (x right, y down; pixel centres at +0.5).
  glm::vec3 direction_at(float px, float py) const {
    const float ndc_x = 2.0f * px / static_cast<float>(width) - 1.0f;
    const float ndc_y = 1.0f - 2.0f * py / static_cast<float>(height);
    return right * (ndc_x * tan_x) + up * (ndc_y * tan_y) - back;
  }
  glm::vec3 direction(std::uint32_t x, std::uint32_t y) const {
    return direction_at(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f);
  }
};

}  // namespace fovea::render::gi
