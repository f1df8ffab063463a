// SPDX-License-Identifier: Apache-2.0
// LOD selection policies (renderer/lod/lod_policy.h): each policy's level, hysteresis, ULOD
// blending, the frame-time budget.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "lod/lod_policy.h"

namespace fovea::render::lod {
namespace {

ObjectView chain_object(std::uint32_t id = 1) {
  ObjectView o;
  o.id = id;
  o.levels = 5;
  o.base = 4;
  o.level_error_m = {0.0f, 0.001f, 0.004f, 0.016f, 0.064f};
  o.level_triangles = {65536, 16384, 4096, 1024, 256};
  o.distance_m = 2;
  o.radius_m = 0.5;
  o.projected_radius_px = 100;
  o.screen_area_px = 1024.0 * 768.0;
  o.px_per_radian = 1000;
  return o;
}

TEST(LodPolicy, DistanceKeepsTrianglesPerProjectedAreaConstant) {
  PolicySettings s;
  s.policy = Policy::Distance;
  s.distance_ref_m = 2;
  ObjectView o = chain_object();
  for (double d : {1.0, 2.0}) {
    o.distance_m = d;
    EXPECT_DOUBLE_EQ(continuous_level(o, s, {}), 0.0);
  }
  o.distance_m = 4;  // twice as far: a quarter of the area, a quarter of the triangles: one level
  EXPECT_NEAR(continuous_level(o, s, {}), 1.0, 1e-12);
  o.distance_m = 16;
  EXPECT_NEAR(continuous_level(o, s, {}), 3.0, 1e-12);
  o.distance_m = 1e9;
  EXPECT_DOUBLE_EQ(continuous_level(o, s, {}), 4.0);
}

TEST(LodPolicy, ScreenSizeKeepsTheProjectedErrorWithinTolerance) {
  PolicySettings s;
  s.policy = Policy::ScreenSize;
  s.tolerance_px = 1;
  ObjectView o = chain_object();
  // At 2 m and 1000 px/rad, level 2's 4 mm error is 2 px: too much; level 1's 1 mm is 0.5 px.
  const double l = continuous_level(o, s, {});
  EXPECT_GE(l, 1.0);
  EXPECT_LT(l, 2.0);
  EXPECT_NEAR(l, 1.0 + (1.0 - 0.5) / (2.0 - 0.5), 1e-6);
  o.distance_m = 200;  // far away: every level's error is sub-pixel
  EXPECT_DOUBLE_EQ(continuous_level(o, s, {}), 4.0);
  o.distance_m = 0.01;  // very near: level 1's error is 100 px, so L = 1 / 100 of the way to it
  EXPECT_NEAR(continuous_level(o, s, {}), 0.01, 1e-6);
}

TEST(LodPolicy, BrownImportanceIsBinaryAndStressCoarsens) {
  PolicySettings s;
  s.policy = Policy::Brown;
  ObjectView important = chain_object();
  important.projected_radius_px = 200;       // size: a share of the screen above 2 %
  important.screen_x = important.screen_y = 0.5;  // position: central
  important.luminance_contrast = 0.2;         // luminance
  EXPECT_EQ(brown_importance(important, s.brown, {}), 1);
  EXPECT_DOUBLE_EQ(continuous_level(important, s, {}), 0.0);  // P_LOD = P
  ObjectView dull = chain_object();
  dull.projected_radius_px = 5;
  dull.screen_x = 0.05;
  EXPECT_EQ(brown_importance(dull, s.brown, {}), -1);
  const double l = continuous_level(dull, s, {});
  EXPECT_NEAR(l, std::log(2.0) / std::log(4.0), 1e-9);  // P (1 - a) = P / 2: half a level at beta 4
  // Motion above the others' mean by a standard deviation is a feature.
  ObjectView spinning = dull;
  spinning.rotation_deg_per_frame = 10;
  FrameStats frame;
  frame.rotation_mean = 1;
  frame.rotation_sd = 1;
  s.brown.threshold = 0.5;
  EXPECT_EQ(brown_importance(spinning, s.brown, frame), 1);
  frame.stress = 1.4;  // the frame is slow: eq. 4's stress takes 140 % of P (of 1 + a = 150 % at most)
  EXPECT_NEAR(continuous_level(important, s, frame), std::log(10.0) / std::log(4.0), 1e-9);  // P_LOD = P / 10
}

TEST(LodPolicy, UlodFollowsEq73AndBlendsAdjacentLevels) {
  PolicySettings s;
  s.policy = Policy::Ulod;
  ObjectView o = chain_object();
  o.attention = 1;
  EXPECT_DOUBLE_EQ(continuous_level(o, s, {}), 0.0);
  o.attention = 0;
  EXPECT_DOUBLE_EQ(continuous_level(o, s, {}), 4.0);
  o.attention = 0.6;  // L = 4 (1 - 0.6) = 1.6: level 1 blended with level 2 by 0.6
  ObjectView top = chain_object(2);
  top.attention = 1.0;  // the frame's most attended object (the selector takes S_o relative to it)
  LodSelector sel(s);
  const auto& out = sel.select({o, top}, 0);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[1].drawn, 0);
  EXPECT_NEAR(out[0].level, 1.6, 1e-12);
  EXPECT_EQ(out[0].drawn, 1);
  EXPECT_EQ(out[0].blend_to, 2);
  EXPECT_NEAR(out[0].blend, 0.6, 1e-12);
  // S_o relative to the frame's top: 0.2 and 0.1 read as 1 and 0.5.
  o.attention = 0.1;
  top.attention = 0.2;
  const auto& rel = sel.select({o, top}, 0);
  EXPECT_NEAR(rel[0].level, 2.0, 1e-12);
  EXPECT_NEAR(rel[1].level, 0.0, 1e-12);
  // The frame's top S_o may belong to an object without a chain: then both are coarser.
  const auto& outside = sel.select({o, top}, 0, 0.4);
  EXPECT_NEAR(outside[0].level, 4.0 * (1.0 - 0.25), 1e-12);
  EXPECT_NEAR(outside[1].level, 4.0 * (1.0 - 0.5), 1e-12);
}

TEST(LodPolicy, GazeCoarsensWithEccentricity) {
  PolicySettings s;
  s.policy = Policy::Gaze;
  ObjectView o = chain_object();
  o.distance_m = 1;
  double previous = -1;
  for (double e : {0.0, 5.0, 10.0, 20.0, 40.0}) {
    o.eccentricity_deg = e;
    const double l = continuous_level(o, s, {});
    EXPECT_GE(l, previous) << e;
    previous = l;
  }
  o.eccentricity_deg = 0;
  EXPECT_LT(continuous_level(o, s, {}), 1.5);  // at the fovea a mm at a metre is resolvable
  // At 60 deg f_c = e2 ln(1/CT0) / (alpha (e + e2)) = 1.45 cycles/deg: errors up to 0.345 deg pass,
  // between level 2 (4 mm at 1 m, 0.23 deg) and level 3 (0.92 deg).
  o.eccentricity_deg = 60;
  const double fc = 2.3 * std::log(64.0) / (0.106 * 62.3);
  const double e2 = std::atan2(0.004, 1.0) * 180 / std::numbers::pi, e3 = std::atan2(0.016, 1.0) * 180 / std::numbers::pi;
  EXPECT_NEAR(continuous_level(o, s, {}), 2.0 + (0.5 / fc - e2) / (e3 - e2), 1e-3);
}

TEST(LodPolicy, HysteresisStopsOscillation) {
  PolicySettings s;
  s.policy = Policy::Distance;
  s.hysteresis = 0.25;
  LodSelector sel(s);
  ObjectView o = chain_object();
  // L oscillates around 1.5 by +-0.2: the drawn level must not flip every frame.
  int flips = 0, previous = -1;
  for (int k = 0; k < 40; ++k) {
    const double l = 1.5 + (k % 2 ? 0.2 : -0.2);
    o.distance_m = 2.0 * std::pow(4.0, l / 2.0);
    const int d = sel.select({o}, 0)[0].drawn;
    if (previous >= 0 && d != previous) ++flips;
    previous = d;
  }
  EXPECT_EQ(flips, 0);
  // A real change goes through.
  o.distance_m = 2.0 * std::pow(4.0, 3.5 / 2.0);
  EXPECT_GE(sel.select({o}, 0)[0].drawn, 3);
}

// Issue 25: with switch_in_saccades the levels change during saccades (hidden by saccadic
// suppression), unblended; outside one a level holds within the slack and a change beyond it is
// counted as a pop. Without it ULOD blends (no pops, blended objects) and the others pop.
TEST(LodPolicy, SwitchInSaccadesChangesLevelsOnlyWhileTheEyeIsBlind) {
  const auto at_level = [](ObjectView o, double l) {
    o.distance_m = 2.0 * std::pow(4.0, l / 2.0);  // distance policy, d_ref 2 m: L = l
    return o;
  };
  PolicySettings s;
  s.policy = Policy::Distance;
  s.switch_in_saccades = true;
  LodSelector sel(s);
  const ObjectView o = chain_object();
  EXPECT_EQ(sel.select({at_level(o, 0.0)}, 0)[0].drawn, 0);
  EXPECT_EQ(sel.select({at_level(o, 1.4)}, 0)[0].drawn, 0) << "held outside a saccade";
  EXPECT_EQ(sel.switches().pops, 0);
  sel.set_in_saccade(true);
  EXPECT_EQ(sel.select({at_level(o, 1.4)}, 0)[0].drawn, 1) << "switched during the saccade";
  EXPECT_EQ(sel.switches().switched_in_saccade, 1);
  EXPECT_TRUE(sel.switches().in_saccade);
  sel.set_in_saccade(false);
  EXPECT_EQ(sel.select({at_level(o, 2.4)}, 0)[0].drawn, 1);
  EXPECT_EQ(sel.select({at_level(o, 2.6)}, 0)[0].drawn, 3) << "beyond the slack it pops";
  EXPECT_EQ(sel.switches().pops, 1);

  // ULOD: blends without the setting (weight moves continuously: no pops), never with it.
  PolicySettings u;
  u.policy = Policy::Ulod;
  LodSelector blend(u);
  ObjectView a = chain_object();
  a.attention = 1;
  ObjectView b = chain_object(2);
  b.attention = 0.55;  // L = 4 (1 - 0.55) = 1.8 relative to a
  blend.select({a, b}, 0);
  b.attention = 0.4;  // L = 2.4: drawn 1 -> 2, blended
  const auto& blended = blend.select({a, b}, 0);
  EXPECT_EQ(blended[1].drawn, 2);
  EXPECT_GT(blended[1].blend, 0.0);
  EXPECT_EQ(blend.switches().pops, 0);
  EXPECT_EQ(blend.switches().blended, 1);
  u.switch_in_saccades = true;
  LodSelector snap(u);
  b.attention = 0.55;
  snap.select({a, b}, 0);
  b.attention = 0.4;
  const auto& snapped = snap.select({a, b}, 0);
  EXPECT_EQ(snapped[1].drawn, 2) << "round(1.8) held: 2.4 is within the slack";
  EXPECT_EQ(snapped[1].blend, 0.0);
  EXPECT_EQ(snap.switches().blended, 0);

  // The hysteresis policies pop whenever their level changes outside a saccade.
  PolicySettings h;
  h.policy = Policy::Distance;
  LodSelector hyst(h);
  hyst.select({at_level(o, 0.0)}, 0);
  hyst.select({at_level(o, 1.0)}, 0);
  EXPECT_EQ(hyst.switches().pops, 1);
}

TEST(LodPolicy, BudgetControllerCoarsensUntilItMeetsTheBudgetOrSaysItCannot) {
  PolicySettings s;
  s.policy = Policy::ScreenSize;
  LodSelector sel(s);
  sel.set_budget_ms(10);
  std::vector<ObjectView> objects = {chain_object(1), chain_object(2)};
  objects[0].distance_m = objects[1].distance_m = 0.1;  // full detail by the policy
  EXPECT_EQ(sel.select(objects, 5)[0].drawn, 0);
  // Over budget: the bias grows a quarter level per frame.
  for (int k = 0; k < 8; ++k) sel.select(objects, 20);
  EXPECT_NEAR(sel.budget().bias, 2.0, 1e-12);
  EXPECT_GE(sel.select(objects, 20)[0].drawn, 2);
  // Still over with everything at the coarsest level: reported.
  for (int k = 0; k < 20; ++k) sel.select(objects, 20);
  EXPECT_TRUE(sel.budget().cannot_meet);
  EXPECT_NE(sel.budget().why.find("coarsest"), std::string::npos);
  // Well under budget: back towards full detail.
  for (int k = 0; k < 40; ++k) sel.select(objects, 2);
  EXPECT_DOUBLE_EQ(sel.budget().bias, 0.0);
  EXPECT_FALSE(sel.budget().cannot_meet);
}

}  // namespace
}  // namespace fovea::render::lod
