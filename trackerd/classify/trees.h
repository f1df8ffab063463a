// SPDX-License-Identifier: Apache-2.0
#pragma once
// A gradient-boosted tree ensemble, as trained by bench/train_classifier.py (scikit-learn's
// HistGradientBoostingClassifier) and written in fovea's own small text format, evaluated here
// without scikit-learn. The format (one token stream, '#' lines are comments):
//
//   fovea-trees 1
//   features N name_1 ... name_N        must equal the features this build computes, in order
//   classes K name_1 ... name_K
//   baseline b_1 ... b_K                 the raw score before any tree
//   trees T
//   tree CLASS NODES                     then NODES lines, node 0 the root:
//   FEATURE THRESHOLD MISSING_LEFT LEFT RIGHT VALUE
//
// A split node (FEATURE >= 0) sends x[FEATURE] <= THRESHOLD to LEFT, a NaN to LEFT when MISSING_LEFT
// is 1; a leaf (FEATURE = -1) adds VALUE to its class's raw score. The class with the highest raw
// score wins (a softmax would not change the order). Children always follow their parent, so every
// walk ends.
#include <string>
#include <vector>

namespace fovea::trackerd::classify {

inline constexpr std::size_t kMaxTreeClasses = 8;  // what fovea's models may have: fixed-size score arrays

class TreeEnsemble {
 public:
  // Throws std::invalid_argument naming `origin`, the line and what is wrong; `expected_features`
  // must equal the model's list. first_line: the text's first line's number in its file.
  static TreeEnsemble parse(const std::string& text, const std::string& origin,
                            const std::vector<std::string>& expected_features, int first_line = 1);
  const std::vector<std::string>& class_names() const { return classes_; }
  std::size_t tree_count() const { return trees_.size(); }
  std::size_t node_count() const { return nodes_.size(); }
  // Raw scores of every class into scores[0..classes); returns the winning class.
  int predict(const float* features, double* scores) const;

 private:
  struct Node {
    int feature = -1;  // -1: leaf
    bool missing_left = false;
    int left = 0, right = 0;  // absolute indices into nodes_
    double value = 0;  // split: the threshold; leaf: the score added
  };
  struct Tree {
    int cls = 0;
    int root = 0;
  };
  std::vector<std::string> classes_;
  std::vector<double> baseline_;
  std::vector<Node> nodes_;
  std::vector<Tree> trees_;
};

}  // namespace fovea::trackerd::classify
