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
class TreesModel {
 public:
  // Throws std::invalid_argument naming origin and what is wrong.
  TreesModel(const std::string& text, const std::string& origin);
  Label label(const float* features) const;
  static bool noise_allowed(const float* features);
  const TreeEnsemble& trees() const { return trees_; }

 private:
  TreeEnsemble trees_;
  std::vector<Label> labels_;  // per class
};

std::shared_ptr<const TreesModel> builtin_trees_model();  // parsed once
std::shared_ptr<const TreesModel> load_trees_model(const std::string& path);  // throws std::invalid_argument

// Called with each sample's input index and its kFeatureCount features as the core labels it.
using FeatureSink = std::function<void(std::uint64_t index, const float* features)>;
// The `gbt` pipeline: the standard front end (without the lid rule) and the trees core; with_pso:
// ivvt's PSO where the trees say saccade or fixation (trees_core.cpp, WithPsoCore). model null:
// every gaze sample is labelled unknown (feature extraction only).
std::unique_ptr<OnlineClassifier> make_trees_pipeline(std::shared_ptr<const TreesModel> model,
                                                      const protocol::DisplayGeometry& display, bool with_pso,
                                                      FeatureSink sink = {});

// The features of every input sample exactly as the `gbt` pipeline computes them online, row-major,
// kFeatureCount per row; NaN rows for samples the pipeline rejected (bad times).
std::vector<float> feature_matrix(const std::vector<Sample>& samples, const protocol::DisplayGeometry& display);

}  // namespace fovea::trackerd::classify
