// SPDX-License-Identifier: Apache-2.0
// The focus pass under random input: G-buffers with NaN, Inf, negative and huge depths and stray
// ids, attention lists with NaN fields, gaze points anywhere (NaN included), times that jump, stall,
// go backwards or are not numbers, every mode and transition. FocusResult stays finite, the focal
// depth positive and within the far plane, and the focus overlay draws without fault.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "attention/focus.h"
#include "passes/overlay.h"

using namespace fovea::render;
using namespace fovea::render::attention;

namespace {

double pick(std::mt19937_64& rng, std::initializer_list<double> values) {
  std::uniform_int_distribution<std::size_t> i(0, values.size() - 1);
  return *(values.begin() + static_cast<std::ptrdiff_t>(i(rng)));
}

double wild(std::mt19937_64& rng, double lo, double hi) {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  std::uniform_real_distribution<double> u(lo, hi);
  std::uniform_int_distribution<int> kind(0, 9);
  switch (kind(rng)) {
    case 0: return pick(rng, {nan, inf, -inf, 0.0, -1.0, 1e300, -1e300, 1e-300});
    default: return u(rng);
  }
}

}  // namespace

TEST(FocusStability, RandomInputsGiveFiniteResults) {
  std::mt19937_64 rng(20260611);
  std::uniform_int_distribution<int> coin(0, 1), die(0, 5);
  const FocusMode modes[] = {FocusMode::Fixed, FocusMode::Gaze, FocusMode::Attention, FocusMode::GazeAndAttention};
  for (int run = 0; run < 60; ++run) {
    FocusSettings s;
    s.mode = modes[run % 4];
    s.transition = coin(rng) ? FocusTransition::Lerp : FocusTransition::LowPass;
    s.transition_s = pick(rng, {0.0, 0.05, 0.3, 2.0});
    s.cutoff_hz = pick(rng, {0.01, 1.0, 2.0});
    s.gaze_radius_deg = pick(rng, {0.0, 1.5, 10.0});
    FocusTracker focus(s);
    Scene scene;
    scene.camera.far_m = static_cast<float>(pick(rng, {100.0, 5.0, std::numeric_limits<double>::quiet_NaN(), -1.0}));
    for (std::uint32_t id = 1; id <= 4; ++id) {
      Object o;
      o.id = id;
      o.name = id % 2 ? "" : "obj" + std::to_string(id);
      o.task_importance = static_cast<float>(id % 3) / 2.0f;
      scene.objects.push_back(o);
    }
    fovea::protocol::DisplayGeometry display;
    if (run % 7 == 0) display.width_m = 0;  // an unusable display: the radius is not a number
    double t = 0;
    for (int frame = 0; frame < 40; ++frame) {
      GBuffer g;
      const int size_kind = die(rng);
      g.resize(size_kind == 0 ? 0u : static_cast<std::uint32_t>(1 + die(rng) * 13),
               size_kind == 0 ? 0u : static_cast<std::uint32_t>(1 + die(rng) * 7));
      std::uniform_int_distribution<std::uint32_t> id(0, 6);  // ids 5, 6 are not in the scene
      for (std::size_t i = 0; i < g.size(); ++i) {
        g.object_id[i] = id(rng);
        g.depth[i] = static_cast<float>(wild(rng, 0.01, 200));
      }
      if (size_kind == 1 && g.size() > 1) g.depth.resize(g.size() / 2);  // inconsistent buffers
      AttentionFrame frame_attention;
      for (std::uint32_t k = 0; k < static_cast<std::uint32_t>(die(rng)); ++k) {
        ObjectAttention o;
        o.id = id(rng);
        o.attention = wild(rng, 0, 1);
        o.depth_m = wild(rng, 0.01, 200);
        frame_attention.objects.push_back(o);
      }
      FocusGaze gaze;
      gaze.available = coin(rng);
      gaze.valid = coin(rng);
      gaze.x = wild(rng, -0.5, 1.5);
      gaze.y = wild(rng, -0.5, 1.5);
      gaze.saccade_or_blink = die(rng) == 0;
      gaze.fixations = static_cast<std::uint64_t>(frame / 4 + die(rng) / 5);
      switch (die(rng)) {
        case 0: t -= 1; break;                                          // backwards
        case 1: t = std::numeric_limits<double>::quiet_NaN(); break;    // not a number
        case 2: t = (std::isfinite(t) ? t : 0) + 10; break;             // a 10 s gap
        default: t = (std::isfinite(t) ? t : 0) + 1.0 / 60; break;
      }
      const FocusResult& r =
          focus.update(t, g, scene, coin(rng) ? &frame_attention : nullptr, gaze, display);
      SCOPED_TRACE("run " + std::to_string(run) + " frame " + std::to_string(frame));
      ASSERT_TRUE(std::isfinite(r.focal_depth_m)) << r.why;
      ASSERT_TRUE(std::isfinite(r.target_depth_m)) << r.why;
      ASSERT_GT(r.focal_depth_m, 0) << r.why;
      ASSERT_GT(r.target_depth_m, 0) << r.why;
      ASSERT_LE(r.target_depth_m, 1e4) << r.why;
      ASSERT_FALSE(r.why.empty());
      if (!std::isfinite(t)) t = 0;

      Image8 image;
      image.resize(static_cast<std::uint32_t>(die(rng) * 9), static_cast<std::uint32_t>(die(rng) * 5));
      draw_focus(image, g, r.object, coin(rng) ? r.focal_depth_m : wild(rng, 0, 100), r.in_transition, r.why);
    }
  }
}
