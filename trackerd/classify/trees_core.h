// SPDX-License-Identifier: Apache-2.0
#pragma once
// The learned method `gbt`: its model and core (trees_core.cpp), and the features it computes for
// every sample of a recording, for training (bench/train_classifier.py through `fovea-ctl classify
// --features-out`).
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "classify/features.h"
#include "classify/pipeline.h"
#include "classify/trees.h"

namespace fovea::trackerd::classify {

// A tree ensemble whose classes are labels. The coders' noise is a blink where a loss of data is
// within kNoiseNearLossS (the lid's artefacts around it), a gap the front end filled in included
// (TreesCore, trees_core.cpp), or the gaze is off the display; elsewhere it is gaze that no movement
// class fits (GazeCom's odd stretches): unknown.
inline constexpr double kNoiseNearLossS = 0.100;
// Smoothing (issue 43): a single sample's trees flip between classes, splitting one pursuit or
// fixation into many events. A saccade is called where the class probabilities averaged over
// +-kSmoothShortS make it the most likely (saccades are short); any other class by the average over
// +-kSmoothLongS. Measured on held-out GazeCom videos: event F1 0.65 / 0.87 / 0.08 -> 0.89 / 0.93 /
// 0.38 (fixation / saccade / pursuit) at no cost in sample F1. The windows are open: a sample
// exactly that far away is out (kTimeSlackS), so no label waits for a sample beyond them (at
// 250 Hz: +-1 and +-3 samples online; closed windows, +-2 and +-4, made each label wait 4 ms more
// for 0.001-0.002 less saccade F1 and 0.004-0.011 more saccade event F1, bench/RESULTS.md).
inline constexpr double kSmoothShortS = 0.008;
inline constexpr double kSmoothLongS = 0.048;
// After a second stage (whose context already spans +-512 ms) the long window is shorter, so the
// labels stay within ivvt's latency bound: 256 ms reach + 32 ms look-ahead + 16 ms = 304 ms.
inline constexpr double kSmoothLongAfterContextS = 0.016;
class TreesModel {
 public:
  // Throws std::invalid_argument naming origin and what is wrong (also more than kMaxTreeClasses).
  TreesModel(TreeEnsemble trees, const std::string& origin);
  // A model over features.h's features alone, from a "fovea-trees" text.
  TreesModel(const std::string& text, const std::string& origin);
  // One sample's label from its own scores (the noise rule applied): what scikit-learn predicts.
  Label label(const float* features, bool noise_as_blink) const;
  // Class probabilities (softmax of the raw scores) into p[0..classes).
  void probabilities(const float* features, double* p) const;
  // The label from probabilities averaged over the short and the long window (above); the long
  // window's choice weighs class k's mean by weights[k] (GbtModel::weights).
  Label smoothed_label(const double* near, const double* wide, const double* weights, bool noise_as_blink) const;
  // Whether the coders' noise is a blink, from a sample's features.h features (above) computed with
  // reach_s ahead: a loss further ahead than that reads as reach_s (features.h), so with a reach
  // under kNoiseNearLossS only a loss within the reach counts ahead.
  static bool noise_is_blink(const float* frame_features, double reach_s);
  const TreeEnsemble& trees() const { return trees_; }
  std::size_t class_count() const { return labels_.size(); }
  // The class labelled l, or class_count() where there is none.
  std::size_t class_of(Label l) const;

 private:
  Label named(std::size_t c, bool noise_as_blink) const;
  TreeEnsemble trees_;
  std::vector<Label> labels_;  // per class
};

// The look-ahead bench/train_classifier.py gives the daemon's second stage (context.h; a model file
// states its own): what fits ivvt's latency bound after the first stage's 256 ms reach and the
// smoothing. GazeCom leave-one-video-out pursuit F1: 0.708 with it, 0.750 with the whole 512 ms.
inline constexpr double kOnlineLookaheadS = 0.032;

// The `gbt` model: the first stage over each sample's features (features.h) and, optionally, second
// stages over the first's probabilities around the sample (context.h), one for the daemon (online,
// short look-ahead) and one for `fovea-ctl classify --offline` (the whole reach). The daemon's chain
// may have a first stage of its own over features that reach less far ahead (features.h), so that
// its labels are final sooner. Its text is either a "fovea-trees" ensemble (the first stage alone)
// or a bundle:
//
//   fovea-gbt 1
//   stage frame                        then a fovea-trees ensemble over features.h's features
//   stage frame-online REACH_S         then one over the same features with REACH_S ahead (optional;
//                                      without it the online chain's first stage is `frame`)
//   stage online LOOKAHEAD_S [weights W_1 ... W_K] [hold HOLD_S RATIO MIN_S]
//                                      then one over context.h's features (optional)
//   stage offline LOOKAHEAD_S [weights W_1 ... W_K] [hold HOLD_S RATIO MIN_S]
//                                      likewise (optional)
//
// A chain's weights (one per class of its second stage, each positive; 1 where not given) weigh the
// long smoothing window's mean probabilities before it picks the class (TreesModel::smoothed_label).
// The most probable class is not the choice that agrees best with the coders: pursuit is rarer than
// fixation and looks like it for its first hundred milliseconds, so argmax calls it late and seldom.
// bench/train_classifier.py fits the pursuit weight on videos each bundle did not see (kPursuitWeights).
// A chain's hold (classifier.h, PursuitHold; none where not given) moves the pursuit onsets its
// smoothing calls late back to the doubtful fixations before them.
//
// Throws std::invalid_argument naming origin, the line and what is wrong.
class GbtModel {
 public:
  GbtModel(const std::string& text, const std::string& origin);
  // The first stage of the online or the offline chain, and how far ahead its features reach.
  const TreesModel& frame(bool offline = true) const { return offline || !frame_online_ ? *frame_ : *frame_online_; }
  double reach_s(bool offline) const { return offline || !frame_online_ ? kFeatureReachS : frame_online_reach_s_; }
  // The second stage for online or offline labelling and its look-ahead; null where there is none.
  const TreesModel* context(bool offline) const { return (offline ? offline_ : online_).get(); }
  double lookahead_s(bool offline) const { return offline ? offline_lookahead_s_ : online_lookahead_s_; }
  // The chain's class weights (above), one per class of its last stage: all 1 without a second stage
  // or where the file gives none.
  std::vector<double> weights(bool offline) const;
  // The chain's pursuit-onset hold (above); hold_s 0 where the file gives none.
  PursuitHold hold(bool offline) const { return offline ? offline_hold_ : online_hold_; }

 private:
  void add_stage(const std::string& header, const std::string& text, const std::string& origin, int line);
  std::unique_ptr<TreesModel> frame_, frame_online_, online_, offline_;
  double frame_online_reach_s_ = kFeatureReachS, online_lookahead_s_ = 0, offline_lookahead_s_ = 0;
  std::vector<double> online_weights_, offline_weights_;  // empty: all 1
  PursuitHold online_hold_, offline_hold_;
};

std::shared_ptr<const GbtModel> builtin_gbt_model();  // parsed once
std::shared_ptr<const GbtModel> load_gbt_model(const std::string& path);  // throws std::invalid_argument

// Called with each sample's input index and its features as the core computes them.
using FeatureSink = std::function<void(std::uint64_t index, const float* features)>;
struct GbtOptions {
  bool offline = false;     // the offline second stage (the whole reach) instead of the online one
  bool trees_only = false;  // the last stage's own label per sample: neither smoothed nor with PSO
                            // (what scikit-learn predicts)
  PsoConvention pso = PsoConvention::Separate;  // classifier.h; Separate and Onset: ivvt's marks beside
                                               // the trees (WithIvvtMarksCore), None: the trees alone
  FeatureSink frame_sink;   // each sample's kFeatureCount features.h features
  FeatureSink context_sink;  // each sample's context features (context.h) from the chain's first
                             // stage, with its second stage's look-ahead (the whole reach where it
                             // has none)
  bool context_only = false;  // no second stage: the context features reach the whole kContextReachS
                              // and the first stage labels (what a second stage is trained on)
  double reach_s = 0;        // without a model: the features' reach ahead (0: kFeatureReachS); a
                             // model's chain states its own
  double pursuit_weight = 0;  // > 0: the chain's weight of pursuit (GbtModel::weights) instead of the
                              // model's (fovea-ctl classify --pursuit-weight; what the training fits)
  // The pursuit-onset hold (classifier.h, PursuitHold) instead of the chain's own (GbtModel::hold):
  // onsets the smoothing calls late move back, and only the doubtful samples wait (OnsetHold).
  std::optional<PursuitHold> pursuit_hold;
};

// The smoothed labels on their way out while a doubtful fixation waits for its verdict
// (GbtOptions::pursuit_hold_s; trees_core.cpp): labels leave in input order, each as soon as
// every doubtful fixation before it has its verdict.
class OnsetHold {
 public:
  struct Item {
    Labeled l;
    double t = 0;
    std::uint64_t run = 0;  // gaze run: the verdict looks only within the fixation's own
    bool doubtful = false;  // a fixation that may be a pursuit's start
  };
  OnsetHold(double hold_s, double min_run_s) : hold_s_(hold_s), min_run_s_(min_run_s) {}
  void push(const Item& item) { held_.push_back(item); }
  // Every label whose turn has come into out; all (the stream's end): undecided ones as fixations.
  void release(std::vector<Labeled>& out, bool all);
  // How long a label may wait here at most: for the pursuit to begin, then to last.
  double max_wait_s() const { return hold_s_ > 0 ? hold_s_ + min_run_s_ : 0.0; }

 private:
  std::optional<Label> verdict(std::size_t head) const;
  double hold_s_, min_run_s_;
  std::deque<Item> held_;
};
// The `gbt` pipeline: the standard front end (without the lid rule), the trees core with its
// smoothing, and (options.pso Separate or Onset) ivvt's PSO after the trees' saccade (Onset: from
// its onset, into the trees' saccade) and ivvt's saccades that lie wholly in the trees' fixations
// (trees_core.cpp, WithIvvtMarksCore).
// model null: every gaze sample is labelled unknown (frame features only).
std::unique_ptr<OnlineClassifier> make_trees_pipeline(std::shared_ptr<const GbtModel> model,
                                                      const protocol::DisplayGeometry& display, GbtOptions options);

// The features of every input sample exactly as the `gbt` pipeline computes them online, row-major,
// kFeatureCount per row; NaN rows for samples the pipeline rejected (bad times).
// reach_s: how far ahead they reach (features.h).
std::vector<float> feature_matrix(const std::vector<Sample>& samples, const protocol::DisplayGeometry& display,
                                  double reach_s = kFeatureReachS);
// The same for the context features (context.h, the whole reach) from the first stage of the
// model's online or offline chain: context_feature_names(model.frame() classes).size() per row,
// what the chain's second stage is trained on.
std::vector<float> context_matrix(const std::vector<Sample>& samples, const protocol::DisplayGeometry& display,
                                  std::shared_ptr<const GbtModel> model, bool offline = true);

}  // namespace fovea::trackerd::classify
