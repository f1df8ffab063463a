// SPDX-License-Identifier: Apache-2.0
// Hard cases of Schedl & Wimmer's layered DOF: non-finite and extreme inputs, degenerate sizes,
// CoCs larger than the image, focus at the focal length: finite output within [0, max input].
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "dof/schedl_layered.h"
#include "dof_test_image.h"
#include "dof_lens.h"

namespace fovea::render::dof {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

void expect_bounded(const RgbImage& out, float max_in) {
  for (const glm::vec3& c : out) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_TRUE(std::isfinite(c[k]));
      ASSERT_GE(c[k], 0.0f);
      ASSERT_LE(c[k], max_in * (1 + 1e-5f) + 1e-6f);
    }
  }
}

using test::DofImage;

RgbImage run(const DofImage& im, const CocModel& coc, const std::vector<PeeledLayer>& peeled = {}) {
  RgbImage out;
  schedl_layered(im.input(coc), peeled, {}, out);
  EXPECT_EQ(out.size(), std::size_t{im.w} * im.h);
  return out;
}

// The image's hidden layer as Schedl's one peeled layer.
std::vector<PeeledLayer> peeled(const DofImage& im) { return {{im.hidden_color.data(), im.hidden_depth.data()}}; }

TEST(SchedlLayeredStability, NonFiniteAndExtremeDepthsAndColours) {
  const std::vector<float> depths = {0.0f, -1.0f, kInf, -kInf, kNaN, 1e-30f, 1e30f, 3e38f, 1.0f, 2.0f};
  DofImage im(20, 20, glm::vec3(0.0f), 0.0f, glm::vec3(kNaN));
  for (std::size_t i = 0; i < 400; ++i) {
    im.depth[i] = depths[i % depths.size()];
    const float v = i % 7 == 0 ? kNaN : i % 11 == 0 ? kInf : i % 13 == 0 ? 1e6f : 0.25f * static_cast<float>(i % 5);
    im.color[i] = glm::vec3(v, 0.5f, -1.0f);
  }
  std::fill(im.hidden_depth.begin(), im.hidden_depth.end(), kNaN);
  expect_bounded(run(im, test::lens_with_k(30), peeled(im)), 1e6f);
}

TEST(SchedlLayeredStability, DegenerateSizes) {
  for (auto [w, h] : {std::pair{1u, 1u}, {1u, 37u}, {37u, 1u}, {2u, 1u}, {0u, 5u}}) {
    DofImage im(w, h, glm::vec3(0.4f), 0.0f);
    for (std::size_t i = 0; i < im.depth.size(); ++i) im.depth[i] = 0.5f + static_cast<float>(i);
    expect_bounded(run(im, test::lens_with_k(100)), 0.4f);
  }
}

TEST(SchedlLayeredStability, CocLargerThanTheImageAndOddFocus) {
  DofImage im(24, 16, glm::vec3(0.0f), 0.0f);
  for (std::size_t i = 0; i < im.color.size(); ++i) {
    im.color[i] = glm::vec3(static_cast<float>(i % 3) * 0.5f);
    im.depth[i] = 0.1f + static_cast<float>(i % 17);
  }
  for (double focus : {0.05, 0.0, -1.0, 1e9, static_cast<double>(kInf), static_cast<double>(kNaN)}) {
    CocModel m = test::lens_with_k(1e4, 2.0);
    m.focus_m = focus;
    expect_bounded(run(im, m), 1.0f);
  }
}

TEST(SchedlLayeredStability, RandomInputsStayFiniteAndBounded) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int t = 0; t < 30; ++t) {
    const auto w = static_cast<std::uint32_t>(1 + rng() % 40), h = static_cast<std::uint32_t>(1 + rng() % 30);
    DofImage im(w, h, glm::vec3(0.0f), 0.0f);
    float max_in = 0;
    for (std::size_t i = 0; i < im.color.size(); ++i) {
      im.color[i] = glm::vec3(u(rng), u(rng), u(rng)) * (t % 3 == 0 ? 100.0f : 1.0f);
      im.hidden_color[i] = glm::vec3(u(rng));
      max_in = std::max({max_in, im.color[i].x, im.color[i].y, im.color[i].z, im.hidden_color[i].x});
      im.depth[i] = 0.2f + 30.0f * u(rng);
      im.hidden_depth[i] = im.depth[i] + 5.0f * u(rng);
    }
    expect_bounded(run(im, test::lens_with_k(5.0 + 80.0 * static_cast<double>(u(rng)), 0.5 + 10.0 * static_cast<double>(u(rng))), peeled(im)),
                   max_in);
  }
}

}  // namespace
}  // namespace fovea::render::dof
