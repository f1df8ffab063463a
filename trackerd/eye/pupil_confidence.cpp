// SPDX-License-Identifier: Apache-2.0
// The confidence of a fitted pupil: the evidence measured on the image (outline contrast as in PuRe,
// Santini, Fuhl & Kasneci 2018 §3.4; arc coverage; share of the outline inside the frame) and the
// logistic model that turns the evidence into P(centre error <= 1 px) (eye/EYE.md).
#include "eye/detector_stages.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

namespace fovea::trackerd::eye {

namespace {

// Logistic model of P(centre error <= 1 px): bias, support, outline, residual px, aspect, contrast/100.
constexpr std::array<double, 6> kConfidenceModel{-21.6006, 15.4716, 4.0722, -12.6362, 18.2015, 2.4973};

}  // namespace

namespace stages {

// Share of the fitted outline where the inside is clearly darker than the outside (PuRe's outline
// contrast, Santini 2018 §3.4).
double outline_contrast(const cv::Mat& smooth, const cv::Rect& valid, const Ellipse& e, double step_needed) {
  constexpr int samples = 48;
  int good = 0, seen = 0;
  for (int i = 0; i < samples; ++i) {
    const double t = 2 * kPi * i / samples;
    const cv::Point2d a = ellipse_point(e, t, 0.75), b = ellipse_point(e, t, 1.25);
    const auto inside = [&](const cv::Point2d& p) {
      return p.x >= valid.x && p.y >= valid.y && p.x <= valid.x + valid.width - 1 && p.y <= valid.y + valid.height - 1;
    };
    if (!inside(a) || !inside(b)) continue;
    ++seen;
    if (bilinear(smooth, b.x, b.y) - bilinear(smooth, a.x, a.y) > step_needed) ++good;
  }
  return seen ? static_cast<double>(good) / samples : 0.0;
}

// Share of 16 directions around the centre in which some inlier edge point lies.
double arc_coverage(const std::vector<EdgePoint>& edges, const std::vector<std::size_t>& inliers, const cv::Point2d& centre) {
  constexpr int bins = 16;
  std::array<bool, bins> hit{};
  for (std::size_t i : inliers) {
    const double a = std::atan2(edges[i].p.y - centre.y, edges[i].p.x - centre.x);
    const int b = std::clamp(static_cast<int>((a + kPi) / (2 * kPi) * bins), 0, bins - 1);
    hit[static_cast<std::size_t>(b)] = true;
  }
  return static_cast<double>(std::count(hit.begin(), hit.end(), true)) / bins;
}

double outline_inside(const cv::Rect& frame, const Ellipse& e) {
  constexpr int samples = 48;
  int inside = 0;
  for (int i = 0; i < samples; ++i) {
    const cv::Point2d p = ellipse_point(e, 2 * kPi * i / samples);
    if (p.x >= frame.x && p.y >= frame.y && p.x <= frame.x + frame.width - 1 && p.y <= frame.y + frame.height - 1) ++inside;
  }
  return static_cast<double>(inside) / samples;
}

}  // namespace stages

using stages::clamp01;

std::array<double, kConfidenceFeatures> confidence_features(const PupilEvidence& v) {
  const auto bounded = [](double x, double hi) { return std::isfinite(x) ? std::clamp(x, 0.0, hi) : hi; };
  return {1.0, bounded(v.support, 1.0), bounded(v.outline, 1.0), bounded(v.residual_px, 3.0), bounded(v.aspect, 1.0),
          bounded(v.contrast / 100.0, 2.0)};
}

// Calibrated confidence: P(centre error <= 1 px) from a logistic model of the fit's evidence
// (coefficients fitted by `bench_eye --fit-confidence` on generated frames; eye/EYE.md).
double confidence_of(const PupilEvidence& evidence) {
  const auto f = confidence_features(evidence);
  double z = 0;
  for (std::size_t i = 0; i < kConfidenceFeatures; ++i) z += kConfidenceModel[i] * f[i];
  return clamp01(1.0 / (1.0 + std::exp(-z)));
}

// The answer's confidence. The weights are fitted by `bench_eye --fit-confidence` on the answers
// over every condition (following gaze sequences with ROI tracking, each frame alone, and eyes
// looking anywhere within +-20 degrees); the fit's own confidence keeps its weight of 1, so an answer
// with neither doubt keeps the calibration the candidate model has (a free slope, fitted on the same
// answers, learnt the mix of the training sets instead: most doubtful answers there are a dark iris
// under lashes, wrong, and it called every doubtful fit wrong). The winner and its rival are
// exclusive hypotheses, so their probabilities cannot sum to more than 1: where the two confidences
// do, the winner is capped at its share, c / (c + rival) -- two fits as confident as each other are a
// coin toss, which the training frames (one eye each) hardly hold.
double answer_confidence(double fit_confidence, double rival_confidence, bool disc_inside) {
  if (!std::isfinite(fit_confidence) || fit_confidence <= 0) return 0.0;
  const double c = std::min(fit_confidence, 1 - 1e-9);
  const double rival = std::isfinite(rival_confidence) ? std::clamp(rival_confidence, 0.0, 1.0) : 1.0;
  const double z = std::log(c / (1 - c)) + kAnswerWeights[0] * rival + kAnswerWeights[1] * (disc_inside ? 1.0 : 0.0);
  const double share = c + rival > 1 ? c / (c + rival) : 1.0;
  return clamp01(std::min(1.0 / (1.0 + std::exp(-z)), share));
}

}  // namespace fovea::trackerd::eye
