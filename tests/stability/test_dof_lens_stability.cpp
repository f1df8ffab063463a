// SPDX-License-Identifier: Apache-2.0
// Hard cases of the thin-lens CoC model (renderer/dof/lens.h): finite and bounded everywhere.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

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

// The batch form gives the scalar call's values for every hard case of focus and depth.
TEST(DofLensStability, BatchCocEqualsTheScalarCoc) {
  const float finf = std::numeric_limits<float>::infinity(), fnan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<float> depths = {0.0f, -1.0f, 1e-30f, 0.05f, 1.0f, 2.0f, 4.0f, 1e9f, 3e38f, finf, -finf, fnan};
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  for (double focus : {0.05, 0.0, -1.0, 1e-12, inf, nan, 4.0}) {
    for (double aperture : {0.0, 0.02, inf}) {
      CocModel m = model(0.05, aperture, focus, 20000);
      m.max_coc_px = 1280;
      for (double scale : {0.5, 0.25, 1e300}) {
        std::vector<float> out(depths.size(), -7.0f);
        m.scaled_coc_px(depths.data(), depths.size(), scale, out.data());
        for (std::size_t i = 0; i < depths.size(); ++i) {
          const double v = scale * m.coc_px(static_cast<double>(depths[i]));
          const double fmax = static_cast<double>(std::numeric_limits<float>::max());
          const float want = std::isfinite(v) ? static_cast<float>(std::clamp(v, 0.0, fmax)) : 0.0f;
          EXPECT_TRUE(std::isfinite(out[i]));
          EXPECT_FLOAT_EQ(out[i], want) << "focus " << focus << " aperture " << aperture << " scale " << scale
                                        << " depth " << depths[i];
        }
      }
    }
  }
}

}  // namespace
}  // namespace fovea::render::dof
