// SPDX-License-Identifier: Apache-2.0
// Lee 2009 ch. 3's pixel stage on the GPU (backend/gl/gl_attention.h) against its CPU reference
// (attention/attention.h): the bundled scenes' G-buffers with every setting, and the CPU's stability
// catalogue (tests/stability/test_attention_stability.cpp) run through the GPU: no visible object,
// one object over the whole screen, ids the scene does not know, NaN / +-Inf / negative / 1e30
// depths and colours, HDR 1e6, 1x1 and 1xN G-buffers, missing planes, odd map sizes, every feature
// group off. Runs through EGL with DISPLAY unset.
//
// Tolerances (the GPU sums in float and takes cos/sin where the CPU adds in double and reads a
// table): S_p and the contrast maps within 2e-4 of the CPU's (relative to the map's largest value);
// per object the same pixel count and the same median depth (both exact), S^_o within 1e-4
// relative, the centroid within 1e-5 of the screen.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <random>
#include <vector>

#include "attention/attention.h"
#include "attention_scene.h"
#include "backend/gl/gl_attention.h"
#include "backend/gl/gl_backend.h"
#include "scene/scene_loader.h"

namespace fovea::render {
namespace {

using attention::AttentionFrame;
using attention::AttentionSettings;
using attention::AttentionTracker;
using attention::ObjectAttention;
using attention::ObjectPixels;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr double kMapTolerance = 2e-4, kSaliencyTolerance = 1e-4, kCentroidTolerance = 1e-5;

// The largest |a - b| over two maps, relative to the larger of their largest values (1 at least).
double map_error(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size()) return std::numeric_limits<double>::infinity();
  double err = 0, scale = 1;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!std::isfinite(a[i]) || !std::isfinite(b[i])) return std::numeric_limits<double>::infinity();
    err = std::max(err, std::fabs(static_cast<double>(a[i]) - static_cast<double>(b[i])));
    scale = std::max({scale, std::fabs(static_cast<double>(a[i])), std::fabs(static_cast<double>(b[i]))});
  }
  return err / scale;
}

// Every test runs on both implementations: the fragment passes and the compute passes.
class GlAttentionTest : public ::testing::TestWithParam<GlAttention::Pass> {
 protected:
  void SetUp() override {
    backend_ = std::make_unique<GlBackend>();
    backend_->context().make_current();
    gl_ = std::make_unique<GlAttention>(backend_->context().features().at_least(4, 3));
    if (GetParam() == GlAttention::Pass::Compute && !gl_->has_compute()) GTEST_SKIP() << "no OpenGL 4.3 compute";
  }

  // The scene's objects with their B_m between the two times, as the pipeline hands them over.
  static GlAttentionObjects objects_of(const Scene& scene, AttentionTracker& tracker, double t, double tp) {
    GlAttentionObjects o;
    for (const Object& obj : scene.objects) {
      o.ids.push_back(obj.id);
      o.motion.push_back(tracker.object_motion(obj, t, tp));
    }
    return o;
  }

  // One frame through both pixel stages and the same object stage; returns the largest map error.
  double expect_agree(const GBuffer& g, const Scene& scene, const AttentionSettings& s, const std::string& what,
                      double t = 0.5, double tp = 0.45) {
    SCOPED_TRACE(what);
    AttentionTracker cpu(s), gpu(s);
    const AttentionFrame& fc = cpu.update(g, scene, t, tp);
    std::vector<ObjectPixels> pixels;
    gl_->run_gbuffer(g, scene.camera.near_m, scene.camera.far_m, s, objects_of(scene, gpu, t, tp), pixels, nullptr,
                     GetParam());
    const AttentionFrame& fg = gpu.update_objects(pixels, s.map_size, scene, t, tp);
    std::vector<float> saliency, contrast[5];
    gl_->read_saliency(saliency);
    gl_->read_contrast(contrast);
    double worst = map_error(saliency, fc.saliency);
    EXPECT_LE(worst, kMapTolerance) << "S_p";
    for (int f = 0; f < 5; ++f) {
      const double e = map_error(contrast[f], fc.contrast[f]);
      EXPECT_LE(e, kMapTolerance) << "contrast map " << f;
      worst = std::max(worst, e);
    }
    EXPECT_EQ(fg.objects.size(), fc.objects.size());
    listed_ = fc.objects.size();
    std::map<std::uint32_t, const ObjectAttention*> by_id;
    for (const ObjectAttention& o : fc.objects) by_id[o.id] = &o;
    for (const ObjectAttention& o : fg.objects) {
      EXPECT_EQ(by_id.count(o.id), 1u) << "object " << o.id << " listed on the GPU only";
      if (by_id.count(o.id) == 0) continue;
      const ObjectAttention& c = *by_id[o.id];
      EXPECT_EQ(o.pixels, c.pixels) << "object " << o.id;
      EXPECT_EQ(o.depth_m, c.depth_m) << "object " << o.id;
      EXPECT_EQ(o.size, c.size) << "object " << o.id;
      EXPECT_EQ(o.motion, c.motion) << "object " << o.id;
      EXPECT_NEAR(o.saliency, c.saliency, kSaliencyTolerance * std::max(1e-3, c.saliency)) << "object " << o.id;
      EXPECT_NEAR(o.screen_x, c.screen_x, kCentroidTolerance) << "object " << o.id;
      EXPECT_NEAR(o.screen_y, c.screen_y, kCentroidTolerance) << "object " << o.id;
      EXPECT_NEAR(o.attention, c.attention, kSaliencyTolerance * std::max(1e-3, c.attention)) << "object " << o.id;
    }
    return worst;
  }

  std::unique_ptr<GlBackend> backend_;
  std::unique_ptr<GlAttention> gl_;
  std::size_t listed_ = 0;  // the objects the last expect_agree compared
};

GBuffer blank(std::uint32_t w, std::uint32_t h) {
  GBuffer g;
  g.resize(w, h);
  std::fill(g.color.begin(), g.color.end(), glm::vec3(0.05f));
  std::fill(g.depth.begin(), g.depth.end(), 100.0f);
  return g;
}

TEST_P(GlAttentionTest, AgreesWithTheCpuOnTheBundledScenes) {
  for (const char* name : {"attention.json", "occlusion.json", "cornell.json"}) {
    Scene scene = load_scene(std::filesystem::path(FOVEA_SOURCE_DIR) / "renderer/scenes" / name);
    scene.camera.width = 320;
    scene.camera.height = 240;
    backend_->set_scene(scene);
    GBuffer g;
    backend_->render({0.5, 0.45}, {}, g);
    backend_->context().make_current();
    for (int map : {64, 256}) {
      AttentionSettings s;
      s.map_size = map;
      const double e = expect_agree(g, scene, s, std::string(name) + " map " + std::to_string(map));
      EXPECT_GE(listed_, 1u) << name;  // objects were compared
      std::printf("%-15s map %3d: %zu objects; largest map difference GL vs CPU %.2e\n", name, map, listed_, e);
    }
  }
}

TEST_P(GlAttentionTest, AgreesWithTheCpuWithEverySetting) {
  Scene scene = load_scene(std::filesystem::path(FOVEA_SOURCE_DIR) / "renderer/scenes/attention.json");
  scene.camera.width = 333;  // not a multiple of any map size: uneven boxes
  scene.camera.height = 201;
  backend_->set_scene(scene);
  GBuffer g;
  backend_->render({1.0, 0.9}, {}, g);
  backend_->context().make_current();
  for (int variant = 0; variant < 7; ++variant) {
    AttentionSettings s;
    s.map_size = variant == 5 ? 97 : variant == 6 ? 512 : 128;
    s.resample = variant == 1 ? attention::Resample::Nearest : attention::Resample::Box;
    s.groups.image = variant != 2 && variant != 4;
    s.groups.object = variant != 3 && variant != 4;
    s.groups.context = variant != 4;
    expect_agree(g, scene, s, "variant " + std::to_string(variant), 1.0, 0.9);
  }
}

// The stability catalogue's G-buffers, through the GPU.
TEST_P(GlAttentionTest, HardCasesAgreeWithTheCpu) {
  Scene scene = test::make_scene();
  test::add_object(scene, 1, {0, 0, -4}, 1.0f);
  test::add_object(scene, 2, {1, 0, -8}, 0.5f);
  test::add_object(scene, 7, {-1, 0, -2}, 0.0f);  // background
  AttentionSettings s;
  s.map_size = 64;
  {
    expect_agree(blank(40, 30), scene, s, "no visible object");
  }
  {
    GBuffer g = blank(40, 30);
    test::paint(g, 0, 0, 40, 30, 1, glm::vec3(0.3f, 0.6f, 0.1f), 4.0f);
    expect_agree(g, scene, s, "one object covers the screen");
  }
  {
    GBuffer g = blank(120, 90);
    test::paint(g, 10, 10, 60, 50, 1, glm::vec3(1e6f, 0.5f, 0.0f), kNaN);  // HDR 1e6, NaN depth
    test::paint(g, 60, 40, 100, 80, 2, glm::vec3(kInf, kNaN, -1.0f), kInf);
    test::paint(g, 0, 80, 30, 90, 99, glm::vec3(0.2f), -kInf);  // an id the scene does not know
    test::paint(g, 100, 0, 120, 20, 7, glm::vec3(0.9f, 0.1f, 0.9f), 0.0f);
    for (int map : {64, 65, 127, 200}) {
      s.map_size = map;
      expect_agree(g, scene, s, "specials, map " + std::to_string(map));
    }
    s.map_size = 64;
  }
  for (auto [w, h] : {std::pair<std::uint32_t, std::uint32_t>{1, 1}, {1, 37}, {53, 1}, {7, 3}}) {
    GBuffer g = blank(w, h);
    test::paint(g, 0, 0, std::max(1u, w / 2), std::max(1u, h / 2), 1, glm::vec3(1.0f, 0.0f, 0.0f), 1e30f);
    expect_agree(g, scene, s, "tiny " + std::to_string(w) + "x" + std::to_string(h));
  }
  {
    GBuffer g = blank(50, 40);
    test::paint(g, 5, 5, 30, 30, 2, glm::vec3(0.1f, 0.9f, 0.3f), 6.0f);
    GBuffer no_depth = g;
    no_depth.depth.clear();
    expect_agree(no_depth, scene, s, "no depth plane");
    GBuffer no_ids = g;
    no_ids.object_id.clear();
    expect_agree(no_ids, scene, s, "no id plane");
    GBuffer no_color = g;
    no_color.color.clear();
    expect_agree(no_color, scene, s, "no colour plane");
    expect_agree(GBuffer{}, scene, s, "an empty G-buffer");
    AttentionSettings off = s;
    off.groups = {false, false, false};
    expect_agree(g, scene, off, "every group off");
  }
}

TEST_P(GlAttentionTest, RandomGBuffersAndScenesAgreeWithTheCpu) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int trial = 0; trial < 8; ++trial) {
    const test::RandomCase c = test::random_attention_case(rng, 37, 5);
    const Scene& scene = c.scene;
    const GBuffer& g = c.g;
    AttentionSettings s;
    s.map_size = 64 + static_cast<int>(rng() % 200);
    s.groups = {u(rng) < 0.7f, u(rng) < 0.7f, u(rng) < 0.7f};
    s.resample = u(rng) < 0.3f ? attention::Resample::Nearest : attention::Resample::Box;
    expect_agree(g, scene, s, "random trial " + std::to_string(trial), 0.3 + trial, 0.25 + trial);
  }
}

TEST_P(GlAttentionTest, RefusesMotionValuesNotOnePerId) {
  GlAttentionObjects o;
  o.ids = {1, 2};
  o.motion = {0.0f};
  std::vector<ObjectPixels> out;
  EXPECT_THROW(gl_->run_gbuffer(blank(8, 8), 0.1, 100, AttentionSettings{}, o, out, nullptr, GetParam()),
               std::invalid_argument);
  AttentionSettings bad;
  bad.map_size = 10;
  o.motion = {0.0f, 0.0f};
  EXPECT_THROW(gl_->run_gbuffer(blank(8, 8), 0.1, 100, bad, o, out, nullptr, GetParam()), std::invalid_argument);
}

// The compute passes run the fragment passes' GLSL functions, but for the resample, whose 64
// invocations per map pixel add the box in another order: S_p agrees within the CPU reference's
// tolerance (measured 3e-5), the per-object pixels and median depths exactly.
TEST_P(GlAttentionTest, TheComputeAndFragmentPassesAgree) {
  if (GetParam() != GlAttention::Pass::Compute) GTEST_SKIP() << "compared once, from the compute side";
  const Scene scene = load_scene(std::filesystem::path(FOVEA_SOURCE_DIR) / "renderer/scenes/attention.json");
  GBuffer g;
  backend_->set_scene(scene);
  backend_->render(FrameTime{0.5, 0.45}, BackendSettings{}, g);
  AttentionTracker tracker{AttentionSettings{}};
  const GlAttentionObjects objects = objects_of(scene, tracker, 0.5, 0.45);
  std::vector<ObjectPixels> out[2];
  std::vector<float> saliency[2];
  // Compute first, on targets no fragment pass wrote.
  for (const GlAttention::Pass pass : {GlAttention::Pass::Compute, GlAttention::Pass::Fragment}) {
    const int k = pass == GlAttention::Pass::Compute ? 0 : 1;
    gl_->run_gbuffer(g, scene.camera.near_m, scene.camera.far_m, AttentionSettings{}, objects, out[k], nullptr, pass);
    gl_->read_saliency(saliency[k]);
  }
  EXPECT_LE(map_error(saliency[0], saliency[1]), kMapTolerance);
  ASSERT_EQ(out[0].size(), out[1].size());
  ASSERT_GT(out[0].size(), 3u);
  for (std::size_t i = 0; i < out[0].size(); ++i) {
    EXPECT_EQ(out[0][i].id, out[1][i].id);
    EXPECT_EQ(out[0][i].pixels, out[1][i].pixels);
    EXPECT_EQ(out[0][i].depth_m, out[1][i].depth_m);
    EXPECT_NEAR(out[0][i].sum_saliency, out[1][i].sum_saliency, 1e-5 * std::max(1.0, out[1][i].sum_saliency));
  }
}

TEST(GlAttentionPassChoice, TheComputePassRefusesWhereItWasNotBuilt) {
  GlBackend backend;
  backend.context().make_current();
  GlAttention fragment_only(false);
  EXPECT_FALSE(fragment_only.has_compute());
  std::vector<ObjectPixels> out;
  EXPECT_THROW(fragment_only.run_gbuffer(blank(8, 8), 0.1, 100, AttentionSettings{}, GlAttentionObjects{}, out, nullptr,
                                         GlAttention::Pass::Compute),
               std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(Passes, GlAttentionTest,
                         ::testing::Values(GlAttention::Pass::Fragment, GlAttention::Pass::Compute),
                         [](const ::testing::TestParamInfo<GlAttention::Pass>& param) {
                           return param.param == GlAttention::Pass::Compute ? "Compute" : "Fragment";
                         });

}  // namespace
}  // namespace fovea::render
