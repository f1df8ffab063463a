// SPDX-License-Identifier: Apache-2.0
#pragma once
// Multi-scale features of one gaze sample, for the learned classifier (issue 43, method `gbt`).
//
// What tells pursuit from fixation and a catch-up saccade from pursuit is how the gaze moves at
// several time scales at once (Larsson et al. 2015: speed, direction consistency and positional
// displacement over windows of different lengths; Startsev, Agtzidis & Dorr 2019 feed the same
// multi-scale speeds and directions to their 1D-CNN-BLSTM). For each scale D (4 ms to 256 ms,
// doubling) a sample gets, from the gaze run it belongs to (no loss in between):
//   speed_c   |p(t+D) - p(t-D)| / 2D               the movement across the window, deg/s
//   speed_b   |p(t) - p(t-D)| / D, speed_f  |p(t+D) - p(t)| / D   before and after: a saccade's edge
//   cos       cosine between p(t) - p(t-D) and p(t+D) - p(t)      direction consistency
//   disp      RMS distance of the window's samples from their mean, deg    spatial spread
//   straight  |net displacement| / path length over the window      1 for a line, ~0 for noise, 0 still
// p(t +- D) interpolated linearly between the samples around t +- D, so the features mean the same
// at 250, 500 or 1000 Hz. Where the run does not reach t - D or t + D the scale's features are NaN
// (the trees send NaN down a learned branch). Displacements are the eye's rotation in the tangent
// frame at the sample (pipeline.h, tangent_map); the path is the sum of each step's rotation in the
// tangent frame where it starts. Besides those: the time since the last loss of data and to the
// next (capped at the reach: what happens around blinks), whether the sample was filled in, the
// tracker's noise (the median |second difference| within +-128 ms, of at most kNoiseMaxTriples
// evenly spread), and how far the gaze lies outside the display (degrees from its nearest edge; 0 on
// it): coders call gaze off the screen noise (GazeCom does), and the trees should learn that from
// where it is, not from how it moves. Last, the speed profile around the sample in 4 ms steps:
// speed_b_4ms_lagL, the speed over the 4 ms that end L before the sample (L in kStepLagsS), and
// speed_f_4ms_leadL, over the 4 ms that start L after it (kStepLeadsS; NaN where the run or the
// reach does not get there). Coders end a saccade at a landed sample (GazeCom's expert at the first
// one: the step into it is slow, the steps before it fast), which the windows' sums blur; with the
// steps a first stage on 9 GazeCom videos, scored on the other 9, finds saccade samples at F1 0.891
// against 0.875 without them (bench/RESULTS.md, "The speed profile in 4 ms steps").
//
// Cost (issue 43: within the order of ivvt's): FeatureWindow keeps running sums of the samples it
// holds, so a sample's features take binary searches and O(1) arithmetic per scale, whatever the
// rate, instead of a walk over the +-256 ms around it (257 samples each side at 1000 Hz). The sums
// restart every kChunkSamples samples of the stream (counted from its first), each chunk relative
// to its own first sample's position: they stay small (no cancellation however long the stream),
// and a sample's features do not depend on how much the window held when they were computed, so
// online and offline agree exactly.
//
// Every feature of sample i reads only samples within kFeatureReachS of it, so an online core
// computes them kFeatureReachS after the sample arrives. A shorter reach R ahead (the daemon's
// first stage, trees_core.h: labels sooner) keeps the past: a scale D > R spans [t - D, t + R]
// (speed_c over D + R, speed_f and cos's second displacement over R), the noise's window ends R
// after the sample and the time to the next loss is capped at R; the features are then computed R
// after the sample, and a model must be trained on features of the same reach.
#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "classify/pipeline.h"

namespace fovea::trackerd::classify {

inline constexpr std::array<double, 7> kFeatureScalesS = {0.004, 0.008, 0.016, 0.032, 0.064, 0.128, 0.256};
inline constexpr double kFeatureReachS = 0.256;
inline constexpr int kFeaturesPerScale = 6;
inline constexpr int kTailFeatures = 5;  // the loss times, filled, noise, off the display
inline constexpr std::array<double, 5> kStepLagsS = {0.004, 0.008, 0.012, 0.016, 0.020};
inline constexpr std::array<double, 3> kStepLeadsS = {0.004, 0.008, 0.012};
inline constexpr int kFeatureCount = static_cast<int>(kFeatureScalesS.size()) * kFeaturesPerScale + kTailFeatures +
                                     static_cast<int>(kStepLagsS.size() + kStepLeadsS.size());

// "speed_c_4ms", ..., "loss_before_s", "loss_after_s", "filled", "noise_deg", "offscreen_deg",
// "speed_b_4ms_lag4ms", ..., "speed_f_4ms_lead4ms", ...: in the order written.
const std::vector<std::string>& feature_names();
std::size_t feature_index(const std::string& name);  // throws std::out_of_range for an unknown name

// The samples around the ones being scored, in time order, with what their features need.
class FeatureWindow {
 public:
  static constexpr std::size_t kChunkSamples = 1024;
  static constexpr std::size_t kNoiseMaxTriples = 32;

  void push(const Prepared& p);
  // Forgets the n oldest samples (they must lie over kFeatureReachS before any still to be scored).
  void pop_front(std::size_t n);
  void clear();
  std::size_t size() const { return rows_.size() - front_; }
  // The features of the i-th sample held (0: the oldest) into out[0..kFeatureCount), with reach_s
  // (in (0, kFeatureReachS]) ahead. The window must reach kFeatureReachS before it and reach_s
  // after it (or the stream's ends) for them to be final. A sample without gaze gets NaN everywhere
  // but the loss times and `filled`.
  void features(std::size_t i, const protocol::DisplayGeometry& display, float* out,
                double reach_s = kFeatureReachS) const;

 private:
  // Sums over a chunk's gaze samples up to a row, relative to the chunk's reference point.
  struct Sums {
    double n = 0, x = 0, y = 0, xx = 0, xy = 0, yy = 0, path = 0;
  };
  struct Row {
    double t = 0, x = 0, y = 0;
    bool gaze = false, filled = false;
    std::int64_t prev_loss = -1;  // stream index of the last sample without gaze before it (-1: none)
    std::int64_t next_loss = -1;  // and of the first after it (-1: none yet)
    double d2 = -1;               // |second difference| centred here (-1: not both neighbours in its run)
    Sums sums;                    // inclusive, within the row's chunk
    double ref_x = 0, ref_y = 0;  // the chunk's reference point
  };
  const Row& at(std::int64_t stream_index) const { return rows_[static_cast<std::size_t>(stream_index - base_)]; }
  std::int64_t first() const { return base_ + static_cast<std::int64_t>(front_); }
  std::int64_t end() const { return base_ + static_cast<std::int64_t>(rows_.size()); }
  // The window's gaze samples [a, b] (stream indices, one run) centred on c, in c's tangent frame.
  struct Centred {
    double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0, path = 0;
  };
  Centred centred_sums(std::int64_t a, std::int64_t b, double cx, double cy) const;
  void scale_features(std::int64_t ci, std::int64_t bj, std::int64_t f, const TangentMap& tm, double d, double a,
                      float* o) const;
  float noise(std::int64_t a, std::int64_t b) const;
  static TangentVector point_at(const Row& c, const Row& r0, const Row& r1, double u, const TangentMap& tm);

  std::vector<Row> rows_;
  std::size_t front_ = 0;   // rows_[front_] is the oldest sample held
  std::int64_t base_ = 0;   // stream index of rows_[0]
  std::int64_t last_loss_ = -1;
  Row last_, before_last_;  // the two rows pushed last (gaze false before the stream's start)
};

// The features of buf[i] into out[0..kFeatureCount), through a FeatureWindow of all of buf (for
// tests and one-off use; a stream keeps its own window).
void sample_features(const std::deque<Prepared>& buf, std::size_t i, const protocol::DisplayGeometry& display,
                     float* out, double reach_s = kFeatureReachS);

}  // namespace fovea::trackerd::classify
