// SPDX-License-Identifier: Apache-2.0
// Lee 2009 chapter 5 splatting DOF under hard and random input: pinholes, depth 0 / inf / NaN,
// colour NaN / Inf / 1e6, CoCs larger than the image, degenerate sizes (1x1, 1xN, Nx1), absent or
// empty hidden layers, wild settings. The output is always finite, of the input's size, and within
// the range of the (finite) input colours.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "dof/lee_splat.h"
#include "dof_test_image.h"
#include "dof_lens.h"

using namespace fovea::render::dof;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNan = std::numeric_limits<float>::quiet_NaN();

CocModel lens(double k_px, double focus_m = 2.0) { return test::lens_with_k(k_px, focus_m); }

using test::DofImage;

// Grey (0.5) at 1 m; the hidden layer grey and empty.
DofImage blank(std::uint32_t w, std::uint32_t h) { return DofImage(w, h, glm::vec3(0.5f), 1.0f); }

float finite_max(const std::vector<glm::vec3>& v) {
  float m = 0;
  for (const auto& c : v) {
    for (int k = 0; k < 3; ++k) {
      if (std::isfinite(c[k])) m = std::max(m, c[k]);
    }
  }
  return m;
}

// Finite, non-negative for non-negative input, and no brighter than the brightest finite input
// colour (visible or hidden) times `gain`.
void expect_sane(const RgbImage& out, std::size_t n, float bound) {
  ASSERT_EQ(out.size(), n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_TRUE(std::isfinite(out[i][k])) << i;
      ASSERT_GE(out[i][k], 0.0f) << i;
      ASSERT_LE(out[i][k], bound * (1 + 1e-5f) + 1e-30f) << i;
    }
  }
}

}  // namespace

TEST(LeeSplatStability, PinholeWithNonFiniteColourIsInputWithZeros) {
  DofImage im = blank(9, 7);
  im.color[3] = glm::vec3(kNan, kInf, -kInf);
  im.color[4] = glm::vec3(1e6f, 0.0f, 3.0f);
  im.depth[5] = kNan;
  im.depth[6] = 0.0f;
  im.depth[7] = kInf;
  CocModel c = lens(30.0);
  c.aperture_m = 0;
  RgbImage out;
  lee_splat(im.input(c, true), LeeSplatSettings{}, out);
  ASSERT_EQ(out.size(), im.color.size());
  EXPECT_EQ(out[3], glm::vec3(0.0f));
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (i != 3) {
      EXPECT_EQ(out[i], im.color[i]) << i;
    }
  }
}

TEST(LeeSplatStability, HardDepthsAndColoursStayFinite) {
  DofImage im = blank(23, 17);
  const float depths[] = {0.0f, -1.0f, kInf, -kInf, kNan, 1e-30f, 1e30f, 2.0f, 0.3f};
  const glm::vec3 colours[] = {glm::vec3(kNan), glm::vec3(kInf), glm::vec3(1e6f), glm::vec3(0.2f),
                               glm::vec3(-kInf, 1.0f, 0.0f), glm::vec3(3e38f)};
  for (std::size_t i = 0; i < im.color.size(); ++i) {
    im.depth[i] = depths[i % 9];
    im.color[i] = colours[i % 6];
    im.hidden_depth[i] = depths[(i + 4) % 9];
    im.hidden_color[i] = colours[(i + 1) % 6];
  }
  for (const Aperture ap : {Aperture::Disc, Aperture::Gaussian, Aperture::Hexagon}) {
    for (const int reduce : {1, 2, 3}) {
      LeeSplatSettings s;
      s.aperture = ap;
      s.reduce = reduce;
      RgbImage out;
      lee_splat(im.input(lens(50.0), true), s, out);
      expect_sane(out, im.color.size(), 3e38f);
    }
  }
  // Only non-finite colours: all black.
  for (auto& c : im.color) c = glm::vec3(kNan, kInf, -kInf);
  RgbImage out;
  lee_splat(im.input(lens(50.0), false), LeeSplatSettings{}, out);
  for (const auto& c : out) ASSERT_EQ(c, glm::vec3(0.0f));
}

TEST(LeeSplatStability, Hdr1e6StaysFiniteAndBounded) {
  DofImage im = blank(31, 29);
  const CocModel coc = lens(40.0);
  for (std::size_t i = 0; i < im.color.size(); ++i) {
    im.depth[i] = static_cast<float>(0.5 + 0.1 * double(i % 37));
    im.color[i] = i % 11 == 0 ? glm::vec3(1e6f) : glm::vec3(0.01f);
  }
  RgbImage out;
  lee_splat(im.input(coc, false), LeeSplatSettings{}, out);
  expect_sane(out, im.color.size(), 1e6f);
}

TEST(LeeSplatStability, CocLargerThanImage) {
  // K = 1e5 px, clamped by max_coc_px = 1e4: every CoC is far beyond the 20 x 12 image. The
  // footprint is clamped to the image diagonal: every pixel covers the whole image.
  DofImage im = blank(20, 12);
  CocModel coc = lens(1e5);
  for (std::size_t i = 0; i < im.depth.size(); ++i) im.depth[i] = i % 2 ? 0.5f : 50.0f;
  RgbImage out;
  lee_splat(im.input(coc, false), LeeSplatSettings{}, out);
  for (const auto& c : out) {
    ASSERT_NEAR(c.x, 0.5f, 1e-5);
    ASSERT_NEAR(c.z, 0.5f, 1e-5);
  }
  // An unbounded max_coc_px and infinite focus distance as well.
  coc.max_coc_px = 1e300;
  for (const double f : {2.0, std::numeric_limits<double>::infinity(), 0.0, -1.0, std::nan("")}) {
    coc.focus_m = f;
    for (std::size_t i = 0; i < im.color.size(); ++i) im.color[i] = glm::vec3(float(i % 5));
    lee_splat(im.input(coc, false), LeeSplatSettings{}, out);
    expect_sane(out, im.color.size(), 4.0f);
  }
}

TEST(LeeSplatStability, DegenerateSizes) {
  const CocModel coc = lens(40.0);
  for (const auto& [w, h] : {std::pair{1u, 1u}, {1u, 37u}, {37u, 1u}, {2u, 1u}, {1u, 2u}, {0u, 5u}, {5u, 0u}}) {
    DofImage im = blank(w, h);
    for (std::size_t i = 0; i < im.depth.size(); ++i) {
      im.depth[i] = static_cast<float>(0.3 + 0.5 * double(i % 7));
      im.color[i] = glm::vec3(float(i % 3), 1.0f, 0.25f);
      im.hidden_color[i] = glm::vec3(0.0f, 1.0f, 2.0f);
      im.hidden_depth[i] = im.depth[i] + 1.0f;
    }
    for (const int reduce : {1, 2}) {
      LeeSplatSettings s;
      s.reduce = reduce;
      RgbImage out;
      lee_splat(im.input(coc, true), s, out);
      expect_sane(out, im.color.size(), 2.0f);
      for (const auto& c : out) ASSERT_NEAR(c.y, 1.0f, 1e-5);  // constant channel stays constant
    }
  }
  // Null colour: zeros; null depth: the (sanitised) colour.
  DofImage im = blank(4, 3);
  DofInput in = im.input(coc, false);
  RgbImage out;
  in.depth = nullptr;
  lee_splat(in, LeeSplatSettings{}, out);
  ASSERT_EQ(out.size(), 12u);
  EXPECT_EQ(out[0], glm::vec3(0.5f));
  in.color = nullptr;
  lee_splat(in, LeeSplatSettings{}, out);
  ASSERT_EQ(out.size(), 12u);
  EXPECT_EQ(out[0], glm::vec3(0.0f));
}

TEST(LeeSplatStability, HiddenLayerAbsentOrEmpty) {
  const CocModel coc = lens(40.0);
  DofImage im = blank(33, 21);
  for (std::size_t i = 0; i < im.depth.size(); ++i) {
    im.depth[i] = (i % 33) < 15 ? static_cast<float>(coc.depth_near_for_coc(12.0)) : 2.0f;
    im.color[i] = glm::vec3(float(i % 4) * 0.25f);
  }
  RgbImage none, empty;
  LeeSplatStats st;
  lee_splat(im.input(coc, false), LeeSplatSettings{}, none);
  lee_splat(im.input(coc, true), LeeSplatSettings{}, empty, &st);  // hidden depth all +inf
  EXPECT_EQ(st.hidden_used, 0u);
  for (std::size_t i = 0; i < none.size(); ++i) ASSERT_EQ(none[i], empty[i]) << i;
  // Hidden layer full of NaN depth and colour.
  for (std::size_t i = 0; i < im.depth.size(); ++i) {
    im.hidden_depth[i] = kNan;
    im.hidden_color[i] = glm::vec3(kNan);
  }
  lee_splat(im.input(coc, true), LeeSplatSettings{}, empty, &st);
  EXPECT_EQ(st.hidden_used, 0u);
  expect_sane(empty, im.color.size(), 0.75f);
  // Hidden colour NaN with valid depth: read as black, still finite.
  for (std::size_t i = 0; i < im.depth.size(); ++i) im.hidden_depth[i] = 2.0f;
  lee_splat(im.input(coc, true), LeeSplatSettings{}, empty, &st);
  EXPECT_GT(st.hidden_used, 0u);
  expect_sane(empty, im.color.size(), 0.75f);
}

TEST(LeeSplatStability, RandomInputsGiveFiniteBoundedResults) {
  std::mt19937_64 rng(20261123);
  std::uniform_int_distribution<int> size(1, 40), die(0, 9), coin(0, 1), red(1, 5), apd(0, 2);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float wild_depths[] = {0.0f, -3.0f, kInf, -kInf, kNan, 1e-20f, 1e20f};
  const glm::vec3 wild_colours[] = {glm::vec3(kNan), glm::vec3(kInf), glm::vec3(1e6f), glm::vec3(0.0f, kNan, 2.0f)};
  for (int run = 0; run < 120; ++run) {
    const auto w = static_cast<std::uint32_t>(size(rng)), h = static_cast<std::uint32_t>(size(rng));
    DofImage im = blank(w, h);
    const double k = std::pow(10.0, 3.0 * double(u(rng)));  // K from 1 to 1000 px
    CocModel coc = lens(k, 0.5 + 4.0 * double(u(rng)));
    if (die(rng) == 0) coc.aperture_m = 0;
    for (std::size_t i = 0; i < im.color.size(); ++i) {
      im.depth[i] = die(rng) == 0 ? wild_depths[std::size_t(die(rng)) % 7] : 0.2f + 6.0f * u(rng);
      im.color[i] = die(rng) == 0 ? wild_colours[std::size_t(die(rng)) % 4] : glm::vec3(u(rng), 3 * u(rng), u(rng));
      im.hidden_depth[i] =
          die(rng) < 3 ? kInf : (die(rng) == 0 ? wild_depths[std::size_t(die(rng)) % 7] : im.depth[i] + 3 * u(rng));
      im.hidden_color[i] =
          die(rng) == 0 ? wild_colours[std::size_t(die(rng)) % 4] : glm::vec3(u(rng), u(rng), 2 * u(rng));
    }
    LeeSplatSettings s;
    s.aperture = static_cast<Aperture>(apd(rng));
    s.reduce = red(rng);
    s.use_hidden = coin(rng) != 0;
    s.ldr_highlights = coin(rng) != 0;
    const float wild_delta[] = {0.0f, 0.4f, 5.0f, kNan, -1.0f};
    s.delta = double{wild_delta[std::size_t(die(rng)) % 5]};
    RgbImage out;
    lee_splat(im.input(coc, coin(rng) != 0), s, out);
    float bound = std::max(finite_max(im.color), finite_max(im.hidden_color));
    if (s.ldr_highlights) bound *= static_cast<float>(s.highlight_gain);
    expect_sane(out, im.color.size(), bound);
    if (HasFatalFailure()) {
      ADD_FAILURE() << "run " << run << " size " << w << "x" << h;
      return;
    }
  }
}
