// Hard cases of the thin-lens CoC model (renderer/dof/lens.h): finite and bounded everywhere.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "dof/lens.h"
#include "dof_lens.h"

namespace fovea::render::dof {
namespace {

CocModel model(double f, double e, double focus, double px_per_m) { return test::thin_lens(f, e, focus, px_per_m); }

TEST(DofLensStability, HardCasesAreFinite) {
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  for (double focus : {0.05 /* = F */, 0.0, -1.0, 1e-12, inf, nan, 4.0}) {
    CocModel m = model(0.05, 0.02, focus, 20000);
    m.max_coc_px = 1280;
    for (double d : {0.0, -1.0, 1e-12, 0.05, 1.0, 4.0, 1e9, inf, -inf, nan}) {
      const double c = m.coc_px(d), b = m.signed_coc_px(d);
      EXPECT_TRUE(std::isfinite(c) && std::isfinite(b)) << focus << " " << d;
      EXPECT_GE(c, 0.0);
      EXPECT_LE(c, 1280.0);
    }
    EXPECT_TRUE(std::isfinite(m.k_px()));
    EXPECT_FALSE(std::isnan(m.depth_near_for_coc(4)));
    EXPECT_FALSE(std::isnan(m.depth_far_for_coc(4)));
  }
  // Pinhole: zero everywhere.
  const CocModel p = model(0.05, 0.0, 4.0, 20000);
  EXPECT_TRUE(p.pinhole());
  for (double d : {0.0, 1.0, inf, nan}) EXPECT_EQ(p.coc_px(d), 0.0);
  // Focus at infinity: R = E F / d (eq. 4.3's limit).
  const CocModel at_inf = model(0.05, 0.02, inf, 1.0);
  EXPECT_NEAR(at_inf.coc_px(2.0), 0.02 * 0.05 / 2.0, 1e-15);
  EXPECT_EQ(at_inf.coc_px(inf), 0.0);
}

}  // namespace
}  // namespace fovea::render::dof
