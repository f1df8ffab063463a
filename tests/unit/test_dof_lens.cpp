// SPDX-License-Identifier: Apache-2.0
// The thin-lens CoC model (Lee 2009 eqs. 4.2-4.4 and 5.3, Schedl & Wimmer eq. 1 and its inversion).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "dof/lens.h"
#include "dof_lens.h"

namespace fovea::render::dof {
namespace {

CocModel model(double f, double e, double focus, double px_per_m) { return test::thin_lens(f, e, focus, px_per_m); }

TEST(DofLens, Eq43MatchesTheImageDistanceForm) {
  // R = |V - V_f| E / V with V = F d / (d - F) (eq. 4.2) equals the closed form of eq. 4.3.
  const double f = 0.05, e = 0.05 / 2.8, df = 4.0;
  const CocModel m = model(f, e, df, 1.0);  // 1 px per metre: coc_px is R in metres
  for (double d : {0.5, 1.0, 3.9, 4.0, 4.1, 10.0, 100.0}) {
    const double v = f * d / (d - f), vf = f * df / (df - f);
    EXPECT_NEAR(m.coc_px(d), std::fabs(v - vf) * e / v, 1e-12) << d;
  }
  EXPECT_EQ(m.coc_px(df), 0.0);
}

TEST(DofLens, SignedCocIsNegativeInFrontAndPositiveBehindEq53) {
  const CocModel m = model(0.05, 0.02, 4.0, 20000);
  EXPECT_LT(m.signed_coc_px(2.0), 0.0);
  EXPECT_GT(m.signed_coc_px(8.0), 0.0);
  EXPECT_NEAR(m.signed_coc_px(8.0), m.k_px() * (8.0 - 4.0) / 8.0, 1e-9);
  // Behind the focal plane the CoC approaches K; in front it grows without bound (clamped).
  EXPECT_NEAR(m.coc_px(1e9), m.k_px(), 1e-3);
  EXPECT_LT(m.coc_px(1e9), m.k_px() + 1e-9);
}

TEST(DofLens, SchedlWimmerEq1IsEq43WithApertureFOverN) {
  const Lens lens = photographic_lens(0.05, 2.8, 4.0);
  EXPECT_NEAR(lens.aperture_m, 0.05 / 2.8, 1e-15);
  const CocModel m = model(lens.focal_length_m, lens.aperture_m, 4.0, 1.0);
  const double a = 0.05 / 2.8, f = 0.05, df = 4.0, d = 1.5;
  EXPECT_NEAR(m.coc_px(d), std::fabs(a * f * (df - d)) / (d * (df - f)), 1e-12);
  EXPECT_TRUE(photographic_lens(0.05, std::numeric_limits<double>::infinity(), 4.0).is_pinhole());
}

TEST(DofLens, InvertedCocGivesTheDepthsBackAndHonoursEq8) {
  const CocModel m = model(0.05, 0.02, 4.0, 20000);
  for (double c : {1.0, 4.0, 16.0}) {
    const double near = m.depth_near_for_coc(c), far = m.depth_far_for_coc(c);
    EXPECT_NEAR(m.coc_px(near), c, 1e-6);
    if (c < m.k_px()) {
      EXPECT_NEAR(m.coc_px(far), c, 1e-6);
    } else {
      EXPECT_TRUE(std::isinf(far));
    }
  }
  EXPECT_TRUE(std::isinf(m.depth_far_for_coc(m.k_px() * 1.01)));  // beyond eq. 8's bound
}

TEST(DofLens, DisplayAndSensorProjectionsAgreeWhenTheFieldOfViewMatchesTheDisplay) {
  Camera cam;
  cam.width = 1024;
  cam.height = 768;
  cam.lens = Lens::human_eye(3.0);
  protocol::DisplayGeometry display;
  display.width_px = 1024;
  display.height_px = 768;
  display.width_m = 3.2;
  display.height_m = 2.4;
  display.viewing_distance_m = 3.0;
  cam.vertical_fov_deg = static_cast<float>(2.0 * std::atan(1.2 / 3.0) * 180.0 / 3.14159265358979323846);
  const CocModel a = coc_model(cam, display, 3.0, CocProjection::Display);
  const CocModel b = coc_model(cam, display, 3.0, CocProjection::Sensor);
  EXPECT_NEAR(a.px_per_image_m, b.px_per_image_m, 1e-3 * a.px_per_image_m);
  // Lee §4.6's VR example: display 3 m away, 1024x768 on 3.2 x 2.4 m, eye lens; the nearest object
  // at 0.3 m gives a CoC of at most ~10 px (eq. 4.4 with F = 17 mm there; our preset is 16.7 mm).
  const double c = a.coc_px(0.3);
  EXPECT_GT(c, 5.0);
  EXPECT_LT(c, 12.0);
}

}  // namespace
}  // namespace fovea::render::dof
