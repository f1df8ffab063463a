// SPDX-License-Identifier: Apache-2.0
// Hard cases of the pupil/glint detector (ctest -L stability): degenerate images, unusual formats
// and occlusions must give a clear "no pupil" or a sane pupil, never NaN, never an exception.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "eye/eye_detector.h"
#include "sim/synthetic_eye.h"

namespace fovea::trackerd::eye {
namespace {

void expect_sane(const EyeMeasurement& m) {
  EXPECT_TRUE(std::isfinite(m.pupil.centre.x) && std::isfinite(m.pupil.centre.y));
  EXPECT_TRUE(std::isfinite(m.pupil.major) && std::isfinite(m.pupil.minor) && std::isfinite(m.pupil.angle_deg));
  EXPECT_TRUE(std::isfinite(m.confidence));
  EXPECT_GE(m.confidence, 0.0);
  EXPECT_LE(m.confidence, 1.0);
  EXPECT_TRUE(std::isfinite(m.pupil_glint.x) && std::isfinite(m.pupil_glint.y));
  for (const auto& g : m.glints) EXPECT_TRUE(std::isfinite(g.centre.x) && std::isfinite(g.centre.y));
  if (!m.pupil_found) {
    EXPECT_FALSE(m.why.empty());
    EXPECT_EQ(m.confidence, 0.0);
    EXPECT_TRUE(m.blink);
    EXPECT_FALSE(m.pupil_glint_valid);
  }
}

// A plain dark ellipse on a mid-grey iris and a bright surround, drawn with sub-pixel precision.
cv::Mat drawn_eye(cv::Size size, cv::Point2d centre, double radius, std::vector<cv::Point2d> glints = {}) {
  cv::Mat img(size, CV_8U, cv::Scalar(170));
  constexpr int shift = 4, one = 1 << shift;
  const auto fixed = [&](cv::Point2d p) {
    return cv::Point(static_cast<int>(std::lround((p.x - 0.5) * one)), static_cast<int>(std::lround((p.y - 0.5) * one)));
  };
  cv::circle(img, fixed(centre), static_cast<int>(std::lround(radius * 2.6 * one)), cv::Scalar(100), cv::FILLED, cv::LINE_AA, shift);
  cv::circle(img, fixed(centre), static_cast<int>(std::lround(radius * one)), cv::Scalar(25), cv::FILLED, cv::LINE_AA, shift);
  for (const auto& g : glints) cv::circle(img, fixed(g), 2 * one, cv::Scalar(255), cv::FILLED, cv::LINE_AA, shift);
  return img;
}

EyeDetector detector() {
  DetectorSettings s;
  return EyeDetector(s);
}

TEST(EyeStability, EmptyAndTinyImages) {
  auto d = detector();
  for (const cv::Size size : {cv::Size(0, 0), cv::Size(1, 1), cv::Size(2, 2), cv::Size(11, 11), cv::Size(1, 400), cv::Size(400, 3)}) {
    const cv::Mat img = size.area() ? cv::Mat(size, CV_8U, cv::Scalar(30)) : cv::Mat();
    const EyeMeasurement m = d.detect(img);
    expect_sane(m);
    EXPECT_FALSE(m.pupil_found) << size;
  }
  expect_sane(detect_pupil_baseline(cv::Mat()));
  expect_sane(detect_pupil_baseline(cv::Mat(1, 1, CV_8U, cv::Scalar(0))));
}

TEST(EyeStability, UniformFramesHaveNoPupil) {
  auto d = detector();
  for (const int level : {0, 1, 128, 254, 255}) {
    const cv::Mat img(240, 320, CV_8U, cv::Scalar(level));
    const EyeMeasurement m = d.detect(img);
    expect_sane(m);
    EXPECT_FALSE(m.pupil_found) << level;
    EXPECT_TRUE(m.glints.empty()) << level;
    const EyeMeasurement b = detect_pupil_baseline(img);
    expect_sane(b);
  }
}

TEST(EyeStability, SixteenBitFloatAndColourInputs) {
  const cv::Mat eight = drawn_eye({320, 240}, {160.3, 120.7}, 18);
  auto d = detector();
  const EyeMeasurement ref = d.detect(eight);
  ASSERT_TRUE(ref.pupil_found) << ref.why;

  cv::Mat sixteen;  // a 10-bit sensor in a 16-bit container
  eight.convertTo(sixteen, CV_16U, 1023.0 / 255.0);
  d.reset();
  const EyeMeasurement m16 = d.detect(sixteen);
  expect_sane(m16);
  ASSERT_TRUE(m16.pupil_found) << m16.why;
  EXPECT_NEAR(m16.pupil.centre.x, ref.pupil.centre.x, 0.3);
  EXPECT_NEAR(m16.pupil.centre.y, ref.pupil.centre.y, 0.3);

  cv::Mat colour;
  cv::cvtColor(eight, colour, cv::COLOR_GRAY2BGR);
  d.reset();
  EXPECT_TRUE(d.detect(colour).pupil_found);
  cv::Mat bgra;
  cv::cvtColor(eight, bgra, cv::COLOR_GRAY2BGRA);
  d.reset();
  EXPECT_TRUE(d.detect(bgra).pupil_found);

  cv::Mat floats;  // NaN and Inf pixels must not leak out
  eight.convertTo(floats, CV_32F, 1.0 / 255.0);
  floats.at<float>(10, 10) = std::numeric_limits<float>::quiet_NaN();
  floats.at<float>(20, 20) = std::numeric_limits<float>::infinity();
  floats.at<float>(30, 30) = -std::numeric_limits<float>::infinity();
  d.reset();
  expect_sane(d.detect(floats));

  const cv::Mat two_channel(240, 320, CV_8UC2, cv::Scalar(10, 20));
  expect_sane(d.detect(two_channel));
}

TEST(EyeStability, PupilTouchingTheBorder) {
  auto d = detector();
  for (const cv::Point2d c : {cv::Point2d(10, 120), cv::Point2d(310, 120), cv::Point2d(160, 8), cv::Point2d(160, 234), cv::Point2d(2, 2)}) {
    d.reset();
    const EyeMeasurement m = d.detect(drawn_eye({320, 240}, c, 18));
    expect_sane(m);
    // Found pupils are accurate, or say they are doubtful.
    if (m.pupil_found && m.confidence >= 0.5) {
      EXPECT_LT(std::hypot(m.pupil.centre.x - c.x, m.pupil.centre.y - c.y), 3.0) << c << " confidence " << m.confidence;
    }
  }
  // Half the pupil outside the frame: still found from the visible arc.
  d.reset();
  const EyeMeasurement half = d.detect(drawn_eye({320, 240}, {160, 4}, 18));
  expect_sane(half);
}

TEST(EyeStability, NoGlintAndFiveGlints) {
  DetectorSettings s;
  s.leds = LedLayout::preset(2);
  EyeDetector d(s);
  const EyeMeasurement none = d.detect(drawn_eye({320, 240}, {160, 120}, 18));
  expect_sane(none);
  EXPECT_TRUE(none.pupil_found);
  EXPECT_TRUE(none.glints.empty());
  EXPECT_FALSE(none.pupil_glint_valid);

  d.reset();
  const std::vector<cv::Point2d> five{{150, 110}, {170, 110}, {170, 130}, {150, 130}, {160, 140}};
  const EyeMeasurement many = d.detect(drawn_eye({320, 240}, {160, 120}, 18, five));
  expect_sane(many);
  EXPECT_TRUE(many.pupil_found) << many.why;
  EXPECT_EQ(many.glints.size(), 5u);
  EXPECT_NEAR(many.pupil.centre.x, 160, 0.5);
  EXPECT_NEAR(many.pupil.centre.y, 120, 0.5);
}

TEST(EyeStability, RandomNoiseNeverBreaksTheDetector) {
  cv::RNG rng(7);
  auto d = detector();
  for (int i = 0; i < 60; ++i) {
    cv::Mat img(120 + i, 160 + 2 * i, CV_8U);
    rng.fill(img, i % 2 ? cv::RNG::UNIFORM : cv::RNG::NORMAL, i % 2 ? 0 : 128, i % 2 ? 256 : 60);
    expect_sane(d.detect(img));
    expect_sane(detect_pupil_baseline(img));
  }
}

TEST(EyeStability, ClosedEyeIsABlink) {
  SyntheticEyeOptions o;
  o.seed = 3;
  SyntheticEye eye(o);
  auto d = detector();
  int false_positives = 0;
  for (int i = 0; i < 20; ++i) {
    EyeTruth truth;
    const cv::Mat img = eye.render(-10 + i, 5 - i * 0.5, 0.0, &truth);
    ASSERT_TRUE(truth.closed);
    const EyeMeasurement m = d.detect(img);
    expect_sane(m);
    if (m.pupil_found && !m.blink) ++false_positives;
  }
  EXPECT_LE(false_positives, 1);
}

TEST(EyeStability, InvalidSettingsNameTheField) {
  DetectorSettings s;
  s.coarse_downscale = 3;
  try {
    EyeDetector d(s);
    FAIL() << "accepted downscale 3";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("coarse_downscale"), std::string::npos) << e.what();
  }
  s = {};
  s.min_pupil_radius = 0.3;
  s.max_pupil_radius = 0.1;
  EXPECT_THROW(EyeDetector{s}, std::invalid_argument);
  s = {};
  s.rays = 2;
  EXPECT_THROW(EyeDetector{s}, std::invalid_argument);
}

}  // namespace
}  // namespace fovea::trackerd::eye
