// SPDX-License-Identifier: Apache-2.0
// ULOD's blend of adjacent levels on the GPU (backend/gl/gl_ulod_blend.h): the fragment pass and the
// in-place compute pass against the blend computed here, texel for texel, on an odd-sized image (the
// compute pass's last work groups straddle the edge) with repeated, unknown, NaN and out-of-range
// factors. Runs through EGL with DISPLAY unset.
#include <gtest/gtest.h>

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_program.h"
#include "backend/gl/gl_ulod_blend.h"

namespace fovea::render {
namespace {

constexpr std::uint32_t kW = 37, kH = 23;

struct Images {
  std::vector<float> drawn, next;                 // RGBA
  std::vector<std::uint32_t> drawn_ids, next_ids;
};

Images random_images() {
  std::mt19937 rng(7u);
  std::uniform_real_distribution<float> u(0, 4);
  Images im;
  for (std::uint32_t i = 0; i < kW * kH; ++i) {
    for (int c = 0; c < 4; ++c) {
      im.drawn.push_back(u(rng));
      im.next.push_back(u(rng));
    }
    const auto id = static_cast<std::uint32_t>(rng() % 6);  // 0 (background) .. 5
    im.drawn_ids.push_back(id);
    im.next_ids.push_back(rng() % 5 == 0 ? (id + 1) % 6 : id);  // a fifth of the pixels change object
  }
  return im;
}

// The blending objects: 3 twice (the first factor counts), 1 with NaN (0), 5 above 1 (1), 0 ignored.
const std::vector<std::uint32_t> kIds = {3, 1, 5, 3, 0};
const std::vector<float> kBlend = {0.25f, std::numeric_limits<float>::quiet_NaN(), 2.0f, 0.9f, 0.5f};

std::vector<float> expected(const Images& im) {
  std::vector<float> out = im.drawn;
  for (std::uint32_t i = 0; i < kW * kH; ++i) {
    const std::uint32_t id = im.drawn_ids[i];
    if (id != im.next_ids[i]) continue;
    const float f = id == 3 ? 0.25f : id == 1 ? 0.0f : id == 5 ? 1.0f : -1.0f;
    if (f < 0) continue;
    for (std::size_t c = 0; c < 3; ++c) out[4 * std::size_t{i} + c] = (1 - f) * im.drawn[4 * std::size_t{i} + c] + f * im.next[4 * std::size_t{i} + c];
  }
  return out;
}

unsigned texture(GLenum internal, GLenum format, GLenum type, const void* data) {
  const unsigned t = gl::make_texture(internal, format, type, kW, kH);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, kW, kH, format, type, data);
  return t;
}

std::vector<float> blended(GlUlodBlend& blend, const Images& im, GlUlodBlend::Pass pass) {
  const unsigned drawn = texture(GL_RGBA32F, GL_RGBA, GL_FLOAT, im.drawn.data());
  const unsigned next = texture(GL_RGBA32F, GL_RGBA, GL_FLOAT, im.next.data());
  const unsigned drawn_ids = texture(GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, im.drawn_ids.data());
  const unsigned next_ids = texture(GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, im.next_ids.data());
  blend.run({drawn, drawn_ids, kW, kH}, {next, next_ids, kW, kH}, kIds, kBlend, pass);
  std::vector<float> out(std::size_t{4} * kW * kH);
  glBindTexture(GL_TEXTURE_2D, drawn);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_FLOAT, out.data());
  for (unsigned t : {drawn, next, drawn_ids, next_ids}) glDeleteTextures(1, &t);
  EXPECT_EQ(glGetError(), static_cast<GLenum>(GL_NO_ERROR));
  return out;
}

void expect_same(const std::vector<float>& got, const std::vector<float>& want, const char* pass) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    ASSERT_NEAR(got[i], want[i], 1e-6f * std::max(1.0f, std::fabs(want[i]))) << pass << " value " << i;
  }
}

TEST(GlUlodBlend, FragmentAndComputePassesBlendAsTheCpuDoes) {
  GlBackend backend;
  backend.context().make_current();
  const Images im = random_images();
  const std::vector<float> want = expected(im);
  std::size_t changed = 0;
  for (std::size_t i = 0; i < want.size(); ++i) changed += want[i] != im.drawn[i];
  ASSERT_GT(changed, 100u) << "the test image would not blend";
  GlUlodBlend blend(backend.context().features().at_least(4, 3));
  expect_same(blended(blend, im, GlUlodBlend::Pass::Fragment), want, "fragment");
  if (!blend.has_compute()) GTEST_SKIP() << "OpenGL " << backend.context().features().version() << ": no compute pass";
  expect_same(blended(blend, im, GlUlodBlend::Pass::Compute), want, "compute");
}

TEST(GlUlodBlend, TheComputePassNeedsOpenGl43) {
  GlBackend backend;
  backend.context().make_current();
  GlUlodBlend fragment_only(false);
  EXPECT_FALSE(fragment_only.has_compute());
  const Images im = random_images();
  EXPECT_THROW(blended(fragment_only, im, GlUlodBlend::Pass::Compute), std::invalid_argument);
}

}  // namespace
}  // namespace fovea::render
