// SPDX-License-Identifier: Apache-2.0
// Schedl & Wimmer's layered DOF (renderer/dof/schedl_layered.h): pinhole exactness, a constant image
// stays constant, the focused layer stays sharp, the peeled layer fills partial occlusion, the layer
// count covers the depth range and honours its cap.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "dof/schedl_layered.h"
#include "dof_test_image.h"
#include "dof_lens.h"

namespace fovea::render::dof {
namespace {

using test::DofImage;

// Colour c at depth d everywhere; the peeled layer black and empty.
DofImage frame(std::uint32_t w, std::uint32_t h, glm::vec3 c, float d) { return DofImage(w, h, c, d, glm::vec3(0.0f)); }

// The image's hidden layer as Schedl's one peeled layer.
std::vector<PeeledLayer> peeled(const DofImage& f) { return {{f.hidden_color.data(), f.hidden_depth.data()}}; }

TEST(SchedlLayered, PinholeReturnsTheInputExactly) {
  DofImage f = frame(40, 30, glm::vec3(0.3f, 0.5f, 0.7f), 2.0f);
  for (std::size_t i = 0; i < f.depth.size(); ++i) f.depth[i] = 1.0f + static_cast<float>(i % 13);
  f.color[17] = glm::vec3(5.0f, 0.0f, 1.0f);
  CocModel pinhole = test::lens_with_k(20);
  pinhole.aperture_m = 0;
  RgbImage out;
  schedl_layered(f.input(pinhole), peeled(f), {}, out);
  for (std::size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], f.color[i]) << i;
}

TEST(SchedlLayered, AConstantImageStaysConstantWhateverTheDepths) {
  DofImage f = frame(64, 48, glm::vec3(0.2f, 0.4f, 0.8f), 2.0f);
  for (std::size_t i = 0; i < f.depth.size(); ++i) f.depth[i] = 0.5f + static_cast<float>((i * 7919) % 97) * 0.2f;
  RgbImage out;
  SchedlStats st;
  schedl_layered(f.input(test::lens_with_k(30)), {}, {}, out, &st);
  EXPECT_GT(st.layers, 3);
  for (const glm::vec3& c : out) {
    ASSERT_NEAR(c.r, 0.2f, 1e-5f);
    ASSERT_NEAR(c.b, 0.8f, 1e-5f);
  }
}

// A blurred bar 1 m away in front of a focused wall at 2 m: far from the bar the wall stays exact;
// at the bar the peeled layer (the wall behind it) shows through, where without it the bar's colour
// is all there is (Schedl & Wimmer's partial occlusion).
TEST(SchedlLayered, ThePeeledLayerFillsPartialOcclusionAndTheFocusLayerStaysSharp) {
  const std::uint32_t w = 96, h = 32;
  DofImage f = frame(w, h, glm::vec3(0.0f), 2.0f);
  for (std::uint32_t y = 0; y < h; ++y) {
    for (std::uint32_t x = 0; x < w; ++x) {
      const std::size_t i = std::size_t{y} * w + x;
      f.color[i] = (x / 4) % 2 ? glm::vec3(1.0f, 0.8f, 0.2f) : glm::vec3(0.1f, 0.2f, 0.9f);  // striped wall
      if (x >= 44 && x < 52) {  // the bar
        f.hidden_color[i] = f.color[i];
        f.hidden_depth[i] = 2.0f;
        f.color[i] = glm::vec3(0.0f);
        f.depth[i] = 1.0f;
      }
    }
  }
  const CocModel coc = test::lens_with_k(40);  // the bar's CoC: 40 px
  RgbImage with, without;
  schedl_layered(f.input(coc), peeled(f), {}, with);
  schedl_layered(f.input(coc), {}, {}, without);
  // The bar's centre: with the wall behind it, much of the wall shows (a thin lens would show ~3/4:
  // the 8 px bar covers ~1/4 of the 40 px disc; measured ~1/2), without it the bar's dark colour.
  const std::size_t centre = std::size_t{16} * w + 48;
  const float wall = glm::dot(f.hidden_color[centre], glm::vec3(1.0f));
  EXPECT_GT(glm::dot(with[centre], glm::vec3(1.0f)), 0.4f * wall);
  EXPECT_LT(glm::dot(without[centre], glm::vec3(1.0f)), 0.5f * glm::dot(with[centre], glm::vec3(1.0f)));
  // Far from the bar (at the end of its blur's tail), the focused wall is kept.
  for (std::uint32_t x : {2u, 90u}) {
    const std::size_t i = std::size_t{16} * w + x;
    EXPECT_NEAR(with[i].r, f.color[i].r, 1e-3f) << x;
    EXPECT_NEAR(with[i].b, f.color[i].b, 1e-3f) << x;
  }
}

TEST(SchedlLayered, LayersCoverTheDepthRangeUpToTheCap) {
  DofImage f = frame(32, 32, glm::vec3(0.5f), 2.0f);
  for (std::size_t i = 0; i < f.depth.size(); ++i) f.depth[i] = i % 2 ? 0.3f : 50.0f;
  RgbImage out;
  SchedlStats st;
  schedl_layered(f.input(test::lens_with_k(60)), {}, {}, out, &st);
  EXPECT_GT(st.focus_layer, 0);                 // layers in front of the focus
  EXPECT_GT(st.layers, st.focus_layer + 1);     // and behind it
  SchedlSettings few;
  few.max_layers = 3;
  schedl_layered(f.input(test::lens_with_k(60)), {}, few, out, &st);
  EXPECT_LE(st.layers, 3);
  for (const glm::vec3& c : out) ASSERT_TRUE(std::isfinite(c.r) && c.r >= 0.0f && c.r <= 0.5f + 1e-6f);
}

}  // namespace
}  // namespace fovea::render::dof
