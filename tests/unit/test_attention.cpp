// SPDX-License-Identifier: Apache-2.0
// Visual attention tracking (Lee 2009 ch. 3) on hand-made G-buffers: the bottom-up saliency map
// (eqs. 3.1-3.6), the object level (eq. 3.7), the top-down contexts (eqs. 3.8-3.10), the Kalman
// filter and the feature-group switches.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "attention/attention.h"
#include "attention_scene.h"
#include "scene/geometry.h"

using namespace fovea::render;
using namespace fovea::render::attention;

namespace {

using test::add_object;
using test::make_scene;
using test::paint;

GBuffer make_gbuffer(std::uint32_t w, std::uint32_t h, glm::vec3 background = glm::vec3(0.05f), float far_m = 100) {
  GBuffer g;
  g.resize(w, h);
  std::fill(g.color.begin(), g.color.end(), background);
  std::fill(g.depth.begin(), g.depth.end(), far_m);
  return g;
}


AttentionSettings small(int map = 64) {
  AttentionSettings s;
  s.map_size = map;
  return s;
}

const ObjectAttention* find(const AttentionFrame& f, std::uint32_t id) {
  for (const auto& o : f.objects) {
    if (o.id == id) return &o;
  }
  return nullptr;
}

}  // namespace

TEST(AttentionSaliency, BrightSquarePeaksOnTheSquareAndIsZeroFarAway) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -4}, 1.0f);
  GBuffer g = make_gbuffer(128, 128);
  paint(g, 32, 32, 64, 64, 1, glm::vec3(1.0f), 4.0f);  // map pixels 16..32 at map size 64
  AttentionTracker tracker(small(64));
  const AttentionFrame& f = tracker.update(g, scene, 0, 0);
  ASSERT_EQ(f.map_width, 64);
  ASSERT_EQ(f.saliency.size(), 64u * 64u);
  const auto it = std::max_element(f.saliency.begin(), f.saliency.end());
  EXPECT_FLOAT_EQ(*it, 1.0f);
  const auto peak = static_cast<int>(it - f.saliency.begin());
  const int px = peak % 64, py = peak / 64;
  EXPECT_GE(px, 12);
  EXPECT_LE(px, 36);
  EXPECT_GE(py, 12);
  EXPECT_LE(py, 36);
  // Far from the square (the opposite corner) the map is ~0.
  for (int y = 56; y < 64; ++y) {
    for (int x = 56; x < 64; ++x) EXPECT_LT(f.saliency[static_cast<std::size_t>(y * 64 + x)], 0.05f) << x << "," << y;
  }
  // The square's mean saliency is far above the background's mean.
  double in = 0, out = 0;
  int n_in = 0, n_out = 0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      const double v = f.saliency[static_cast<std::size_t>(y * 64 + x)];
      if (x >= 16 && x < 32 && y >= 16 && y < 32) {
        in += v;
        ++n_in;
      } else if (x >= 48 || y >= 48) {
        out += v;
        ++n_out;
      }
    }
  }
  EXPECT_GT(in / n_in, 5 * out / n_out);
  ASSERT_EQ(f.objects.size(), 1u);
  EXPECT_EQ(f.most_attended, 1u);
  EXPECT_EQ(f.objects[0].pixels, 16u * 16u);
  EXPECT_NEAR(f.objects[0].size, 32.0 * 32.0 / (128.0 * 128.0), 1e-9);  // eq. 3.2 on the item buffer
  EXPECT_NEAR(f.objects[0].screen_x, 0.375, 1e-9);
  EXPECT_NEAR(f.objects[0].screen_y, 0.375, 1e-9);
  EXPECT_NEAR(f.objects[0].depth_m, 4.0, 1e-6);
}

// attention.resample: box sees a one-pixel light between the map pixels' centres (a quarter of a
// map pixel's box); nearest reads only the pixel under each centre and misses it (the aliasing its
// setting's help names).
TEST(AttentionSaliency, BoxResampleSeesAOnePixelLightNearestMissesIt) {
  Scene scene = make_scene();
  GBuffer g = make_gbuffer(128, 128, glm::vec3(0.0f));
  paint(g, 40, 40, 41, 41, 0, glm::vec3(1.0f), 100.0f);  // map 64: box of pixel 20 is source 40..41, centre 41
  AttentionSettings box = small(64), nearest = small(64);
  nearest.resample = Resample::Nearest;
  AttentionTracker tb(box), tn(nearest);
  const AttentionFrame& fb = tb.update(g, scene, 0, 0);
  EXPECT_GT(*std::max_element(fb.contrast[0].begin(), fb.contrast[0].end()), 0.0f);
  EXPECT_FLOAT_EQ(fb.saliency[20 * 64 + 20], 1.0f);  // the light's map pixel is the peak
  const AttentionFrame& fn = tn.update(g, scene, 0, 0);
  EXPECT_EQ(*std::max_element(fn.contrast[0].begin(), fn.contrast[0].end()), 0.0f);
  // Moved under a centre, nearest sees it too.
  paint(g, 40, 40, 41, 41, 0, glm::vec3(0.0f), 100.0f);
  paint(g, 41, 41, 42, 42, 0, glm::vec3(1.0f), 100.0f);
  const AttentionFrame& fn2 = tn.update(g, scene, 0, 0);
  EXPECT_FLOAT_EQ(fn2.saliency[20 * 64 + 20], 1.0f);
}

TEST(AttentionSaliency, CentreSurroundOfAConstantMapIsZero) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -4}, 1.0f);
  GBuffer g = make_gbuffer(100, 60, glm::vec3(0.3f, 0.6f, 0.2f));
  paint(g, 0, 0, 100, 60, 1, glm::vec3(0.3f, 0.6f, 0.2f), 4.0f);  // one object covers everything
  AttentionTracker tracker(small(96));
  const AttentionFrame& f = tracker.update(g, scene, 0, 0);
  for (const auto& c : f.contrast) {
    ASSERT_EQ(c.size(), 96u * 96u);
    for (float v : c) EXPECT_NEAR(v, 0.0f, 1e-6f);
  }
  for (float v : f.saliency) EXPECT_EQ(v, 0.0f);  // all equal -> all 0, never NaN
}

TEST(AttentionSaliency, WeightsNormaliseEachContrastMapByItsMaximum) {
  Scene scene = make_scene();
  add_object(scene, 1, {-1, 0, -3}, 1.0f);
  add_object(scene, 2, {1, 0, -8}, 1.0f);
  GBuffer g = make_gbuffer(128, 128);
  paint(g, 10, 20, 40, 60, 1, glm::vec3(0.9f, 0.1f, 0.1f), 3.0f);
  paint(g, 80, 70, 120, 90, 2, glm::vec3(0.1f, 0.2f, 0.9f), 8.0f);
  AttentionTracker tracker(small(64));
  const AttentionFrame& f = tracker.update(g, scene, 0, 0);
  // Eqs. 3.5-3.6 recomputed from the exposed contrast maps, then normalised to [0, 1].
  std::vector<double> sbar(f.saliency.size(), 0.0);
  for (const auto& c : f.contrast) {
    const float mx = *std::max_element(c.begin(), c.end());
    if (mx <= 0) continue;
    for (std::size_t i = 0; i < c.size(); ++i) sbar[i] += static_cast<double>(c[i]) / static_cast<double>(mx);
  }
  const auto [lo, hi] = std::minmax_element(sbar.begin(), sbar.end());
  ASSERT_GT(*hi - *lo, 0);
  for (std::size_t i = 0; i < sbar.size(); ++i) {
    EXPECT_NEAR(f.saliency[i], (sbar[i] - *lo) / (*hi - *lo), 1e-5);
  }
  EXPECT_FLOAT_EQ(*std::max_element(f.saliency.begin(), f.saliency.end()), 1.0f);
  EXPECT_FLOAT_EQ(*std::min_element(f.saliency.begin(), f.saliency.end()), 0.0f);
  // Size (C_s) and hue (C_h) have contrast here; motion (C_m) has none (static scene).
  EXPECT_GT(*std::max_element(f.contrast[1].begin(), f.contrast[1].end()), 0.0f);
  EXPECT_GT(*std::max_element(f.contrast[3].begin(), f.contrast[3].end()), 0.0f);
  EXPECT_EQ(*std::max_element(f.contrast[4].begin(), f.contrast[4].end()), 0.0f);
}

TEST(AttentionSaliency, GreyHasNoHueContrast) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -4}, 1.0f);
  GBuffer g = make_gbuffer(64, 64, glm::vec3(0.0f));
  paint(g, 16, 16, 48, 48, 1, glm::vec3(0.7f), 100.0f);  // grey on black at the far plane
  AttentionTracker tracker(small(64));
  const AttentionFrame& f = tracker.update(g, scene, 0, 0);
  for (float v : f.contrast[1]) EXPECT_EQ(v, 0.0f);
  EXPECT_GT(*std::max_element(f.contrast[0].begin(), f.contrast[0].end()), 0.0f);
}

TEST(AttentionObjects, OrderFollowsTaskImportanceWhenSaliencyIsEqual) {
  for (bool context : {false, true}) {
    Scene scene = make_scene();
    add_object(scene, 1, {-1, 0, -4}, 0.3f);
    add_object(scene, 2, {1, 0, -4}, 0.9f);
    add_object(scene, 3, {0, 2, -4}, 0.0f);  // background: never listed
    GBuffer g = make_gbuffer(128, 128);
    // Mirror-symmetric about the vertical centre line: equal saliency, equal screen distance.
    paint(g, 24, 48, 48, 80, 1, glm::vec3(0.8f, 0.5f, 0.1f), 4.0f);
    paint(g, 80, 48, 104, 80, 2, glm::vec3(0.8f, 0.5f, 0.1f), 4.0f);
    paint(g, 56, 4, 72, 20, 3, glm::vec3(0.9f, 0.9f, 0.2f), 4.0f);
    AttentionSettings s = small(64);
    s.groups.context = context;
    AttentionTracker tracker(s);
    const AttentionFrame& f = tracker.update(g, scene, 0, 0);
    ASSERT_EQ(f.objects.size(), 2u) << context;
    EXPECT_EQ(f.objects[0].id, 2u);
    EXPECT_EQ(f.objects[1].id, 1u);
    EXPECT_EQ(f.most_attended, 2u);
    EXPECT_NEAR(f.objects[0].saliency / 0.9, f.objects[1].saliency / 0.3, 1e-6);  // eq. 3.7
    EXPECT_GT(f.objects[1].attention, 0);
    if (!context) {
      EXPECT_DOUBLE_EQ(f.objects[0].attention_raw, f.objects[0].saliency);
    }
  }
}

TEST(AttentionContext, ObjectMovingAwayWhileObserverMovesForwardGetsZero) {
  Scene scene = make_scene();
  Animation forward;  // the observer moves 1 m/s towards -z (its viewing direction)
  forward.loop = false;
  forward.keys = {{0, {0, 0, 0}, {}}, {10, {0, 0, -10}, {}}};
  scene.camera.animation = forward;
  Object& away = add_object(scene, 1, {-1, 0, -4}, 1.0f);
  Animation faster;  // 3 m/s away from the observer
  faster.loop = false;
  faster.keys = {{0, {0, 0, 0}, {}}, {10, {0, 0, -30}, {}}};
  away.animation = faster;
  add_object(scene, 2, {1, 0, -4}, 1.0f);  // static: the observer approaches it
  GBuffer g = make_gbuffer(128, 128);
  paint(g, 24, 48, 48, 80, 1, glm::vec3(0.8f, 0.5f, 0.1f), 4.0f);
  paint(g, 80, 48, 104, 80, 2, glm::vec3(0.8f, 0.5f, 0.1f), 4.0f);
  AttentionTracker tracker(small(64));
  const AttentionFrame& f = tracker.update(g, scene, 1.0, 1.0 - 1.0 / 60);
  const ObjectAttention* a = find(f, 1);
  const ObjectAttention* b = find(f, 2);
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(a->spatial, 0.0);
  EXPECT_GT(b->spatial, 0.0);
  EXPECT_GT(a->motion, 0.04);  // 3 m/s over 1/60 s = 0.05 m per frame
  EXPECT_LT(a->motion, 0.06);
  EXPECT_EQ(f.most_attended, 2u);

  // The same object moving away while the observer stands still is not excluded.
  scene.camera.animation.reset();
  const AttentionFrame& still = tracker.update(g, scene, 1.0, 1.0 - 1.0 / 60);
  EXPECT_GT(find(still, 1)->spatial, 0.0);
}

TEST(AttentionContext, WeibullPeaksAtPreferredDistance) {
  const double L = 4.0;
  const auto spatial_at = [&](double x) {
    Scene scene = make_scene();
    add_object(scene, 1, {0, 0, static_cast<float>(-x)}, 1.0f);
    GBuffer g = make_gbuffer(64, 64);
    paint(g, 24, 24, 40, 40, 1, glm::vec3(1.0f), static_cast<float>(x));  // centroid at the screen centre
    AttentionSettings s = small(64);
    s.preferred_distance_m = L;
    AttentionTracker tracker(s);
    const AttentionFrame& f = tracker.update(g, scene, 0, 0);
    EXPECT_EQ(f.objects.size(), 1u);
    EXPECT_NEAR(f.objects[0].distance_m, x, 1e-5);
    return f.objects.empty() ? -1.0 : f.objects[0].spatial;
  };
  EXPECT_NEAR(spatial_at(L), 0.5, 1e-6);  // c_s makes the maximum exactly 0.5
  EXPECT_LT(spatial_at(0.8 * L), spatial_at(L));
  EXPECT_LT(spatial_at(1.25 * L), spatial_at(L));
  EXPECT_LT(spatial_at(0.5 * L), spatial_at(0.9 * L));
  // Off the screen centre: e^{-c_y y^2} with y = 1 at a corner.
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, static_cast<float>(-L)}, 1.0f);
  GBuffer g = make_gbuffer(64, 64);
  paint(g, 0, 0, 2, 2, 1, glm::vec3(1.0f), static_cast<float>(L));  // the top-left corner
  AttentionTracker tracker(small(64));
  const AttentionFrame& f = tracker.update(g, scene, 0, 0);
  ASSERT_EQ(f.objects.size(), 1u);
  const double y = std::hypot(f.objects[0].screen_x - 0.5, f.objects[0].screen_y - 0.5) / std::sqrt(0.5);
  EXPECT_NEAR(f.objects[0].spatial, 0.5 * std::exp(-4.0 * y * y), 1e-6);
}

TEST(AttentionContext, TemporalContextIsTheMeanOverLambdaFrames) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -4}, 1.0f);
  GBuffer g = make_gbuffer(64, 64);
  paint(g, 24, 24, 40, 40, 1, glm::vec3(1.0f), 4.0f);
  GBuffer empty = make_gbuffer(64, 64);
  AttentionSettings s = small(64);
  s.temporal_window = 4;
  s.kalman = false;
  AttentionTracker tracker(s);
  double ts = 0;
  for (int k = 1; k <= 6; ++k) {
    const AttentionFrame& f = tracker.update(g, scene, k / 60.0, (k - 1) / 60.0);
    ASSERT_EQ(f.objects.size(), 1u);
    ts = f.objects[0].spatial;
    EXPECT_NEAR(f.objects[0].temporal, ts * std::min(k, 4) / 4.0, 1e-12) << k;
    EXPECT_NEAR(f.objects[0].attention_raw, (f.objects[0].spatial + f.objects[0].temporal) * f.objects[0].saliency,
                1e-12);
  }
  // Two frames out of view count as T_s = 0: back in view, T_t = (0 + 0 + T_s + T_s) / 4.
  tracker.update(empty, scene, 7 / 60.0, 6 / 60.0);
  tracker.update(empty, scene, 8 / 60.0, 7 / 60.0);
  const AttentionFrame& back = tracker.update(g, scene, 9 / 60.0, 8 / 60.0);
  ASSERT_EQ(back.objects.size(), 1u);
  EXPECT_NEAR(back.objects[0].temporal, 2 * ts / 4, 1e-12);
}

TEST(AttentionKalman, SmoothsAStep) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -4}, 0.2f);
  GBuffer g = make_gbuffer(64, 64);
  paint(g, 24, 24, 40, 40, 1, glm::vec3(1.0f), 4.0f);
  AttentionSettings s = small(64);
  s.groups.context = false;  // S_o = S^_o = T_i * mean S_p: the step is exactly the T_i step
  AttentionTracker tracker(s);
  AttentionSettings off = s;
  off.kalman = false;
  AttentionTracker raw(off);
  const double dt = 1.0 / 60;
  double before = 0;
  for (int k = 0; k < 30; ++k) before = tracker.update(g, scene, k * dt, k == 0 ? 0 : (k - 1) * dt).objects[0].attention;
  scene.objects[0].task_importance = 0.8f;
  std::vector<double> after;
  double target = 0;
  for (int k = 30; k < 330; ++k) {
    const AttentionFrame& f = tracker.update(g, scene, k * dt, (k - 1) * dt);
    target = f.objects[0].attention_raw;
    after.push_back(f.objects[0].attention);
    EXPECT_DOUBLE_EQ(raw.update(g, scene, k * dt, (k - 1) * dt).objects[0].attention, target);  // off: raw
  }
  ASSERT_GT(target, before * 3.5);
  EXPECT_GT(after[0], before);
  EXPECT_LT(after[0], before + 0.5 * (target - before));  // not a jump
  EXPECT_NEAR(after.back(), target, 0.02 * target);       // but it gets there (5 s later)
  for (double a : after) EXPECT_GE(a, 0);
}

TEST(AttentionGroups, SwitchesChangeWhatIsUsed) {
  Scene scene = make_scene();
  add_object(scene, 1, {0, 0, -2}, 1.0f);
  GBuffer g = make_gbuffer(128, 128, glm::vec3(0.5f));
  // Same colour as the background: only depth and size tell the object apart.
  paint(g, 40, 40, 88, 88, 1, glm::vec3(0.5f), 2.0f);
  const auto run = [&](bool image, bool object, bool context) {
    AttentionSettings s = small(64);
    s.groups = {image, object, context};
    AttentionTracker tracker(s);
    return tracker.update(g, scene, 0, 0);
  };
  const AttentionFrame b = run(true, false, false);
  for (float v : b.saliency) EXPECT_EQ(v, 0.0f);  // B alone sees nothing
  for (int k = 2; k < 5; ++k) {
    for (float v : b.contrast[k]) EXPECT_EQ(v, 0.0f);
  }
  const AttentionFrame e = run(false, true, false);
  EXPECT_FLOAT_EQ(*std::max_element(e.saliency.begin(), e.saliency.end()), 1.0f);
  EXPECT_GT(*std::max_element(e.contrast[2].begin(), e.contrast[2].end()), 0.0f);  // depth
  for (int k = 0; k < 2; ++k) {
    for (float v : e.contrast[k]) EXPECT_EQ(v, 0.0f);
  }
  ASSERT_EQ(e.objects.size(), 1u);
  EXPECT_DOUBLE_EQ(e.objects[0].attention_raw, e.objects[0].saliency);  // no T: S_o = S^_o
  const AttentionFrame et = run(false, true, true);
  ASSERT_EQ(et.objects.size(), 1u);
  EXPECT_NE(et.objects[0].attention_raw, et.objects[0].saliency);
  // Only T: no bottom-up map; S^_o = T_i.
  const AttentionFrame t = run(false, false, true);
  ASSERT_EQ(t.objects.size(), 1u);
  EXPECT_DOUBLE_EQ(t.objects[0].saliency, 1.0);
}

TEST(AttentionSettingsCheck, RejectsBadFields) {
  AttentionSettings s;
  s.map_size = 32;
  EXPECT_THROW(s.check(), std::invalid_argument);
  s = {};
  s.temporal_window = 0;
  EXPECT_THROW(s.check(), std::invalid_argument);
  s = {};
  s.preferred_distance_m = 0;
  EXPECT_THROW(AttentionTracker{s}, std::invalid_argument);
  s = {};
  s.kalman_measurement_noise = std::nan("");
  EXPECT_THROW(s.check(), std::invalid_argument);
  EXPECT_NO_THROW(AttentionSettings{}.check());
}
