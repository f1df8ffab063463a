// SPDX-License-Identifier: Apache-2.0
#pragma once
// One image for the DOF tests: visible colour and depth plus a hidden (second, peeled) layer, handed
// to a method as the DofInput of renderer/dof/dof_image.h.
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/vec3.hpp>

#include "dof/dof_image.h"

namespace fovea::render::dof::test {

struct DofImage {
  std::uint32_t w = 0, h = 0;
  std::vector<glm::vec3> color, hidden_color;
  std::vector<float> depth, hidden_depth;

  // Every pixel `col` at depth `d`; the hidden layer starts empty (depth +inf) with colour `hidden_col`.
  DofImage(std::uint32_t width, std::uint32_t height, glm::vec3 col, float d, glm::vec3 hidden_col)
      : w(width), h(height), color(std::size_t{width} * height, col), hidden_color(color.size(), hidden_col),
        depth(color.size(), d), hidden_depth(color.size(), std::numeric_limits<float>::infinity()) {}
  // As above, the hidden layer's colour that of the visible one.
  DofImage(std::uint32_t width, std::uint32_t height, glm::vec3 col, float d) : DofImage(width, height, col, d, col) {}

  std::size_t at(std::uint32_t x, std::uint32_t y) const { return std::size_t{y} * w + x; }

  // The hidden layer is passed only when asked for; the vectors must outlive the returned input.
  DofInput input(const CocModel& coc, bool with_hidden = false) const {
    DofInput in;
    in.width = w;
    in.height = h;
    in.color = color.data();
    in.depth = depth.data();
    in.coc = coc;
    if (with_hidden) {
      in.hidden_color = hidden_color.data();
      in.hidden_depth = hidden_depth.data();
    }
    return in;
  }
};

}  // namespace fovea::render::dof::test
