// SPDX-License-Identifier: Apache-2.0
// Pupil and glint detector: accuracy on drawn and generated eyes, ROI tracking, LED pairing, blinks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "eye/detector_stages.h"
#include "eye/eye_detector.h"
#include "sim/synthetic_eye.h"

namespace fovea::trackerd::eye {
namespace {

constexpr int kShift = 4, kOne = 1 << kShift;
cv::Point fixed(cv::Point2d p) {  // Ellipse's pixel convention -> OpenCV's sub-pixel drawing
  return {static_cast<int>(std::lround((p.x - 0.5) * kOne)), static_cast<int>(std::lround((p.y - 0.5) * kOne))};
}

cv::Mat drawn_eye(cv::Point2d centre, cv::Size2d axes, double angle_deg, const std::vector<cv::Point2d>& glints = {}) {
  cv::Mat img(240, 320, CV_8U, cv::Scalar(170));
  cv::circle(img, fixed(centre), static_cast<int>(std::lround(axes.width * 1.3 * kOne)), cv::Scalar(100), cv::FILLED, cv::LINE_AA, kShift);
  cv::ellipse(img, fixed(centre),
              cv::Size(static_cast<int>(std::lround(axes.width / 2 * kOne)), static_cast<int>(std::lround(axes.height / 2 * kOne))),
              angle_deg, 0, 360, cv::Scalar(25), cv::FILLED, cv::LINE_AA, kShift);
  for (const auto& g : glints) cv::circle(img, fixed(g), 2 * kOne, cv::Scalar(255), cv::FILLED, cv::LINE_AA, kShift);
  return img;
}

double distance(cv::Point2d a, cv::Point2d b) { return std::hypot(a.x - b.x, a.y - b.y); }

TEST(EyeDetector, FindsADrawnPupilToSubPixelPrecision) {
  EyeDetector d;
  for (int i = 0; i < 12; ++i) {
    const cv::Point2d c(120 + 7.37 * i, 90 + 4.61 * i);
    d.reset();
    const EyeMeasurement m = d.detect(drawn_eye(c, {38, 34}, 15 * i));
    ASSERT_TRUE(m.pupil_found) << m.why;
    EXPECT_LT(distance(m.pupil.centre, c), 0.25) << "at " << c;
    EXPECT_NEAR(m.pupil.major, 38, 1.5);
    EXPECT_NEAR(m.pupil.minor, 34, 1.5);
    EXPECT_FALSE(m.blink);
    EXPECT_GT(m.confidence, 0.5);
  }
}

TEST(EyeDetector, ReportsTheMajorAxisAngle) {
  EyeDetector d;
  for (const double angle : {0.0, 30.0, 60.0, 90.0, 135.0}) {
    d.reset();
    const EyeMeasurement m = d.detect(drawn_eye({160, 120}, {44, 32}, angle));
    ASSERT_TRUE(m.pupil_found) << m.why;
    const double diff = std::abs(std::remainder(m.pupil.angle_deg - angle, 180.0));
    EXPECT_LT(diff, 3.0) << angle << " vs " << m.pupil.angle_deg;
  }
}

TEST(EyeDetector, AFlatEllipseIsABlink) {  // Lee 2009 §3.5.2: aspect ratio < 0.7
  EyeDetector d;
  const EyeMeasurement m = d.detect(drawn_eye({160, 120}, {50, 25}, 0));
  ASSERT_TRUE(m.pupil_found) << m.why;
  EXPECT_TRUE(m.blink);
  EXPECT_FALSE(m.pupil_glint_valid);
}

TEST(EyeDetector, TracksTheRoiAndRecoversWhenThePupilJumps) {
  EyeDetector d;
  EXPECT_FALSE(d.detect(drawn_eye({150, 110}, {36, 36}, 0)).used_roi);
  const EyeMeasurement near = d.detect(drawn_eye({153, 112}, {36, 36}, 0));
  EXPECT_TRUE(near.pupil_found);
  EXPECT_TRUE(near.used_roi);
  const EyeMeasurement far = d.detect(drawn_eye({40, 40}, {36, 36}, 0));  // far outside the tracked ROI
  ASSERT_TRUE(far.pupil_found) << far.why;
  EXPECT_FALSE(far.used_roi);
  EXPECT_LT(distance(far.pupil.centre, {40, 40}), 0.5);
}

TEST(EyeDetector, PairsGlintsWithTheLedLayout) {
  DetectorSettings s;
  s.leds = LedLayout::preset(2);  // LEDs at (-10, 0) and (10, 0) mm
  EyeDetector d(s);
  const cv::Point2d c(160, 120);
  const std::vector<cv::Point2d> glints{{150, 126}, {166, 126}, {120, 60}};  // the third is a stray reflection
  const EyeMeasurement m = d.detect(drawn_eye(c, {36, 36}, 0, glints));
  ASSERT_TRUE(m.pupil_found) << m.why;
  ASSERT_TRUE(m.pupil_glint_valid);
  EXPECT_NEAR(m.pupil_glint.x, 160 - 158, 0.3);
  EXPECT_NEAR(m.pupil_glint.y, 120 - 126, 0.3);
  int paired = 0;
  for (const auto& g : m.glints) {
    if (g.led < 0) continue;
    ++paired;
    EXPECT_EQ(g.led, g.centre.x < 158 ? 0 : 1);
  }
  EXPECT_EQ(paired, 2);
  // One glint lost (e.g. behind an eyelash): the layout's scale from the last frame places the pair.
  const EyeMeasurement one = d.detect(drawn_eye(c, {36, 36}, 0, {{150, 126}}));
  ASSERT_TRUE(one.pupil_glint_valid);
  EXPECT_NEAR(one.pupil_glint.x, 2, 0.5);
  EXPECT_NEAR(one.pupil_glint.y, -6, 0.5);
}

// A pupil does not double in size from one frame to the next: an answer 1.8x the size of this eye's
// recent clear pupils (a dark iris under the lid, fitted whole) is doubted, confidence <= 0.5; a
// lasting change of size is learnt within five clear frames.
TEST(EyeDetector, DoubtsAnAnswerTwiceTheRecentPupilsSize) {
  EyeDetector d;
  for (int i = 0; i < 6; ++i) {
    const EyeMeasurement m = d.detect(drawn_eye({160.3 + i, 120.4}, {34, 33}, 0));
    ASSERT_TRUE(m.pupil_found) << m.why;
    EXPECT_FALSE(m.size_jump) << i;
    EXPECT_GT(m.confidence, 0.9) << i;
  }
  for (int i = 0; i < 6; ++i) {
    const EyeMeasurement m = d.detect(drawn_eye({160.3 + i, 120.4}, {72, 70}, 0));
    ASSERT_TRUE(m.pupil_found) << m.why;
    ASSERT_GT(m.fit_confidence, 0.9) << i;  // clear by its own evidence: only its size is doubtful
    EXPECT_EQ(m.size_jump, i < 5) << i;     // 6 small and 4 large of the last 9 clear fits: still small
    if (i < 5) EXPECT_LE(m.confidence, 0.5) << i;
    else EXPECT_GT(m.confidence, 0.9);
  }
  d.reset();  // a new eye: nothing is known of its pupil's size
  EXPECT_FALSE(d.detect(drawn_eye({160.3, 120.4}, {34, 33}, 0)).size_jump);
}

TEST(EyeDetector, BaselineFindsACleanPupil) {
  const EyeMeasurement m = detect_pupil_baseline(drawn_eye({160.4, 120.2}, {36, 34}, 0));
  ASSERT_TRUE(m.pupil_found) << m.why;
  EXPECT_LT(distance(m.pupil.centre, {160.4, 120.2}), 1.0);
}

// On generated infrared eyes with exact ground truth.
struct Errors {
  std::vector<double> error;
  int missed = 0;
  int wrong_size = 0;  // answers whose major axis is off the truth's by more than 25 %
  int missed_edge_on = 0;  // misses of pupils seen nearly edge-on (minor/major < 0.2: none is accepted)
  // Answers at confidence >= 0.8, and of them right (within 5 px, size within 25 %): by the answer's
  // confidence and by its fit's own (EYE.md step 6c).
  int confident = 0, confident_right = 0, fit_confident = 0, fit_confident_right = 0;
  bool doubts_only_lower = true;  // the answer's confidence never above its fit's
};

// `tweak` changes the detector's settings (nullptr: the defaults); gazes are drawn within
// +-gaze_deg across and 0.75 of it down and up.
Errors run_generated(SyntheticEyeOptions o, int frames, void (*tweak)(DetectorSettings&) = nullptr,
                     double gaze_deg = 20) {
  SyntheticEye eye(o);
  DetectorSettings s;
  s.leds = o.leds;
  if (tweak) tweak(s);
  EyeDetector d(s);
  Errors out;
  std::mt19937 rng(static_cast<unsigned>(o.seed));
  std::uniform_real_distribution<double> angle(-gaze_deg, gaze_deg);
  for (int i = 0; i < frames; ++i) {
    EyeTruth truth;
    const cv::Mat img = eye.render(angle(rng), angle(rng) * 0.75, 1.0, &truth);
    const EyeMeasurement m = d.detect(img);
    if (!m.pupil_found) {
      ++out.missed;
      out.missed_edge_on += truth.pupil.minor / truth.pupil.major < 0.2;
      continue;
    }
    out.error.push_back(distance(m.pupil.centre, truth.pupil.centre));
    const bool wrong_size = std::abs(m.pupil.major / truth.pupil.major - 1) > 0.25;
    out.wrong_size += wrong_size;
    const bool right = out.error.back() <= 5 && !wrong_size;
    if (m.confidence >= 0.8) out.confident += 1, out.confident_right += right;
    if (m.fit_confidence >= 0.8) out.fit_confident += 1, out.fit_confident_right += right;
    out.doubts_only_lower &= m.confidence <= m.fit_confidence + 1e-12;
  }
  std::sort(out.error.begin(), out.error.end());
  return out;
}

double quantile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return 1e9;
  return sorted[std::min(sorted.size() - 1, static_cast<std::size_t>(q * static_cast<double>(sorted.size())))];
}

TEST(EyeDetector, GeneratedCleanEyes) {
  SyntheticEyeOptions o;
  o.seed = 101;
  const Errors e = run_generated(o, 80);
  EXPECT_EQ(e.missed, 0);
  EXPECT_LT(quantile(e.error, 0.5), 0.5);
  EXPECT_LT(quantile(e.error, 0.95), 1.0);
}

// Each hard condition of the benchmark's hard set, one at a time (bench_eye reports all of them
// at once separately, as a stress set).
TEST(EyeDetector, GeneratedHardEyes) {
  const auto tweaks = std::vector<void (*)(SyntheticEyeOptions&)>{
      [](SyntheticEyeOptions& o) { o.glint_on_pupil_edge = true; },
      [](SyntheticEyeOptions& o) { o.eyelid_cover = 0.3; },
      [](SyntheticEyeOptions& o) { o.noise_sigma = 10; },
      [](SyntheticEyeOptions& o) {
        o.motion_blur_px = 3;
        o.defocus_px = 1.5;
      },
      [](SyntheticEyeOptions& o) {
        o.glasses_reflection = true;
        o.illumination_gradient = 0.4;
      }};
  std::uint64_t seed = 300;
  for (const auto tweak : tweaks) {
    SyntheticEyeOptions o;
    o.seed = ++seed;
    tweak(o);
    const Errors e = run_generated(o, 40);
    EXPECT_LE(e.missed, 2) << "condition " << seed;
    EXPECT_LT(quantile(e.error, 0.95), 2.0) << "condition " << seed;
  }
}

// Issue 44: a dark iris (the pupil only 5..15 grey levels darker) is itself the strongest dark disc;
// the pupil is found inside it, not the iris reported in its place; weak light likewise.
TEST(EyeDetector, GeneratedDarkIrisesAndWeakLight) {
  std::uint64_t seed = 400;
  for (double contrast : {5.0, 9.0, 15.0}) {
    SyntheticEyeOptions o;
    o.seed = ++seed;
    o.pupil_iris_contrast = contrast;
    const Errors e = run_generated(o, 40);
    // At 5 levels, with the upper lid's shadow over the pupil looking up, some are missed: never
    // answered wrong.
    EXPECT_LE(e.missed, contrast < 6 ? 4 : 1) << "contrast " << contrast;
    EXPECT_EQ(e.wrong_size, 0) << "contrast " << contrast;
    EXPECT_LT(quantile(e.error, 0.95), 1.0) << "contrast " << contrast;
    // Without the search inside the winning candidate, the iris is the answer.
    const Errors iris = run_generated(o, 10, [](DetectorSettings& s) { s.search_inside = false; });
    EXPECT_GE(iris.wrong_size, 8) << "contrast " << contrast;
  }
  SyntheticEyeOptions o;
  o.seed = 410;
  o.pupil_iris_contrast = 15;
  o.exposure = 0.6;
  o.illumination_gradient = 0.4;
  o.defocus_px = 1.5;
  const Errors e = run_generated(o, 40);
  EXPECT_LE(e.missed, 1);
  EXPECT_EQ(e.wrong_size, 0);
  EXPECT_LT(quantile(e.error, 0.95), 1.0);
  o = SyntheticEyeOptions{};
  o.seed = 411;
  o.exposure = 0.3;
  const Errors weak = run_generated(o, 40);
  EXPECT_EQ(weak.missed, 0);
  EXPECT_LT(quantile(weak.error, 0.95), 1.0);
}

// Issue 44: long lashes lit by the LEDs hang across the pupil as grey lines; the pupil is still
// found, and not a piece of it between two lashes.
TEST(EyeDetector, GeneratedLitLashesAcrossThePupil) {
  SyntheticEyeOptions o;
  o.seed = 430;
  o.eyelash_length = 2.5;
  o.lit_lashes = true;
  o.eyelid_cover = 0.15;
  const Errors e = run_generated(o, 40);
  EXPECT_LE(e.missed, 2);
  EXPECT_LE(e.wrong_size, 1);  // step 6b once took such pieces inside a confident pupil (3 of 40)
  EXPECT_LT(quantile(e.error, 0.9), 1.0);
}

// Issue 44: a dark iris (9 levels) under long lit lashes, the lid over the pupil's top, at 192x192
// (the real dark-iris sets' size), eyes looking within +-10 degrees: no ray edge follows the pupil's
// outline there. The contour integral (EYE.md step 6b) finds it and moves the fit onto it; without
// it the iris is answered, or a piece of the pupil. When written: 86 of 160 within 2 px against 30,
// 1 of 32 confident answers wrong against 3 of 13 (none of 25 since the size doubt of step 6c).
TEST(EyeDetector, GeneratedDarkIrisUnderLashes) {
  int with = 0, without = 0, frames = 0, confident = 0, wrong_confident = 0, far_confident = 0, far_wrong = 0;
  const auto within2 = [](const Errors& e) {
    return static_cast<int>(std::count_if(e.error.begin(), e.error.end(), [](double x) { return x <= 2; }));
  };
  for (std::uint64_t seed = 460; seed < 468; ++seed) {
    SyntheticEyeOptions o;
    o.seed = seed;
    o.width = o.height = 192;
    o.pupil_iris_contrast = 9;
    o.eyelash_length = 2.5;
    o.lit_lashes = true;
    o.eyelid_cover = 0.15;
    const Errors a = run_generated(o, 20, nullptr, 10);
    const Errors b = run_generated(o, 20, [](DetectorSettings& s) { s.contour_candidates = false; }, 10);
    const Errors far = run_generated(o, 20, nullptr, 20);
    far_confident += far.confident;
    far_wrong += far.confident - far.confident_right;
    with += within2(a);
    without += within2(b);
    confident += a.confident;
    wrong_confident += a.confident - a.confident_right;
    frames += 20;
  }
  EXPECT_GE(with, 70) << with << " of " << frames << " within 2 px; without the contour integral " << without;
  EXPECT_LE(without, 45) << without << " of " << frames;
  EXPECT_GE(confident, 20);
  EXPECT_LE(wrong_confident, 2) << wrong_confident << " of " << confident;
  // Looking within +-20 degrees the lid hides more of the pupil, and a dark iris under it, fitted
  // whole, was answered confidently (6 of 13 confident answers wrong): its size, three times the
  // eye's recent pupils', now holds its confidence at 0.5 (3 of 10 when written).
  EXPECT_LE(far_wrong, 4) << far_wrong << " of " << far_confident;
}

// Issue 44 (track_inside): a dark iris (9 levels) under long lit lashes at 320x240, followed for 60
// frames of a slow pursuit (0.1 degrees a frame: 12 degrees/s at 120 Hz), a saccade of 15 degrees,
// and 20 more. Once the pupil has been found inside the iris, the next frame looks inside an iris
// around it first, where every candidate around the iris was fitted again (no fit under lashes is
// clear): half the time (bench_eye), and the answers no worse. A followed answer keeps the doubt of
// the search it follows: after the saccade a doubted wrong pupil, followed, was answered at
// confidence 0.97. When written: 41 of 81 followed; within 2 px 37 against 30, within 5 px 46
// against 39; no confident wrong answer either way.
TEST(EyeDetector, FollowsAPupilInsideADarkIrisFromFrameToFrame) {
  struct Run {
    int followed = 0, within2 = 0, within5 = 0, confident_wrong = 0;
  };
  const auto run = [](bool track_inside) {
    SyntheticEyeOptions o;
    o.seed = 480;
    o.pupil_iris_contrast = 9;
    o.eyelash_length = 2.5;
    o.lit_lashes = true;
    o.eyelid_cover = 0.15;
    SyntheticEye eye(o);
    DetectorSettings s;
    s.leds = o.leds;
    s.track_inside = track_inside;
    EyeDetector d(s);
    Run r;
    for (int i = 0; i <= 80; ++i) {
      const double x = i <= 60 ? -6 + 0.1 * i : 15 - 0.1 * (i - 60);  // the saccade: 0 -> 15 degrees
      EyeTruth truth;
      const EyeMeasurement m = d.detect(eye.render(x, 2, 1.0, &truth));
      if (!m.pupil_found) continue;
      r.followed += m.followed;
      const double error = distance(m.pupil.centre, truth.pupil.centre);
      const bool right = error <= 5 && std::abs(m.pupil.major / truth.pupil.major - 1) <= 0.25;
      r.within2 += error <= 2;
      r.within5 += error <= 5;
      r.confident_wrong += m.confidence >= 0.8 && !right;
    }
    return r;
  };
  const Run with = run(true), without = run(false);
  EXPECT_EQ(without.followed, 0);
  EXPECT_GE(with.followed, 30) << "of 81";
  EXPECT_GE(with.within2, without.within2) << with.within2 << " within 2 px against " << without.within2;
  EXPECT_GE(with.within5, without.within5) << with.within5 << " within 5 px against " << without.within5;
  EXPECT_EQ(with.confident_wrong, 0);
}

// Issue 44: an eye camera low and to the side sees the pupil strongly elliptical (minor/major
// 0.3-0.5); its flat sides are as straight as a lid margin over the lid test's span. They were taken
// for lids and removed, leaving a fit the confidence rejected (18 % found in bench_eye).
TEST(EyeDetector, GeneratedOffAxisViews) {
  SyntheticEyeOptions o;
  o.seed = 420;
  o.camera.position_mm = {26, 26, 26};
  const Errors e = run_generated(o, 40);
  EXPECT_LE(e.missed - e.missed_edge_on, 1);  // this camera sees some of the gazes nearly edge-on
  EXPECT_LE(e.missed, 10);
  EXPECT_EQ(e.wrong_size, 0);
  EXPECT_LT(quantile(e.error, 0.95), 0.5);
}

// Spectacle reflections and uneven light at 640x480: the pupil, veiled and lifted, is lighter than
// the resolved lashes, so the darkest blobs are lashes; the edge candidates (EYE.md step 2b) offer it.
TEST(EyeDetector, GeneratedGlassesAtHighResolution) {
  Errors with, without;
  for (std::uint64_t seed = 7000; seed < 7004; ++seed) {
    SyntheticEyeOptions o;
    o.seed = seed;
    o.width = 640;
    o.height = 480;
    o.glasses_reflection = true;
    o.illumination_gradient = 0.4;
    const Errors a = run_generated(o, 10),
                 b = run_generated(o, 10, [](DetectorSettings& s) { s.edge_candidates = false; });
    with.missed += a.missed;
    with.wrong_size += a.wrong_size;
    with.error.insert(with.error.end(), a.error.begin(), a.error.end());
    without.missed += b.missed;
  }
  std::sort(with.error.begin(), with.error.end());
  EXPECT_LE(with.missed, 2);
  EXPECT_GT(without.missed, with.missed + 5) << "the frames no longer need the edge candidates";
  EXPECT_EQ(with.wrong_size, 0);
  EXPECT_LT(quantile(with.error, 0.9), 1.0);
}

// The edge candidates on a drawn frame: a pupil 30 levels below its surround and dark bars (lashes,
// 70 levels below it) elsewhere. The darkest blobs are the bars; the edge candidates give the pupil.
TEST(EyeDetectorStages, EdgeCandidatesFindAPupilLighterThanLashes) {
  namespace st = fovea::trackerd::eye::stages;
  cv::Mat img(240, 320, CV_8U, cv::Scalar(160));
  cv::ellipse(img, cv::Point2d(180.3, 130.6), cv::Size2d(22, 18), 20, 0, 360, cv::Scalar(130), cv::FILLED, cv::LINE_AA);
  for (int i = 0; i < 12; ++i)
    cv::line(img, cv::Point(20 + 8 * i, 30), cv::Point(30 + 8 * i, 90), cv::Scalar(60), 3, cv::LINE_AA);
  cv::Mat small, integral;
  const cv::Rect frame(0, 0, img.cols, img.rows);
  const auto blobs = st::find_dark_blobs(img, frame, 2, 4.8, 60, 8, small, integral);
  ASSERT_FALSE(blobs.empty());
  EXPECT_GT(std::hypot(blobs[0].centre.x - 180.3, blobs[0].centre.y - 130.6), 30) << "the darkest blob is a bar";
  const auto edges = st::find_edge_candidates(small, frame, 4.8, 60, 4);
  ASSERT_FALSE(edges.empty());
  EXPECT_LT(std::hypot(edges[0].centre.x - 180.3, edges[0].centre.y - 130.6), 2.0);
  EXPECT_NEAR(edges[0].radius, 18, 4);
  EXPECT_GT(edges[0].surround - edges[0].inner, 15);
}

// The contour integral's stages (EYE.md step 6b) on a drawn window as step 6b gives it to them
// (blurred, and opened when there are lashes): a pupil 9 levels darker than the iris around it,
// sensor noise, and lit lashes across it or not.
cv::Mat faint_pupil(const Ellipse& pupil, bool lashes) {
  cv::Mat img(110, 110, CV_8U, cv::Scalar(60));
  cv::ellipse(img, cv::RotatedRect(cv::Point2f(static_cast<float>(pupil.centre.x - 0.5), static_cast<float>(pupil.centre.y - 0.5)),
                                   cv::Size2f(static_cast<float>(pupil.major), static_cast<float>(pupil.minor)),
                                   static_cast<float>(pupil.angle_deg)),
              cv::Scalar(51), cv::FILLED, cv::LINE_AA);
  for (int i = 0; lashes && i < 14; ++i)
    cv::line(img, cv::Point(18 + 6 * i, 10), cv::Point(26 + 5 * i, 100), cv::Scalar(90), 1, cv::LINE_AA);
  cv::Mat noise(img.size(), CV_16S);
  cv::randn(noise, 0, 2);
  cv::Mat out;
  img.convertTo(out, CV_16S);
  out += noise;
  out.convertTo(img, CV_8U);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 1.0);
  if (lashes) cv::morphologyEx(img, img, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
  return img;
}

TEST(EyeDetectorStages, TheContourIntegralFindsAFaintPupil) {
  namespace st = fovea::trackerd::eye::stages;
  const Ellipse truth{{55.3, 52.6}, 26, 21, 15};  // internal convention, as the stages use
  const cv::Mat under_lashes = faint_pupil(truth, true);
  const auto found =
      st::find_contour_candidates(under_lashes, cv::Rect(0, 0, 110, 110), {52, 55}, 16, 6, 25, 2);
  ASSERT_FALSE(found.empty());
  EXPECT_LT(distance(found[0].centre, truth.centre), 2.0) << found[0].centre;
  EXPECT_NEAR(found[0].radius, 12, 2.5);
  EXPECT_TRUE(found[0].on_contour);
  EXPECT_GT(found[0].surround - found[0].inner, 4);  // measured on the image: the pupil is darker
  // From a fit 2 px off and 15 % small, the refinement moves onto the outline (read 2.5 px either
  // side of it: within about a pixel, not the rays' tenth).
  const Ellipse start{truth.centre + cv::Point2d(1.5, -1.4), 0.85 * truth.major, 0.85 * truth.minor, 30};
  const Ellipse refined = st::refine_on_contour(faint_pupil(truth, false), start, 2.5);
  EXPECT_LT(distance(refined.centre, truth.centre), 0.9) << refined.centre;
  EXPECT_NEAR(refined.major, truth.major, 1.5);
  EXPECT_NEAR(refined.minor, truth.minor, 1.5);
  // Under lashes the centre still comes within a pixel; the outline is read 1-2 px inside where
  // lashes run along it (the opening keeps them, joined to the iris: EYE.md Known limitations).
  const Ellipse lashed = st::refine_on_contour(under_lashes, start, 2.5);
  EXPECT_LT(distance(lashed.centre, truth.centre), 1.0) << lashed.centre;
  EXPECT_GT(lashed.major, 0.8 * truth.major);
  // It stays near where it starts: a fit of something else is not moved onto this pupil.
  const Ellipse far{truth.centre + cv::Point2d(14, 8), truth.major, truth.minor, 15};
  EXPECT_GT(distance(st::refine_on_contour(under_lashes, far, 2.5).centre, truth.centre), 8);
}

// The stages' fast reads give what the general ones give: bilinear_inside() (bilinear()'s inlined
// path) the value bilinear_clamped() clamps its way to, bit for bit, anywhere off the last row and
// column, and bilinear() beyond the image the edge's level; in_glint() rounds half away from zero as
// std::lround does.
TEST(EyeDetectorStages, FastSamplesEqualTheClampedOnes) {
  namespace st = fovea::trackerd::eye::stages;
  cv::Mat img(37, 53, CV_8U);
  cv::randu(img, 0, 256);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> x(0, 52 - 1e-9), y(0, 36 - 1e-9);
  for (int i = 0; i < 5000; ++i) {
    const double px = i < 4 ? (i % 2) * (52 - 1e-9) : x(rng), py = i < 4 ? (i / 2) * (36 - 1e-9) : y(rng);
    ASSERT_EQ(st::bilinear_inside(img, px, py), st::bilinear_clamped(img, px, py)) << px << "," << py;
  }
  EXPECT_EQ(st::bilinear(img, -4.5, 0), img.at<std::uint8_t>(0, 0));
  EXPECT_EQ(st::bilinear(img, 60, 40), img.at<std::uint8_t>(36, 52));
  EXPECT_EQ(st::bilinear(img, 52, 0), img.at<std::uint8_t>(0, 52));
  st::GlintCandidates g;
  g.glints.push_back({});
  g.window = cv::Rect(-3, -3, 9, 9);
  g.mask = cv::Mat::zeros(9, 9, CV_8U);
  g.mask.at<std::uint8_t>(3, 3) = 255;  // the pixel (0, 0)
  for (const double v : {-0.5, -0.49, 0.0, 0.49, 0.5})
    EXPECT_EQ(st::in_glint(g, v, 0), std::lround(v) == 0) << v;
}

// Glints anywhere in the window are found, listed top to bottom then left to right (an order that
// does not depend on how the components are labelled), and masked; a streak is no glint.
TEST(EyeDetectorStages, GlintsAreFoundWhereverTheyLieInRasterOrder) {
  namespace st = fovea::trackerd::eye::stages;
  cv::Mat img(240, 320, CV_8U, cv::Scalar(90));
  const std::vector<cv::Point> at = {{300, 200}, {12, 200}, {160, 10}, {40, 41}, {250, 40}};
  for (const cv::Point& p : at) cv::circle(img, p, 2, cv::Scalar(255), cv::FILLED);
  cv::line(img, {100, 120}, {140, 122}, cv::Scalar(255), 2);  // a reflection's streak
  const cv::Rect window(4, 3, 310, 230);
  const st::GlintCandidates g = st::find_glints(img, window, 240);
  ASSERT_EQ(g.glints.size(), at.size());
  const std::vector<cv::Point> expected = {{160, 10}, {250, 40}, {40, 41}, {12, 200}, {300, 200}};
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_NEAR(g.glints[i].centre.x, expected[i].x, 1e-9) << i;
    EXPECT_NEAR(g.glints[i].centre.y, expected[i].y, 1e-9) << i;
    EXPECT_TRUE(st::in_glint(g, expected[i].x, expected[i].y)) << i;
  }
  EXPECT_FALSE(st::in_glint(g, 120, 121));
  EXPECT_TRUE(st::find_glints(cv::Mat(240, 320, CV_8U, cv::Scalar(90)), window, 240).glints.empty());
}

// The lid test itself: the straight run of a lid over a round pupil goes, an elliptical pupil's
// flat sides stay.
TEST(EyeDetectorStages, LidLinesAreNotAnEllipsesFlatSides) {
  namespace st = fovea::trackerd::eye::stages;
  const auto ellipse_points = [](double a, double b, double cut_y) {
    std::vector<st::EdgePoint> pts;
    for (int i = 0; i < 64; ++i) {
      const double t = 2 * 3.14159265358979 * i / 64;
      cv::Point2d p(100 + a * std::cos(t), 100 + b * std::sin(t));
      if (p.y < cut_y) p.y = cut_y;  // a lid: the outline above cut_y follows its straight margin
      pts.push_back({p, 50});
    }
    return pts;
  };
  std::mt19937 rng(3);
  auto flat = ellipse_points(30, 10, -1e9);  // minor/major 0.33, no lid
  st::remove_eyelid_lines(flat, 10, rng);
  EXPECT_EQ(flat.size(), 64U);
  rng.seed(3);
  auto lid = ellipse_points(15, 15, 93);  // a round pupil, the lid over its top 7 px
  const auto on_lid = [](const std::vector<st::EdgePoint>& pts) {
    return std::count_if(pts.begin(), pts.end(), [](const st::EdgePoint& p) { return p.p.y < 93.5; });
  };
  const auto arc = static_cast<std::ptrdiff_t>(lid.size()) - on_lid(lid);
  ASSERT_GE(on_lid(lid), 12);
  st::remove_eyelid_lines(lid, 15, rng);
  EXPECT_LE(on_lid(lid), 2);  // the lid's run went
  EXPECT_GE(static_cast<std::ptrdiff_t>(lid.size()) - on_lid(lid), arc - 3);  // the arc stayed (but near the corners)
  // A small pupil (radius 7 px, as at 160x120) under a lid 3 px deep: the tolerance (1.2 px) is a
  // sixth of the radius, so one least-squares ellipse through every point bends to pass near the
  // lid's chord; the outline without the chord still says where the pupil goes on.
  const auto small_points = [](double cut_y) {
    std::vector<st::EdgePoint> pts;
    for (int i = 0; i < 48; ++i) {
      const double t = 2 * 3.14159265358979 * i / 48;
      cv::Point2d p(100 + 7 * std::cos(t), 100 + 7 * std::sin(t));
      if (p.y < cut_y) p.y = cut_y;
      pts.push_back({p, 50});
    }
    return pts;
  };
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    rng.seed(seed);
    auto small = small_points(96);
    const auto on_small_lid = std::count_if(small.begin(), small.end(), [](const st::EdgePoint& p) { return p.p.y < 96.5; });
    ASSERT_GE(on_small_lid, 8);
    st::remove_eyelid_lines(small, 7, rng);
    EXPECT_LE(std::count_if(small.begin(), small.end(), [](const st::EdgePoint& p) { return p.p.y < 96.5; }), 2)
        << "seed " << seed;
  }
}

// The confidence predicts the error: confident pupils are accurate, doubtful ones often are not.
TEST(EyeDetector, ConfidenceMeansSomething) {
  // Frames from an easy, a hard and a very hard eye, interleaved.
  std::vector<SyntheticEye> eyes;
  for (int level = 0; level < 3; ++level) {
    SyntheticEyeOptions o;
    o.seed = 77 + static_cast<std::uint64_t>(level);
    if (level >= 1) {
      o.eyelid_cover = 0.3;
      o.noise_sigma = 10;
    }
    if (level >= 2) {
      o.glasses_reflection = true;
      o.illumination_gradient = 0.5;
      o.motion_blur_px = 2;
      o.glint_on_pupil_edge = true;
    }
    eyes.emplace_back(o);
  }
  DetectorSettings s;
  s.min_confidence = 0;
  s.roi_tracking = false;
  EyeDetector d(s);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> angle(-20, 20);
  double high_hits = 0, high = 0, low_hits = 0, low = 0, low_confidence = 0;
  for (int i = 0; i < 150; ++i) {
    EyeTruth truth;
    const cv::Mat img = eyes[static_cast<std::size_t>(i % 3)].render(angle(rng), angle(rng) * 0.75, 1.0, &truth);
    const EyeMeasurement m = d.detect(img);
    if (!m.pupil_found) continue;
    const bool hit = distance(m.pupil.centre, truth.pupil.centre) <= 1.0;
    if (m.confidence >= 0.8) {
      ++high;
      high_hits += hit ? 1 : 0;
    } else {
      ++low;
      low_hits += hit ? 1 : 0;
      low_confidence += m.confidence;
    }
  }
  ASSERT_GT(high, 30);
  EXPECT_GT(high_hits / high, 0.85);
  ASSERT_GT(low, 5);
  EXPECT_LT(low_hits / low, high_hits / high);
  // Calibrated: among doubtful pupils, the share within 1 px is about their mean confidence.
  EXPECT_NEAR(low_hits / low, low_confidence / low, 0.25);
}

// Step 6c: without doubts the answer keeps its fit's confidence; a rival elsewhere or a darker disc
// inside lowers it; two fits as confident as each other are a coin toss at most.
TEST(EyeDetectorConfidence, AnswersAreDoubtedForRivalsAndDiscsInside) {
  for (double c : {0.05, 0.5, 0.9, 0.999}) {
    EXPECT_NEAR(answer_confidence(c, 0, false), c, 1e-9);
    EXPECT_LT(answer_confidence(c, 0, true), c);
    double last = c;
    for (double rival : {0.1, 0.3, 0.6, 0.9}) {
      const double a = answer_confidence(c, rival, false);
      EXPECT_LT(a, last) << c << " with a rival at " << rival;
      last = a;
    }
  }
  EXPECT_LE(answer_confidence(0.999999, 0.999999, false), 0.5);
  EXPECT_LT(answer_confidence(0.95, 0.8, false), 0.8);  // issue 44: not confident
  EXPECT_EQ(answer_confidence(0, 0.5, true), 0.0);
  for (double bad : {std::nan(""), std::numeric_limits<double>::infinity(), -1.0, 2.0})
    for (double other : {0.0, 0.5, bad}) {
      const double a = answer_confidence(bad, other, false), b = answer_confidence(0.7, bad, true);
      EXPECT_TRUE(std::isfinite(a) && a >= 0 && a <= 1) << bad << " " << other;
      EXPECT_TRUE(std::isfinite(b) && b >= 0 && b <= 1) << bad;
    }
}

// Issue 44: a dark iris (9 levels) under long lit lashes, the eye looking anywhere within +-20
// degrees. Step 6b often finds no pupil inside the iris there, and the iris's own fit looks
// confident (its outline is a sharp dark disc, lashes over a third of it): of the answers whose fit
// alone was confident, about half are the iris (19 of 42 here; 24 of 37 before the contour
// integral of step 6b). The answer's confidence (step 6c) weighs the darker disc the search fitted
// inside it and the rivals elsewhere: 9 confident answers, all right (4 of 5 before).
TEST(EyeDetector, ConfidentAnswersUnderLashesOverADarkIris) {
  int confident = 0, confident_right = 0, fit_confident = 0, fit_confident_right = 0;
  for (std::uint64_t seed = 440; seed < 500; seed += 10) {
    SyntheticEyeOptions o;
    o.seed = seed;
    o.pupil_iris_contrast = 9;
    o.eyelash_length = 2.5;
    o.lit_lashes = true;
    o.eyelid_cover = 0.15;
    const Errors e = run_generated(o, 20);
    EXPECT_TRUE(e.doubts_only_lower) << "seed " << seed;
    confident += e.confident;
    confident_right += e.confident_right;
    fit_confident += e.fit_confident;
    fit_confident_right += e.fit_confident_right;
  }
  ASSERT_GE(fit_confident, 25) << fit_confident_right << " of " << fit_confident << "; answer: " << confident_right << " of " << confident;
  EXPECT_LE(confident, fit_confident / 4);
  EXPECT_GE(confident, 5);
  EXPECT_GE(confident_right, confident - 1) << confident_right << " of " << confident;
}

}  // namespace
}  // namespace fovea::trackerd::eye
