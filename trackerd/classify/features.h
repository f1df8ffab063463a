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
//   straight  |net displacement| / path length over the window      1 for a line, ~0 for noise
// p(t +- D) interpolated linearly between the samples around t +- D, so the features mean the same
// at 250, 500 or 1000 Hz. Where the run does not reach t - D or t + D the scale's features are NaN
// (the trees send NaN down a learned branch). Displacements are the eye's rotation in the tangent
// frame at the sample (pipeline.h, tangent_map). Besides those: the time since the last loss of
// data and to the next (capped at the reach: what happens around blinks), whether the sample was
// filled in, the tracker's noise (median absolute second difference within +-128 ms), and how far
// the gaze lies outside the display (degrees from its nearest edge; 0 on it): coders call gaze off
// the screen noise (GazeCom does), and the trees should learn that from where it is, not from how
// it moves.
//
// Every feature of sample i reads only samples within kFeatureReachS of it, so an online core
// computes them kFeatureReachS after the sample arrives, and offline and online agree exactly.
#include <array>
#include <cstddef>
#include <deque>
#include <string>
#include <vector>

#include "classify/pipeline.h"

namespace fovea::trackerd::classify {

inline constexpr std::array<double, 7> kFeatureScalesS = {0.004, 0.008, 0.016, 0.032, 0.064, 0.128, 0.256};
inline constexpr double kFeatureReachS = 0.256;
inline constexpr int kFeaturesPerScale = 6;
inline constexpr int kFeatureCount = static_cast<int>(kFeatureScalesS.size()) * kFeaturesPerScale + 5;

// "speed_c_4ms", ..., "loss_before_s", "loss_after_s", "filled", "noise_deg", "offscreen_deg": in
// the order written.
const std::vector<std::string>& feature_names();
std::size_t feature_index(const std::string& name);  // throws std::out_of_range for an unknown name

// The features of buf[i] into out[0..kFeatureCount). buf holds Prepared samples in time order and
// must reach kFeatureReachS either side of buf[i] (or the stream's ends) for the result to be the
// final one. A sample without gaze gets NaN everywhere but the loss times.
void sample_features(const std::deque<Prepared>& buf, std::size_t i, const protocol::DisplayGeometry& display,
                     float* out);

}  // namespace fovea::trackerd::classify
