// SPDX-License-Identifier: Apache-2.0
// Schedl & Wimmer's layered DOF on the GPU (backend/gl/gl_schedl_layered.h) against its CPU reference
// (dof/schedl_layered.h) on the same inputs: the bundled scenes' visible and depth-peeled layers
// (M = 1, 2, 3) at several apertures, and the CPU's stability catalogue
// (tests/stability/test_dof_schedl_layered_stability.cpp) through the GPU: non-finite and extreme
// depths and colours, degenerate sizes, a CoC larger than the image, focus at F / 0 / infinity / NaN.
// Runs through EGL with DISPLAY unset.
//
// Tolerance: PSNR >= 40 dB against the CPU (the goal) on the colour clamped to [0, 1]. The
// GPU sums each box blur's taps where the CPU keeps a running sum, and compares depths with the
// anchors in float: the same K layers (checked), float rounding apart.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "backend/backend.h"
#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_schedl_layered.h"
#include "dof/schedl_layered.h"
#include "dof_lens.h"
#include "dof_test_image.h"
#include "hdr_compare.h"
#include "scene/scene_loader.h"

namespace fovea::render {
namespace {

using dof::CocModel;
using dof::PeeledLayer;
using dof::RgbImage;
using dof::test::DofImage;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

void expect_bounded(const RgbImage& out, float max_in, const std::string& what) {
  for (const glm::vec3& c : out)
    for (int k = 0; k < 3; ++k) {
      ASSERT_TRUE(std::isfinite(c[k])) << what;
      ASSERT_GE(c[k], 0.0f) << what;
      ASSERT_LE(c[k], max_in * (1 + 1e-5f) + 1e-6f) << what;
    }
}

// Every test runs with both box blurs: the fragment pass and the compute pass's running sums.
class GlSchedlLayeredTest : public ::testing::TestWithParam<GlSchedlLayered::Pass> {
 protected:
  void SetUp() override {
    backend_ = std::make_unique<GlBackend>();
    backend_->context().make_current();
    gl_ = std::make_unique<GlSchedlLayered>(backend_->context().features().at_least(4, 3));
    if (GetParam() == GlSchedlLayered::Pass::Compute && !gl_->has_compute()) GTEST_SKIP() << "no OpenGL 4.3 compute";
  }
  // The GPU within the tolerance of the CPU, with the same layers cut; both bounded by max_in.
  // Returns the PSNR against the CPU.
  double expect_agree(const dof::DofInput& in, const std::vector<PeeledLayer>& peeled, float max_in,
                      const std::string& what) {
    RgbImage cpu, gpu;
    dof::SchedlStats cs, gs;
    dof::schedl_layered(in, peeled, {}, cpu, &cs);
    backend_->context().make_current();
    gs = gl_->run_image(in, peeled, {}, gpu, nullptr, GetParam());
    expect_bounded(gpu, max_in, what);
    EXPECT_EQ(gs.layers, cs.layers) << what;
    EXPECT_EQ(gs.focus_layer, cs.focus_layer) << what;
    const double db = test::psnr_shown(gpu, cpu);
    EXPECT_GE(db, 40.0) << what << " " << in.width << "x" << in.height;
    return db;
  }
  std::unique_ptr<GlBackend> backend_;
  std::unique_ptr<GlSchedlLayered> gl_;
};

TEST_P(GlSchedlLayeredTest, AgreesWithTheCpuReferenceOnTheBundledScenesPeeledLayers) {
  std::unique_ptr<Backend> embree = make_backend(BackendKind::Embree);
  struct Case {
    const char* scene;
    double focus_m;
  };
  for (const Case& c : {Case{"occlusion.json", 6.0}, Case{"attention.json", 2.9}, Case{"attention.json", 14.0}}) {
    Scene s = load_scene(std::filesystem::path(FOVEA_SOURCE_DIR) / "renderer/scenes" / c.scene);
    s.camera.width = 200;
    s.camera.height = 150;
    embree->set_scene(s);
    GBuffer visible, p1, p2;
    embree->render({}, {}, visible);
    BackendSettings peel;
    peel.peel = 1;
    embree->render({}, peel, p1);
    peel.peel = 2;
    embree->render({}, peel, p2);
    const std::vector<PeeledLayer> all = {{p1.color.data(), p1.depth.data()}, {p2.color.data(), p2.depth.data()}};
    for (double k : {4.0, 16.0, 64.0}) {
      for (std::size_t m = 0; m <= all.size(); ++m) {
        dof::DofInput in;
        in.width = visible.width;
        in.height = visible.height;
        in.color = visible.color.data();
        in.depth = visible.depth.data();
        in.coc = dof::test::lens_with_k(k, c.focus_m);
        float max_in = 0;
        for (const glm::vec3& v : visible.color) max_in = std::max({max_in, v.x, v.y, v.z});
        const std::vector<PeeledLayer> peeled(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(m));
        const std::string what = std::string(c.scene) + " focus " + std::to_string(c.focus_m) + " K " +
                                 std::to_string(k) + " M " + std::to_string(m + 1);
        std::printf("%s: GL vs CPU %.1f dB\n", what.c_str(), expect_agree(in, peeled, max_in, what));
      }
    }
  }
}

TEST_P(GlSchedlLayeredTest, StabilityCatalogueNonFiniteAndExtremeDepthsAndColours) {
  const std::vector<float> depths = {0.0f, -1.0f, kInf, -kInf, kNaN, 1e-30f, 1e30f, 3e38f, 1.0f, 2.0f};
  DofImage im(20, 20, glm::vec3(0.0f), 0.0f, glm::vec3(kNaN));
  for (std::size_t i = 0; i < 400; ++i) {
    im.depth[i] = depths[i % depths.size()];
    const float v = i % 7 == 0 ? kNaN : i % 11 == 0 ? kInf : i % 13 == 0 ? 1e6f : 0.25f * static_cast<float>(i % 5);
    im.color[i] = glm::vec3(v, 0.5f, -1.0f);
  }
  std::fill(im.hidden_depth.begin(), im.hidden_depth.end(), kNaN);
  expect_agree(im.input(dof::test::lens_with_k(30)), {{im.hidden_color.data(), im.hidden_depth.data()}}, 1e6f,
               "non-finite and extreme");
}

TEST_P(GlSchedlLayeredTest, StabilityCatalogueDegenerateSizesAndLenses) {
  for (auto [w, h] : {std::pair{1u, 1u}, {1u, 37u}, {37u, 1u}, {2u, 1u}}) {
    DofImage im(w, h, glm::vec3(0.4f), 0.0f);
    for (std::size_t i = 0; i < im.depth.size(); ++i) im.depth[i] = 0.5f + static_cast<float>(i);
    expect_agree(im.input(dof::test::lens_with_k(100)), {}, 0.4f, "size " + std::to_string(w) + "x" + std::to_string(h));
  }
  DofImage im(24, 16, glm::vec3(0.0f), 0.0f);
  for (std::size_t i = 0; i < im.color.size(); ++i) {
    im.color[i] = glm::vec3(static_cast<float>(i % 3) * 0.5f);
    im.depth[i] = 0.1f + static_cast<float>(i % 17);
  }
  for (double focus : {0.05, 0.0, -1.0, 1e9, static_cast<double>(kInf), static_cast<double>(kNaN)}) {
    CocModel m = dof::test::lens_with_k(1e4, 2.0);  // a CoC larger than the image
    m.focus_m = focus;
    expect_agree(im.input(m), {}, 1.0f, "focus " + std::to_string(focus));
  }
  CocModel pinhole = dof::test::lens_with_k(100);
  pinhole.aperture_m = 0;
  DofImage flat(16, 12, glm::vec3(0.3f, -1.0f, kNaN), 2.0f);
  RgbImage out;
  gl_->run_image(flat.input(pinhole), {}, {}, out, nullptr, GetParam());
  for (const glm::vec3& c : out) EXPECT_EQ(c, glm::vec3(0.3f, 0.0f, 0.0f));  // the input, sanitised
}

TEST_P(GlSchedlLayeredTest, RandomInputsAgree) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int t = 0; t < 20; ++t) {
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
    const CocModel lens =
        dof::test::lens_with_k(5.0 + 80.0 * static_cast<double>(u(rng)), 0.5 + 10.0 * static_cast<double>(u(rng)));
    expect_agree(im.input(lens), {{im.hidden_color.data(), im.hidden_depth.data()}}, max_in, "random " + std::to_string(t));
  }
}

// Lines long enough for several of the compute pass's segments, boxes wider than a segment, and a
// stripe of HDR light (1e6) beside dark pixels (0.5): the running sums leave no residue where the
// light left the window, and agree with the fragment pass's direct sums.
TEST_P(GlSchedlLayeredTest, WideBoxesOverLongLinesAndHdrLightAgree) {
  for (const double k : {20.0, 200.0}) {
    DofImage im(600, 90, glm::vec3(0.5f), 8.0f);
    float max_in = 0.5f;
    for (std::uint32_t y = 0; y < 90; ++y)
      for (std::uint32_t x = 0; x < 600; ++x) {
        const std::size_t i = std::size_t{y} * 600 + x;
        if (x >= 280 && x < 284) im.color[i] = glm::vec3(1e6f, 1e6f * 0.5f, 1.0f);
        if ((x / 37 + y / 23) % 2 == 0) im.color[i].y += 0.25f;
        im.depth[i] = x < 300 ? 2.0f : 8.0f;
        max_in = std::max({max_in, im.color[i].x, im.color[i].y, im.color[i].z});
      }
    const double db = expect_agree(im.input(dof::test::lens_with_k(k, 8.0)), {}, max_in, "K " + std::to_string(k));
    std::printf("600x90, HDR stripe, K %.0f px: GL vs CPU %.1f dB\n", k, db);
    if (GetParam() == GlSchedlLayered::Pass::Compute) {
      RgbImage fragment, compute;
      gl_->run_image(im.input(dof::test::lens_with_k(k, 8.0)), {}, {}, compute, nullptr, GlSchedlLayered::Pass::Compute);
      gl_->run_image(im.input(dof::test::lens_with_k(k, 8.0)), {}, {}, fragment, nullptr, GlSchedlLayered::Pass::Fragment);
      EXPECT_GE(test::psnr_shown(compute, fragment), 60.0) << "K " << k;
    }
  }
}

TEST(GlSchedlLayeredPassChoice, TheComputePassRefusesWhereItWasNotBuilt) {
  GlBackend backend;
  backend.context().make_current();
  GlSchedlLayered fragment_only(false);
  EXPECT_FALSE(fragment_only.has_compute());
  RgbImage out;
  DofImage im(8, 8, glm::vec3(0.5f), 2.0f);
  EXPECT_THROW(fragment_only.run_image(im.input(dof::test::lens_with_k(20)), {}, {}, out, nullptr,
                                       GlSchedlLayered::Pass::Compute),
               std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(Passes, GlSchedlLayeredTest,
                         ::testing::Values(GlSchedlLayered::Pass::Fragment, GlSchedlLayered::Pass::Compute),
                         [](const ::testing::TestParamInfo<GlSchedlLayered::Pass>& param) {
                           return param.param == GlSchedlLayered::Pass::Compute ? "Compute" : "Fragment";
                         });

}  // namespace
}  // namespace fovea::render
