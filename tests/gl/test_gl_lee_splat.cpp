// SPDX-License-Identifier: Apache-2.0
// Lee 2009 ch. 5 on the GPU (backend/gl/gl_lee_splat.h) against its CPU reference (dof/lee_splat.h):
// the bundled scenes' G-buffers with the hidden image peeled by the raster backend, every aperture
// and setting, and the CPU's stability catalogue (tests/stability/test_dof_lee_splat_stability.cpp)
// run through the GPU: a pinhole copies the input exactly, focus at F / 0 / infinity / NaN, depth 0 /
// infinity / NaN, a CoC larger than the image, 1x1 and 1xN images, HDR 1e6. Runs through EGL with
// DISPLAY unset.
//
// Tolerance: PSNR >= 40 dB against the CPU reference (the goal), on the colour clamped to
// [0, 1]. The GPU adds the splats in another order and in float where the CPU uses double for the
// footprint's rim and the Gaussian IDF.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_lee_splat.h"
#include "dof/lee_splat.h"
#include "dof_lens.h"
#include "dof_test_image.h"
#include "gl_dof_scene.h"
#include "hdr_compare.h"
#include "scene/scene_loader.h"

namespace fovea::render {
namespace {

using dof::Aperture;
using dof::CocModel;
using dof::LeeSplatSettings;
using dof::RgbImage;
using dof::test::DofImage;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr double kMinPsnrDb = 40.0;

using test::psnr_shown;

// Every test runs both implementations of the splat: the instanced quads with blending (OpenGL 3.3)
// and the tiled gather in compute passes (OpenGL 4.3).
class GlLeeSplatTest : public ::testing::TestWithParam<GlLeeSplat::Pass> {
 protected:
  void SetUp() override {
    backend_ = std::make_unique<GlBackend>();
    backend_->context().make_current();
    gl_ = std::make_unique<GlLeeSplat>(backend_->context().features().at_least(4, 3));
    if (GetParam() == GlLeeSplat::Pass::Compute && !gl_->has_compute()) GTEST_SKIP() << "no OpenGL 4.3 compute";
  }
  RgbImage on_gpu(const dof::DofInput& in, const LeeSplatSettings& s = {}) {
    RgbImage out;
    gl_->run_image(in, s, out, nullptr, GetParam());
    return out;
  }
  static RgbImage on_cpu(const dof::DofInput& in, const LeeSplatSettings& s = {}) {
    RgbImage out;
    dof::lee_splat(in, s, out);
    return out;
  }
  // Finite everywhere, and the GPU within the tolerance of the CPU; returns the PSNR.
  double expect_agree(const dof::DofInput& in, const LeeSplatSettings& s, const std::string& what) {
    const RgbImage cpu = on_cpu(in, s), gpu = on_gpu(in, s);
    EXPECT_EQ(gpu.size(), cpu.size()) << what;
    for (std::size_t i = 0; i < gpu.size(); ++i)
      for (int c = 0; c < 3; ++c) EXPECT_TRUE(std::isfinite(gpu[i][c])) << what << " pixel " << i;
    const double db = psnr_shown(gpu, cpu);
    EXPECT_GE(db, kMinPsnrDb) << what << " " << in.width << "x" << in.height;
    return db;
  }
  std::unique_ptr<GlBackend> backend_;
  std::unique_ptr<GlLeeSplat> gl_;
};

// A bundled scene's G-buffer with its hidden image (the first peeled layer).
using SceneImage = test::DofSceneImage;
SceneImage scene_image(GlBackend& backend, const char* name, double focus_m, double k_px) {
  return test::dof_scene_image(backend, name, focus_m, k_px, 128, 96, true);
}

TEST_P(GlLeeSplatTest, AgreesWithTheCpuReferenceOnTheBundledScenesWithTheHiddenImage) {
  struct Case {
    const char* scene;
    double focus_m;
  };
  for (const Case& c : {Case{"attention.json", 2.9}, Case{"attention.json", 14.0}, Case{"occlusion.json", 6.0},
                        Case{"cornell.json", 1.0}}) {
    for (double k : {4.0, 16.0}) {
      const SceneImage im = scene_image(*backend_, c.scene, c.focus_m, k);
      const double db = expect_agree(im.input(true), {}, std::string(c.scene) + " K " + std::to_string(k));
      // Something is defocused: the result is not the input.
      const double blur_db = psnr_shown(on_gpu(im.input(true)), im.g.color);
      EXPECT_LT(blur_db, 45.0) << c.scene << " K " << k << ": nothing was blurred";
      std::printf("%-15s focus %5.1f m K %3.0f px: GL vs CPU %.1f dB (GL vs the sharp input %.1f dB)\n", c.scene,
                  c.focus_m, k, db, blur_db);
    }
  }
}

TEST_P(GlLeeSplatTest, AgreesWithTheCpuReferenceWithEverySetting) {
  const SceneImage im = scene_image(*backend_, "attention.json", 2.9, 12.0);
  for (int variant = 0; variant < 7; ++variant) {
    LeeSplatSettings s;
    if (variant == 1) s.aperture = Aperture::Gaussian;
    if (variant == 2) s.aperture = Aperture::Hexagon;
    if (variant == 3) s.use_hidden = false;
    if (variant == 4) s.delta = 0.3;
    if (variant == 5) s.ldr_highlights = true;
    if (variant == 6) s.laplacian_threshold = 0.0;
    expect_agree(im.input(true), s, "setting variant " + std::to_string(variant));
  }
  LeeSplatSettings reduced;
  reduced.reduce = 2;
  RgbImage out;
  EXPECT_THROW(gl_->run_image(im.input(true), reduced, out), std::invalid_argument);  // §5.3 stays on the CPU
}

TEST_P(GlLeeSplatTest, APinholeCopiesTheInputExactly) {
  DofImage im(31, 17, glm::vec3(0.25f, 3.0f, 1e6f), 1.0f);
  im.color[5] = {kNaN, kInf, -kInf};
  im.color[6] = {-1.0f, 2.0f, 0.0f};
  im.depth[7] = kNaN;
  CocModel pin = dof::test::lens_with_k(300);
  pin.aperture_m = 0;
  for (const bool ldr : {false, true}) {
    LeeSplatSettings s;
    s.ldr_highlights = ldr;
    const RgbImage out = on_gpu(im.input(pin), s), cpu = on_cpu(im.input(pin), s);
    ASSERT_EQ(out.size(), cpu.size());
    for (std::size_t i = 0; i < out.size(); ++i) EXPECT_EQ(0, std::memcmp(&out[i], &cpu[i], sizeof(glm::vec3))) << i;
  }
}

TEST_P(GlLeeSplatTest, StabilityCatalogueDepthsColoursAndLenses) {
  const CocModel lens = dof::test::lens_with_k(60);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float specials[] = {0.0f, -0.0f, kInf, -kInf, kNaN, -1.0f, 1e-30f, 1e30f, 2.0f, 0.05f};
  DofImage im(48, 36, glm::vec3(0.0f), 1.0f, glm::vec3(0.9f, 0.1f, 0.1f));
  for (std::size_t i = 0; i < im.color.size(); ++i) {
    im.color[i] = {u(rng), u(rng), u(rng)};
    im.depth[i] = specials[rng() % std::size(specials)];
    im.hidden_depth[i] = specials[rng() % std::size(specials)];
  }
  expect_agree(im.input(lens, true), {}, "special depths with a hidden image");
  DofImage hdr(40, 30, glm::vec3(0.01f), static_cast<float>(lens.depth_far_for_coc(12.0)));
  hdr.color[15 * 40 + 20] = glm::vec3(1e6f);
  hdr.color[16 * 40 + 20] = {kNaN, kInf, 3e5f};
  expect_agree(hdr.input(lens), {}, "HDR 1e6 and non-finite colour");
  CocModel huge = dof::test::lens_with_k(1e5);
  DofImage bars(24, 16, glm::vec3(0.2f), 50.0f);
  for (std::size_t i = 0; i < bars.color.size(); i += 3) bars.color[i] = glm::vec3(1.0f, 0.0f, 0.5f);
  for (const Aperture a : {Aperture::Disc, Aperture::Gaussian, Aperture::Hexagon}) {
    LeeSplatSettings s;
    s.aperture = a;
    expect_agree(bars.input(huge), s, "CoC larger than the image");
  }
  for (double focus : {0.05, 0.0, -1.0, std::numeric_limits<double>::infinity(), std::numeric_limits<double>::quiet_NaN()}) {
    CocModel odd = dof::test::lens_with_k(40);
    odd.focus_m = focus;
    DofImage ramp(30, 20, glm::vec3(0.3f), 1.0f);
    for (std::size_t i = 0; i < ramp.depth.size(); ++i) ramp.depth[i] = 0.02f * static_cast<float>(i % 200);
    for (std::size_t i = 0; i < ramp.color.size(); i += 7) ramp.color[i] = glm::vec3(2.0f);
    if (odd.terms().k > 1e6) continue;  // a focus inside F: float and double disagree about what is in focus
    expect_agree(ramp.input(odd), {}, "focus " + std::to_string(focus));
  }
}

TEST_P(GlLeeSplatTest, StabilityCatalogueTinySizes) {
  const CocModel lens = dof::test::lens_with_k(40);
  for (auto [w, h] : {std::pair{1u, 1u}, {1u, 2u}, {2u, 1u}, {1u, 37u}, {53u, 1u}, {3u, 5u}}) {
    DofImage im(w, h, glm::vec3(0.4f), 100.0f);
    for (std::size_t i = 0; i < im.color.size(); i += 2) im.color[i] = glm::vec3(1.0f, 0.1f, 0.0f);
    for (std::size_t i = 1; i < im.depth.size(); i += 3) im.depth[i] = 0.3f;
    expect_agree(im.input(lens), {}, "tiny " + std::to_string(w) + "x" + std::to_string(h));
  }
}

// The two implementations add the same splats in another order: the same image to float rounding.
TEST_P(GlLeeSplatTest, TheComputeAndFragmentSplatsAgree) {
  if (GetParam() != GlLeeSplat::Pass::Compute) GTEST_SKIP() << "compared once, from the compute side";
  std::mt19937 rng(42);
  std::uniform_real_distribution<float> colour(0.0f, 4.0f), depth(0.3f, 30.0f);
  DofImage im(61, 47, glm::vec3(0.0f), 1.0f);
  for (auto& c : im.color) c = glm::vec3(colour(rng), colour(rng), colour(rng));
  for (auto& c : im.hidden_color) c = glm::vec3(colour(rng), colour(rng), colour(rng));
  for (std::size_t i = 0; i < im.depth.size(); ++i) {
    im.depth[i] = depth(rng);
    im.hidden_depth[i] = im.depth[i] + depth(rng);
  }
  const dof::DofInput in = im.input(dof::test::lens_with_k(30), true);
  for (const Aperture a : {Aperture::Disc, Aperture::Gaussian, Aperture::Hexagon}) {
    LeeSplatSettings s;
    s.aperture = a;
    RgbImage fragment, compute;
    gl_->run_image(in, s, fragment, nullptr, GlLeeSplat::Pass::Fragment);
    gl_->run_image(in, s, compute, nullptr, GlLeeSplat::Pass::Compute);
    EXPECT_GE(psnr_shown(compute, fragment), 60.0) << "aperture " << static_cast<int>(a);
    RgbImage again;
    gl_->run_image(in, s, again, nullptr, GlLeeSplat::Pass::Compute);
    EXPECT_EQ(std::memcmp(again.data(), compute.data(), compute.size() * sizeof(glm::vec3)), 0)
        << "the compute splat adds in the same order every run";
  }
}

TEST(GlLeeSplatPassChoice, TheComputeSplatRefusesWhereItWasNotBuilt) {
  GlBackend backend;
  backend.context().make_current();
  GlLeeSplat fragment_only(false);
  EXPECT_FALSE(fragment_only.has_compute());
  DofImage im(8, 8, glm::vec3(0.5f), 2.0f);
  RgbImage out;
  EXPECT_THROW(fragment_only.run_image(im.input(dof::test::lens_with_k(10)), {}, out, nullptr, GlLeeSplat::Pass::Compute),
               std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(Passes, GlLeeSplatTest, ::testing::Values(GlLeeSplat::Pass::Fragment, GlLeeSplat::Pass::Compute),
                         [](const ::testing::TestParamInfo<GlLeeSplat::Pass>& p) {
                           return p.param == GlLeeSplat::Pass::Compute ? "Compute" : "Fragment";
                         });

}  // namespace
}  // namespace fovea::render
