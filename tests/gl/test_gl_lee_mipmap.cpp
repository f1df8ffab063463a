// SPDX-License-Identifier: Apache-2.0
// Lee 2009 ch. 4 on the GPU (backend/gl/gl_lee_mipmap.h) against its CPU reference (dof/lee_mipmap.h):
// the bundled scenes' G-buffers at several apertures and every setting, and the CPU's stability
// catalogue (tests/stability/test_dof_lee_mipmap_stability.cpp) run through the GPU: pinhole and
// in-focus images copied exactly, focus at F / 0 / infinity, depth 0 / infinity / NaN, a CoC larger
// than the image, 1x1 and 1xN images, HDR 1e6. Runs through EGL with DISPLAY unset.
//
// Tolerance: PSNR >= 40 dB against the CPU reference (the goal), measured on the colour
// clamped to [0, 1] (what a display shows of it). The GPU differs by design in its bilinear filter
// weights (8-bit on most GPUs; float on llvmpipe), in GLSL's exp2/log2 and in the order of a few
// float sums; where the images are exactly defined (pinhole, everything in focus) they are equal.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_lee_mipmap.h"
#include "dof/lee_mipmap.h"
#include "dof_lens.h"
#include "dof_test_image.h"
#include "gl_dof_scene.h"
#include "hdr_compare.h"
#include "scene/scene_loader.h"

namespace fovea::render {
namespace {

using dof::CocModel;
using dof::LeeMipmapSettings;
using dof::RgbImage;
using dof::test::DofImage;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr double kMinPsnrDb = 40.0;

using test::psnr_shown;

float clean(float v) { return std::isfinite(v) ? std::max(v, 0.0f) : 0.0f; }

// Finite, non-negative and per channel no brighter than the brightest finite input.
void expect_bounded(const dof::DofInput& in, const RgbImage& out, const char* what) {
  ASSERT_EQ(out.size(), in.pixels()) << what;
  glm::vec3 mx(0.0f);
  for (std::size_t i = 0; i < in.pixels(); ++i) {
    const glm::vec3 c = in.color[i];
    mx = glm::max(mx, glm::vec3(clean(c.x), clean(c.y), clean(c.z)));
  }
  for (std::size_t i = 0; i < out.size(); ++i)
    for (int ch = 0; ch < 3; ++ch) {
      const float v = out[i][ch];
      ASSERT_TRUE(std::isfinite(v)) << what << " pixel " << i;
      ASSERT_GE(v, 0.0f) << what << " pixel " << i;
      ASSERT_LE(v, mx[ch] * (1.0f + 1e-6f)) << what << " pixel " << i;
    }
}

// Every test runs on both implementations: the fragment passes and the compute passes.
class GlLeeMipmapTest : public ::testing::TestWithParam<GlLeeMipmap::Pass> {
 protected:
  void SetUp() override {
    backend_ = std::make_unique<GlBackend>();
    backend_->context().make_current();
    gl_ = std::make_unique<GlLeeMipmap>(backend_->context().features().at_least(4, 3));
    if (GetParam() == GlLeeMipmap::Pass::Compute && !gl_->has_compute()) GTEST_SKIP() << "no OpenGL 4.3 compute";
  }
  RgbImage on_gpu(const dof::DofInput& in, const LeeMipmapSettings& s = {}) {
    RgbImage out;
    gl_->run_image(in, s, out, nullptr, GetParam());
    return out;
  }
  static RgbImage on_cpu(const dof::DofInput& in, const LeeMipmapSettings& s = {}) {
    RgbImage out;
    dof::lee_mipmap(in, s, out);
    return out;
  }
  // Both bounded, and the GPU within the tolerance of the CPU.
  void expect_agree(const dof::DofInput& in, const LeeMipmapSettings& s, const char* what) {
    const RgbImage cpu = on_cpu(in, s), gpu = on_gpu(in, s);
    expect_bounded(in, gpu, what);
    EXPECT_GE(psnr_shown(gpu, cpu), kMinPsnrDb) << what << " " << in.width << "x" << in.height;
  }
  std::unique_ptr<GlBackend> backend_;
  std::unique_ptr<GlLeeMipmap> gl_;
};

class GlLeeMipmapPassChoice : public ::testing::Test {
 protected:
  void SetUp() override {
    backend_ = std::make_unique<GlBackend>();
    backend_->context().make_current();
  }
  std::unique_ptr<GlBackend> backend_;
};

using SceneImage = test::DofSceneImage;
SceneImage scene_image(GlBackend& backend, const char* name, double focus_m, double k_px) {
  return test::dof_scene_image(backend, name, focus_m, k_px, 256, 192);
}

TEST_P(GlLeeMipmapTest, AgreesWithTheCpuReferenceOnTheBundledScenes) {
  struct Case {
    const char* scene;
    double focus_m;
  };
  for (const Case& c : {Case{"attention.json", 2.9}, Case{"attention.json", 14.0}, Case{"occlusion.json", 6.0},
                        Case{"cornell.json", 1.0}}) {
    for (double k : {4.0, 16.0, 64.0}) {
      const SceneImage im = scene_image(*backend_, c.scene, c.focus_m, k);
      const RgbImage cpu = on_cpu(im.input()), gpu = on_gpu(im.input());
      const double db = psnr_shown(gpu, cpu);
      EXPECT_GE(db, kMinPsnrDb) << c.scene << " focus " << c.focus_m << " K " << k;
      std::printf("%-15s focus %5.1f m K %3.0f px: GL vs CPU %.1f dB\n", c.scene, c.focus_m, k, db);
    }
  }
}

TEST_P(GlLeeMipmapTest, AgreesWithTheCpuReferenceWithEverySetting) {
  const SceneImage im = scene_image(*backend_, "attention.json", 2.9, 32.0);
  for (int variant = 0; variant < 7; ++variant) {
    LeeMipmapSettings s;
    s.anisotropic = variant != 1;
    s.smooth_foreground = variant != 2;
    s.circular = variant != 3;
    s.geometric = variant != 4;
    if (variant == 5) s.dob_per_coc = 0.25;
    if (variant == 6) s.max_level = 2;
    expect_agree(im.input(), s, "setting variant");
  }
  // Foreground blur: the DoN smoothing (eqs. 4.10-4.11) does the work.
  const SceneImage fg = scene_image(*backend_, "attention.json", 14.0, 32.0);
  expect_agree(fg.input(), {}, "foreground blur");
}

TEST_P(GlLeeMipmapTest, PinholeAndInFocusImagesAreCopiedExactly) {
  DofImage im(31, 17, glm::vec3(0.25f, 3.0f, 1e6f), 1.0f);
  im.color[5] = {kNaN, kInf, -kInf};
  im.color[6] = {-1.0f, 2.0f, 0.0f};
  im.depth[7] = kNaN;
  CocModel pin = dof::test::lens_with_k(300);
  pin.aperture_m = 0;
  const RgbImage out = on_gpu(im.input(pin));
  const RgbImage cpu = on_cpu(im.input(pin));
  for (std::size_t i = 0; i < out.size(); ++i) EXPECT_EQ(0, std::memcmp(&out[i], &cpu[i], sizeof(glm::vec3))) << i;
  EXPECT_EQ(out[5], glm::vec3(0.0f));
  EXPECT_EQ(out[6], glm::vec3(-1.0f, 2.0f, 0.0f));  // as the CPU: a pinhole changes nothing finite
  DofImage focused(40, 30, glm::vec3(0.5f), 4.0f);
  focused.color[3] = {9.0f, 0.0f, 1.0f};
  const RgbImage f = on_gpu(focused.input(dof::test::lens_with_k(300, 4.0)));
  EXPECT_EQ(0, std::memcmp(f.data(), focused.color.data(), f.size() * sizeof(glm::vec3)));
}

TEST_P(GlLeeMipmapTest, StabilityCatalogueSpecialDepths) {
  const CocModel lens = dof::test::lens_with_k(300);
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
      expect_agree(im.input(lens), s, "special depths");
    }
  for (float d : specials) {
    DofImage flat(33, 21, glm::vec3(0.3f, 0.6f, 0.9f), d);
    flat.color[100] = glm::vec3(5.0f);
    expect_agree(flat.input(lens), {}, "flat special depth");
  }
}

TEST_P(GlLeeMipmapTest, StabilityCatalogueColoursAndLenses) {
  const CocModel lens = dof::test::lens_with_k(300);
  DofImage dirty(50, 40, glm::vec3(0.5f), static_cast<float>(lens.depth_far_for_coc(20.0)));
  dirty.color[10] = {kNaN, kInf, -kInf};
  dirty.color[500] = {kInf, kInf, kInf};
  expect_agree(dirty.input(lens), {}, "non-finite colour");
  DofImage hdr(80, 60, glm::vec3(0.01f), static_cast<float>(lens.depth_far_for_coc(30.0)));
  hdr.color[30 * 80 + 40] = glm::vec3(1e6f);
  hdr.color[31 * 80 + 40] = glm::vec3(1e6f, 0.0f, 3e5f);
  for (bool geometric : {true, false}) {
    LeeMipmapSettings s;
    s.geometric = geometric;
    expect_agree(hdr.input(lens), s, "HDR 1e6");
  }
  CocModel huge = dof::test::lens_with_k(1e5);
  DofImage bars(24, 16, glm::vec3(0.2f), 50.0f);
  for (std::size_t i = 0; i < bars.color.size(); i += 3) bars.color[i] = glm::vec3(1.0f, 0.0f, 0.5f);
  expect_agree(bars.input(huge), {}, "CoC larger than the image");
  huge.max_coc_px = 1e30;
  expect_agree(bars.input(huge), {}, "unclamped CoC");
  for (double focus : {0.05, 0.04, 0.0, -1.0, 1e-9, std::numeric_limits<double>::infinity(),
                       std::numeric_limits<double>::quiet_NaN()}) {
    CocModel odd = dof::test::lens_with_k(300);
    odd.focus_m = focus;
    DofImage im(40, 30, glm::vec3(0.3f), 1.0f);
    for (std::size_t i = 0; i < im.depth.size(); ++i) im.depth[i] = 0.02f * static_cast<float>(i % 200);
    for (std::size_t i = 0; i < im.color.size(); i += 7) im.color[i] = glm::vec3(2.0f);
    const std::string what = "focus at F, 0, infinity, NaN: " + std::to_string(focus);
    // Focus inside the focal length: K ~ 1e10 px, so a depth a float ulp from d_f (which the GPU
    // holds as a float, the CPU as a double) is in focus on one and capped on the other. Bounded only.
    if (odd.terms().k > 1e6) {
      expect_bounded(im.input(odd), on_gpu(im.input(odd)), what.c_str());
    } else {
      expect_agree(im.input(odd), {}, what.c_str());
    }
  }
}

TEST_P(GlLeeMipmapTest, StabilityCatalogueTinyAndDegenerateSizes) {
  const CocModel lens = dof::test::lens_with_k(300);
  for (auto [w, h] : {std::pair{1u, 1u}, {1u, 2u}, {2u, 1u}, {1u, 37u}, {53u, 1u}, {2u, 2u}, {3u, 5u}, {1u, 1024u}}) {
    DofImage im(w, h, glm::vec3(0.4f), 100.0f);
    for (std::size_t i = 0; i < im.color.size(); i += 2) im.color[i] = glm::vec3(1.0f, 0.1f, 0.0f);
    for (std::size_t i = 1; i < im.depth.size(); i += 3) im.depth[i] = 0.3f;
    expect_agree(im.input(lens), {}, "tiny");
    if (w * h == 1) {
      EXPECT_EQ(on_gpu(im.input(lens))[0], im.color[0]);
    }
  }
}

TEST_P(GlLeeMipmapTest, RandomInputsAgreeAndReuseTheirTargets) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::uniform_real_distribution<double> ud(0.0, 1.0);
  const float specials[] = {kNaN, kInf, -kInf, 0.0f, 1e6f, -3.0f};
  for (int trial = 0; trial < 30; ++trial) {
    const auto w = 1 + static_cast<std::uint32_t>(rng() % 90), h = 1 + static_cast<std::uint32_t>(rng() % 70);
    DofImage im(w, h, glm::vec3(0), 1);
    const bool dirty = trial % 3 == 0;
    for (std::size_t i = 0; i < im.color.size(); ++i) {
      im.color[i] = {u(rng), u(rng), u(rng) * u(rng)};
      im.depth[i] = 0.1f + 30.0f * u(rng) * u(rng);
      if (dirty && rng() % 10 == 0) im.color[i][static_cast<int>(rng() % 3)] = specials[rng() % std::size(specials)];
      if (dirty && rng() % 10 == 0) im.depth[i] = specials[rng() % std::size(specials)];
    }
    const CocModel lens = dof::test::lens_with_k(5.0 + 400.0 * ud(rng), 0.2 + 10.0 * ud(rng));
    LeeMipmapSettings s;
    s.anisotropic = rng() % 2;
    s.smooth_foreground = rng() % 4 != 0;
    s.circular = rng() % 4 != 0;
    s.geometric = rng() % 4 != 0;
    s.delta = 2.0 * ud(rng);
    s.max_level = static_cast<int>(rng() % 3);
    expect_agree(im.input(lens), s, "random");
  }
}

// The compute passes run the fragment passes' GLSL functions: the two agree to float rounding, not
// only within the tolerance of the CPU reference.
TEST_P(GlLeeMipmapTest, TheComputeAndFragmentPassesAgree) {
  if (GetParam() != GlLeeMipmap::Pass::Compute) GTEST_SKIP() << "compared once, from the compute side";
  for (double k : {4.0, 64.0}) {
    const SceneImage im = scene_image(*backend_, "attention.json", 2.9, k);
    RgbImage fragment, compute;
    // Compute first, on targets no fragment pass wrote (each test makes its own GlLeeMipmap).
    gl_->run_image(im.input(), {}, compute, nullptr, GlLeeMipmap::Pass::Compute);
    gl_->run_image(im.input(), {}, fragment, nullptr, GlLeeMipmap::Pass::Fragment);
    EXPECT_GE(psnr_shown(compute, fragment), 80.0) << "K " << k;
  }
}

TEST_F(GlLeeMipmapPassChoice, TheComputePassRefusesWhereItWasNotBuilt) {
  GlLeeMipmap fragment_only(false);
  EXPECT_FALSE(fragment_only.has_compute());
  RgbImage out;
  DofImage im(8, 8, glm::vec3(0.5f), 2.0f);
  EXPECT_THROW(fragment_only.run_image(im.input(dof::test::lens_with_k(20)), {}, out, nullptr, GlLeeMipmap::Pass::Compute),
               std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(Passes, GlLeeMipmapTest,
                         ::testing::Values(GlLeeMipmap::Pass::Fragment, GlLeeMipmap::Pass::Compute),
                         [](const ::testing::TestParamInfo<GlLeeMipmap::Pass>& param) {
                           return param.param == GlLeeMipmap::Pass::Compute ? "Compute" : "Fragment";
                         });

}  // namespace
}  // namespace fovea::render
