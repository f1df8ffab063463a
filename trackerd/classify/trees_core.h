// SPDX-License-Identifier: Apache-2.0
#pragma once
// The learned method `gbt`: its model and core (trees_core.cpp), and the features it computes for
// every sample of a recording, for training (bench/train_classifier.py through `fovea-ctl classify
// --features-out`).
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "classify/pipeline.h"
#include "classify/trees.h"

namespace fovea::trackerd::classify {

// A tree ensemble over features.h's features whose classes are labels. The coders' noise is a
// blink where a loss of data is within kNoiseNearLossS (the lid's artefacts around it) or the gaze
// is off the display; elsewhere the best of the movement classes wins.
inline constexpr double kNoiseNearLossS = 0.100;
// Smoothing (issue 43): a single sample's trees flip between classes, splitting one pursuit or
// fixation into many events. A saccade is called where the class probabilities averaged over
// +-kSmoothShortS make it the most likely (saccades are short); any other class by the average over
// +-kSmoothLongS. Measured on held-out GazeCom videos: event F1 0.65 / 0.87 / 0.08 -> 0.89 / 0.93 /
// 0.38 (fixation / saccade / pursuit) at no cost in sample F1.
inline constexpr double kSmoothShortS = 0.008;
inline constexpr double kSmoothLongS = 0.048;
inline constexpr std::size_t kMaxTreeClasses = 8;
class TreesModel {
 public:
  // Throws std::invalid_argument naming origin and what is wrong (also more than kMaxTreeClasses).
  TreesModel(const std::string& text, const std::string& origin);
  // One sample's label from its own scores (the noise rule applied): what scikit-learn predicts.
  Label label(const float* features) const;
  // Class probabilities (softmax of the raw scores) into p[0..classes).
  void probabilities(const float* features, double* p) const;
  // The label from probabilities averaged over the short and the long window (above).
  Label smoothed_label(const double* near, const double* wide, bool noise_ok) const;
  static bool noise_allowed(const float* features);
  const TreeEnsemble& trees() const { return trees_; }

 private:
  std::size_t best_movement(const double* scores, std::size_t fallback) const;
  TreeEnsemble trees_;
  std::vector<Label> labels_;  // per class
};

std::shared_ptr<const TreesModel> builtin_trees_model();  // parsed once
std::shared_ptr<const TreesModel> load_trees_model(const std::string& path);  // throws std::invalid_argument

// Called with each sample's input index and its kFeatureCount features as the core labels it.
using FeatureSink = std::function<void(std::uint64_t index, const float* features)>;
// The `gbt` pipeline: the standard front end (without the lid rule), the trees core with its
// smoothing, and ivvt's PSO where the trees say saccade or fixation (trees_core.cpp, WithPsoCore).
// trees_only: each sample's own trees' label, neither smoothed nor with PSO (what scikit-learn
// predicts). model null: every gaze sample is labelled unknown (feature extraction only).
std::unique_ptr<OnlineClassifier> make_trees_pipeline(std::shared_ptr<const TreesModel> model,
                                                      const protocol::DisplayGeometry& display, bool trees_only,
                                                      FeatureSink sink = {});

// The features of every input sample exactly as the `gbt` pipeline computes them online, row-major,
// kFeatureCount per row; NaN rows for samples the pipeline rejected (bad times).
std::vector<float> feature_matrix(const std::vector<Sample>& samples, const protocol::DisplayGeometry& display);

}  // namespace fovea::trackerd::classify
