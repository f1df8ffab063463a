// SPDX-License-Identifier: Apache-2.0
#pragma once
// Dark-pupil and corneal-glint detection on infrared eye-camera frames.
//
// Pupil: coarse localisation by a centre-surround (Haar-like) dark-blob response on an integral
// image (Świrski, Bulling & Dodgson 2012, §3.1) and, when none gives a clear pupil, from curved
// edges with darker inside (PuRe: Santini, Fuhl & Kasneci 2018, §3.2); edge points found along
// rays cast from the candidate's centre (Starburst: Li, Winfield & Parkhurst 2005, §2.3) with
// glints masked out, a RANSAC
// ellipse fit with an image-aware support check rejecting eyelid, eyelash and glint outliers
// (Świrski 2012 §3.3; Fischler & Bolles 1981), then a least-squares refit on the inliers for a
// sub-pixel centre. Confidence combines outline contrast, edge support and aspect ratio in the
// spirit of PuRe (Santini, Fuhl & Kasneci 2018, §3.4) and is calibrated: it is the predicted
// probability that the centre is within 1 px of the truth (see eye/EYE.md for how it is fitted).
// Glints: small saturated blobs near the pupil, paired with the LED layout; the pupil–glint vector
// uses the centroid of the layout's glints (estimated from the paired ones when some are missing).
// Blinks: no pupil, or a fitted ellipse with minor/major < 0.7 (Lee 2009 §3.5.2) times the
// eye's recent open minor/major (an off-axis camera sees open eyes flattened).
#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "eye/ellipse.h"
#include "eye/led_layout.h"

namespace fovea::trackerd::eye {

enum class EdgeMethod { Rays, Canny };         // Starburst-style rays | Canny edges of the ROI
enum class FitMethod { Ransac, LeastSquares };  // RANSAC + inlier refit | one fit to all edge points

struct DetectorSettings {
  int coarse_downscale = 2;       // 1, 2 or 4: coarse localisation runs on an image this much smaller
  bool roi_tracking = true;       // search near the last pupil first; fall back to the whole frame
  // With it, when the last pupil was found inside a candidate (a dark iris, step 6b), look inside
  // such a candidate around the last pupil first, and stop at a confident fit (0.5) where it was:
  // under lashes no fit is clear (0.9) and every candidate was fitted (eye/EYE.md step 6b).
  bool track_inside = true;
  EdgeMethod edges = EdgeMethod::Rays;
  FitMethod fit = FitMethod::Ransac;
  int rays = 64;                  // rays cast for edge points (EdgeMethod::Rays)
  // Look for a darker disc inside the winning candidate on its contrast-normalised window: the pupil
  // inside a dark iris taken for the pupil (issue 44; eye/EYE.md step 6b).
  bool search_inside = true;
  // When no dark blob gives a clear pupil, candidates from curved edges with darker inside as well
  // (PuRe-style): a pupil veiled by a spectacle reflection, or lighter than lashes (issue 44).
  bool edge_candidates = true;
  // Inside the winning candidate (search_inside), candidates from the contour integral as well: the
  // circles the mean level rises fastest across (Daugman 2004), for a pupil whose outline lashes
  // split into arcs too short for an edge to follow (issue 44; eye/EYE.md step 6b).
  bool contour_candidates = true;
  // Pupil radius range as fractions of min(width, height); everything else scales with the image.
  double min_pupil_radius = 0.02, max_pupil_radius = 0.25;
  double blink_aspect = 0.7;      // Lee 2009 §3.5.2: minor/major below this (relative to the eye's open aspect) is a blink
  double min_confidence = 0.5;    // below this the pupil counts as not found (more likely wrong than right)
  LedLayout leds;                 // empty: glints are reported unpaired
  // Checks ranges; throws std::invalid_argument naming the field and its allowed range.
  void validate() const;
};

struct Glint {
  cv::Point2d centre;   // pixels, intensity-weighted (sub-pixel)
  double area_px = 0;
  int led = -1;         // index into DetectorSettings::leds, -1 when unpaired
};

// What the confidence is computed from (kept for diagnostics and for refitting the model).
struct PupilEvidence {
  double support = 0;    // share of rays (or of the outline, for Canny) whose edge point fits the ellipse
  double outline = 0;    // share of the outline where inside is clearly darker than outside
  double residual_px = 0;  // RMS distance of the inlier edge points from the ellipse
  double contrast = 0;   // surround minus pupil grey level
  double aspect = 0;     // minor / major of the fitted ellipse
};

// The logistic confidence model: features of the evidence (bias term first) and the probability.
inline constexpr std::size_t kConfidenceFeatures = 6;
std::array<double, kConfidenceFeatures> confidence_features(const PupilEvidence& evidence);
double confidence_of(const PupilEvidence& evidence);

// The reported answer's confidence (eye/EYE.md step 6c): the winning fit's own confidence lowered by
// what else the search fitted, logit(answer) = logit(fit) + kAnswerWeights[0] x rival +
// kAnswerWeights[1] x disc_inside. rival: the most confident fit elsewhere in the frame (centre
// farther than max(3 px, a quarter of the winner's minor axis)); disc_inside: a smaller disc near the
// winner's centre darker than its surround along most of its outline (the winner is likely an iris).
inline constexpr std::array<double, 2> kAnswerWeights{-7.427, -3.826};
double answer_confidence(double fit_confidence, double rival_confidence, bool disc_inside);

struct EyeMeasurement {
  bool pupil_found = false;
  Ellipse pupil;                  // valid when pupil_found
  double confidence = 0;          // [0, 1]: predicted probability that the centre is within 1 px; 0 when not found
  double fit_confidence = 0;      // the winning fit's own confidence (from its evidence alone)
  double rival_confidence = 0;    // the most confident fit elsewhere in the frame, 0 when none
  bool disc_inside = false;       // a smaller disc darker than its surround was fitted inside the pupil
  bool size_jump = false;         // 1.8x larger or smaller than this eye's recent clear pupils: confidence <= 0.5
  PupilEvidence evidence;         // of the best candidate, also when it was rejected
  bool blink = false;             // no pupil, or aspect < blink_aspect
  std::vector<Glint> glints;      // near the pupil, nearest first (without a pupil: anywhere, top to bottom), at most 8
  bool pupil_glint_valid = false;
  cv::Point2d pupil_glint;        // pupil centre - reference glint point, pixels
  std::string why;                // when no pupil: what failed ("no dark blob", "too few edge points", ...)
  bool used_roi = false;          // found within the tracked ROI (no full-frame search needed)
  bool followed = false;          // found by following the last pupil inside a dark iris (track_inside)
  cv::Rect search_region;         // where the search looked last: the ROI when used_roi, else the frame
};

class EyeDetector {
 public:
  explicit EyeDetector(DetectorSettings settings = {});
  const DetectorSettings& settings() const { return settings_; }
  // Any image: 8- or 16-bit, grey, BGR or BGRA (other channel counts: the first channel), converted to 8-bit grey; empty or tiny images
  // give "no pupil". Never throws for image content; never returns NaN. Keeps ROI state between calls.
  EyeMeasurement detect(const cv::Mat& image) { return detect(image, nullptr); }
  // Also lists every pupil candidate that was fitted (for refitting the confidence model).
  struct CandidateFit {
    Ellipse ellipse;  // in Ellipse's pixel convention
    PupilEvidence evidence;
    double confidence = 0;
  };
  EyeMeasurement detect(const cv::Mat& image, std::vector<CandidateFit>* candidates);
  void reset();  // forget the tracked ROI and what was learnt of this eye (its open aspect, its pupil's size)

 private:
  void doubt_size_jumps(EyeMeasurement& result);

  DetectorSettings settings_;
  std::optional<Ellipse> last_pupil_;
  std::optional<Ellipse> last_outer_;  // the candidate last_pupil_ was found inside (search_inside), if it was
  double last_rival_ = 0;  // the last searched answer's rival confidence (step 6c), which followed ones keep
  double last_glint_scale_ = 0;
  // Image of the LED layout's centroid in the last frame with paired glints: with one glint left,
  // the LED it belongs to is the one that keeps the reference where it was.
  std::optional<cv::Point2d> last_reference_;
  double open_aspect_ = 0;  // running minor/major of this eye's confident open pupils (0: none yet)
  // Major axes of the last clear pupil fits (ring buffer; `recent_count_` of them held).
  std::array<double, 9> recent_major_{};
  std::size_t recent_count_ = 0, recent_next_ = 0;
  cv::Mat grey_, integral_, small_, smooth_;  // reused buffers
};

// The peer baseline: threshold at a fixed fraction of the dark range, take the largest dark
// contour and cv::fitEllipse it. No glint handling, no outlier rejection.
EyeMeasurement detect_pupil_baseline(const cv::Mat& image);

}  // namespace fovea::trackerd::eye
