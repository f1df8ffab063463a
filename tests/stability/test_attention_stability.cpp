// SPDX-License-Identifier: Apache-2.0
// The attention tracker's hard cases (Lee 2009 ch. 3 on inputs the paper never saw): whatever the
// G-buffer, scene or clock does, every output is finite, S_p lies in [0, 1] and attention is >= 0.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "attention/attention.h"
#include "attention_scene.h"
#include "scene/geometry.h"

using namespace fovea::render;
using namespace fovea::render::attention;

namespace {

using test::add_object;
using test::make_scene;
using test::paint;

GBuffer make_gbuffer(std::uint32_t w, std::uint32_t h) {
  GBuffer g;
  g.resize(w, h);
  std::fill(g.color.begin(), g.color.end(), glm::vec3(0.05f));
  std::fill(g.depth.begin(), g.depth.end(), 100.0f);
  return g;
}


// Every number the tracker hands out is finite; S_p and contrast in range; attention >= 0; sorted.
void expect_sane(const AttentionFrame& f, const char* what) {
  SCOPED_TRACE(what);
  ASSERT_EQ(f.saliency.size(), static_cast<std::size_t>(f.map_width) * static_cast<std::size_t>(f.map_height));
  for (float v : f.saliency) {
    ASSERT_TRUE(std::isfinite(v));
    ASSERT_GE(v, 0.0f);
    ASSERT_LE(v, 1.0f);
  }
  for (const auto& c : f.contrast) {
    ASSERT_EQ(c.size(), f.saliency.size());
    for (float v : c) {
      ASSERT_TRUE(std::isfinite(v));
      ASSERT_GE(v, 0.0f);
    }
  }
  for (std::size_t i = 0; i < f.objects.size(); ++i) {
    const ObjectAttention& o = f.objects[i];
    for (double v : {o.size, o.motion, o.saliency, o.spatial, o.temporal, o.attention_raw, o.attention, o.screen_x,
                     o.screen_y, o.distance_m, o.depth_m}) {
      ASSERT_TRUE(std::isfinite(v)) << "object " << o.id;
    }
    EXPECT_GE(o.attention, 0);
    EXPECT_GE(o.attention_raw, 0);
    EXPECT_GE(o.spatial, 0);
    EXPECT_LE(o.spatial, 0.5 + 1e-12);
    EXPECT_GT(o.pixels, 0u);
    if (i > 0) {
      EXPECT_GE(f.objects[i - 1].attention, o.attention);
    }
  }
  if (f.objects.empty()) {
    EXPECT_EQ(f.most_attended, 0u);
  } else {
    EXPECT_EQ(f.most_attended, f.objects[0].id);
  }
  EXPECT_TRUE(std::isfinite(f.seconds));
  EXPECT_GE(f.seconds, 0);
}

AttentionSettings small(int map = 64) {
  AttentionSettings s;
  s.map_size = map;
  return s;
}

}  // namespace

TEST(AttentionStability, NoVisibleObject) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -4}, 1.0f);
  AttentionTracker tracker(small());
  const AttentionFrame& f = tracker.update(make_gbuffer(80, 60), scene, 0, 0);
  expect_sane(f, "background only");
  EXPECT_TRUE(f.objects.empty());
  EXPECT_EQ(f.most_attended, 0u);
  GBuffer none;  // 0 x 0, no planes at all
  expect_sane(tracker.update(none, scene, 1, 0), "empty G-buffer");
  GBuffer broken = make_gbuffer(80, 60);
  broken.depth.clear();  // missing planes read as far/black/no object
  broken.color.resize(3);
  expect_sane(tracker.update(broken, scene, 2, 1), "missing planes");
  Scene empty_scene = make_scene();
  GBuffer g = make_gbuffer(80, 60);
  paint(g, 10, 10, 30, 30, 7, glm::vec3(1.0f), 3.0f);  // an id the scene does not know
  expect_sane(tracker.update(g, empty_scene, 3, 2), "unknown id");
  EXPECT_TRUE(tracker.last().objects.empty());
}

TEST(AttentionStability, OneObjectCoversTheScreen) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -0.2f}, 1.0f);
  GBuffer g = make_gbuffer(96, 96);
  paint(g, 0, 0, 96, 96, 1, glm::vec3(0.9f, 0.2f, 0.2f), 0.2f);
  AttentionTracker tracker(small());
  const AttentionFrame& f = tracker.update(g, scene, 0, 0);
  expect_sane(f, "full screen");
  ASSERT_EQ(f.objects.size(), 1u);
  EXPECT_NEAR(f.objects[0].size, 1.0, 1e-12);
  EXPECT_EQ(f.objects[0].saliency, 0.0);  // nothing stands out from anything
}

TEST(AttentionStability, ObjectWithZeroPixelsIsNotListed) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -4}, 1.0f);
  add_object(scene, 2, {0, 0, -5}, 1.0f);  // hidden
  Object& empty = add_object(scene, 3, {0, 0, -5}, 1.0f);
  empty.mesh = std::make_shared<Mesh>();  // no vertices at all
  GBuffer g = make_gbuffer(64, 64);
  paint(g, 20, 20, 40, 40, 1, glm::vec3(1.0f), 4.0f);
  paint(g, 50, 50, 51, 51, 3, glm::vec3(1.0f), 5.0f);  // one source pixel: may vanish in a coarser map
  AttentionTracker tracker(small(64));
  const AttentionFrame& f = tracker.update(g, scene, 0.1, 0);
  expect_sane(f, "zero pixels");
  for (const auto& o : f.objects) EXPECT_NE(o.id, 2u);
}

TEST(AttentionStability, LambdaOne) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -4}, 1.0f);
  GBuffer g = make_gbuffer(64, 64);
  paint(g, 20, 20, 40, 40, 1, glm::vec3(1.0f), 4.0f);
  AttentionSettings s = small();
  s.temporal_window = 1;
  AttentionTracker tracker(s);
  for (int k = 0; k < 5; ++k) {
    const AttentionFrame& f = tracker.update(g, scene, k / 60.0, k == 0 ? 0 : (k - 1) / 60.0);
    expect_sane(f, "lambda 1");
    ASSERT_EQ(f.objects.size(), 1u);
    EXPECT_DOUBLE_EQ(f.objects[0].temporal, f.objects[0].spatial);
  }
}

TEST(AttentionStability, TenSecondGapAndTimeGoingBackwards) {
  Scene scene = make_scene();
  Object& o = add_object(scene, 1, {0, 0, -4}, 1.0f);
  Animation a;
  a.keys = {{0, {0, 0, 0}, {0, 0, 0}}, {2, {3, 0, 0}, {0, 360, 0}}, {4, {0, 0, 0}, {0, 0, 0}}};
  o.animation = a;
  Animation cam;
  cam.keys = {{0, {0, 0, 0}, {}}, {5, {0, 0, -3}, {}}};
  scene.camera.animation = cam;
  GBuffer g = make_gbuffer(64, 64);
  paint(g, 20, 20, 40, 40, 1, glm::vec3(1.0f), 4.0f);
  AttentionTracker tracker(small());
  double t = 0;
  for (int k = 0; k < 10; ++k, t += 1.0 / 60) expect_sane(tracker.update(g, scene, t, t - 1.0 / 60), "normal");
  expect_sane(tracker.update(g, scene, t + 10, t), "10 s gap");
  expect_sane(tracker.update(g, scene, t + 10.1, t + 10), "after the gap");
  expect_sane(tracker.update(g, scene, t - 5, t + 10.1), "backwards");
  expect_sane(tracker.update(g, scene, 1e12, -1e12), "absurd times");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  expect_sane(tracker.update(g, scene, nan, 0), "NaN time");
  expect_sane(tracker.update(g, scene, 1, nan), "NaN previous time");
  expect_sane(tracker.update(g, scene, std::numeric_limits<double>::infinity(), 0), "infinite time");
  expect_sane(tracker.update(g, scene, 2, 1), "recovered");
  ASSERT_EQ(tracker.last().objects.size(), 1u);
  EXPECT_GT(tracker.last().objects[0].attention, 0);
}

TEST(AttentionStability, NanObjectPositions) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Scene scene = make_scene();
  Object& animated = add_object(scene, 1, {0, 0, -4}, 1.0f);
  Animation a;
  a.keys = {{0, {0, 0, 0}, {}}, {1, {nan, 0, 0}, {0, nan, 0}}};
  animated.animation = a;
  add_object(scene, 2, {nan, nan, nan}, 1.0f);
  Object& inf = add_object(scene, 3, {0, 0, -4}, 1.0f);
  inf.transform.scale = glm::vec3(std::numeric_limits<float>::infinity());
  Mesh bad = make_box({1, 1, 1});
  bad.positions[0] = glm::vec3(nan);
  add_object(scene, 4, {1, 0, -4}, 1.0f).mesh = std::make_shared<Mesh>(bad);
  GBuffer g = make_gbuffer(64, 64);
  paint(g, 4, 4, 20, 20, 1, glm::vec3(1.0f), 4.0f);
  paint(g, 24, 4, 40, 20, 2, glm::vec3(0.2f, 1.0f, 0.2f), 4.0f);
  paint(g, 44, 4, 60, 20, 3, glm::vec3(0.2f, 0.2f, 1.0f), 4.0f);
  paint(g, 4, 40, 20, 60, 4, glm::vec3(1.0f, 0.2f, 0.2f), 4.0f);
  AttentionTracker tracker(small());
  for (int k = 0; k < 4; ++k) {
    const AttentionFrame& f = tracker.update(g, scene, 0.5 + k / 60.0, 0.5 + (k - 1) / 60.0);
    expect_sane(f, "NaN positions");
    EXPECT_EQ(f.objects.size(), 4u);
  }
  // NaN camera position too.
  Animation cam;
  cam.keys = {{0, {0, 0, 0}, {}}, {1, {nan, nan, nan}, {}}};
  scene.camera.animation = cam;
  expect_sane(tracker.update(g, scene, 0.7, 0.6), "NaN camera");
}

TEST(AttentionStability, AllSaliencyEqual) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -4}, 1.0f);
  for (glm::vec3 c : {glm::vec3(0.0f), glm::vec3(1.0f), glm::vec3(0.5f, 0.2f, 0.9f)}) {
    GBuffer g = make_gbuffer(64, 64);
    std::fill(g.color.begin(), g.color.end(), c);
    AttentionTracker tracker(small());
    const AttentionFrame& f = tracker.update(g, scene, 0, 0);
    expect_sane(f, "uniform");
    for (float v : f.saliency) EXPECT_EQ(v, 0.0f);
  }
  // Degenerate clip planes (far == near) and a scene with no importance at all.
  Scene odd = make_scene();
  odd.camera.far_m = odd.camera.near_m;
  add_object(odd, 1, {0, 0, -4}, 0.0f);
  GBuffer g = make_gbuffer(64, 64);
  paint(g, 10, 10, 30, 30, 1, glm::vec3(1.0f), 4.0f);
  AttentionTracker tracker(small());
  expect_sane(tracker.update(g, odd, 0, 0), "far == near, T_i = 0");
  EXPECT_TRUE(tracker.last().objects.empty());
}

TEST(AttentionStability, ManyObjects) {
  Scene scene = make_scene();
  const std::uint32_t count = 300;
  GBuffer g = make_gbuffer(300, 200);
  for (std::uint32_t k = 0; k < count; ++k) {
    const std::uint32_t id = 1000 + k * 7;  // sparse ids
    add_object(scene, id, {static_cast<float>(k % 20) - 10, 0, -2 - static_cast<float>(k / 20)}, 0.1f + 0.003f * static_cast<float>(k));
    const std::uint32_t x = (k % 30) * 10, y = (k / 30) * 20;
    paint(g, x, y, x + 10, y + 20, id, glm::vec3(static_cast<float>(k % 7) / 7.0f, 0.5f, static_cast<float>(k % 3) / 3.0f),
          2.0f + static_cast<float>(k % 11));
  }
  AttentionSettings s = small(128);
  s.temporal_window = 3;
  AttentionTracker tracker(s);
  for (int f = 0; f < 5; ++f) {
    const AttentionFrame& frame = tracker.update(g, scene, f / 60.0, (f - 1) / 60.0);
    expect_sane(frame, "300 objects");
    EXPECT_EQ(frame.objects.size(), count);
  }
  // All of them leave the view; their tracks go after lambda frames, and nothing breaks.
  const GBuffer empty = make_gbuffer(300, 200);
  for (int f = 5; f < 10; ++f) expect_sane(tracker.update(empty, scene, f / 60.0, (f - 1) / 60.0), "all gone");
  expect_sane(tracker.update(g, scene, 11 / 60.0, 10 / 60.0), "back");
}

TEST(AttentionStability, SettingsChangesAndMapSizes) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -4}, 1.0f);
  GBuffer g = make_gbuffer(7, 3);  // far smaller than any map
  paint(g, 2, 1, 5, 2, 1, glm::vec3(1.0f, 0.0f, 0.0f), 4.0f);
  AttentionTracker tracker(small());
  for (int map : {64, 65, 100, 127, 256, 512}) {
    AttentionSettings s = small(map);
    s.temporal_window = map % 7 + 1;
    tracker.set_settings(s);
    const AttentionFrame& f = tracker.update(g, scene, 0, 0);
    expect_sane(f, "map sizes");
    EXPECT_EQ(f.map_width, map);
    EXPECT_EQ(f.map_height, map);
  }
  AttentionSettings bad;
  bad.map_size = 1000;
  EXPECT_THROW(tracker.set_settings(bad), std::invalid_argument);
  EXPECT_EQ(tracker.settings().map_size, 512);
}

TEST(AttentionStability, RandomGBuffersAndScenes) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int trial = 0; trial < 12; ++trial) {
    test::RandomCase c = test::random_attention_case(rng);
    const Scene& scene = c.scene;
    const GBuffer& g = c.g;
    AttentionSettings s = small(64 + static_cast<int>(rng() % 200));
    s.groups = {u(rng) < 0.7f, u(rng) < 0.7f, u(rng) < 0.7f};
    s.temporal_window = 1 + static_cast<int>(rng() % 40);
    s.kalman = u(rng) < 0.7f;
    AttentionTracker tracker(s);
    double t = u(rng) * 10;
    for (int f = 0; f < 4; ++f) {
      const double step = (u(rng) < 0.2f ? -1.0 : 1.0) * static_cast<double>(u(rng)) * 0.5;
      expect_sane(tracker.update(g, scene, t + step, t), "random");
      t += step;
    }
  }
}
