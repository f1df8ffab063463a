// SPDX-License-Identifier: Apache-2.0
#pragma once
// What every depth-of-field method reads and writes: a pinhole image (linear HDR colour and
// view-axis depth, row-major, row 0 at the top) and the lens's CoC model; out comes linear HDR
// colour of the same size. No method lets NaN or Inf through: non-finite colour reads as black,
// non-finite depth as the far limit of the CoC model.
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "dof/lens.h"

namespace fovea::render::dof {

struct DofInput {
  std::uint32_t width = 0, height = 0;
  const glm::vec3* color = nullptr;  // width * height
  const float* depth = nullptr;      // width * height, metres along the view axis
  CocModel coc;
  // Optional second layer: the nearest surface behind the visible one per pixel (depth peeling),
  // for methods that fill partial occlusion from it (Lee's hidden image H, §5.1.2). Null: absent.
  const glm::vec3* hidden_color = nullptr;
  const float* hidden_depth = nullptr;  // +inf where nothing lies behind
  std::size_t pixels() const { return std::size_t{width} * height; }
};

using RgbImage = std::vector<glm::vec3>;

}  // namespace fovea::render::dof
