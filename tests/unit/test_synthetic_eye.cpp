// SPDX-License-Identifier: Apache-2.0
// The synthetic infrared eye is ground truth for the pupil/glint detector, so its geometry must be
// exact and its rendering unbiased to well under the detector's ~0.1 px errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "sim/synthetic_eye.h"

namespace fovea::trackerd::eye {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

SyntheticEyeOptions clean() {
  SyntheticEyeOptions o;
  o.noise_sigma = 0;
  return o;
}

// Signed distance (pixels, to first order) of p from the ellipse's boundary; negative inside.
double signed_distance(const Ellipse& e, cv::Point2d p) {
  const double th = e.angle_deg * kDeg, a = e.major / 2, b = e.minor / 2;
  const double dx = p.x - e.centre.x, dy = p.y - e.centre.y;
  const double u = (dx * std::cos(th) + dy * std::sin(th)) / a;
  const double v = (-dx * std::sin(th) + dy * std::cos(th)) / b;
  const double q = u * u + v * v - 1;
  const double gu = 2 * u / a, gv = 2 * v / b;  // gradient in the rotated frame (same length)
  return q / std::sqrt(gu * gu + gv * gv + 1e-300);
}

int count_below(const cv::Mat& img, int level) {
  int n = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) n += img.at<std::uint8_t>(y, x) < level;
  return n;
}

bool finite(cv::Point2d p) { return std::isfinite(p.x) && std::isfinite(p.y); }

void expect_finite(const EyeTruth& t) {
  EXPECT_TRUE(finite(t.pupil.centre));
  EXPECT_TRUE(std::isfinite(t.pupil.major) && std::isfinite(t.pupil.minor) && std::isfinite(t.pupil.angle_deg));
  EXPECT_TRUE(std::isfinite(t.pupil_visible_fraction));
  EXPECT_TRUE(finite(t.glint_centroid));
  EXPECT_TRUE(finite(t.pupil_glint));
  EXPECT_TRUE(std::isfinite(t.pupil_radius_mm));
  for (const auto& g : t.glints) EXPECT_TRUE(finite(g));
}

TEST(SyntheticEye, TruthCentreIsTheCentroidOfTheRenderedPupil) {
  SyntheticEyeOptions o = clean();
  o.leds = LedLayout::preset(0);  // no glints inside the pupil
  o.eyelashes = false;
  SyntheticEye eye(o);
  const std::vector<std::pair<double, double>> gazes = {{0, 0}, {15, -10}, {-20, 8}, {7.3, 12.1}, {-11.7, -4.4}, {18.2, 16.9}};
  for (const auto& [yaw, pitch] : gazes) {
    EyeTruth t;
    const cv::Mat img = eye.render(yaw, pitch, 1.0, &t);
    ASSERT_FALSE(t.closed);
    ASSERT_EQ(t.pupil_visible_fraction, 1.0) << yaw << "," << pitch;
    // The iris level just outside the pupil (it is flat there) and the pupil level inside.
    std::vector<int> ring;
    int pupil_level = 255;
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const double sd = signed_distance(t.pupil, {x + 0.5, y + 0.5});
        const int v = img.at<std::uint8_t>(y, x);
        if (sd > 1.5 && sd < 2.5) ring.push_back(v);
        if (sd < -2) pupil_level = std::min(pupil_level, v);
      }
    ASSERT_FALSE(ring.empty());
    std::nth_element(ring.begin(), ring.begin() + static_cast<long>(ring.size() / 2), ring.end());
    const double iris = ring[ring.size() / 2];
    EXPECT_GE(pupil_level, 15);
    EXPECT_LE(pupil_level, 30);
    EXPECT_GT(iris - pupil_level, 50);
    // Darkness (0 = iris, 1 = pupil) inside the boundary and half a pixel beyond; its centroid.
    double sw = 0, sx = 0, sy = 0;
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        if (signed_distance(t.pupil, {x + 0.5, y + 0.5}) > 1.5) continue;
        const double wgt = std::clamp((iris - img.at<std::uint8_t>(y, x)) / (iris - pupil_level), 0.0, 1.0);
        sw += wgt;
        sx += wgt * (x + 0.5);
        sy += wgt * (y + 0.5);
      }
    const cv::Point2d c(sx / sw, sy / sw);
    EXPECT_LT(std::hypot(c.x - t.pupil.centre.x, c.y - t.pupil.centre.y), 0.05)
        << "gaze " << yaw << "," << pitch << ": centroid " << c << " truth " << t.pupil.centre;
    const double area = 3.14159265358979 * t.pupil.major * t.pupil.minor / 4;
    EXPECT_NEAR(sw / area, 1.0, 0.02);
  }
}

TEST(SyntheticEye, SizesWithTheDefaultCamera) {
  SyntheticEye eye(clean());
  const EyeTruth t = eye.project(0, 0);
  EXPECT_GT(t.pupil.major, 25);
  EXPECT_LT(t.pupil.major, 45);
  EXPECT_GT(t.pupil.aspect(), 0.75);  // seen from 30 degrees below
  EXPECT_LT(t.pupil.aspect(), 0.95);
  EXPECT_NEAR(t.pupil.angle_deg, 0, 1e-6);  // a camera straight below: the major axis is horizontal
  EXPECT_DOUBLE_EQ(t.pupil_radius_mm, 2.0);
  // The iris: the same plane, so a pupil as large as the iris shows where it is.
  SyntheticEyeOptions o = clean();
  o.eye.pupil_radius_mm = o.eye.iris_radius_mm * 0.95;
  const EyeTruth big = SyntheticEye(o).project(0, 0);
  const double r = big.pupil.major / 2 / 0.95;
  EXPECT_GT(big.pupil.centre.x - r, 0);
  EXPECT_LT(big.pupil.centre.x + r, o.width);
  EXPECT_GT(big.pupil.centre.y - r, 0);
  EXPECT_LT(big.pupil.centre.y + r, o.height);
}

TEST(SyntheticEye, TheTruthIsTheConicCentreNotTheProjectedPupilCentre) {
  // Off-axis perspective: the image of the disc's centre is not the centre of its image ellipse.
  SyntheticEye eye(clean());
  const EyeTruth t = eye.project(25, 20);
  const double a = t.pupil.major / 2, b = t.pupil.minor / 2;
  // The truth ellipse is symmetric about its centre: check points on it are on the boundary.
  for (int k = 0; k < 8; ++k) {
    const double phi = k * 45 * kDeg, th = t.pupil.angle_deg * kDeg;
    const cv::Point2d p(t.pupil.centre.x + a * std::cos(phi) * std::cos(th) - b * std::sin(phi) * std::sin(th),
                        t.pupil.centre.y + a * std::cos(phi) * std::sin(th) + b * std::sin(phi) * std::cos(th));
    EXPECT_NEAR(signed_distance(t.pupil, p), 0, 1e-9);
  }
  EXPECT_GE(t.pupil.angle_deg, 0);
  EXPECT_LT(t.pupil.angle_deg, 180);
  EXPECT_GE(t.pupil.major, t.pupil.minor);
}

TEST(SyntheticEye, PupilMovesWithGaze) {
  SyntheticEye eye(clean());
  const EyeTruth c = eye.project(0, 0);
  // The default camera faces the eye from below: the eye's right (+yaw) is the image's left.
  EXPECT_LT(eye.project(10, 0).pupil.centre.x, c.pupil.centre.x - 10);
  EXPECT_GT(eye.project(-10, 0).pupil.centre.x, c.pupil.centre.x + 10);
  EXPECT_GT(eye.project(0, 10).pupil.centre.y, c.pupil.centre.y + 10);  // looking down: image down
  EXPECT_LT(eye.project(0, -10).pupil.centre.y, c.pupil.centre.y - 10);
  EXPECT_NEAR(eye.project(10, 0).pupil.centre.y, eye.project(-10, 0).pupil.centre.y, 1e-9);  // symmetric camera
}

struct FitResidual {
  double worst = 0, rms = 0;  // degrees
};

// Fits yaw and pitch each as a 2nd-order polynomial of the pupil-glint vector (the usual
// calibration model) over a 9 x 9 grid of +-4 steps; returns the residuals.
FitResidual poly2_residual(const SyntheticEye& eye, double step, std::vector<cv::Point2d>* grid = nullptr) {
  cv::Mat1d a(81, 6), by(81, 1), bp(81, 1);
  for (int i = -4, k = 0; i <= 4; ++i)
    for (int j = -4; j <= 4; ++j, ++k) {
      const cv::Point2d pg = eye.project(step * i, step * j).pupil_glint;
      if (grid) grid->push_back(pg);
      const double x = pg.x / 100, y = pg.y / 100;
      const double row[] = {1, x, y, x * x, x * y, y * y};
      for (int c = 0; c < 6; ++c) a(k, c) = row[c];
      by(k) = step * i;
      bp(k) = step * j;
    }
  cv::Mat1d cy, cp, ry, rp;
  cv::solve(a, by, cy, cv::DECOMP_SVD);
  cv::solve(a, bp, cp, cv::DECOMP_SVD);
  cv::subtract(a * cy, by, ry);
  cv::subtract(a * cp, bp, rp);
  FitResidual out;
  for (int k = 0; k < 81; ++k) {
    out.worst = std::max({out.worst, std::abs(ry(k)), std::abs(rp(k))});
    out.rms += ry(k) * ry(k) + rp(k) * rp(k);
  }
  out.rms = std::sqrt(out.rms / 162);
  return out;
}

TEST(SyntheticEye, PupilGlintVectorIsASmoothMonotonicFunctionOfGaze) {
  SyntheticEye eye(clean());
  std::vector<cv::Point2d> pg;
  const FitResidual wide = poly2_residual(eye, 5.0, &pg);  // +-20 degrees
  // Monotonic along each grid line: x falls with yaw (mirrored camera), y rises with pitch.
  const auto at = [&](int i, int j) { return pg[static_cast<std::size_t>(i * 9 + j)]; };
  for (int i = 0; i < 9; ++i)
    for (int j = 0; j < 9; ++j) {
      if (i + 1 < 9) {
        EXPECT_LT(at(i + 1, j).x, at(i, j).x - 2);
      }
      if (j + 1 < 9) {
        EXPECT_GT(at(i, j + 1).y, at(i, j).y + 2);
      }
    }
  // Over +-10 degrees a 2nd-order polynomial maps it to gaze to well within the noise of real
  // trackers. Over +-20 it cannot do as well: the exact geometry has a 3rd-order part (yaw's
  // effect shrinks with cos(pitch); the camera 31 degrees below foreshortens upward gaze), which
  // leaves about 1.6 degrees at the grid's corners (1.2 even with an on-axis camera).
  const FitResidual narrow = poly2_residual(eye, 2.5);
  EXPECT_LT(narrow.worst, 0.3);
  EXPECT_LT(narrow.rms, 0.1);
  EXPECT_LT(wide.worst, 2.0);
  EXPECT_LT(wide.rms, 0.6);
}

TEST(SyntheticEye, EveryPresetGivesItsGlintsAtCentralGaze) {
  for (int n = 0; n <= 5; ++n) {
    SyntheticEyeOptions o = clean();
    o.leds = LedLayout::preset(n);
    SyntheticEye eye(o);
    EyeTruth t;
    eye.render(0, 0, 1, &t);
    if (n == 5)
      EXPECT_GE(t.glints.size(), 4u);
    else
      EXPECT_EQ(t.glints.size(), static_cast<std::size_t>(n)) << n << " LEDs";
    ASSERT_EQ(t.glints.size(), t.glint_led.size());
    for (std::size_t k = 0; k < t.glints.size(); ++k) {
      // Near the pupil (on the cornea), not far away on the lids.
      EXPECT_LT(std::hypot(t.glints[k].x - t.pupil.centre.x, t.glints[k].y - t.pupil.centre.y), 60);
    }
    EXPECT_EQ(t.leds_used.positions_mm, o.leds.positions_mm);
    expect_finite(t);
  }
}

TEST(SyntheticEye, GlintsAreAnUprightReducedCopyOfTheLeds) {
  SyntheticEyeOptions o = clean();
  o.leds = LedLayout::preset(2);  // left, right (in the camera's image orientation)
  const EyeTruth t = SyntheticEye(o).project(0, 0);
  ASSERT_EQ(t.glints.size(), 2u);
  EXPECT_LT(t.glints[0].x, t.glints[1].x);
  EXPECT_NEAR(t.glints[0].y, t.glints[1].y, 1e-9);
  EXPECT_NEAR(t.glint_centroid.x, (t.glints[0].x + t.glints[1].x) / 2, 1e-9);
  EXPECT_NEAR(t.pupil_glint.x, t.pupil.centre.x - t.glint_centroid.x, 1e-12);
}

TEST(SyntheticEye, GlintsAreBrightInTheImage) {
  SyntheticEye eye(clean());
  EyeTruth t;
  const cv::Mat img = eye.render(3, -2, 1, &t);
  ASSERT_EQ(t.glints.size(), 2u);
  for (const auto& g : t.glints) EXPECT_EQ(img.at<std::uint8_t>(static_cast<int>(g.y), static_cast<int>(g.x)), 255);
}

// The mean grey level of the pixels whose signed distance from e's boundary lies in [d0, d1),
// away from the glints.
double mean_in_band(const cv::Mat& img, const EyeTruth& t, double d0, double d1) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const cv::Point2d p(x + 0.5, y + 0.5);
      const double d = signed_distance(t.pupil, p);
      if (d < d0 || d >= d1) continue;
      bool near_glint = false;
      for (const auto& g : t.glints) near_glint = near_glint || std::hypot(p.x - g.x, p.y - g.y) < 6;
      if (near_glint) continue;
      sum += img.at<std::uint8_t>(y, x);
      ++n;
    }
  return n ? sum / n : std::nan("");
}

TEST(SyntheticEye, ADarkIrisStandsTheGivenLevelsAboveThePupil) {
  for (double contrast : {5.0, 9.0, 15.0}) {
    SyntheticEyeOptions o = clean();
    o.eyelashes = false;
    o.pupil_iris_contrast = contrast;
    SyntheticEye eye(o);
    EyeTruth t;
    const cv::Mat img = eye.render(0, -5, 1, &t);  // looking up a little: the lid's shadow stays off the pupil
    const double pupil = mean_in_band(img, t, -1e9, -2), iris = mean_in_band(img, t, 1.5, 3);
    EXPECT_NEAR(iris - pupil, contrast, 1.0) << "contrast " << contrast;
  }
  SyntheticEye natural(clean());
  EyeTruth t;
  const cv::Mat img = natural.render(0, -5, 1, &t);
  EXPECT_GT(mean_in_band(img, t, 1.5, 3) - mean_in_band(img, t, -1e9, -2), 60);  // the instance's own iris
}

TEST(SyntheticEye, WeakLightScalesTheLevelsNotTheNoise) {
  SyntheticEyeOptions o = clean();
  o.eyelashes = false;
  SyntheticEye full(o);
  o.exposure = 0.3;
  SyntheticEye weak(o);
  EyeTruth t;
  const cv::Mat a = full.render(0, -5, 1, &t), b = weak.render(0, -5, 1, nullptr);
  for (auto [d0, d1] : {std::pair{-1e9, -2.0}, std::pair{1.5, 3.0}, std::pair{30.0, 40.0}})
    EXPECT_NEAR(mean_in_band(b, t, d0, d1), 0.3 * mean_in_band(a, t, d0, d1), 0.6) << "band " << d0;
  // The same noise on the weaker signal.
  o.noise_sigma = 4;
  o.exposure = 1;
  SyntheticEye noisy_full(o);
  o.exposure = 0.3;
  SyntheticEye noisy_weak(o);
  const cv::Mat na = noisy_full.render(0, -5, 1, nullptr), nb = noisy_weak.render(0, -5, 1, nullptr);
  cv::Mat da, db;
  cv::subtract(na, a, da, cv::noArray(), CV_32F);
  cv::subtract(nb, b, db, cv::noArray(), CV_32F);
  cv::Scalar ma, sa, mb, sb;
  cv::meanStdDev(da, ma, sa);
  cv::meanStdDev(db, mb, sb);
  EXPECT_NEAR(sa[0], 4, 0.4);
  EXPECT_NEAR(sb[0], 4, 0.4);
}

TEST(SyntheticEye, LongLashesHangOverThePupilsBorder) {
  SyntheticEyeOptions o = clean();
  o.eyelid_cover = 0.15;  // the lid's margin, where the lashes grow, just over the pupil
  SyntheticEye normal(o);
  o.eyelash_length = 2.5;
  SyntheticEye long_lashes(o);
  EyeTruth t;
  const cv::Mat a = normal.render(0, -5, 1, &t), b = long_lashes.render(0, -5, 1, nullptr);
  // The longer lashes cross the pupil's border: the iris just outside it darkens where they lie.
  // (Unlit lashes only darken, so over the pupil itself they do not show: see LitLashesShowOverThePupil.)
  int crossed = 0;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      const double d = signed_distance(t.pupil, {x + 0.5, y + 0.5});
      if (d > 0.5 && d < 4)
        crossed += static_cast<int>(a.at<std::uint8_t>(y, x)) - static_cast<int>(b.at<std::uint8_t>(y, x)) > 10;
    }
  EXPECT_GT(crossed, 10);
}

// Lashes lit by the LEDs are at their own level everywhere: grey lines across the (darker) pupil.
TEST(SyntheticEye, LitLashesShowOverThePupil) {
  SyntheticEyeOptions o = clean();
  o.eyelid_cover = 0.15;
  o.eyelash_length = 2.5;
  SyntheticEye unlit(o);
  o.lit_lashes = true;
  SyntheticEye lit(o);
  EyeTruth t;
  const cv::Mat a = unlit.render(0, -5, 1, &t), b = lit.render(0, -5, 1, nullptr);
  int brighter = 0, darker = 0;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      const int d = static_cast<int>(b.at<std::uint8_t>(y, x)) - static_cast<int>(a.at<std::uint8_t>(y, x));
      if (signed_distance(t.pupil, {x + 0.5, y + 0.5}) < -1.5) brighter += d > 10;  // inside the pupil
      darker += d < -10;
    }
  EXPECT_GT(brighter, 10);
  EXPECT_EQ(darker, 0);  // where the unlit lashes darkened, the lit ones are no darker
}

TEST(SyntheticEye, ClosedEyeShowsNoPupil) {
  SyntheticEye eye(clean());
  EyeTruth open, shut;
  const cv::Mat a = eye.render(0, 0, 1, &open);
  const cv::Mat b = eye.render(0, 0, 0, &shut);
  EXPECT_FALSE(open.closed);
  EXPECT_TRUE(shut.closed);
  EXPECT_EQ(shut.pupil_visible_fraction, 0);
  EXPECT_TRUE(shut.glints.empty());
  const double area = 3.14159265358979 * open.pupil.major * open.pupil.minor / 4;
  EXPECT_NEAR(count_below(a, 40), area, 0.05 * area);
  EXPECT_LT(count_below(b, 40), 0.02 * area);
  // Half closed: the lid is lower but the pupil still shows.
  const EyeTruth half = eye.project(0, 0, 0.5);
  EXPECT_FALSE(half.closed);
  EXPECT_LT(half.pupil_visible_fraction, 1);
}

TEST(SyntheticEye, EyelidCoverHidesThatShareOfThePupil) {
  SyntheticEyeOptions o = clean();
  o.eyelid_cover = 0.3;
  o.eyelashes = false;
  SyntheticEye eye(o);
  for (const auto& [yaw, pitch] : std::vector<std::pair<double, double>>{{0, 0}, {15, 10}, {-15, -10}}) {
    EyeTruth t;
    const cv::Mat img = eye.render(yaw, pitch, 1, &t);
    EXPECT_NEAR(t.pupil_visible_fraction, 0.7, 0.1) << yaw << "," << pitch;
    EXPECT_FALSE(t.closed);
    const double area = 3.14159265358979 * t.pupil.major * t.pupil.minor / 4;
    EXPECT_NEAR(count_below(img, 40) / area, t.pupil_visible_fraction, 0.05);
  }
  o.eyelid_cover = 1;
  EXPECT_LT(SyntheticEye(o).project(0, 0).pupil_visible_fraction, 0.05);
}

TEST(SyntheticEye, GlintOnPupilEdgeLiesOnTheConic) {
  SyntheticEyeOptions o = clean();
  o.glint_on_pupil_edge = true;
  int displaced = 0;
  for (const int leds : {1, 2, 4}) {
    o.leds = LedLayout::preset(leds);
    SyntheticEye eye(o);
    for (int i = -2; i <= 2; ++i)
      for (int j = -2; j <= 2; ++j) {
        EyeTruth t;
        eye.render(9.0 * i, 7.0 * j, 1, &t);
        ASSERT_FALSE(t.glints.empty()) << leds << " LEDs at " << i << "," << j;
        double best = 1e9;
        for (const auto& g : t.glints) best = std::min(best, std::abs(signed_distance(t.pupil, g)));
        EXPECT_LT(best, 0.05) << leds << " LEDs at " << 9.0 * i << "," << 7.0 * j;
        EXPECT_GE(t.pupil_radius_mm, 1.0);
        EXPECT_LE(t.pupil_radius_mm, 4.0);
        ASSERT_EQ(t.leds_used.positions_mm.size(), o.leds.positions_mm.size());
        displaced += t.leds_used.positions_mm != o.leds.positions_mm;
        // project() agrees with render().
        const EyeTruth p = eye.project(9.0 * i, 7.0 * j);
        EXPECT_EQ(p.pupil.centre, t.pupil.centre);
        EXPECT_EQ(p.pupil_radius_mm, t.pupil_radius_mm);
      }
  }
  // One LED below the lens makes its glint near the pupil centre at central gaze: it has to move.
  EXPECT_GT(displaced, 0);
}

TEST(SyntheticEye, DeterministicForASeedAndCallSequence) {
  SyntheticEyeOptions o;
  o.seed = 77;
  o.glasses_reflection = true;
  o.illumination_gradient = 0.5;
  o.noise_sigma = 5;
  SyntheticEye a(o), b(o);
  const cv::Mat a1 = a.render(5, 3, 1, nullptr);
  (void)a.project(-7, 2);  // project() draws no randomness
  const cv::Mat a2 = a.render(-4, 1, 0.8, nullptr);
  const cv::Mat b1 = b.render(5, 3, 1, nullptr);
  const cv::Mat b2 = b.render(-4, 1, 0.8, nullptr);
  EXPECT_EQ(cv::norm(a1, b1, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(a2, b2, cv::NORM_INF), 0);
  EXPECT_GT(cv::norm(a1, a.render(5, 3, 1, nullptr), cv::NORM_INF), 0);  // fresh noise each frame
  o.seed = 78;
  EXPECT_GT(cv::norm(a1, SyntheticEye(o).render(5, 3, 1, nullptr), cv::NORM_INF), 0);
}

TEST(SyntheticEye, InvalidOptionsThrowNamingTheField) {
  const auto expect_throw = [](auto mutate, const std::string& field) {
    SyntheticEyeOptions o;
    mutate(o);
    try {
      SyntheticEye eye(o);
      ADD_FAILURE() << "no exception for " << field;
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(field), std::string::npos) << what;
      EXPECT_NE(what.find("allowed"), std::string::npos) << what;
    }
  };
  const double nan = std::nan("");
  expect_throw([](SyntheticEyeOptions& o) { o.width = 0; }, "width");
  expect_throw([](SyntheticEyeOptions& o) { o.width = 4097; }, "width");
  expect_throw([](SyntheticEyeOptions& o) { o.height = -3; }, "height");
  expect_throw([](SyntheticEyeOptions& o) { o.noise_sigma = -1; }, "noise_sigma");
  expect_throw([&](SyntheticEyeOptions& o) { o.noise_sigma = nan; }, "noise_sigma");
  expect_throw([](SyntheticEyeOptions& o) { o.eyelid_cover = 1.5; }, "eyelid_cover");
  expect_throw([](SyntheticEyeOptions& o) { o.eyelid_cover = -0.1; }, "eyelid_cover");
  expect_throw([](SyntheticEyeOptions& o) { o.leds.positions_mm.assign(9, {1, 1}); }, "leds");
  expect_throw([](SyntheticEyeOptions& o) { o.leds.positions_mm = {{INFINITY, 0}}; }, "leds[0]");
  expect_throw([&](SyntheticEyeOptions& o) { o.defocus_px = nan; }, "defocus_px");
  expect_throw([](SyntheticEyeOptions& o) { o.motion_blur_px = -2; }, "motion_blur_px");
  expect_throw([](SyntheticEyeOptions& o) { o.illumination_gradient = 2; }, "illumination_gradient");
  expect_throw([](SyntheticEyeOptions& o) { o.exposure = 0; }, "exposure");
  expect_throw([](SyntheticEyeOptions& o) { o.eyelash_length = 5; }, "eyelash_length");
  expect_throw([&](SyntheticEyeOptions& o) { o.exposure = nan; }, "exposure");
  expect_throw([](SyntheticEyeOptions& o) { o.pupil_iris_contrast = 1; }, "pupil_iris_contrast");
  expect_throw([](SyntheticEyeOptions& o) { o.pupil_iris_contrast = -5; }, "pupil_iris_contrast");
  expect_throw([](SyntheticEyeOptions& o) { o.camera.position_mm.x = INFINITY; }, "camera.position_mm");
  expect_throw([](SyntheticEyeOptions& o) { o.camera.position_mm = {0, 0, 5}; }, "camera.position_mm");
  expect_throw([](SyntheticEyeOptions& o) { o.camera.look_at_mm = o.camera.position_mm; }, "camera.look_at_mm");
  expect_throw([](SyntheticEyeOptions& o) { o.camera.horizontal_fov_deg = 180; }, "camera.horizontal_fov_deg");
  expect_throw([](SyntheticEyeOptions& o) { o.eye.pupil_radius_mm = 7; }, "eye.pupil_radius_mm");
  expect_throw([&](SyntheticEyeOptions& o) { o.eye.cornea_radius_mm = nan; }, "eye.cornea_radius_mm");

  SyntheticEye eye(clean());
  EXPECT_THROW(eye.project(nan, 0), std::invalid_argument);
  EXPECT_THROW(eye.render(0, INFINITY, 1, nullptr), std::invalid_argument);
  EXPECT_DOUBLE_EQ(eye.project(0, 90).pitch_deg, 60.0);  // clamped to the eye's range
  EXPECT_THROW(eye.render(0, 0, nan, nullptr), std::invalid_argument);
  EXPECT_DOUBLE_EQ(eye.project(0, 0, 7).openness, 1.0);  // clamped
}

TEST(SyntheticEye, TinyImagesRender) {
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(2, 3), cv::Size(3, 2), cv::Size(2, 2)}) {
    SyntheticEyeOptions o;
    o.width = size.width;
    o.height = size.height;
    o.defocus_px = 3;
    o.motion_blur_px = 4;
    o.glasses_reflection = true;
    o.illumination_gradient = 1;
    o.glint_on_pupil_edge = true;
    o.eyelid_cover = 0.5;
    SyntheticEye eye(o);
    EyeTruth t;
    const cv::Mat img = eye.render(10, -5, 1, &t);
    EXPECT_EQ(img.size(), size);
    EXPECT_EQ(img.type(), CV_8UC1);
    expect_finite(t);
  }
}

TEST(SyntheticEye, HardCasesStayFinite) {
  SyntheticEyeOptions o;
  o.leds = LedLayout::preset(5);
  o.noise_sigma = 10;
  o.defocus_px = 3;
  o.motion_blur_px = 5;
  o.motion_blur_angle_deg = 30;
  o.glasses_reflection = true;
  o.illumination_gradient = 1;
  o.glint_on_pupil_edge = true;
  o.eyelid_cover = 0.3;
  SyntheticEye eye(o);
  for (int i = -3; i <= 3; ++i)
    for (int j = -3; j <= 3; ++j) {
      EyeTruth t;
      const cv::Mat img = eye.render(20.0 * i, 20.0 * j, (i + 3) / 6.0, &t);
      ASSERT_EQ(img.type(), CV_8UC1);
      expect_finite(t);
      EXPECT_GE(t.pupil_radius_mm, 1.0);
      EXPECT_LE(t.pupil_radius_mm, 4.0);
    }
  // A camera beside the eye sees the pupil edge-on or from behind at some gazes.
  SyntheticEyeOptions side;
  side.camera.position_mm = {40, 0, 0};
  side.camera.look_at_mm = {0, 0, 0};
  SyntheticEye s(side);
  for (int i = -3; i <= 3; ++i) {
    EyeTruth t;
    s.render(20.0 * i, 0, 1, &t);
    expect_finite(t);
  }
}

// FOVEA_EYEGEN_DIR=/tmp/eyegen ./test_synthetic_eye --gtest_filter='*Examples*' writes example frames.
TEST(SyntheticEye, WritesExamplesWhenAsked) {
  const char* dir = std::getenv("FOVEA_EYEGEN_DIR");
  if (!dir) GTEST_SKIP() << "set FOVEA_EYEGEN_DIR to write example PNGs";
  std::filesystem::create_directories(dir);
  const auto save = [&](const std::string& name, SyntheticEyeOptions o, double yaw, double pitch, double openness) {
    SyntheticEye eye(o);
    EyeTruth t;
    const cv::Mat img = eye.render(yaw, pitch, openness, &t);
    ASSERT_TRUE(cv::imwrite(std::string(dir) + "/" + name + ".png", img));
  };
  SyntheticEyeOptions o;
  save("clean", o, 0, 0, 1);
  save("clean_yaw20_pitch10", o, 20, 10, 1);
  save("clean_up_left", o, -15, -15, 1);
  SyntheticEyeOptions four = o;
  four.leds = LedLayout::preset(4);
  save("four_leds", four, 8, -5, 1);
  save("half_closed", o, 0, 0, 0.4);
  save("closed", o, 0, 0, 0);
  SyntheticEyeOptions hard = o;
  hard.seed = 5;
  hard.noise_sigma = 10;
  hard.defocus_px = 3;
  hard.eyelid_cover = 0.3;
  hard.glasses_reflection = true;
  hard.illumination_gradient = 0.5;
  hard.glint_on_pupil_edge = true;
  save("hard", hard, 10, 5, 1);
  SyntheticEyeOptions motion = o;
  motion.motion_blur_px = 6;
  motion.motion_blur_angle_deg = 20;
  save("motion", motion, -5, 5, 1);
  SyntheticEyeOptions big = o;
  big.width = 640;
  big.height = 480;
  big.seed = 9;
  save("big_640", big, 12, -6, 1);
  SyntheticEyeOptions small = o;
  small.width = 192;
  small.height = 192;
  save("small_192", small, -10, 8, 1);
}

}  // namespace
}  // namespace fovea::trackerd::eye
