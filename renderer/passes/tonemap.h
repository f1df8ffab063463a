// SPDX-License-Identifier: Apache-2.0
#pragma once
// HDR colour to the display image: exposure, an operator, the sRGB transfer function.
#include <string>

#include "backend/gbuffer.h"
#include "image/image.h"

namespace fovea::render {

struct TonemapParams {
  float exposure = 1.0f;
  // reinhard: c / (1 + c) per channel; clamp: min(c, 1); exponential: 1 - exp(-c) (Jensen &
  // Pedersen 2009, eq. 8.7, the hybrid renderer's operator); c = exposure x radiance.
  std::string op = "reinhard";
  bool exact = false;            // true: pow() per channel (the reference); false: 16K-entry table
};

void tonemap(const std::vector<glm::vec3>& hdr, std::uint32_t width, std::uint32_t height, const TonemapParams& p,
             Image8& out);

}  // namespace fovea::render
