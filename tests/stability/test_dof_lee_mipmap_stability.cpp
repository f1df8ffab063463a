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
#include "dof_lens.h"

namespace fovea::render::dof {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

CocModel lens_k(double k_px, double focus_m = 2.0) { return test::lens_with_k(k_px, focus_m); }

struct Image {
  std::uint32_t w = 0, h = 0;
  std::vector<glm::vec3> c;
  std::vector<float> z;
  Image(std::uint32_t w_, std::uint32_t h_, glm::vec3 col, float depth)
      : w(w_), h(h_), c(std::size_t{w_} * h_, col), z(std::size_t{w_} * h_, depth) {}
  DofInput input(const CocModel& m) const { return DofInput{w, h, c.data(), z.data(), m, nullptr, nullptr}; }
};

float clean(float v) { return std::isfinite(v) ? std::max(v, 0.0f) : 0.0f; }

// Finite, non-negative and per channel no brighter than the brightest finite input.
void expect_bounded(const Image& im, const RgbImage& out, const char* what) {
  ASSERT_EQ(out.size(), im.c.size()) << what;
  glm::vec3 mx(0.0f);
  for (const auto& c : im.c) mx = glm::max(mx, glm::vec3(clean(c.x), clean(c.y), clean(c.z)));
  for (std::size_t i = 0; i < out.size(); ++i)
    for (int ch = 0; ch < 3; ++ch) {
      const float v = out[i][ch];
      ASSERT_TRUE(std::isfinite(v)) << what << " pixel " << i;
      ASSERT_GE(v, 0.0f) << what << " pixel " << i;
      ASSERT_LE(v, mx[ch]) << what << " pixel " << i;
    }
}

RgbImage run(const Image& im, const CocModel& m, const LeeMipmapSettings& s = {}) {
  RgbImage out;
  lee_mipmap(im.input(m), s, out);
  return out;
}

TEST(LeeMipmapStability, PinholeCopiesFiniteInputAndZeroesNonFinite) {
  Image im(31, 17, glm::vec3(0.25f, 3.0f, 1e6f), 1.0f);
  im.c[5] = {kNaN, kInf, -kInf};
  im.c[6] = {-1.0f, 2.0f, 0.0f};
  im.z[7] = kNaN;
  CocModel pin = lens_k(300);
  pin.aperture_m = 0;
  const RgbImage out = run(im, pin);
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (i == 5) {
      EXPECT_EQ(out[i], glm::vec3(0.0f));
    } else {
      EXPECT_EQ(0, std::memcmp(&out[i], &im.c[i], sizeof(glm::vec3))) << i;
    }
  }
  pin = lens_k(300);
  pin.px_per_image_m = 0;
  const RgbImage out2 = run(im, pin);
  EXPECT_EQ(0, std::memcmp(&out2[0], &im.c[0], sizeof(glm::vec3)));
}

TEST(LeeMipmapStability, EverythingInFocus) {
  const CocModel lens = lens_k(300, 4.0);
  Image im(40, 30, glm::vec3(0.5f), 4.0f);
  im.c[3] = {9.0f, 0.0f, 1.0f};
  const RgbImage out = run(im, lens);
  EXPECT_EQ(0, std::memcmp(out.data(), im.c.data(), out.size() * sizeof(glm::vec3)));
}

TEST(LeeMipmapStability, SpecialDepths) {
  const CocModel lens = lens_k(300);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float specials[] = {0.0f, -0.0f, kInf, -kInf, kNaN, -1.0f, 1e-30f, 1e30f, 2.0f, 0.05f};
  Image im(64, 48, glm::vec3(0.0f), 1.0f);
  for (std::size_t i = 0; i < im.c.size(); ++i) {
    im.c[i] = {u(rng), u(rng), u(rng)};
    im.z[i] = specials[rng() % std::size(specials)];
  }
  for (bool smooth : {false, true})
    for (bool aniso : {false, true}) {
      LeeMipmapSettings s;
      s.smooth_foreground = smooth;
      s.anisotropic = aniso;
      expect_bounded(im, run(im, lens, s), "special depths");
    }
  for (float d : specials) {
    Image flat(33, 21, glm::vec3(0.3f, 0.6f, 0.9f), d);
    flat.c[100] = glm::vec3(5.0f);
    expect_bounded(flat, run(flat, lens), "flat special depth");
  }
}

TEST(LeeMipmapStability, NonFiniteColourReadsAsZero) {
  const CocModel lens = lens_k(300);
  Image im(50, 40, glm::vec3(0.5f), static_cast<float>(lens.depth_far_for_coc(20.0)));
  im.c[10] = {kNaN, kInf, -kInf};
  im.c[500] = {kInf, kInf, kInf};
  im.c[900] = {kNaN, kNaN, kNaN};
  const RgbImage out = run(im, lens);
  expect_bounded(im, out, "non-finite colour");
  // A NaN read as 0 darkens its neighbourhood a little; it never spreads as NaN.
  EXPECT_LT(out[10].x, 0.5f);
}

TEST(LeeMipmapStability, HdrHighlight) {
  const CocModel lens = lens_k(300);
  Image im(80, 60, glm::vec3(0.01f), static_cast<float>(lens.depth_far_for_coc(30.0)));
  im.c[30 * 80 + 40] = glm::vec3(1e6f);
  im.c[31 * 80 + 40] = glm::vec3(1e6f, 0.0f, 3e5f);
  for (bool geometric : {true, false}) {
    LeeMipmapSettings s;
    s.geometric = geometric;
    expect_bounded(im, run(im, lens, s), "HDR");
  }
  Image all(40, 40, glm::vec3(1e6f), static_cast<float>(lens.depth_far_for_coc(30.0)));
  expect_bounded(all, run(all, lens), "HDR constant");
}

TEST(LeeMipmapStability, CocLargerThanImage) {
  CocModel lens = lens_k(1e5);
  Image im(24, 16, glm::vec3(0.2f), 50.0f);
  for (std::size_t i = 0; i < im.c.size(); i += 3) im.c[i] = glm::vec3(1.0f, 0.0f, 0.5f);
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
    Image im(w, h, glm::vec3(0.4f), 100.0f);
    for (std::size_t i = 0; i < im.c.size(); i += 2) im.c[i] = glm::vec3(1.0f, 0.1f, 0.0f);
    for (std::size_t i = 1; i < im.z.size(); i += 3) im.z[i] = 0.3f;
    const RgbImage out = run(im, lens);
    expect_bounded(im, out, "tiny");
    if (w * h == 1) {
      EXPECT_EQ(out[0], im.c[0]);
    }
  }
  Image empty(0, 0, glm::vec3(0), 1);
  EXPECT_TRUE(run(empty, lens).empty());
}

TEST(LeeMipmapStability, FocusAtFocalLengthAndOtherOddLenses) {
  for (double focus : {0.05, 0.04, 0.0, -1.0, 1e-9, std::numeric_limits<double>::infinity(),
                       std::numeric_limits<double>::quiet_NaN()}) {
    CocModel lens = lens_k(300);
    lens.focus_m = focus;
    Image im(40, 30, glm::vec3(0.3f), 1.0f);
    for (std::size_t i = 0; i < im.z.size(); ++i) im.z[i] = 0.02f * static_cast<float>(i % 200);
    for (std::size_t i = 0; i < im.c.size(); i += 7) im.c[i] = glm::vec3(2.0f);
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
    Image im(w, h, glm::vec3(0), 1);
    const bool dirty = trial % 3 == 0;
    for (std::size_t i = 0; i < im.c.size(); ++i) {
      im.c[i] = {10 * u(rng) * u(rng), u(rng), 1e3f * u(rng) * u(rng) * u(rng)};
      im.z[i] = 0.1f + 30.0f * u(rng) * u(rng);
      if (dirty && rng() % 10 == 0) im.c[i][static_cast<int>(rng() % 3)] = specials[rng() % std::size(specials)];
      if (dirty && rng() % 10 == 0) im.z[i] = specials[rng() % std::size(specials)];
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
