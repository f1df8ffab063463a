// SPDX-License-Identifier: Apache-2.0
#pragma once
// The moments of a blur spot: the total (energy) and the per-axis variance about its centroid, of
// one colour channel of a square image. The DOF tests measure a blur's width this way.
#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

namespace fovea::test {

struct ImageMoments {
  double sum = 0, var_x = 0, var_y = 0;
};

inline ImageMoments image_moments(const std::vector<glm::vec3>& img, std::uint32_t size, int channel) {
  const auto value = [&](std::uint32_t x, std::uint32_t y) {
    return static_cast<double>(img[std::size_t{y} * size + x][channel]);
  };
  ImageMoments m;
  double sx = 0, sy = 0;
  for (std::uint32_t y = 0; y < size; ++y) {
    for (std::uint32_t x = 0; x < size; ++x) {
      m.sum += value(x, y);
      sx += value(x, y) * x;
      sy += value(x, y) * y;
    }
  }
  const double mx = sx / m.sum, my = sy / m.sum;
  for (std::uint32_t y = 0; y < size; ++y) {
    for (std::uint32_t x = 0; x < size; ++x) {
      m.var_x += value(x, y) * (x - mx) * (x - mx);
      m.var_y += value(x, y) * (y - my) * (y - my);
    }
  }
  m.var_x /= m.sum;
  m.var_y /= m.sum;
  return m;
}

}  // namespace fovea::test
