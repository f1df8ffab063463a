// SPDX-License-Identifier: Apache-2.0
// Display passes: tone mapping (table vs exact reference, hard values) and overlays.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "passes/overlay.h"
#include "passes/tonemap.h"

using namespace fovea::render;

TEST(Tonemap, TableIsWithinOneLevelOfTheExactEncoding) {
  std::vector<glm::vec3> hdr;
  for (int i = 0; i < 200000; ++i) {
    const float v = std::pow(10.0f, -6.0f + 9.0f * static_cast<float>(i) / 200000.0f);  // 1e-6 .. 1e3
    hdr.emplace_back(v, v * 0.5f, v * 2.0f);
  }
  for (const char* op : {"reinhard", "clamp"}) {
    Image8 table, exact;
    TonemapParams p;
    p.op = op;
    tonemap(hdr, 1000, 200, p, table);
    p.exact = true;
    tonemap(hdr, 1000, 200, p, exact);
    int worst = 0;
    for (std::size_t i = 0; i < table.rgb.size(); ++i) worst = std::max(worst, std::abs(table.rgb[i] - exact.rgb[i]));
    EXPECT_LE(worst, 1) << op;
  }
}

TEST(Tonemap, HardValuesBecomeBlackOrWhiteNeverGarbage) {
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<glm::vec3> hdr = {{std::nanf(""), -1.0f, inf}, {-inf, 0.0f, 1e30f}};
  for (bool exact : {false, true}) {
    Image8 img;
    TonemapParams p;
    p.exact = exact;
    p.op = "clamp";
    tonemap(hdr, 2, 1, p, img);
    EXPECT_EQ(img.rgb[0], 0);    // NaN -> 0
    EXPECT_EQ(img.rgb[1], 0);    // negative -> 0
    EXPECT_EQ(img.rgb[2], 0);    // +Inf is not finite -> 0
    EXPECT_EQ(img.rgb[5], 255);  // huge finite -> white
  }
}

TEST(Overlay, DegreesToPixelsFollowsTheDisplayGeometry) {
  fovea::protocol::DisplayGeometry d;  // 531.3 mm wide at 650 mm
  // 1 degree at 650 mm is 11.35 mm; the 1920-pixel-wide image spans 531.3 mm.
  EXPECT_NEAR(degrees_to_pixels(d, 1920, 1.0), 11.345 / 531.3 * 1920, 0.05);
  EXPECT_NEAR(degrees_to_pixels(d, 960, 1.0), degrees_to_pixels(d, 1920, 1.0) / 2, 1e-9);
}

TEST(Overlay, GazeRingIsDrawnAtTheGazePointAndClippedAtEdges) {
  Image8 img;
  img.resize(200, 100);
  fovea::protocol::DisplayGeometry d;
  draw_gaze(img, d, GazeMark{0.25, 0.5, true}, 0.0);
  // Something red near (50, 50), nothing far away.
  bool near = false;
  for (std::uint32_t y = 40; y < 60; ++y) {
    for (std::uint32_t x = 40; x < 60; ++x) near |= img.get(x, y).r > 0.9f;
  }
  EXPECT_TRUE(near);
  EXPECT_EQ(img.get(150, 50).r, 0.0f);
  draw_gaze(img, d, GazeMark{-5.0, 7.0, false}, 20.0);  // far off-screen: no crash, clipped
  draw_gaze(img, d, GazeMark{1.0, 1.0, true}, 180.0);
}
