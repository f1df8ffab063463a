// SPDX-License-Identifier: Apache-2.0
// Textures and the PBR material (scene/texture.h, scene/shading.h): mip chains averaged in linear
// light, the texture budget, wrap modes, trilinear sampling between levels, and the glTF 2.0
// appendix B BRDF against its formulas (reciprocity, a rough dielectric's Lambert limit, a smooth
// metal's finite peak).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "scene/shading.h"
#include "scene/texture.h"

using namespace fovea::render;

namespace {

std::vector<std::uint8_t> solid(std::uint32_t w, std::uint32_t h, std::uint8_t r, std::uint8_t g, std::uint8_t b,
                                std::uint8_t a = 255) {
  std::vector<std::uint8_t> px;
  for (std::uint32_t i = 0; i < w * h; ++i) px.insert(px.end(), {r, g, b, a});
  return px;
}

// A 2x2 image: black and white texels on the top row, white and black below.
std::vector<std::uint8_t> checker2() {
  return {0, 0, 0, 255, 255, 255, 255, 255, 255, 255, 255, 255, 0, 0, 0, 255};
}

}  // namespace

TEST(Texture, SrgbRoundTrip) {
  for (int i = 0; i < 256; ++i) {
    const float c = static_cast<float>(i) / 255.0f;
    EXPECT_NEAR(linear_to_srgb(srgb_to_linear(c)), c, 1e-5f);
  }
  EXPECT_NEAR(srgb_to_linear(128.0f / 255.0f), 0.2158605f, 1e-6f);
}

// The mip chain's sRGB encoding (a search over byte boundaries) rounds exactly as lround(encode * 255).
TEST(Texture, SrgbLevelsRoundAsTheExactEncoding) {
  for (int i = 0; i < 256; ++i) {
    for (int j = 0; j < 256; j += 5) {
      // A 2x1 image of bytes i and j: level 1 is their linear mean, encoded.
      const auto img = make_texture_image("p", 2, 1, {static_cast<std::uint8_t>(i), 0, 0, 255, static_cast<std::uint8_t>(j), 0, 0, 255},
                                          true).image;
      const float mean = 0.5f * (srgb_to_linear(static_cast<float>(i) / 255.0f) + srgb_to_linear(static_cast<float>(j) / 255.0f));
      ASSERT_EQ(img->levels[1].rgba[0], std::lround(linear_to_srgb(mean) * 255.0f)) << i << " " << j;
    }
  }
}

TEST(Texture, MipChainAveragesInLinearLight) {
  const MipChainResult srgb = make_texture_image("c", 2, 2, checker2(), true);
  ASSERT_TRUE(srgb.image);
  ASSERT_EQ(srgb.image->levels.size(), 2u);
  // Half white, half black is 0.5 in linear light: sRGB 188, not 128.
  EXPECT_EQ(srgb.image->levels[1].rgba[0], 188);
  const MipChainResult linear = make_texture_image("c", 2, 2, checker2(), false);
  EXPECT_EQ(linear.image->levels[1].rgba[0], 128);
  EXPECT_EQ(srgb.image->bytes(), mip_chain_bytes(2, 2));
  EXPECT_EQ(mip_chain_bytes(4, 1), 16u + 8u + 4u);
  EXPECT_EQ(mip_chain_bytes(3, 5), 60u + 8u + 4u);  // 3x5, 1x2, 1x1
}

TEST(Texture, BudgetDropsTheLargestLevels) {
  const MipChainResult r = make_texture_image("big", 64, 32, solid(64, 32, 10, 20, 30), false, mip_chain_bytes(16, 8));
  ASSERT_TRUE(r.image);
  EXPECT_EQ(r.dropped_levels, 2u);
  EXPECT_EQ(r.image->levels[0].width, 16u);
  EXPECT_EQ(r.image->levels[0].height, 8u);
  EXPECT_FALSE(make_texture_image("none", 4, 4, solid(4, 4, 0, 0, 0), false, 3).image);  // not even 1x1 fits
  EXPECT_FALSE(make_texture_image("short", 4, 4, solid(2, 2, 0, 0, 0), false).image);   // wrong byte count
}

TEST(Texture, WrapModesAndNearestMagnification) {
  // 2x1: black, white.
  const auto img = make_texture_image("w", 2, 1, {0, 0, 0, 255, 255, 255, 255, 255}, false).image;
  TextureSampler nearest;
  nearest.mag_nearest = true;
  EXPECT_FLOAT_EQ(sample_texture(*img, nearest, {0.25f, 0.5f}, -1).r, 0.0f);
  EXPECT_FLOAT_EQ(sample_texture(*img, nearest, {0.75f, 0.5f}, -1).r, 1.0f);
  EXPECT_FLOAT_EQ(sample_texture(*img, nearest, {1.25f, 0.5f}, -1).r, 0.0f);  // repeat
  nearest.wrap_s = TextureWrap::ClampToEdge;
  EXPECT_FLOAT_EQ(sample_texture(*img, nearest, {1.25f, 0.5f}, -1).r, 1.0f);
  nearest.wrap_s = TextureWrap::MirroredRepeat;
  EXPECT_FLOAT_EQ(sample_texture(*img, nearest, {1.25f, 0.5f}, -1).r, 1.0f);  // mirrored: white again
  EXPECT_FLOAT_EQ(sample_texture(*img, nearest, {1.75f, 0.5f}, -1).r, 0.0f);
  // Bilinear halfway between the two texel centres, with repeat wrapping past the edge.
  TextureSampler linear;
  EXPECT_NEAR(sample_texture(*img, linear, {0.5f, 0.5f}, 0).r, 0.5f, 1e-6f);
  EXPECT_NEAR(sample_texture(*img, linear, {0.0f, 0.5f}, 0).r, 0.5f, 1e-6f);  // between texel 1 (wrapped) and 0
  // Hostile coordinates stay finite.
  const glm::vec4 huge = sample_texture(*img, linear, {1e30f, -1e30f}, 1e30f);
  EXPECT_TRUE(std::isfinite(huge.r));
  EXPECT_TRUE(std::isfinite(sample_texture(*img, linear, {NAN, 0}, NAN).r));
}

TEST(Texture, TrilinearBlendsLevels) {
  const auto img = make_texture_image("c", 2, 2, checker2(), false).image;  // level 1: 128
  TextureSampler s;
  s.wrap_s = s.wrap_t = TextureWrap::ClampToEdge;
  const float l0 = sample_texture(*img, s, {0.25f, 0.25f}, 0).r;  // texel (0, 0): black
  const float l1 = sample_texture(*img, s, {0.25f, 0.25f}, 1).r;
  EXPECT_FLOAT_EQ(l0, 0.0f);
  EXPECT_NEAR(l1, 128.0f / 255.0f, 1e-6f);
  EXPECT_NEAR(sample_texture(*img, s, {0.25f, 0.25f}, 0.25f).r, 0.25f * l1, 1e-6f);
  EXPECT_NEAR(sample_texture(*img, s, {0.25f, 0.25f}, 7).r, l1, 1e-6f);  // past the last level
  EXPECT_FLOAT_EQ(texel_area_lod(*img), 1.0f);                         // 0.5 log2(2 * 2)
}

TEST(PbrBrdf, ReciprocalAndRoughDielectricIsNearlyLambert) {
  SurfaceSample s;
  s.base_color = glm::vec3(0.5f, 0.25f, 1.0f);
  s.metallic = 0;
  s.roughness = 1;
  const glm::vec3 l = glm::normalize(glm::vec3(0.3f, 0.2f, 1.0f)), v = glm::normalize(glm::vec3(-0.5f, 0.1f, 1.0f));
  const glm::vec3 a = pbr_brdf(s, l, v), b = pbr_brdf(s, v, l);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-6f);
  // At normal incidence and view: F = 0.04, D = 1/pi, V = 1/4 (alpha 1): f = 0.96 c/pi + 0.04/(4 pi).
  const glm::vec3 n(0, 0, 1);
  const glm::vec3 f = pbr_brdf(s, n, n);
  const float pi = std::numbers::pi_v<float>;
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(f[c], 0.96f * s.base_color[c] / pi + 0.04f / (4 * pi), 1e-6f);
  EXPECT_EQ(pbr_brdf(s, glm::vec3(0, 0, -1), n), glm::vec3(0.0f));  // light below the surface
}

TEST(PbrBrdf, SmoothMetalHasAFiniteColouredPeakAndNoDiffuse) {
  SurfaceSample s;
  s.base_color = glm::vec3(1.0f, 0.5f, 0.0f);
  s.metallic = 1;
  s.roughness = 0;  // alpha floored at 1e-3
  const glm::vec3 n(0, 0, 1);
  const glm::vec3 peak = pbr_brdf(s, n, n);
  EXPECT_TRUE(std::isfinite(peak.r));
  EXPECT_GT(peak.r, 1e4f);
  EXPECT_NEAR(peak.g / peak.r, 0.5f, 1e-4f);  // F0 = base colour
  EXPECT_EQ(peak.b, 0.0f);
  const glm::vec3 off = pbr_brdf(s, glm::normalize(glm::vec3(0.5f, 0, 1)), n);
  EXPECT_LT(off.r, 1e-8f * peak.r);  // no diffuse lobe; GGX's tail 27° off the peak is tiny
}

TEST(PbrEvaluate, FactorsTexturesAndBackFaces) {
  Scene scene;
  // 1x1 metallic-roughness texel: G roughness 0.5, B metallic 1.
  scene.textures.push_back(make_texture_image("mr", 1, 1, {0, 128, 255, 255}, false).image);
  PbrParameters m;
  m.base_color = glm::vec4(0.5f, 0.5f, 0.5f, 0.8f);
  m.metallic = 0.5f;
  m.roughness = 1.0f;
  m.metallic_roughness_texture = TextureBinding{0, 0, {}};
  m.emissive = glm::vec3(2, 0, 0);
  SurfacePoint p;
  p.color = glm::vec4(1, 0, 1, 0.5f);
  SurfaceSample s = evaluate_pbr(scene, m, p);
  EXPECT_EQ(s.base_color, glm::vec3(0.5f, 0, 0.5f));
  EXPECT_FLOAT_EQ(s.alpha, 0.4f);
  EXPECT_FLOAT_EQ(s.metallic, 0.5f);
  EXPECT_NEAR(s.roughness, 128.0f / 255.0f, 1e-6f);
  EXPECT_EQ(s.emission, glm::vec3(2, 0, 0));
  EXPECT_FLOAT_EQ(pbr_alpha(scene, m, p), 0.4f);
  p.back_face = true;
  EXPECT_EQ(evaluate_pbr(scene, m, p).normal, glm::vec3(0, 0, -1));
  // A binding past the scene's textures samples as 1 (the factor alone).
  m.metallic_roughness_texture->texture = 7;
  EXPECT_FLOAT_EQ(evaluate_pbr(scene, m, p).roughness, 1.0f);
}
