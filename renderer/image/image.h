// SPDX-License-Identifier: Apache-2.0
#pragma once
// Display images (8-bit sRGB) and image files: PNG for display images and G-buffer maps, OpenEXR
// for HDR colour.
#include <cstdint>
#include <glm/glm.hpp>
#include <string>
#include <vector>

namespace fovea::render {

struct Image8 {
  std::uint32_t width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // 3 bytes per pixel, row 0 at the top
  void resize(std::uint32_t w, std::uint32_t h) {
    width = w;
    height = h;
    rgb.assign(std::size_t{w} * h * 3, 0);
  }
  void set(std::uint32_t x, std::uint32_t y, glm::vec3 srgb01);  // clamps to [0, 1]
  glm::vec3 get(std::uint32_t x, std::uint32_t y) const;
};


// Throw std::runtime_error naming the file on failure.
void write_png(const std::string& path, const Image8& image);
void write_exr(const std::string& path, std::uint32_t width, std::uint32_t height, const std::vector<glm::vec3>& rgb);

}  // namespace fovea::render
