// SPDX-License-Identifier: Apache-2.0
#pragma once
// The second stage of the learned classifier `gbt` (issue 43): what the first stage's class
// probabilities say around a sample. One sample's multi-scale features (features.h) see at most
// kFeatureReachS either side, and a sample in the middle of a slow pursuit looks like fixation
// there; the pursuit shows over the longer stretch, as the stage-1 probabilities of its neighbours.
// Stacking a second model on those (Wolpert 1992, "Stacked generalization") is what the sequence
// models of Startsev, Agtzidis & Dorr 2019 (1D-CNN-BLSTM) and Elmadjian et al. 2023 (TCN) learn
// end to end. Per sample, K stage-1 classes:
//   p_<c>                    the sample's own probabilities
//   p_<c>_mD / p_<c>_pD      at the sample D before / after it: the last at or within D (D 8-512 ms,
//                            doubling), if it lies beyond D/2 (else, at a pause or a low rate, NaN)
//   mean_<c>_mW / _pW        mean over the gaze samples within W before / after it (W 32, 128, 512 ms)
//   gaze_mW / gaze_pW        the share of those windows' samples that have gaze
//   and the sample's own frame features (features.h)
// A sample without gaze has no probabilities (NaN); contexts cross losses (pursuit before and after
// a blink is one pursuit).
//
// Each feature reaches a known time ahead of the sample (the D or W of a _p feature, 0 for the
// rest). With look-ahead L a feature reaching further than L is NaN: the daemon labels with a short
// look-ahead (kOnlineLookaheadS) and `fovea-ctl classify --offline` with the whole reach, each with a
// model trained on features computed the same way (bench/train_classifier.py derives the online
// ones by blanking the columns that reach further than L).
#include <array>
#include <cstddef>
#include <deque>
#include <string>
#include <vector>

#include "classify/features.h"
#include "classify/trees.h"

namespace fovea::trackerd::classify {

inline constexpr std::array<double, 7> kContextOffsetsS = {0.008, 0.016, 0.032, 0.064, 0.128, 0.256, 0.512};
inline constexpr std::array<double, 3> kContextWindowsS = {0.032, 0.128, 0.512};
inline constexpr double kContextReachS = 0.512;
// The classifiers' time slack (pipeline.h): a sample 32 ms after another at 250 Hz may be
// 0.032000000000001 s after it, and the online stage must take it as the one 32 ms ahead, as the
// offline stage does (it waits this much longer for it to be scored). The context's windows are
// closed: a sample exactly a window's length away is in.
inline constexpr double kContextSlackS = kTimeSlackS;
inline constexpr std::size_t kMaxContextFeatures =
    kMaxTreeClasses * (1 + 2 * kContextOffsetsS.size() + 2 * kContextWindowsS.size()) + 2 * kContextWindowsS.size() +
    kFeatureCount;

// One sample as the second stage sees it. `before` and the counts are running totals over the
// stream up to (not including) this sample, so a window's mean is a difference of two of them.
struct ContextSample {
  double t = 0;
  bool gaze = false;
  std::array<double, kMaxTreeClasses> p{};       // stage-1 class probabilities (gaze only)
  std::array<double, kMaxTreeClasses> before{};  // the sum of p over earlier gaze samples
  double gaze_before = 0, all_before = 0;        // earlier samples with gaze, and all
  std::array<float, kFeatureCount> frame{};      // features.h's features
};

// Appends s to buf with its running totals taken on from buf's last sample.
void push_context(std::deque<ContextSample>& buf, ContextSample s, std::size_t classes);

// The names, in the order written, for stage-1 classes with these names.
std::vector<std::string> context_feature_names(const std::vector<std::string>& classes);
// How far ahead of the sample a named feature reaches, in seconds (0 for the sample and the past).
double context_feature_reach_s(const std::string& name);

// Where context_features' searches for one sample ended, so that the next sample's searches start
// there: its targets (its time +- the offsets and windows) lie at or after them, as times only
// grow, and a walk forward finds each in a step or two at a steady rate where a search takes ten
// (they were 8 % of gbt's instructions). The same indices as a bisection.
class ContextCursor {
 public:
  // buf lost its first n samples.
  void dropped_front(std::size_t n) {
    for (std::size_t& a : at_) a = a > n ? a - n : 0;
  }
  void reset() { at_.fill(0); }
  // The first sample of buf at or after t (buf.size() if none), walking on from search `slot`'s last
  // answer; t must not be before that search's previous target.
  std::size_t first_at_or_after(const std::deque<ContextSample>& buf, std::size_t slot, double t);

 private:
  std::array<std::size_t, 2 * kContextOffsetsS.size() + 2 * kContextWindowsS.size()> at_{};
};

// The context features of buf[i] into out[0..context_feature_names(classes).size()). buf must reach
// kContextReachS before buf[i] (or the stream's start) and lookahead_s after it (or the stream's end).
// cursor: the previous call's, for a buf[i] later than that call's sample and the same look-ahead
// (null: search afresh).
void context_features(const std::deque<ContextSample>& buf, std::size_t i, std::size_t classes, double lookahead_s,
                      float* out, ContextCursor* cursor = nullptr);

}  // namespace fovea::trackerd::classify
