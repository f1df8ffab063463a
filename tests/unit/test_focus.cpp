// SPDX-License-Identifier: Apache-2.0
// The focus pass (renderer/attention/focus.h): where the thin lens focuses, from attention, gaze or
// both (Lee 2009 §6.1, §6.3), with hand-made G-buffers and AttentionFrames; the gaze inputs'
// fixation onsets that drive refocusing; the focus overlay.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <thread>
#include <unistd.h>

#include "attention/focus.h"
#include "attention/focus_input.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/csv.h"
#include "fovea/protocol/recording.h"
#include "fovea/protocol/server.h"
#include "gaze/gaze_events.h"
#include "gaze/gaze_input.h"
#include "passes/overlay.h"
#include "pipeline/planner.h"

using namespace fovea::render;
using namespace fovea::render::attention;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// A 200 x 100 G-buffer shown full-width on the default display (1920 px over 0.5313 m at 0.65 m):
// 1.5 deg of gaze radius is about 6.4 G-buffer pixels.
struct World {
  GBuffer g;
  Scene scene;
  AttentionFrame attention;
  fovea::protocol::DisplayGeometry display;

  World() {
    g.resize(200, 100);
    scene.camera.far_m = 50;
    for (std::size_t i = 0; i < g.size(); ++i) g.depth[i] = 50;  // the far plane where nothing is hit
    add_object(1, "left_cup", 1.0f);
    add_object(2, "right_cup", 1.0f);
    add_object(3, "wall", 0.0f);  // background: T_i = 0
  }
  void add_object(std::uint32_t id, const std::string& name, float importance) {
    Object o;
    o.id = id;
    o.name = name;
    o.task_importance = importance;
    scene.objects.push_back(o);
  }
  // Paints [x0, x1) x [y0, y1) with an object at a depth.
  void paint(std::uint32_t id, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1, float depth) {
    for (std::uint32_t y = y0; y < y1; ++y) {
      for (std::uint32_t x = x0; x < x1; ++x) {
        g.object_id[g.index(x, y)] = id;
        g.depth[g.index(x, y)] = depth;
      }
    }
  }
  // Takes an object out of view, revealing what is behind it (by default nothing: the far plane).
  void erase(std::uint32_t id, std::uint32_t behind = 0, float behind_depth = 50) {
    for (std::size_t i = 0; i < g.size(); ++i) {
      if (g.object_id[i] == id) {
        g.object_id[i] = behind;
        g.depth[i] = behind_depth;
      }
    }
  }
  // Sets the attention list (sorted, highest first, as the attention pass does).
  void attend(std::vector<ObjectAttention> objects) {
    std::sort(objects.begin(), objects.end(), [](const auto& a, const auto& b) { return a.attention > b.attention; });
    attention.objects = std::move(objects);
    attention.most_attended = attention.objects.empty() ? 0 : attention.objects.front().id;
  }
};

ObjectAttention attended(std::uint32_t id, double attention, double depth_m) {
  ObjectAttention o;
  o.id = id;
  o.attention = o.attention_raw = attention;
  o.depth_m = depth_m;
  return o;
}

FocusGaze gaze_at(double x, double y, std::uint64_t fixations, bool saccade = false) {
  FocusGaze g;
  g.available = true;
  g.valid = true;
  g.x = x;
  g.y = y;
  g.fixations = fixations;
  g.saccade_or_blink = saccade;
  return g;
}

FocusSettings settings(FocusMode mode, double transition_s = 0.3) {
  FocusSettings s;
  s.mode = mode;
  s.transition_s = transition_s;
  return s;
}

// The scene of the required case: two cups, 4 px apart around the gaze point (x = 100 px,
// y = 50 px), both within 1.5 deg (6.4 px); the wall behind them and around the screen centre.
World two_cups() {
  World w;
  w.paint(3, 0, 0, 200, 100, 9.0f);   // the wall fills the view
  w.paint(1, 60, 30, 98, 70, 2.0f);   // left cup: x in [60, 98)
  w.paint(2, 102, 30, 140, 70, 5.0f); // right cup: x in [102, 140)
  return w;
}
constexpr double kGapX = 100.0 / 200, kGapY = 50.0 / 100;

}  // namespace

TEST(FocusSettings, RejectsValuesOutsideTheirRangesNamingTheField) {
  EXPECT_NO_THROW(FocusSettings{}.check());
  FocusSettings s;
  s.cutoff_hz = 3;  // Lee 2009 §6.1: <= 2 Hz
  EXPECT_THROW(s.check(), std::invalid_argument);
  try {
    s.check();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cutoff_hz"), std::string::npos) << e.what();
  }
  s = {};
  s.transition_s = kNaN;
  EXPECT_THROW(FocusTracker{s}, std::invalid_argument);
  s = {};
  s.gaze_radius_deg = -1;
  EXPECT_THROW(s.check(), std::invalid_argument);
  s = {};
  s.fixed_depth_m = 0;
  EXPECT_THROW(s.check(), std::invalid_argument);
}

// Lee 2009, eq. 6.1: Z_f(t) = lerp(Z_p(t), Z_n(t), t / tau), with both objects moving.
TEST(FocusLerp, Eq61AtZeroHalfAndFullTransitionFollowingMovingObjects) {
  World w = two_cups();
  FocusTracker focus(settings(FocusMode::Attention, 0.3));
  const FocusGaze none;
  w.attend({attended(1, 0.8, 2.0), attended(2, 0.3, 6.0)});
  EXPECT_DOUBLE_EQ(focus.update(0.0, w.g, w.scene, &w.attention, none, w.display).focal_depth_m, 2.0);
  EXPECT_FALSE(focus.last().in_transition);
  EXPECT_EQ(focus.last().object, 1u);
  EXPECT_NE(focus.last().why.find("left_cup"), std::string::npos) << focus.last().why;

  // t = 0 of the transition: attention moves to the right cup.
  w.attend({attended(1, 0.2, 2.0), attended(2, 0.9, 6.0)});
  const FocusResult& r0 = focus.update(1.0, w.g, w.scene, &w.attention, none, w.display);
  EXPECT_DOUBLE_EQ(r0.focal_depth_m, 2.0);
  EXPECT_DOUBLE_EQ(r0.target_depth_m, 6.0);
  EXPECT_TRUE(r0.in_transition);
  EXPECT_EQ(r0.object, 2u);
  EXPECT_NE(r0.why.find("right_cup"), std::string::npos) << r0.why;

  // t = tau / 2: both have moved (Z_p = 3, Z_n = 8): Z_f = (3 + 8) / 2.
  w.attend({attended(1, 0.2, 3.0), attended(2, 0.9, 8.0)});
  const FocusResult& r1 = focus.update(1.15, w.g, w.scene, &w.attention, none, w.display);
  EXPECT_NEAR(r1.focal_depth_m, 5.5, 1e-9);
  EXPECT_DOUBLE_EQ(r1.target_depth_m, 8.0);
  EXPECT_TRUE(r1.in_transition);

  // t = tau: on the (still moving) target.
  w.attend({attended(1, 0.2, 3.0), attended(2, 0.9, 10.0)});
  const FocusResult& r2 = focus.update(1.3, w.g, w.scene, &w.attention, none, w.display);
  EXPECT_NEAR(r2.focal_depth_m, 10.0, 1e-9);
  EXPECT_FALSE(r2.in_transition);
  // ... and it keeps following the target afterwards.
  w.attend({attended(1, 0.2, 3.0), attended(2, 0.9, 11.0)});
  EXPECT_DOUBLE_EQ(focus.update(1.4, w.g, w.scene, &w.attention, none, w.display).focal_depth_m, 11.0);
}

TEST(FocusLerp, GazeModeFollowsTheMedianDepthOfAMovingObjectsPixels) {
  World w = two_cups();
  FocusTracker focus(settings(FocusMode::Gaze, 0.2));
  EXPECT_EQ(focus.update(0.0, w.g, w.scene, nullptr, gaze_at(0.3, 0.5, 1), w.display).object, 1u);
  EXPECT_DOUBLE_EQ(focus.last().focal_depth_m, 2.0);
  // A new fixation on the right cup; then the right cup recedes to 7 m while the transition runs.
  focus.update(1.0, w.g, w.scene, nullptr, gaze_at(0.6, 0.5, 2), w.display);
  EXPECT_DOUBLE_EQ(focus.last().focal_depth_m, 2.0);
  w.paint(2, 102, 30, 140, 70, 7.0f);
  w.paint(2, 102, 30, 104, 70, kNaN);  // NaN pixels do not count in the median
  EXPECT_NEAR(focus.update(1.1, w.g, w.scene, nullptr, gaze_at(0.6, 0.5, 2), w.display).focal_depth_m, 4.5, 1e-9);
  EXPECT_NEAR(focus.update(1.2, w.g, w.scene, nullptr, gaze_at(0.6, 0.5, 2), w.display).focal_depth_m, 7.0, 1e-9);
}

TEST(FocusLerp, ChangeDuringATransitionStartsFromTheCurrentFocalDepth) {
  World w = two_cups();
  FocusTracker focus(settings(FocusMode::Attention, 0.4));
  const FocusGaze none;
  w.attend({attended(1, 0.8, 2.0), attended(2, 0.3, 6.0)});
  focus.update(0.0, w.g, w.scene, &w.attention, none, w.display);
  w.attend({attended(1, 0.2, 2.0), attended(2, 0.9, 6.0)});
  focus.update(1.0, w.g, w.scene, &w.attention, none, w.display);
  EXPECT_NEAR(focus.update(1.2, w.g, w.scene, &w.attention, none, w.display).focal_depth_m, 4.0, 1e-9);
  // Back to the left cup halfway: no jump, a new transition from 4 m.
  w.attend({attended(1, 0.9, 2.0), attended(2, 0.2, 6.0)});
  EXPECT_NEAR(focus.update(1.2, w.g, w.scene, &w.attention, none, w.display).focal_depth_m, 4.0, 1e-9);
  EXPECT_NEAR(focus.update(1.4, w.g, w.scene, &w.attention, none, w.display).focal_depth_m, 3.0, 1e-9);
  EXPECT_NEAR(focus.update(1.6, w.g, w.scene, &w.attention, none, w.display).focal_depth_m, 2.0, 1e-9);
}

TEST(FocusLowPass, SettlesWithoutOvershootOnAStep) {
  World w = two_cups();
  FocusSettings s = settings(FocusMode::Attention);
  s.transition = FocusTransition::LowPass;
  s.cutoff_hz = 1.0;
  FocusTracker focus(s);
  const FocusGaze none;
  w.attend({attended(1, 0.8, 2.0), attended(2, 0.3, 6.0)});
  focus.update(0.0, w.g, w.scene, &w.attention, none, w.display);
  w.attend({attended(1, 0.2, 2.0), attended(2, 0.9, 6.0)});
  double previous = 2.0;
  bool settled = false;
  double settled_at = 0;
  for (int i = 0; i <= 60 * 3; ++i) {
    const double t = 1.0 + i / 60.0;
    const FocusResult& r = focus.update(t, w.g, w.scene, &w.attention, none, w.display);
    ASSERT_TRUE(std::isfinite(r.focal_depth_m));
    EXPECT_GE(r.focal_depth_m, previous - 1e-12) << "t=" << t;  // monotone
    EXPECT_LE(r.focal_depth_m, 6.0 + 1e-9) << "t=" << t;        // critically damped: no overshoot
    previous = r.focal_depth_m;
    if (!r.in_transition && !settled) {
      settled = true;
      settled_at = t - 1.0;
    }
  }
  EXPECT_TRUE(settled);
  EXPECT_NEAR(previous, 6.0, 1e-3);
  // A 1 Hz cut-off settles within a second or so; the lerp's 300 ms is faster, as in Lee's Fig. 6.1.
  EXPECT_GT(settled_at, 0.3);
  EXPECT_LT(settled_at, 1.5);
}

// The cut-off is the -3 dB frequency: a target depth oscillating at f comes through with gain
// 1 / (1 + (f/f0)^2), f0 = cutoff / sqrt(sqrt(2) - 1).
TEST(FocusLowPass, RespectsTheCutOffFrequency) {
  for (const double cutoff : {0.5, 1.0, 2.0}) {
    for (const double ratio : {0.1, 1.0, 3.0}) {
      const double f = cutoff * ratio;
      World w = two_cups();
      FocusSettings s = settings(FocusMode::Attention);
      s.transition = FocusTransition::LowPass;
      s.cutoff_hz = cutoff;
      FocusTracker focus(s);
      const FocusGaze none;
      const double rate = 480, settle = 8 / cutoff, periods = 4;
      double lo = kInf, hi = -kInf;
      const int frames = static_cast<int>((settle + periods / f) * rate);
      for (int i = 0; i <= frames; ++i) {
        const double t = i / rate;
        w.attend({attended(1, 0.8, 10.0 + std::sin(2 * std::numbers::pi * f * t))});
        const double z = focus.update(t, w.g, w.scene, &w.attention, none, w.display).focal_depth_m;
        if (t > settle) {
          lo = std::min(lo, z);
          hi = std::max(hi, z);
        }
      }
      const double gain = (hi - lo) / 2;
      const double f0 = cutoff / std::sqrt(std::sqrt(2.0) - 1.0);
      SCOPED_TRACE("cutoff " + std::to_string(cutoff) + " Hz, f " + std::to_string(f) + " Hz");
      EXPECT_NEAR(gain, 1 / (1 + (f / f0) * (f / f0)), 0.02);
      if (ratio == 1.0) {
        EXPECT_NEAR(gain, std::sqrt(0.5), 0.02);
      }
      if (ratio > 1.0) {
        EXPECT_LT(gain, std::sqrt(0.5));
      }
    }
  }
}

TEST(FocusAttention, NoForegroundObjectAttendedUsesTheScreenCentreDepth) {
  World w = two_cups();  // the screen centre (100, 50) is in the gap between the cups: the wall, 9 m
  FocusTracker focus(settings(FocusMode::Attention, 0.0));
  const FocusGaze none;
  w.attend({});
  const FocusResult& r = focus.update(0.0, w.g, w.scene, &w.attention, none, w.display);
  EXPECT_DOUBLE_EQ(r.focal_depth_m, 9.0);  // the wall at the centre pixel
  EXPECT_EQ(r.object, 0u);
  EXPECT_NE(r.why.find("screen centre"), std::string::npos) << r.why;
  // Attention below min_attention counts as none.
  w.attend({attended(1, 1e-6, 2.0)});
  EXPECT_DOUBLE_EQ(focus.update(0.1, w.g, w.scene, &w.attention, none, w.display).focal_depth_m, 9.0);
  // Nothing hit at the centre: the far plane.
  w.erase(3);
  EXPECT_DOUBLE_EQ(focus.update(0.2, w.g, w.scene, &w.attention, none, w.display).focal_depth_m, 50.0);
  // No attention pass at all (null): the screen centre too.
  EXPECT_DOUBLE_EQ(focus.update(0.3, w.g, w.scene, nullptr, none, w.display).focal_depth_m, 50.0);
  // The centre as Z_p / Z_n of a transition (Lee §6.1, last paragraph).
  FocusTracker lerp(settings(FocusMode::Attention, 0.2));
  w.attend({});
  lerp.update(0.0, w.g, w.scene, &w.attention, none, w.display);
  w.attend({attended(1, 0.5, 2.0)});
  lerp.update(1.0, w.g, w.scene, &w.attention, none, w.display);
  EXPECT_NEAR(lerp.update(1.1, w.g, w.scene, &w.attention, none, w.display).focal_depth_m, 26.0, 1e-9);
}

// The required case: the gaze point lands between two objects, both within the gaze radius.
TEST(FocusGazeAndAttention, BetweenTwoObjectsTheHigherAttentionWins) {
  World w = two_cups();
  FocusTracker focus(settings(FocusMode::GazeAndAttention, 0.0));
  w.attend({attended(1, 0.8, 2.0), attended(2, 0.3, 5.0)});
  const FocusResult& a = focus.update(0.0, w.g, w.scene, &w.attention, gaze_at(kGapX, kGapY, 1), w.display);
  EXPECT_EQ(a.object, 1u);
  EXPECT_DOUBLE_EQ(a.focal_depth_m, 2.0);
  EXPECT_NE(a.why.find("gaze+attention: left_cup"), std::string::npos) << a.why;
  EXPECT_NE(a.why.find("2 candidate(s)"), std::string::npos) << a.why;

  // Attention swapped: the other one (at the next fixation, same place).
  FocusTracker swapped(settings(FocusMode::GazeAndAttention, 0.0));
  w.attend({attended(1, 0.3, 2.0), attended(2, 0.8, 5.0)});
  const FocusResult& b = swapped.update(0.0, w.g, w.scene, &w.attention, gaze_at(kGapX, kGapY, 1), w.display);
  EXPECT_EQ(b.object, 2u);
  EXPECT_DOUBLE_EQ(b.focal_depth_m, 5.0);
  EXPECT_NE(b.why.find("right_cup"), std::string::npos) << b.why;
  EXPECT_EQ(focus.update(0.1, w.g, w.scene, &w.attention, gaze_at(kGapX, kGapY, 2), w.display).object, 2u);

  // Gaze only: the object under the gaze point; on the background (the wall between the cups), the
  // depth under the gaze point.
  FocusTracker gaze(settings(FocusMode::Gaze, 0.0));
  const FocusResult& c = gaze.update(0.0, w.g, w.scene, &w.attention, gaze_at(kGapX, kGapY, 1), w.display);
  EXPECT_EQ(c.object, 0u);
  EXPECT_DOUBLE_EQ(c.focal_depth_m, 9.0);
  EXPECT_NE(c.why.find("wall, background"), std::string::npos) << c.why;
  EXPECT_EQ(gaze.update(0.1, w.g, w.scene, &w.attention, gaze_at(0.45, kGapY, 2), w.display).object, 1u);
  EXPECT_DOUBLE_EQ(gaze.last().focal_depth_m, 2.0);
  EXPECT_EQ(gaze.update(0.2, w.g, w.scene, &w.attention, gaze_at(0.55, kGapY, 3), w.display).object, 2u);
  EXPECT_DOUBLE_EQ(gaze.last().focal_depth_m, 5.0);
}

TEST(FocusGazeAndAttention, NoForegroundObjectInReachUsesTheDepthUnderTheGazePoint) {
  World w = two_cups();
  w.attend({attended(1, 0.8, 2.0), attended(2, 0.3, 5.0)});
  FocusTracker focus(settings(FocusMode::GazeAndAttention, 0.0));
  // Far from both cups (the wall at 9 m).
  const FocusResult& r = focus.update(0.0, w.g, w.scene, &w.attention, gaze_at(0.05, 0.1, 1), w.display);
  EXPECT_EQ(r.object, 0u);
  EXPECT_DOUBLE_EQ(r.focal_depth_m, 9.0);
  EXPECT_NE(r.why.find("depth under the gaze point"), std::string::npos) << r.why;
  // A zero radius: only what is under the gaze point competes.
  FocusSettings s = settings(FocusMode::GazeAndAttention, 0.0);
  s.gaze_radius_deg = 0;
  FocusTracker narrow(s);
  EXPECT_EQ(narrow.update(0.0, w.g, w.scene, &w.attention, gaze_at(kGapX, kGapY, 1), w.display).object, 0u);
  EXPECT_EQ(narrow.update(0.1, w.g, w.scene, &w.attention, gaze_at(0.55, kGapY, 2), w.display).object, 2u);
  // Without attention (not planned), gaze+attention acts as gaze.
  FocusTracker blind(settings(FocusMode::GazeAndAttention, 0.0));
  EXPECT_EQ(blind.update(0.0, w.g, w.scene, nullptr, gaze_at(0.45, kGapY, 1), w.display).object, 1u);
  // Without a gaze source it acts as attention.
  FocusTracker no_gaze(settings(FocusMode::GazeAndAttention, 0.0));
  EXPECT_EQ(no_gaze.update(0.0, w.g, w.scene, &w.attention, FocusGaze{}, w.display).object, 1u);
}

TEST(FocusGaze, RefocusesOnlyAtFixationOnsetAndHoldsDuringSaccades) {
  World w = two_cups();
  FocusTracker focus(settings(FocusMode::Gaze, 0.0));
  EXPECT_EQ(focus.update(0.0, w.g, w.scene, nullptr, gaze_at(0.4, 0.5, 5), w.display).object, 1u);
  // The gaze drifts onto the right cup within the same fixation: held.
  EXPECT_EQ(focus.update(0.1, w.g, w.scene, nullptr, gaze_at(0.6, 0.5, 5), w.display).object, 1u);
  // A saccade (a new onset already counted, but the eye is still moving): held.
  const FocusResult& s = focus.update(0.2, w.g, w.scene, nullptr, gaze_at(0.6, 0.5, 6, true), w.display);
  EXPECT_EQ(s.object, 1u);
  EXPECT_NE(s.why.find("held"), std::string::npos) << s.why;
  // A blink (invalid sample): held.
  FocusGaze blink = gaze_at(0.6, 0.5, 6);
  blink.valid = false;
  EXPECT_EQ(focus.update(0.3, w.g, w.scene, nullptr, blink, w.display).object, 1u);
  // The fixation has started and the eye is still: refocus.
  EXPECT_EQ(focus.update(0.4, w.g, w.scene, nullptr, gaze_at(0.6, 0.5, 6), w.display).object, 2u);
  EXPECT_DOUBLE_EQ(focus.last().focal_depth_m, 5.0);
  // The focused object disappears without a new fixation: refocus at the gaze point.
  w.erase(2, 3, 9.0f);
  const FocusResult& gone = focus.update(0.5, w.g, w.scene, nullptr, gaze_at(0.6, 0.5, 6), w.display);
  EXPECT_EQ(gone.object, 0u);
  EXPECT_DOUBLE_EQ(gone.focal_depth_m, 9.0);
  // ... also during a saccade (at the fixation's place).
  FocusTracker second(settings(FocusMode::Gaze, 0.0));
  second.update(0.0, w.g, w.scene, nullptr, gaze_at(0.4, 0.5, 1), w.display);
  w.erase(1, 3, 9.0f);
  EXPECT_EQ(second.update(0.1, w.g, w.scene, nullptr, gaze_at(0.9, 0.9, 1, true), w.display).object, 0u);
  EXPECT_DOUBLE_EQ(second.last().focal_depth_m, 9.0);
}

TEST(FocusGaze, RefocusesAtPursuitOnsetUnlessTurnedOff) {
  // The eye lands on the right cup and pursues it with no fixation between (the fixation count stays
  // 5): a pursuit onset is a new thing looked at.
  for (const bool on : {true, false}) {
    World w = two_cups();
    FocusSettings s = settings(FocusMode::Gaze, 0.0);
    s.refocus_on_pursuit = on;
    FocusTracker focus(s);
    EXPECT_EQ(focus.update(0.0, w.g, w.scene, nullptr, gaze_at(0.4, 0.5, 5), w.display).object, 1u);
    FocusGaze pursuing = gaze_at(0.6, 0.5, 5);
    pursuing.pursuits = 1;
    EXPECT_EQ(focus.update(0.1, w.g, w.scene, nullptr, pursuing, w.display).object, on ? 2u : 1u) << on;
    // Later pursuit onsets refocus again, and only once each.
    pursuing.x = 0.4;
    EXPECT_EQ(focus.update(0.2, w.g, w.scene, nullptr, pursuing, w.display).object, on ? 2u : 1u) << on;
    pursuing.pursuits = 2;
    EXPECT_EQ(focus.update(0.3, w.g, w.scene, nullptr, pursuing, w.display).object, 1u) << on;
  }
}

TEST(FocusGaze, NoGazeYetUsesTheScreenCentre) {
  World w = two_cups();
  w.paint(1, 90, 40, 110, 60, 2.0f);  // the left cup at the centre
  FocusTracker focus(settings(FocusMode::Gaze, 0.0));
  EXPECT_DOUBLE_EQ(focus.update(0.0, w.g, w.scene, nullptr, FocusGaze{}, w.display).focal_depth_m, 2.0);
  EXPECT_NE(focus.last().why.find("screen centre"), std::string::npos) << focus.last().why;
  FocusGaze blink = gaze_at(0.9, 0.5, 0);
  blink.valid = false;
  EXPECT_DOUBLE_EQ(focus.update(0.1, w.g, w.scene, nullptr, blink, w.display).focal_depth_m, 2.0);
  // The first valid gaze is used at once (no onset needed).
  EXPECT_EQ(focus.update(0.2, w.g, w.scene, nullptr, gaze_at(0.6, 0.5, 0), w.display).object, 2u);
}

TEST(FocusFixed, UsesTheFixedDepth) {
  World w = two_cups();
  FocusSettings s = settings(FocusMode::Fixed);
  s.fixed_depth_m = 3.5;
  FocusTracker focus(s);
  const FocusResult& r = focus.update(0.0, w.g, w.scene, nullptr, gaze_at(0.4, 0.5, 1), w.display);
  EXPECT_DOUBLE_EQ(r.focal_depth_m, 3.5);
  EXPECT_FALSE(r.in_transition);
  EXPECT_NE(r.why.find("fixed"), std::string::npos);
}

// The hard cases: nothing here may produce NaN.
TEST(FocusHardCases, NaNAndInfDepthsAreSkipped) {
  World w = two_cups();
  w.paint(1, 60, 30, 70, 70, kNaN);
  w.paint(1, 70, 30, 80, 70, static_cast<float>(kInf));
  w.paint(1, 80, 30, 85, 70, -1.0f);
  w.paint(3, 99, 49, 101, 51, kNaN);  // the centre pixel and its neighbours
  FocusTracker gaze(settings(FocusMode::Gaze, 0.0));
  const FocusResult& r = gaze.update(0.0, w.g, w.scene, nullptr, gaze_at(0.45, 0.5, 1), w.display);
  EXPECT_EQ(r.object, 1u);
  EXPECT_DOUBLE_EQ(r.focal_depth_m, 2.0);  // the median of the finite pixels
  FocusTracker centre(settings(FocusMode::Attention, 0.0));
  EXPECT_DOUBLE_EQ(centre.update(0.0, w.g, w.scene, nullptr, FocusGaze{}, w.display).focal_depth_m, 9.0);
  // An object whose every depth is NaN is not focusable; NaN attention and depth_m fall back.
  w.paint(2, 102, 30, 140, 70, kNaN);
  w.attend({attended(2, kNaN, kNaN), attended(1, 0.5, kNaN)});
  FocusTracker att(settings(FocusMode::Attention, 0.0));
  const FocusResult& a = att.update(0.0, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
  EXPECT_EQ(a.object, 1u);
  EXPECT_DOUBLE_EQ(a.focal_depth_m, 2.0);
  // The whole G-buffer NaN: the far plane.
  for (auto& d : w.g.depth) d = static_cast<float>(kNaN);
  FocusTracker all(settings(FocusMode::GazeAndAttention, 0.0));
  w.attend({});
  EXPECT_DOUBLE_EQ(all.update(0.0, w.g, w.scene, &w.attention, gaze_at(0.5, 0.5, 1), w.display).focal_depth_m, 50.0);
}

TEST(FocusHardCases, EmptyGBuffer) {
  World w;
  w.g.resize(0, 0);
  for (FocusMode mode : {FocusMode::Fixed, FocusMode::Gaze, FocusMode::Attention, FocusMode::GazeAndAttention}) {
    FocusTracker focus(settings(mode));
    w.attend({attended(1, 0.5, 3.0)});
    for (int i = 0; i < 3; ++i) {
      const FocusResult& r = focus.update(i * 0.1, w.g, w.scene, &w.attention, gaze_at(0.5, 0.5, 1), w.display);
      EXPECT_TRUE(std::isfinite(r.focal_depth_m) && r.focal_depth_m > 0);
      EXPECT_TRUE(std::isfinite(r.target_depth_m));
    }
    const FocusResult& r = focus.update(1, w.g, w.scene, nullptr, gaze_at(0.5, 0.5, 2), w.display);
    EXPECT_TRUE(std::isfinite(r.focal_depth_m) && r.focal_depth_m > 0);
  }
  // Buffers shorter than width x height are treated as empty.
  World bad;
  bad.g.depth.resize(3);
  FocusTracker focus(settings(FocusMode::Gaze));
  EXPECT_DOUBLE_EQ(focus.update(0, bad.g, bad.scene, nullptr, gaze_at(0.5, 0.5, 1), bad.display).focal_depth_m, 50.0);
}

TEST(FocusHardCases, GazeOutsideTheScreenIsClamped) {
  World w = two_cups();
  w.add_object(4, "corner_ball", 1.0f);
  w.paint(4, 190, 90, 200, 100, 4.0f);  // the bottom-right corner
  FocusTracker focus(settings(FocusMode::Gaze, 0.0));
  EXPECT_EQ(focus.update(0.0, w.g, w.scene, nullptr, gaze_at(7.0, 3.0, 1), w.display).object, 4u);
  EXPECT_DOUBLE_EQ(focus.last().focal_depth_m, 4.0);
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{{-5, -5}, {kNaN, 0.5}, {kInf, -kInf}, {1.0, 1.0}}) {
    FocusTracker f(settings(FocusMode::GazeAndAttention, 0.0));
    w.attend({attended(1, 0.5, 2.0)});
    const FocusResult& r = f.update(0.0, w.g, w.scene, &w.attention, gaze_at(x, y, 1), w.display);
    EXPECT_TRUE(std::isfinite(r.focal_depth_m)) << x << "," << y;
  }
}

TEST(FocusTransitions, TheFirstTargetIsInFocusAndStaysWithoutATransition) {
  // Found in a headless run: the first frame focused at once, but the next frames started a lerp
  // from the default target (the screen centre) although the target had not changed.
  for (FocusTransition transition : {FocusTransition::Lerp, FocusTransition::LowPass}) {
    World w = two_cups();
    FocusSettings s = settings(FocusMode::Attention, 0.3);
    s.transition = transition;
    FocusTracker focus(s);
    w.attend({attended(1, 0.8, 2.0)});
    for (double t : {0.0, 0.1, 0.2, 0.35}) {
      const FocusResult& r = focus.update(t, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
      EXPECT_NEAR(r.focal_depth_m, 2.0, 1e-9) << "t=" << t;
      EXPECT_FALSE(r.in_transition) << "t=" << t;
    }
  }
}

TEST(FocusHardCases, TenSecondGapCompletesTheTransition) {
  for (FocusTransition transition : {FocusTransition::Lerp, FocusTransition::LowPass}) {
    World w = two_cups();
    FocusSettings s = settings(FocusMode::Attention, 0.3);
    s.transition = transition;
    FocusTracker focus(s);
    w.attend({attended(1, 0.8, 2.0)});
    focus.update(0.0, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
    w.attend({attended(2, 0.8, 6.0)});
    focus.update(1.0, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
    focus.update(1.01, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
    const FocusResult& r = focus.update(11.01, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
    EXPECT_NEAR(r.focal_depth_m, 6.0, 1e-6);
    EXPECT_FALSE(r.in_transition);
    // An absurd gap too.
    EXPECT_NEAR(focus.update(1e300, w.g, w.scene, &w.attention, FocusGaze{}, w.display).focal_depth_m, 6.0, 1e-6);
  }
}

TEST(FocusHardCases, TimeGoingBackwardsHoldsTheTransition) {
  for (FocusTransition transition : {FocusTransition::Lerp, FocusTransition::LowPass}) {
    World w = two_cups();
    FocusSettings s = settings(FocusMode::Attention, 0.3);
    s.transition = transition;
    FocusTracker focus(s);
    w.attend({attended(1, 0.8, 2.0)});
    focus.update(5.0, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
    w.attend({attended(2, 0.8, 6.0)});
    focus.update(6.0, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
    const double mid = focus.update(6.1, w.g, w.scene, &w.attention, FocusGaze{}, w.display).focal_depth_m;
    EXPECT_GT(mid, 2.0);
    EXPECT_LT(mid, 6.0);
    // Back in time, and NaN time: the focal depth holds.
    EXPECT_DOUBLE_EQ(focus.update(2.0, w.g, w.scene, &w.attention, FocusGaze{}, w.display).focal_depth_m, mid);
    EXPECT_DOUBLE_EQ(focus.update(kNaN, w.g, w.scene, &w.attention, FocusGaze{}, w.display).focal_depth_m, mid);
    EXPECT_DOUBLE_EQ(focus.update(-kInf, w.g, w.scene, &w.attention, FocusGaze{}, w.display).focal_depth_m, mid);
    // Forward again from there: the transition goes on.
    const double later = focus.update(2.1, w.g, w.scene, &w.attention, FocusGaze{}, w.display).focal_depth_m;
    EXPECT_GT(later, mid);
    EXPECT_LE(later, 6.0 + 1e-9);
  }
}

TEST(FocusHardCases, ZeroTransitionTimeJumps) {
  World w = two_cups();
  FocusTracker focus(settings(FocusMode::Attention, 0.0));
  w.attend({attended(1, 0.8, 2.0)});
  focus.update(0.0, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
  w.attend({attended(2, 0.8, 6.0)});
  const FocusResult& r = focus.update(0.0, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
  EXPECT_DOUBLE_EQ(r.focal_depth_m, 6.0);
  EXPECT_FALSE(r.in_transition);
}

TEST(FocusHardCases, ResetStartsOver) {
  World w = two_cups();
  FocusTracker focus(settings(FocusMode::Attention, 0.3));
  w.attend({attended(1, 0.8, 2.0)});
  focus.update(0.0, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
  w.attend({attended(2, 0.8, 6.0)});
  focus.update(1.0, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
  EXPECT_TRUE(focus.last().in_transition);
  focus.reset();
  const FocusResult& r = focus.update(1.01, w.g, w.scene, &w.attention, FocusGaze{}, w.display);
  EXPECT_DOUBLE_EQ(r.focal_depth_m, 6.0);  // no transition from a previous life
  EXPECT_FALSE(r.in_transition);
}

// --- the gaze side: what the pipeline hands the focus pass --------------------------------------

TEST(FocusInput, FromGazeState) {
  GazeState s;
  s.x = 0.3;
  s.y = 0.7;
  s.valid = true;
  s.movement = fovea::protocol::EyeMovement::Fixation;
  s.fixations = 4;
  FocusGaze g = focus_gaze_from(s, true);
  EXPECT_TRUE(g.available && g.valid && !g.saccade_or_blink);
  EXPECT_EQ(g.fixations, 4u);
  EXPECT_DOUBLE_EQ(g.x, 0.3);
  s.in_saccade = true;  // what every input sets while the sample's movement is Saccade
  EXPECT_TRUE(focus_gaze_from(s, true).saccade_or_blink);
  s.in_saccade = false;
  s.movement = fovea::protocol::EyeMovement::Blink;
  EXPECT_TRUE(focus_gaze_from(s, true).saccade_or_blink);
  // With provisional events the final label trails the eye: a valid sample out of a provisional
  // saccade may refocus although its final label still says saccade or blink.
  s.provisional = true;
  EXPECT_FALSE(focus_gaze_from(s, true).saccade_or_blink);
  s.movement = fovea::protocol::EyeMovement::Saccade;
  EXPECT_FALSE(focus_gaze_from(s, true).saccade_or_blink);
  s.in_saccade = true;
  EXPECT_TRUE(focus_gaze_from(s, true).saccade_or_blink);
  s.in_saccade = false;
  s.provisional = false;
  s.movement = fovea::protocol::EyeMovement::Pursuit;
  EXPECT_FALSE(focus_gaze_from(s, true).saccade_or_blink);
  s.valid = false;
  EXPECT_TRUE(focus_gaze_from(s, true).saccade_or_blink);
  EXPECT_FALSE(focus_gaze_from(GazeState{}, false).available);
}

TEST(GazeFixations, MouseCountsAFixationAfterResting100ms) {
  auto mouse = make_gaze_input("mouse");
  EXPECT_EQ(mouse->at(0.0).fixations, 0u);
  EXPECT_EQ(mouse->at(0.05).fixations, 0u);
  EXPECT_EQ(mouse->at(0.1).fixations, 1u);
  EXPECT_EQ(mouse->at(0.5).fixations, 1u);
  mouse->set_cursor(0.505, 0.5);  // well under 1 deg: the same fixation
  EXPECT_EQ(mouse->at(0.7).fixations, 1u);
  mouse->set_cursor(0.9, 0.2);    // a move
  EXPECT_EQ(mouse->at(0.8).fixations, 1u);
  EXPECT_EQ(mouse->at(0.85).fixations, 1u);
  EXPECT_EQ(mouse->at(0.9).fixations, 2u);
  const GazeState s = mouse->at(1.0);
  EXPECT_EQ(s.movement, fovea::protocol::EyeMovement::Fixation);  // unchanged behaviour
  EXPECT_TRUE(s.valid);
  EXPECT_DOUBLE_EQ(s.x, 0.9);
  EXPECT_EQ(make_gaze_input("none")->at(1.0).fixations, 0u);
}

TEST(GazeFixations, FileReplayCountsFixationStartEventsUpToTheReplayTime) {
  namespace fs = std::filesystem;
  const fs::path path = fs::temp_directory_path() / ("fovea_test_focus_" + std::to_string(::getpid()) + ".fgr");
  fs::remove(path);
  {
    fovea::protocol::RecordingHeader h;
    h.device = "test";
    h.nominal_rate_hz = 100;
    fovea::protocol::RecordingWriter writer(path.string(), h);
    std::uint64_t seq = 0;
    const std::int64_t t0 = 1'000'000'000;
    for (int i = 0; i <= 100; ++i) {  // 1 s of samples at 100 Hz
      fovea::protocol::GazeSample s;
      s.tracker_time_ns = t0 + i * 10'000'000LL;
      s.x = 0.5f;
      s.y = 0.5f;
      s.flags = fovea::protocol::kGazeValid;
      s.state = fovea::protocol::EyeMovement::Fixation;
      writer.append({seq++, s});
    }
    // Fixation starts at 0.2 s and 0.6 s; a saccade start and a fixation end in between do not count.
    const auto event = [&](fovea::protocol::EyeMovement kind, fovea::protocol::EventPhase phase, double at_s) {
      fovea::protocol::GazeEvent e;
      e.kind = kind;
      e.phase = phase;
      e.start_time_ns = t0 + static_cast<std::int64_t>(at_s * 1e9);
      writer.append({seq++, e});
    };
    event(fovea::protocol::EyeMovement::Fixation, fovea::protocol::EventPhase::Start, 0.2);
    event(fovea::protocol::EyeMovement::Saccade, fovea::protocol::EventPhase::Start, 0.5);
    event(fovea::protocol::EyeMovement::Fixation, fovea::protocol::EventPhase::End, 0.5);
    event(fovea::protocol::EyeMovement::Fixation, fovea::protocol::EventPhase::Start, 0.6);
    event(fovea::protocol::EyeMovement::Pursuit, fovea::protocol::EventPhase::Start, 0.8);
    event(fovea::protocol::EyeMovement::Pursuit, fovea::protocol::EventPhase::End, 0.9);
  }
  auto file = make_gaze_input("file:" + path.string());
  EXPECT_EQ(file->at(0.0).fixations, 0u);
  EXPECT_EQ(file->at(0.19).fixations, 0u);
  EXPECT_EQ(file->at(0.2).fixations, 1u);  // time <= the replay time
  EXPECT_EQ(file->at(0.59).fixations, 1u);
  EXPECT_EQ(file->at(0.6).fixations, 2u);
  EXPECT_EQ(file->at(5.0).fixations, 2u);
  EXPECT_EQ(file->at(0.1).fixations, 0u);  // replay is a function of time: earlier frames see fewer
  EXPECT_EQ(file->at(0.79).pursuits, 0u);
  EXPECT_EQ(file->at(0.8).pursuits, 1u);
  EXPECT_EQ(file->at(5.0).pursuits, 1u);
  EXPECT_TRUE(file->at(0.3).valid);        // samples as before
  fs::remove(path);
}

TEST(GazeFixations, ACsvRecordingsOnsetsAreWhereTheSamplesStateTurns) {
  namespace fs = std::filesystem;
  using fovea::protocol::EyeMovement;
  const fs::path path = fs::temp_directory_path() / ("fovea_test_focus_" + std::to_string(::getpid()) + ".csv");
  fovea::protocol::Recording rec;
  rec.header.device = "test";
  rec.header.nominal_rate_hz = 100;
  // 100 Hz: fixation, saccade, pursuit, saccade, fixation, pursuit (0.1 s each).
  const EyeMovement states[] = {EyeMovement::Fixation, EyeMovement::Saccade, EyeMovement::Pursuit,
                                EyeMovement::Saccade,  EyeMovement::Fixation, EyeMovement::Pursuit};
  for (int i = 0; i < 60; ++i) {
    fovea::protocol::GazeSample s;
    s.tracker_time_ns = 1'000'000'000 + i * 10'000'000LL;
    s.flags = fovea::protocol::kGazeValid;
    s.state = states[i / 10];
    rec.records.push_back({static_cast<std::uint64_t>(i), s});
  }
  {
    std::ofstream out(path);
    fovea::protocol::write_csv(out, rec);
  }
  auto file = make_gaze_input("file:" + path.string());
  EXPECT_EQ(file->at(0.15).fixations, 1u);
  EXPECT_EQ(file->at(0.15).pursuits, 0u);
  EXPECT_EQ(file->at(0.2).pursuits, 1u);
  EXPECT_EQ(file->at(0.45).fixations, 2u);
  EXPECT_EQ(file->at(0.5).pursuits, 2u);
  fs::remove(path);
}

// --- the focus overlay ---------------------------------------------------------------------------

TEST(FocusOverlay, OutlinesTheFocusedObjectOrTheFocalDepthLine) {
  World w = two_cups();
  Image8 image;
  image.resize(w.g.width, w.g.height);
  draw_focus(image, w.g, 1, 2.0, false, "attention: left_cup");
  // The left cup's border is drawn, its inside and the right cup are not.
  EXPECT_NE(image.get(60, 50), glm::vec3(0.0f));
  EXPECT_NE(image.get(97, 50), glm::vec3(0.0f));
  EXPECT_EQ(image.get(80, 50), glm::vec3(0.0f));
  EXPECT_EQ(image.get(102, 50), glm::vec3(0.0f));
  // In transition: another colour.
  Image8 moving;
  moving.resize(w.g.width, w.g.height);
  draw_focus(moving, w.g, 1, 2.0, true, "");
  EXPECT_NE(moving.get(60, 50), image.get(60, 50));
  // No object: the line where the depth crosses 3 m (around the left cup, 2 m against the 9 m wall).
  Image8 line;
  line.resize(w.g.width, w.g.height);
  draw_focus(line, w.g, 0, 3.0, false, "");
  EXPECT_NE(line.get(59, 50), glm::vec3(0.0f));
  EXPECT_EQ(line.get(80, 50), glm::vec3(0.0f));
  EXPECT_EQ(line.get(10, 10), glm::vec3(0.0f));
  // A different image size, an empty G-buffer, NaN depth: no crash.
  Image8 half;
  half.resize(100, 50);
  draw_focus(half, w.g, 2, 5.0, false, "");
  EXPECT_NE(half.get(51, 25), glm::vec3(0.0f));
  GBuffer empty;
  draw_focus(half, empty, 1, kNaN, false, "");
  draw_focus(half, w.g, 0, kNaN, false, "");
}

// A floor seen level: every pixel of a row at one depth. When the focal depth is that row's depth,
// the row is the iso-depth line: drawn whole, however the depth's last bit falls (the forward and the
// visibility-buffer G-buffers round it differently), not dotted by it.
TEST(FocusOverlay, TheIsoDepthLineAlongARowAtTheFocalDepthIsWholeWhateverItsRounding) {
  GBuffer g;
  g.resize(64, 8);
  const float focal = 4.0f;
  for (std::uint32_t y = 0; y < g.height; ++y) {
    for (std::uint32_t x = 0; x < g.width; ++x) {
      // Row 4 at the focal depth, one ulp above or below by pixel; rows above nearer, below farther.
      const float on_row = (x * 7 + 3) % 3 == 0 ? std::nextafter(focal, 0.0f)
                           : (x % 2 == 0)        ? std::nextafter(focal, 10.0f)
                                                 : focal;
      g.depth[g.index(x, y)] = y == 4 ? on_row : focal + 0.1f * (static_cast<float>(y) - 4.0f);
      g.object_id[g.index(x, y)] = 7;
    }
  }
  Image8 image;
  image.resize(g.width, g.height);
  draw_focus(image, g, 0, focal, false, "");
  for (std::uint32_t x = 0; x < g.width; ++x) {
    EXPECT_NE(image.get(x, 4), glm::vec3(0.0f)) << "x=" << x;
    EXPECT_EQ(image.get(x, 1), glm::vec3(0.0f)) << "x=" << x;
    EXPECT_EQ(image.get(x, 6), glm::vec3(0.0f)) << "x=" << x;
  }
}

// --- the planner's focus decision -----------------------------------------------------------------

TEST(FocusPlanner, TheFocusOverlayNeedsTheFocusPassBeforeDofExists) {
  Scene pinhole;  // no DOF: only the overlay can consume a focal depth
  const auto plan = [&](std::vector<std::string> assignments, bool gaze = true) {
    Settings s;
    for (const auto& a : assignments) s.set_assignment(a);
    return plan_frame(PlanContext{pinhole, s, gaze});
  };
  // overlay.focus is off by default: focusing costs attention every frame, and a pinhole image shows no focus.
  const FramePlan off_by_default = plan({});
  EXPECT_FALSE(off_by_default.needed(PassId::Focus));
  EXPECT_FALSE(off_by_default.needed(PassId::Attention));
  const FramePlan shown = plan({"overlay.focus=true"});
  EXPECT_TRUE(shown.needed(PassId::Focus));
  EXPECT_TRUE(shown.needed(PassId::Overlay));
  EXPECT_NE(shown.at(PassId::Focus).reason.find("consumed by overlay (overlay.focus=true)"), std::string::npos)
      << shown.at(PassId::Focus).reason;
  EXPECT_TRUE(shown.needed(PassId::Attention)) << "focus.mode=gaze+attention consumes attention";
  const FramePlan hidden = plan({"overlay.focus=false"});
  EXPECT_FALSE(hidden.needed(PassId::Focus));
  EXPECT_NE(hidden.at(PassId::Focus).reason.find("overlay reads it only with overlay.focus=true"), std::string::npos);
  EXPECT_FALSE(plan({"overlay.focus=true", "output=gbuffer"}).needed(PassId::Focus));
  EXPECT_FALSE(plan({"overlay.focus=true", "focus.mode=fixed"}).needed(PassId::Focus));
  EXPECT_FALSE(plan({"overlay.focus=true", "focus.mode=gaze"}).needed(PassId::Attention));
  // With DOF too, the reason says both.
  Scene thin = pinhole;
  thin.camera.lens.aperture_m = 0.01;
  Settings s;
  s.set_assignment("overlay.focus=true");
  const FramePlan both = plan_frame(PlanContext{thin, s, true});
  EXPECT_NE(both.at(PassId::Focus).reason.find("consumed by dof, overlay (overlay.focus=true)"), std::string::npos)
      << both.at(PassId::Focus).reason;
}

TEST(FocusPlanner, PassesWhoseConsumersDoNotRunYetWait) {
  // A thin lens needs dof, dof needs focus, focus needs attention. When dof cannot run (the
  // ray-traced reference on the raster backend), focus and attention would compute what nobody
  // reads, so they wait (needed, not run) and say why.
  Scene thin;
  thin.camera.lens.aperture_m = 0.01;
  Settings s;
  s.set_assignment("dof.method=reference");
  const FramePlan p = plan_frame(PlanContext{thin, s, true, false});
  ASSERT_TRUE(p.needed(PassId::Dof));
  ASSERT_FALSE(p.runs(PassId::Dof));
  EXPECT_TRUE(p.needed(PassId::Focus));
  EXPECT_FALSE(p.runs(PassId::Focus));
  EXPECT_NE(p.at(PassId::Focus).reason.find("waits: dof does not run"), std::string::npos)
      << p.at(PassId::Focus).reason;
  EXPECT_FALSE(p.runs(PassId::Attention));
  EXPECT_NE(p.explain().find("waits"), std::string::npos) << p.explain();
  // With a method that runs, they run for it.
  EXPECT_TRUE(plan_frame(PlanContext{thin, Settings{}, true}).runs(PassId::Focus));
  // Something that shows them makes them run.
  s.set_assignment("overlay.focus=true");
  const FramePlan shown = plan_frame(PlanContext{thin, s, true, false});
  EXPECT_TRUE(shown.runs(PassId::Focus));
  EXPECT_TRUE(shown.runs(PassId::Attention));
  Settings map;
  map.set_assignment("dof.method=reference");
  map.set_assignment("overlay.map=saliency");
  EXPECT_TRUE(plan_frame(PlanContext{thin, map, true, false}).runs(PassId::Attention));
}

TEST(FocusPlanner, FocusSettingsAreKnownWithTheirRanges) {
  Settings s;
  EXPECT_EQ(s.text("focus.transition"), "lerp");
  EXPECT_DOUBLE_EQ(s.number("focus.transition_ms"), 300);
  EXPECT_DOUBLE_EQ(s.number("focus.cutoff_hz"), 1);
  EXPECT_DOUBLE_EQ(s.number("focus.gaze_radius_deg"), 1.5);
  EXPECT_FALSE(s.flag("overlay.focus"));
  EXPECT_NO_THROW(s.set_assignment("focus.transition=lowpass"));
  EXPECT_THROW(s.set_assignment("focus.transition=spring"), std::invalid_argument);
  EXPECT_THROW(s.set_assignment("focus.cutoff_hz=3"), std::invalid_argument);
  EXPECT_THROW(s.set_assignment("focus.cutoff_hz=0"), std::invalid_argument);
  EXPECT_THROW(s.set_assignment("focus.transition_ms=-1"), std::invalid_argument);
  EXPECT_THROW(s.set_assignment("focus.gaze_radius_deg=11"), std::invalid_argument);
}

// Issue 25: provisional events move the fixation count and the saccade in flight at once; their
// final events do not count the same fixation twice.
TEST(GazeFixations, ProvisionalOnsetsCountOnceAndSaccadesFlyUntilTheyLand) {
  using fovea::protocol::EventPhase;
  using fovea::protocol::EyeMovement;
  using fovea::protocol::GazeEvent;
  using fovea::protocol::kEventProvisional;
  using fovea::protocol::kEventRetracted;
  const auto event = [](EyeMovement kind, EventPhase phase, std::int64_t start_ms, std::uint8_t flags) {
    GazeEvent e;
    e.kind = kind;
    e.phase = phase;
    e.start_time_ns = start_ms * 1'000'000;
    e.flags = flags;
    return e;
  };
  constexpr std::int64_t ms = 1'000'000;
  fovea::render::GazeEventTracker t;
  t.on_event(event(EyeMovement::Fixation, EventPhase::Start, 0, 0), 0);  // a final onset, none provisional
  EXPECT_EQ(t.fixations(), 1u);
  EXPECT_FALSE(t.provisional());
  t.on_event(event(EyeMovement::Saccade, EventPhase::Start, 1000, kEventProvisional), 1010 * ms);
  EXPECT_TRUE(t.provisional());
  EXPECT_TRUE(t.in_saccade(1020 * ms));
  t.on_event(event(EyeMovement::Saccade, EventPhase::End, 1000, kEventProvisional), 1050 * ms);
  t.on_event(event(EyeMovement::Fixation, EventPhase::Start, 1045, kEventProvisional), 1050 * ms);
  EXPECT_FALSE(t.in_saccade(1051 * ms)) << "landed";
  EXPECT_EQ(t.fixations(), 2u) << "counted at the provisional onset";
  t.on_event(event(EyeMovement::Fixation, EventPhase::Start, 1080, 0), 1270 * ms);  // its final event, 35 ms off
  EXPECT_EQ(t.fixations(), 2u) << "the final event of a fixation already counted";
  t.on_event(event(EyeMovement::Fixation, EventPhase::Start, 2000, 0), 2200 * ms);  // nobody said it early
  EXPECT_EQ(t.fixations(), 3u);
  // A provisional saccade retracted ends at once; one never landed ends after 200 ms.
  t.on_event(event(EyeMovement::Saccade, EventPhase::Start, 3000, kEventProvisional), 3005 * ms);
  t.on_event(event(EyeMovement::Saccade, EventPhase::Start, 3000, kEventProvisional | kEventRetracted), 3200 * ms);
  EXPECT_FALSE(t.in_saccade(3201 * ms));
  t.on_event(event(EyeMovement::Saccade, EventPhase::Start, 4000, kEventProvisional), 4005 * ms);
  EXPECT_TRUE(t.in_saccade(4200 * ms));
  EXPECT_FALSE(t.in_saccade(4206 * ms));
  // Pursuit onsets: final events only (the daemon says none provisionally).
  EXPECT_EQ(t.pursuits(), 0u);
  t.on_event(event(EyeMovement::Pursuit, EventPhase::Start, 5000, 0), 5300 * ms);
  t.on_event(event(EyeMovement::Pursuit, EventPhase::End, 5000, 0), 5600 * ms);
  EXPECT_EQ(t.pursuits(), 1u);
  EXPECT_EQ(t.fixations(), 3u);
}

// End to end: a daemon's provisional fixation onset reaches the renderer's udp gaze input.
TEST(GazeFixations, UdpInputTakesTheDaemonsProvisionalEvents) {
  fovea::protocol::ServerOptions so;
  so.listen = {0x7F000001, 0};
  fovea::protocol::GazeServer server(so);
  auto input = make_gaze_input("udp://" + server.local_endpoint().to_string());
  fovea::protocol::GazeSample s;
  s.flags = fovea::protocol::kGazeValid;
  s.state = fovea::protocol::EyeMovement::Saccade;  // the final label, trailing
  fovea::protocol::GazeEvent landing;
  landing.kind = fovea::protocol::EyeMovement::Fixation;
  landing.phase = fovea::protocol::EventPhase::Start;
  landing.flags = fovea::protocol::kEventProvisional;
  GazeState g;
  for (int i = 0; i < 400 && g.fixations == 0; ++i) {
    s.tracker_time_ns = landing.start_time_ns = fovea::protocol::monotonic_ns();
    server.publish(s);
    server.publish(landing);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    g = input->at(0);
  }
  EXPECT_EQ(g.fixations, 1u);
  EXPECT_TRUE(g.provisional);
  EXPECT_FALSE(g.in_saccade) << "the provisional stream, not the trailing final label, says where the eye is";
  EXPECT_FALSE(focus_gaze_from(g, true).saccade_or_blink);
}
