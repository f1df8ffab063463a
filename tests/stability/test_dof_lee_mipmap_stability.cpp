// SPDX-License-Identifier: Apache-2.0
// Lee 2009 ch. 4 depth of field (renderer/dof/lee_mipmap.h) on hard inputs: the output is finite
// and within [0, max input] always, and a pinhole copies the input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "dof/lee_mipmap.h"
#include "dof_test_image.h"
#include "dof_lens.h"

namespace fovea::render::dof {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

CocModel lens_k(double k_px, double focus_m = 2.0) { return test::lens_with_k(k_px, focus_m); }

using test::DofImage;

float clean(float v) { return std::isfinite(v) ? std::max(v, 0.0f) : 0.0f; }

// Finite, non-negative and per channel no brighter than the brightest finite input.
void expect_bounded(const DofImage& im, const RgbImage& out, const char* what) {
  ASSERT_EQ(out.size(), im.color.size()) << what;
  glm::vec3 mx(0.0f);
  for (const auto& c : im.color) mx = glm::max(mx, glm::vec3(clean(c.x), clean(c.y), clean(c.z)));
  for (std::size_t i = 0; i < out.size(); ++i)
    for (int ch = 0; ch < 3; ++ch) {
      const float v = out[i][ch];
      ASSERT_TRUE(std::isfinite(v)) << what << " pixel " << i;
      ASSERT_GE(v, 0.0f) << what << " pixel " << i;
      ASSERT_LE(v, mx[ch]) << what << " pixel " << i;
    }
}

RgbImage run(const DofImage& im, const CocModel& m, const LeeMipmapSettings& s = {}) {
  RgbImage out;
  lee_mipmap(im.input(m), s, out);
  return out;
}

TEST(LeeMipmapStability, PinholeCopiesFiniteInputAndZeroesNonFinite) {
  DofImage im(31, 17, glm::vec3(0.25f, 3.0f, 1e6f), 1.0f);
  im.color[5] = {kNaN, kInf, -kInf};
  im.color[6] = {-1.0f, 2.0f, 0.0f};
  im.depth[7] = kNaN;
  CocModel pin = lens_k(300);
  pin.aperture_m = 0;
  const RgbImage out = run(im, pin);
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (i == 5) {
      EXPECT_EQ(out[i], glm::vec3(0.0f));
    } else {
      EXPECT_EQ(0, std::memcmp(&out[i], &im.color[i], sizeof(glm::vec3))) << i;
    }
  }
  pin = lens_k(300);
  pin.px_per_image_m = 0;
  const RgbImage out2 = run(im, pin);
  EXPECT_EQ(0, std::memcmp(&out2[0], &im.color[0], sizeof(glm::vec3)));
}

TEST(LeeMipmapStability, EverythingInFocus) {
  const CocModel lens = lens_k(300, 4.0);
  DofImage im(40, 30, glm::vec3(0.5f), 4.0f);
  im.color[3] = {9.0f, 0.0f, 1.0f};
  const RgbImage out = run(im, lens);
  EXPECT_EQ(0, std::memcmp(out.data(), im.color.data(), out.size() * sizeof(glm::vec3)));
}

TEST(LeeMipmapStability, SpecialDepths) {
  const CocModel lens = lens_k(300);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float specials[] = {0.0f, -0.0f, kInf, -kInf, kNaN, -1.0f, 1e-30f, 1e30f, 2.0f, 0.05f};
  DofImage im(64, 48, glm::vec3(0.0f), 1.0f);
  for (std::size_t i = 0; i < im.color.size(); ++i) {
    im.color[i] = {u(rng), u(rng), u(rng)};
    im.depth[i] = specials[rng() % std::size(specials)];
  }
  for (bool smooth : {false, true})
    for (bool aniso : {false, true}) {
      LeeMipmapSettings s;
      s.smooth_foreground = smooth;
      s.anisotropic = aniso;
      expect_bounded(im, run(im, lens, s), "special depths");
    }
  for (float d : specials) {
    DofImage flat(33, 21, glm::vec3(0.3f, 0.6f, 0.9f), d);
    flat.color[100] = glm::vec3(5.0f);
    expect_bounded(flat, run(flat, lens), "flat special depth");
  }
}

TEST(LeeMipmapStability, NonFiniteColourReadsAsZero) {
  const CocModel lens = lens_k(300);
  DofImage im(50, 40, glm::vec3(0.5f), static_cast<float>(lens.depth_far_for_coc(20.0)));
  im.color[10] = {kNaN, kInf, -kInf};
  im.color[500] = {kInf, kInf, kInf};
  im.color[900] = {kNaN, kNaN, kNaN};
  const RgbImage out = run(im, lens);
  expect_bounded(im, out, "non-finite colour");
  // A NaN read as 0 darkens its neighbourhood a little; it never spreads as NaN.
  EXPECT_LT(out[10].x, 0.5f);
}

TEST(LeeMipmapStability, HdrHighlight) {
  const CocModel lens = lens_k(300);
  DofImage im(80, 60, glm::vec3(0.01f), static_cast<float>(lens.depth_far_for_coc(30.0)));
  im.color[30 * 80 + 40] = glm::vec3(1e6f);
  im.color[31 * 80 + 40] = glm::vec3(1e6f, 0.0f, 3e5f);
  for (bool geometric : {true, false}) {
    LeeMipmapSettings s;
    s.geometric = geometric;
    expect_bounded(im, run(im, lens, s), "HDR");
  }
  DofImage all(40, 40, glm::vec3(1e6f), static_cast<float>(lens.depth_far_for_coc(30.0)));
  expect_bounded(all, run(all, lens), "HDR constant");
}

TEST(LeeMipmapStability, CocLargerThanImage) {
  CocModel lens = lens_k(1e5);
  DofImage im(24, 16, glm::vec3(0.2f), 50.0f);
  for (std::size_t i = 0; i < im.color.size(); i += 3) im.color[i] = glm::vec3(1.0f, 0.0f, 0.5f);
  LeeMipmapStats st;
  RgbImage out;
  lee_mipmap(im.input(lens), {}, out, &st);
  expect_bounded(im, out, "huge CoC");
  EXPECT_EQ(st.levels, 4);  // the top level of a 24 x 16 mipmap
  lens.max_coc_px = 1e30;
  expect_bounded(im, run(im, lens), "unclamped CoC");
}

TEST(LeeMipmapStability, TinyAndDegenerateSizes) {
  const CocModel lens = lens_k(300);
  for (auto [w, h] : {std::pair{1u, 1u}, {1u, 2u}, {2u, 1u}, {1u, 37u}, {53u, 1u}, {2u, 2u}, {3u, 5u}, {1u, 1024u}}) {
    DofImage im(w, h, glm::vec3(0.4f), 100.0f);
    for (std::size_t i = 0; i < im.color.size(); i += 2) im.color[i] = glm::vec3(1.0f, 0.1f, 0.0f);
    for (std::size_t i = 1; i < im.depth.size(); i += 3) im.depth[i] = 0.3f;
    const RgbImage out = run(im, lens);
    expect_bounded(im, out, "tiny");
    if (w * h == 1) {
      EXPECT_EQ(out[0], im.color[0]);
    }
  }
  DofImage empty(0, 0, glm::vec3(0), 1);
  EXPECT_TRUE(run(empty, lens).empty());
}

TEST(LeeMipmapStability, FocusAtFocalLengthAndOtherOddLenses) {
  for (double focus : {0.05, 0.04, 0.0, -1.0, 1e-9, std::numeric_limits<double>::infinity(),
                       std::numeric_limits<double>::quiet_NaN()}) {
    CocModel lens = lens_k(300);
    lens.focus_m = focus;
    DofImage im(40, 30, glm::vec3(0.3f), 1.0f);
    for (std::size_t i = 0; i < im.depth.size(); ++i) im.depth[i] = 0.02f * static_cast<float>(i % 200);
    for (std::size_t i = 0; i < im.color.size(); i += 7) im.color[i] = glm::vec3(2.0f);
    expect_bounded(im, run(im, lens), "odd lens");
  }
}

TEST(LeeMipmapStability, RandomInputs) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::uniform_real_distribution<double> ud(0.0, 1.0);
  const float specials[] = {kNaN, kInf, -kInf, 0.0f, 1e6f, -3.0f};
  LeeMipmap reused;
  for (int trial = 0; trial < 60; ++trial) {
    const auto w = 1 + static_cast<std::uint32_t>(rng() % 90), h = 1 + static_cast<std::uint32_t>(rng() % 70);
    DofImage im(w, h, glm::vec3(0), 1);
    const bool dirty = trial % 3 == 0;
    for (std::size_t i = 0; i < im.color.size(); ++i) {
      im.color[i] = {10 * u(rng) * u(rng), u(rng), 1e3f * u(rng) * u(rng) * u(rng)};
      im.depth[i] = 0.1f + 30.0f * u(rng) * u(rng);
      if (dirty && rng() % 10 == 0) im.color[i][static_cast<int>(rng() % 3)] = specials[rng() % std::size(specials)];
      if (dirty && rng() % 10 == 0) im.depth[i] = specials[rng() % std::size(specials)];
    }
    const CocModel lens = lens_k(5.0 + 400.0 * ud(rng), 0.2 + 10.0 * ud(rng));
    LeeMipmapSettings s;
    s.anisotropic = rng() % 2;
    s.smooth_foreground = rng() % 4 != 0;
    s.circular = rng() % 4 != 0;
    s.geometric = rng() % 4 != 0;
    s.delta = 2.0 * ud(rng);
    s.max_level = static_cast<int>(rng() % 3);
    RgbImage a, b;
    lee_mipmap(im.input(lens), s, a);
    expect_bounded(im, a, "random");
    // A reused instance (buffers from earlier, other-sized frames) gives the same image.
    reused.run(im.input(lens), s, b);
    ASSERT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(glm::vec3))) << "trial " << trial;
  }
}

}  // namespace
}  // namespace fovea::render::dof
