// SPDX-License-Identifier: Apache-2.0
// Hard cases of LOD selection (renderer/lod/lod_policy.h): S_o outside [0, 1] or NaN, objects without
// a chain, non-finite distances and eccentricities, unknown policy names, a budget no level meets.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

#include "lod/lod_policy.h"

namespace fovea::render::lod {
namespace {

TEST(LodPolicyStability, EveryPolicyStaysInRangeForHardInput) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  ObjectView o;
  o.levels = 4;
  o.level_error_m = {0.0f, 0.01f, 0.02f, 0.04f};
  for (Policy p : {Policy::None, Policy::Distance, Policy::ScreenSize, Policy::Brown, Policy::Ulod, Policy::Gaze}) {
    PolicySettings s;
    s.policy = p;
    for (double v : {nan, inf, -inf, -1.0, 0.0, 2.0, 1e300}) {
      o.attention = v;
      o.distance_m = v;
      o.eccentricity_deg = v;
      o.projected_radius_px = v;
      o.rotation_deg_per_frame = v;
      o.velocity_px_per_frame = v;
      o.px_per_radian = v;
      o.base = v;
      const double l = continuous_level(o, s, {});
      EXPECT_TRUE(std::isfinite(l)) << to_string(p) << " " << v;
      EXPECT_GE(l, 0.0);
      EXPECT_LE(l, 3.0);
    }
  }
  // S_o above 1 is the most attended; NaN is not attended.
  PolicySettings ulod;
  ulod.policy = Policy::Ulod;
  o.attention = 7;
  EXPECT_DOUBLE_EQ(continuous_level(o, ulod, {}), 0.0);
  o.attention = nan;
  EXPECT_DOUBLE_EQ(continuous_level(o, ulod, {}), 3.0);
  // No chain: level 0 whatever the policy.
  ObjectView plain;
  plain.levels = 1;
  plain.distance_m = 1e9;
  for (Policy p : {Policy::Distance, Policy::Ulod, Policy::Gaze}) {
    PolicySettings s;
    s.policy = p;
    EXPECT_DOUBLE_EQ(continuous_level(plain, s, {}), 0.0);
  }
  // Fewer errors than levels: the missing levels count as unreachable tolerance.
  ObjectView short_errors = o;
  short_errors.level_error_m = {0.0f};
  short_errors.distance_m = 5;
  short_errors.px_per_radian = 1000;
  PolicySettings size;
  size.policy = Policy::ScreenSize;
  EXPECT_DOUBLE_EQ(continuous_level(short_errors, size, {}), 0.0);
}

TEST(LodPolicyStability, NamesAndBudgetsAreChecked) {
  EXPECT_EQ(parse_policy("ulod"), Policy::Ulod);
  try {
    parse_policy("fast");
    FAIL() << "unknown policy accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fast"), std::string::npos);
  }
  LodSelector sel;
  for (double b : {-5.0, 0.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    sel.set_budget_ms(b);
    EXPECT_DOUBLE_EQ(sel.budget().target_ms, 0.0) << b;
  }
  // A budget of 1 ms that no level meets: reported; an empty frame selects nothing.
  sel.set_budget_ms(1);
  ObjectView o;
  o.levels = 2;
  o.level_error_m = {0.0f, 0.01f};
  for (int k = 0; k < 10; ++k) sel.select({o}, 50);
  EXPECT_TRUE(sel.budget().cannot_meet);
  EXPECT_TRUE(sel.select({}, 50).empty());
  EXPECT_TRUE(std::isfinite(sel.budget().bias));
}

}  // namespace
}  // namespace fovea::render::lod
