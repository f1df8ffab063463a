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
//
// Evaluation (issue 43's cost bound): a walk is a chain of dependent loads, so the nodes are small
// and near each other: 8 bytes, depth first (a split's left child is the next node), thresholds as
// floats (the largest float <= the file's double: for float features exactly the same split). On
// a first stage of 240 trees of 31 leaves this walks GazeCom samples 15 % faster than 24-byte nodes in the
// file's order, with the same scores bit for bit; walking 8 trees at once without branches was
// slower here (every lane waits for the deepest: 10 steps per tree where a walk takes 5.9).
#include <cstdint>
#include <string>
#include <vector>

namespace fovea::trackerd::classify {

inline constexpr std::size_t kMaxTreeClasses = 8;  // what fovea's models may have: fixed-size score arrays

class TreeEnsemble {
 public:
  // Throws std::invalid_argument naming `origin`, the line and what is wrong. The model's nodes read
  // features by the names its `features` line gives; predict() reads them at those names' places in
  // `available_features` (what the caller computes), each of which the model's list must name at
  // most once. first_line: the text's first line's number in its file.
  static TreeEnsemble parse(const std::string& text, const std::string& origin,
                            const std::vector<std::string>& available_features, int first_line = 1);
  const std::vector<std::string>& class_names() const { return classes_; }
  std::size_t tree_count() const { return root_.size(); }
  std::size_t node_count() const { return nodes_.size(); }
  // Raw scores of every class into scores[0..classes); returns the winning class.
  int predict(const float* features, double* scores) const;

  // A node as the file gives it (parse's input).
  struct FileNode {
    long feature = -1, left = 0, right = 0;
    double threshold = 0, value = 0;
    bool missing_left = false;
  };

 private:
  void add_depth_first(const std::vector<FileNode>& tree);
  // Nodes in depth-first order, each tree's root first: a split's left child is the next node.
  struct Node {
    float threshold = 0;         // split: x <= threshold goes left; leaf: NaN (everything goes right)
    std::uint16_t feature = 0;   // index into the features, kMissingLeft where NaN goes left
    std::uint16_t right = 0;     // offset to the right child; 0 at a leaf, which so leads to itself
  };
  static constexpr std::uint16_t kMissingLeft = 0x8000;
  static constexpr std::size_t kMaxTreeNodes = 0xffff;  // what `right` can reach
  static_assert(sizeof(Node) == 8);
  std::vector<std::string> classes_;
  std::vector<double> baseline_;
  std::vector<Node> nodes_;
  std::vector<double> value_;        // per node: a leaf's score (0 at splits)
  std::vector<std::int32_t> root_;   // per tree
  std::vector<std::int32_t> class_;  // per tree
};

}  // namespace fovea::trackerd::classify
