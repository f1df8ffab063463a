// SPDX-License-Identifier: Apache-2.0
// The exact Gaussian gather (renderer/dof/gaussian_gather.h), the filter lee-mipmap approximates:
// a pinhole copies the input bit for bit, a point spreads into a spot whose variance is sigma^2 on a
// blur level and between two (the mixture's weight), energy is kept, a constant image stays constant
// under any depth, non-finite colour stays out of the result, and bad settings are named.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "dof/gaussian_gather.h"
#include "dof/lens.h"
#include "image_moments.h"

using namespace fovea::render;
using namespace fovea::render::dof;

namespace {

constexpr std::uint32_t kSize = 97;

CocModel lens() {
  CocModel m;
  m.focal_length_m = 0.05;
  m.aperture_m = 0.025;
  m.focus_m = 2;
  m.px_per_image_m = 200000;  // the far limit K = 128 px
  return m;
}

// The depth behind the focal plane whose CoC diameter is c px.
float depth_for_coc(const CocModel& m, double c) { return static_cast<float>(m.depth_far_for_coc(c)); }

using Spot = fovea::test::ImageMoments;
Spot spot(const RgbImage& img) { return fovea::test::image_moments(img, kSize, 1); }

struct Case {
  std::vector<glm::vec3> color;
  std::vector<float> depth;
  DofInput input(const CocModel& m) const {
    DofInput in;
    in.width = in.height = kSize;
    in.color = color.data();
    in.depth = depth.data();
    in.coc = m;
    return in;
  }
};

Case point_light(float depth_m) {
  Case c;
  c.color.assign(std::size_t{kSize} * kSize, glm::vec3(0.0f));
  c.depth.assign(c.color.size(), depth_m);
  c.color[std::size_t{kSize / 2} * kSize + kSize / 2] = glm::vec3(1.0f, 2.0f, 3.0f);
  return c;
}

}  // namespace

TEST(GaussianGather, APinholeCopiesTheInputBitForBit) {
  Case c = point_light(5.0f);
  for (std::size_t i = 0; i < c.color.size(); ++i) c.color[i] = glm::vec3(0.1f * static_cast<float>(i % 13), 0.5f, 1e6f);
  CocModel m = lens();
  m.aperture_m = 0;
  RgbImage out;
  gaussian_gather(c.input(m), {}, out);
  ASSERT_EQ(out.size(), c.color.size());
  for (std::size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], c.color[i]) << i;
}

// On a blur level (sigma = 0.25 x 2^k) and between two: the spot's variance is sigma^2 per axis
// (the mixture's weight is chosen for it), and the light's energy is kept.
TEST(GaussianGather, APointSpreadsIntoTheVarianceOfItsSigma) {
  const CocModel m = lens();
  for (const double sigma : {2.0, 3.1, 5.3, 8.0}) {
    for (const double per_coc : {0.5, 0.25}) {
      const Case c = point_light(depth_for_coc(m, sigma / per_coc));
      RgbImage out;
      GaussianGatherStats stats;
      gaussian_gather(c.input(m), {.sigma_per_coc = per_coc}, out, &stats);
      const Spot s = spot(out);
      EXPECT_NEAR(std::sqrt(s.var_x), sigma, 0.002 * sigma) << sigma << " " << per_coc;
      EXPECT_NEAR(std::sqrt(s.var_y), sigma, 0.002 * sigma) << sigma << " " << per_coc;
      EXPECT_NEAR(s.sum, 2.0, 1e-4) << sigma;
      EXPECT_NEAR(stats.max_sigma_px, sigma, 1e-3 * sigma);
      EXPECT_LE(stats.blurs, 2);  // one bin: only the two levels around sigma are blurred
    }
  }
}

TEST(GaussianGather, AConstantImageStaysConstantUnderAnyDepth) {
  Case c = point_light(5.0f);
  const CocModel m = lens();
  for (std::size_t i = 0; i < c.color.size(); ++i) {
    c.color[i] = glm::vec3(0.25f, 0.5f, 4.0f);
    c.depth[i] = i % 7 == 0 ? std::numeric_limits<float>::infinity() : 0.5f + 0.1f * static_cast<float>(i % 50);
  }
  RgbImage out;
  gaussian_gather(c.input(m), {}, out);
  for (std::size_t i = 0; i < out.size(); ++i) {
    ASSERT_NEAR(out[i].x, 0.25f, 1e-5f) << i;
    ASSERT_NEAR(out[i].y, 0.5f, 1e-5f) << i;
    ASSERT_NEAR(out[i].z, 4.0f, 1e-4f) << i;
  }
}

TEST(GaussianGather, NonFiniteColourAndDepthStayOut) {
  Case c = point_light(5.0f);
  const CocModel m = lens();
  c.color[3] = glm::vec3(std::nanf(""), std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity());
  c.depth[5] = std::nanf("");
  c.depth[7] = 0.0f;
  c.depth[9] = -1.0f;
  RgbImage out;
  gaussian_gather(c.input(m), {}, out);
  for (std::size_t i = 0; i < out.size(); ++i) {
    ASSERT_TRUE(std::isfinite(out[i].x) && std::isfinite(out[i].y) && std::isfinite(out[i].z)) << i;
  }
}

TEST(GaussianGather, RefusesBadSettings) {
  const Case c = point_light(5.0f);
  const CocModel m = lens();
  const auto refused = [&](const GaussianGatherSettings& s, const std::string& what) {
    RgbImage out;
    try {
      gaussian_gather(c.input(m), s, out);
      ADD_FAILURE() << what;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  refused({.sigma_per_coc = 0}, "sigma per CoC diameter");
  refused({.sigma_per_coc = std::nan("")}, "sigma per CoC diameter");
  refused({.steps_per_octave = 0}, "steps per octave");
  refused({.max_sigma_px = 0.1}, "largest sigma");
}
