// SPDX-License-Identifier: Apache-2.0
#pragma once
// Comparing HDR images as a display shows them: PSNR of the colour clamped to [0, 1] (non-finite as
// 0), peak 1, over every channel; +infinity when equal. The GPU passes' tolerance against their CPU
// references (tests/gl/) is stated in it.
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>
#include <glm/vec3.hpp>

namespace fovea::render::test {

inline double psnr_shown(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b) {
  EXPECT_EQ(a.size(), b.size());
  const auto shown = [](float v) { return std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f; };
  double se = 0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i)
    for (int c = 0; c < 3; ++c) {
      const double d = static_cast<double>(shown(a[i][c])) - static_cast<double>(shown(b[i][c]));
      se += d * d;
    }
  if (se == 0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(3.0 * static_cast<double>(a.size()) / se);
}

}  // namespace fovea::render::test
