// SPDX-License-Identifier: Apache-2.0
// Lee 2009 ch. 4 depth of field (renderer/dof/lee_mipmap.h): exactness, blur shape against a
// brute-force Gaussian, intensity leakage (Fig. 4.7) and foreground smoothing (Fig. 4.9).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "dof/lee_mipmap.h"
#include "dof_test_image.h"
#include "dof_lens.h"

namespace fovea::render::dof {
namespace {

CocModel lens_k(double k_px, double focus_m = 2.0) { return test::lens_with_k(k_px, focus_m); }
// The depth behind the focal plane whose CoC is c (c < K).
float depth_for_coc(const CocModel& m, double c) { return static_cast<float>(m.depth_far_for_coc(c)); }

using test::DofImage;

RgbImage run(const DofImage& im, const CocModel& m, const LeeMipmapSettings& s = {}) {
  RgbImage out;
  lee_mipmap(im.input(m), s, out);
  return out;
}

TEST(LeeMipmap, PinholeIsBitExact) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> col(0.0f, 50.0f), dep(0.1f, 100.0f);
  DofImage im(97, 61, glm::vec3(0), 1);
  for (auto& c : im.color) c = {col(rng), col(rng), col(rng)};
  for (auto& z : im.depth) z = dep(rng);
  CocModel pin = lens_k(200);
  pin.aperture_m = 0;
  const RgbImage out = run(im, pin);
  ASSERT_EQ(out.size(), im.color.size());
  EXPECT_EQ(0, std::memcmp(out.data(), im.color.data(), out.size() * sizeof(glm::vec3)));
  // C = 0 everywhere: every pixel exactly at the focus distance.
  const CocModel lens = lens_k(200, 3.0);
  std::fill(im.depth.begin(), im.depth.end(), 3.0f);
  const RgbImage out2 = run(im, lens);
  EXPECT_EQ(0, std::memcmp(out2.data(), im.color.data(), out2.size() * sizeof(glm::vec3)));
}

TEST(LeeMipmap, ConstantImageStaysConstant) {
  std::mt19937 rng(3);
  const glm::vec3 c(0.3f, 0.5f, 7.0f);
  const CocModel lens = lens_k(400);
  std::uniform_real_distribution<double> coc(0.0, 120.0);
  for (int variant = 0; variant < 4; ++variant) {
    DofImage im(160, 90, c, 2);
    for (auto& z : im.depth) z = rng() % 2 ? depth_for_coc(lens, coc(rng)) : static_cast<float>(lens.depth_near_for_coc(coc(rng)));
    LeeMipmapSettings s;
    s.anisotropic = variant & 1;
    s.circular = variant & 2;
    const RgbImage out = run(im, lens, s);
    float worst = 0;
    for (const auto& o : out) worst = std::max({worst, std::fabs(o.x - c.x) / c.x, std::fabs(o.y - c.y) / c.y, std::fabs(o.z - c.z) / c.z});
    EXPECT_LT(worst, 1e-5f) << "variant " << variant;
  }
}

// The 10 %-90 % rise of a horizontal step edge (0.2 -> 1.0 at x = 128) on row y.
struct EdgeProfile {
  bool monotonic = true;
  int width = 0;
};
EdgeProfile step_edge(double coc_px, const LeeMipmapSettings& s = {}) {
  const CocModel lens = lens_k(400);
  DofImage im(256, 48, glm::vec3(0.2f), depth_for_coc(lens, coc_px));
  for (std::uint32_t y = 0; y < im.h; ++y)
    for (std::uint32_t x = 128; x < im.w; ++x) im.color[im.at(x, y)] = glm::vec3(1.0f);
  const RgbImage out = run(im, lens, s);
  EdgeProfile e;
  for (std::uint32_t y : {20u, 23u, 24u, 31u}) {
    int width = 0;
    for (std::uint32_t x = 1; x < im.w; ++x) {
      const float a = out[im.at(x - 1, y)].x, b = out[im.at(x, y)].x;
      if (b < a - 1e-5f) e.monotonic = false;
      if (b > 0.2f + 0.08f && b < 1.0f - 0.08f) ++width;
    }
    e.width = std::max(e.width, width);
  }
  return e;
}

TEST(LeeMipmap, StepEdgeIsMonotonicAndWidensWithCoc) {
  int last = 0;
  for (double c : {3.0, 6.0, 12.0, 24.0, 48.0}) {
    const EdgeProfile e = step_edge(c);
    EXPECT_TRUE(e.monotonic) << "C = " << c;
    EXPECT_GT(e.width, last) << "C = " << c;
    last = e.width;
  }
}

// Brute-force reference: a Gaussian with sigma = C / 2 (§4.1.3), clamped to the edge, separable.
std::vector<float> gaussian_blur(const std::vector<float>& v, int w, int h, double sigma) {
  const int r = static_cast<int>(std::ceil(4 * sigma));
  std::vector<double> k(static_cast<std::size_t>(2 * r + 1));
  double sum = 0;
  for (int i = -r; i <= r; ++i) sum += k[static_cast<std::size_t>(i + r)] = std::exp(-0.5 * i * i / (sigma * sigma));
  for (auto& x : k) x /= sum;
  std::vector<float> tmp(v.size()), out(v.size());
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double a = 0;
      for (int i = -r; i <= r; ++i) a += k[static_cast<std::size_t>(i + r)] * static_cast<double>(v[static_cast<std::size_t>(y * w + std::clamp(x + i, 0, w - 1))]);
      tmp[static_cast<std::size_t>(y * w + x)] = static_cast<float>(a);
    }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double a = 0;
      for (int i = -r; i <= r; ++i) a += k[static_cast<std::size_t>(i + r)] * static_cast<double>(tmp[static_cast<std::size_t>(std::clamp(y + i, 0, h - 1) * w + x)]);
      out[static_cast<std::size_t>(y * w + x)] = static_cast<float>(a);
    }
  return out;
}

double rmse(const std::vector<float>& a, const std::vector<float>& b) {
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += static_cast<double>(a[i] - b[i]) * static_cast<double>(a[i] - b[i]);
  return std::sqrt(s / static_cast<double>(a.size()));
}

TEST(LeeMipmap, FlatDepthMatchesGaussianReference) {
  // A texture of blobs and bars in [0.1, 1], 192 x 160, one depth: the blur should approach a
  // Gaussian of sigma = C / 2 (the paper's fit of eq. 4.5 was by RMSE against exactly that).
  const int w = 192, h = 160;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<float> tex(static_cast<std::size_t>(w * h), 0.1f);
  for (int b = 0; b < 40; ++b) {
    const int cx = static_cast<int>(u(rng) * w), cy = static_cast<int>(u(rng) * h), r = 2 + static_cast<int>(u(rng) * 14);
    const float val = 0.1f + 0.9f * u(rng);
    for (int y = std::max(0, cy - r); y < std::min(h, cy + r); ++y)
      for (int x = std::max(0, cx - r); x < std::min(w, cx + r); ++x) tex[static_cast<std::size_t>(y * w + x)] = val;
  }
  const CocModel lens = lens_k(400);
  for (double c : {4.0, 8.0, 16.0, 32.0}) {
    DofImage im(w, h, glm::vec3(0), depth_for_coc(lens, c));
    for (std::size_t i = 0; i < tex.size(); ++i) im.color[i] = glm::vec3(tex[i]);
    const RgbImage out = run(im, lens);
    std::vector<float> got(tex.size());
    for (std::size_t i = 0; i < got.size(); ++i) got[i] = out[i].x;
    const auto ref = gaussian_blur(tex, w, h, c / 2);
    const double err = rmse(got, ref), unblurred = rmse(tex, ref);
    // Reference against a too-small and a too-large blur: the method must sit nearer the right one.
    const double err_half = rmse(gaussian_blur(tex, w, h, c / 4), ref);
    std::printf("C=%5.1f  rmse %.4f  (input %.4f, sigma/2 %.4f)\n", c, err, unblurred, err_half);
    EXPECT_LT(err, 0.35 * unblurred) << "C = " << c;
    EXPECT_LT(err, err_half) << "C = " << c;
    EXPECT_LT(err, 0.035) << "C = " << c;
  }
}

// Fig. 4.7: a sharp bright square (in focus) on a dark blurred background (behind the focal plane).
// Leakage: the mean excess brightness of the background in a band around the square.
double leak(bool anisotropic) {
  const CocModel lens = lens_k(400);
  const std::uint32_t n = 160;
  DofImage im(n, n, glm::vec3(0.1f), depth_for_coc(lens, 32.0));
  for (std::uint32_t y = 64; y < 96; ++y)
    for (std::uint32_t x = 64; x < 96; ++x) {
      im.color[im.at(x, y)] = glm::vec3(1.0f);
      im.depth[im.at(x, y)] = static_cast<float>(lens.focus_m);
    }
  LeeMipmapSettings s;
  s.anisotropic = anisotropic;
  s.smooth_foreground = false;
  const RgbImage out = run(im, lens, s);
  double sum = 0;
  int count = 0;
  for (std::uint32_t y = 0; y < n; ++y)
    for (std::uint32_t x = 0; x < n; ++x) {
      const int dx = std::max({64 - static_cast<int>(x), static_cast<int>(x) - 95, 0});
      const int dy = std::max({64 - static_cast<int>(y), static_cast<int>(y) - 95, 0});
      const int d = std::max(dx, dy);
      if (d >= 1 && d <= 16) {
        sum += static_cast<double>(out[im.at(x, y)].x) - 0.1;
        ++count;
      }
    }
  return sum / count;
}

TEST(LeeMipmap, AnisotropicMipmapLeaksLess) {
  const double iso = leak(false), aniso = leak(true);
  std::printf("leak: isotropic %.4f, anisotropic %.4f\n", iso, aniso);
  EXPECT_GT(iso, 0.02);  // the isotropic mipmap does leak (else the comparison says nothing)
  EXPECT_LT(aniso, 0.6 * iso);
}

TEST(LeeMipmap, FocusedSquareStaysSharp) {
  // The square's own pixels are in focus: output equals input inside it.
  const CocModel lens = lens_k(400);
  DofImage im(64, 64, glm::vec3(0.1f), depth_for_coc(lens, 20.0));
  for (std::uint32_t y = 20; y < 40; ++y)
    for (std::uint32_t x = 20; x < 40; ++x) {
      im.color[im.at(x, y)] = glm::vec3(1.0f, 0.5f, 0.25f);
      im.depth[im.at(x, y)] = static_cast<float>(lens.focus_m);
    }
  const RgbImage out = run(im, lens);
  for (std::uint32_t y = 20; y < 40; ++y)
    for (std::uint32_t x = 20; x < 40; ++x) EXPECT_EQ(out[im.at(x, y)], im.color[im.at(x, y)]);
}

// Fig. 4.9: a blurred foreground object (left, in front of the focal plane) over a focused
// background. Without smoothing the DoB jumps from the foreground's to 0 at the boundary; with
// eq. 4.11 it changes gradually and the background next to the boundary is blurred too.
struct Boundary {
  float max_dob_jump = 0;    // largest DoB change between neighbouring pixels along a row
  float max_color_jump = 0;  // largest colour change between neighbouring pixels along a row
  float dob_bg_near = 0;     // DoB of the background 2 px right of the boundary
};
Boundary foreground_edge(bool smooth) {
  const CocModel lens = lens_k(400, 10.0);
  const std::uint32_t w = 256, h = 64;
  DofImage im(w, h, glm::vec3(0.1f), static_cast<float>(lens.focus_m));
  const float near = static_cast<float>(lens.depth_near_for_coc(32.0));
  for (std::uint32_t y = 0; y < h; ++y)
    for (std::uint32_t x = 0; x < 128; ++x) {
      im.color[im.at(x, y)] = glm::vec3(0.8f);
      im.depth[im.at(x, y)] = near;
    }
  LeeMipmapSettings s;
  s.smooth_foreground = smooth;
  LeeMipmap mm;
  mm.set_record_debug(true);
  RgbImage out;
  mm.run(im.input(lens), s, out);
  Boundary b;
  const auto& dob = mm.dob_map();
  for (std::uint32_t y = 8; y < h - 8; y += 7) {
    for (std::uint32_t x = 100; x < 160; ++x) {
      b.max_dob_jump = std::max(b.max_dob_jump, std::fabs(dob[im.at(x, y)] - dob[im.at(x - 1, y)]));
      b.max_color_jump = std::max(b.max_color_jump, std::fabs(out[im.at(x, y)].x - out[im.at(x - 1, y)].x));
    }
    b.dob_bg_near = std::max(b.dob_bg_near, dob[im.at(130, y)]);
  }
  return b;
}

TEST(LeeMipmap, ForegroundSmoothingMakesBoundaryContinuous) {
  const Boundary hard = foreground_edge(false), soft = foreground_edge(true);
  std::printf("DoB jump %.3f -> %.3f, colour jump %.4f -> %.4f, background DoB at +2 px %.3f -> %.3f\n",
              double{hard.max_dob_jump}, double{soft.max_dob_jump}, double{hard.max_color_jump},
              double{soft.max_color_jump}, double{hard.dob_bg_near}, double{soft.dob_bg_near});
  EXPECT_GT(hard.max_dob_jump, 15.0f);  // sigma = 16 next to sigma = 0
  EXPECT_LT(soft.max_dob_jump, 0.25f * hard.max_dob_jump);
  EXPECT_EQ(hard.dob_bg_near, 0.0f);
  EXPECT_GT(soft.dob_bg_near, 2.0f);
  EXPECT_LT(soft.max_color_jump, 0.6f * hard.max_color_jump);
}

TEST(LeeMipmap, StatsAndLevels) {
  const CocModel lens = lens_k(400);
  DofImage im(1024, 768, glm::vec3(0.5f), depth_for_coc(lens, 64.0));
  LeeMipmapStats st;
  RgbImage out;
  lee_mipmap(im.input(lens), {}, out, &st);
  EXPECT_NEAR(st.max_dob_px, 32.0, 1e-3);
  // eq. 4.6: m = 1 + log2(k_sigma * 32) = 6.14 for k_sigma = 1.1: levels up to 6 (eq. 4.8 reads
  // levels floor(m) - 1 and floor(m)); with the paper's k_sigma = 2/3, m = 5.41: up to 5.
  EXPECT_EQ(st.levels, 6);
  LeeMipmapSettings paper;
  paper.k_sigma = 2.0 / 3.0;
  lee_mipmap(im.input(lens), paper, out, &st);
  EXPECT_EQ(st.levels, 5);
  LeeMipmapSettings capped;
  capped.max_level = 2;
  lee_mipmap(im.input(lens), capped, out, &st);
  EXPECT_EQ(st.levels, 2);
}

}  // namespace
}  // namespace fovea::render::dof
