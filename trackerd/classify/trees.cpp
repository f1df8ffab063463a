// SPDX-License-Identifier: Apache-2.0
#include "classify/trees.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace fovea::trackerd::classify {
namespace {

constexpr long kMaxCount = 1L << 22;  // any count in a model: bounds what a damaged file can allocate

// Whitespace-separated tokens with their line numbers; '#' starts a comment to the end of the line.
class Tokens {
 public:
  Tokens(const std::string& text, std::string origin, int first_line)
      : text_(text), origin_(std::move(origin)), line_(first_line) {}

  std::string word(const char* what) {
    skip_space();
    if (pos_ >= text_.size()) fail(std::string("ends where ") + what + " should be");
    const std::size_t start = pos_;
    while (pos_ < text_.size() && !std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    return text_.substr(start, pos_ - start);
  }
  long integer(const char* what, long lo, long hi) {
    const std::string w = word(what);
    long v = 0;
    const auto [end, ec] = std::from_chars(w.data(), w.data() + w.size(), v);
    if (ec != std::errc() || end != w.data() + w.size() || v < lo || v > hi) {
      fail(std::string(what) + " '" + w + "' is not an integer in [" + std::to_string(lo) + ", " +
           std::to_string(hi) + "]");
    }
    return v;
  }
  // infinite_ok: +-inf are taken (a split that sends every number one way and only NaN the other
  // has the threshold inf); NaN never is.
  double number(const char* what, bool infinite_ok = false) {
    const std::string w = word(what);
    double v = 0;
    const auto [end, ec] = std::from_chars(w.data(), w.data() + w.size(), v);
    if (ec != std::errc() || end != w.data() + w.size() || std::isnan(v) || (!infinite_ok && std::isinf(v))) {
      fail(std::string(what) + " '" + w + (infinite_ok ? "' is not a number" : "' is not a finite number"));
    }
    return v;
  }
  void expect(const char* keyword) {
    if (const std::string w = word(keyword); w != keyword) fail(std::string("expected '") + keyword + "', found '" + w + "'");
  }
  void expect_end() {
    skip_space();
    if (pos_ < text_.size()) fail("unexpected text after the last tree");
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw std::invalid_argument(origin_ + ":" + std::to_string(line_) + ": " + what);
  }

 private:
  void skip_space() {
    while (pos_ < text_.size()) {
      const char c = text_[pos_];
      if (c == '#') {
        while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
      } else if (std::isspace(static_cast<unsigned char>(c))) {
        if (c == '\n') ++line_;
        ++pos_;
      } else {
        return;
      }
    }
  }
  const std::string& text_;
  std::string origin_;
  std::size_t pos_ = 0;
  int line_;
};

std::vector<std::string> names(Tokens& in, const char* keyword, long max) {
  in.expect(keyword);
  const long n = in.integer(keyword, 1, max);
  std::vector<std::string> out;
  for (long k = 0; k < n; ++k) out.push_back(in.word(keyword));
  return out;
}

// The largest float <= t: for every float x, x <= t exactly when x <= float_at_or_below(t).
float float_at_or_below(double t) {
  float f = static_cast<float>(t);
  if (static_cast<double>(f) > t) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}

// Why a tree's nodes (as in the file, children after parents) do not form one tree: every node but
// the root must be the child of exactly one split (else a walk could meet it twice and a hostile
// file could make the depth-first copy exponential). "" if they do.
std::string tree_fault(const std::vector<TreeEnsemble::FileNode>& tree) {
  std::vector<int> parents(tree.size(), 0);
  for (const auto& n : tree) {
    if (n.feature < 0) continue;
    ++parents[static_cast<std::size_t>(n.left)];
    ++parents[static_cast<std::size_t>(n.right)];
  }
  for (std::size_t k = 1; k < tree.size(); ++k) {
    if (parents[k] != 1) return "node " + std::to_string(k) + " is the child of " + std::to_string(parents[k]) + " splits, not 1";
  }
  return "";
}

}  // namespace

TreeEnsemble TreeEnsemble::parse(const std::string& text, const std::string& origin,
                                 const std::vector<std::string>& available_features, int first_line) {
  Tokens in(text, origin, first_line);
  in.expect("fovea-trees");
  if (in.integer("format version", 0, kMaxCount) != 1) in.fail("format version is not 1");
  // The model names the features its nodes read, in its own order; each must be one this build
  // computes (a model trained before a feature was added still reads the ones it knew).
  const std::vector<std::string> features = names(in, "features", 4096);
  std::vector<long> index_of;
  for (const std::string& f : features) {
    const auto it = std::find(available_features.begin(), available_features.end(), f);
    if (it == available_features.end()) {
      in.fail("the model reads feature '" + f + "', which this build does not compute: retrain it");
    }
    if (std::find(features.begin(), features.end(), f) != features.begin() + static_cast<std::ptrdiff_t>(index_of.size())) {
      in.fail("the model names feature '" + f + "' twice");
    }
    index_of.push_back(it - available_features.begin());
  }
  TreeEnsemble m;
  m.classes_ = names(in, "classes", 64);
  in.expect("baseline");
  for (std::size_t c = 0; c < m.classes_.size(); ++c) m.baseline_.push_back(in.number("baseline"));
  in.expect("trees");
  const long trees = in.integer("tree count", 1, kMaxCount);
  std::vector<FileNode> tree;
  for (long t = 0; t < trees; ++t) {
    in.expect("tree");
    const int cls = static_cast<int>(in.integer("tree class", 0, static_cast<long>(m.classes_.size()) - 1));
    const long count = in.integer("node count", 1, static_cast<long>(kMaxTreeNodes));
    tree.clear();
    for (long k = 0; k < count; ++k) {
      FileNode n;
      n.feature = in.integer("node feature", -1, static_cast<long>(features.size()) - 1);
      if (n.feature >= 0) n.feature = index_of[static_cast<std::size_t>(n.feature)];
      n.threshold = in.number("node threshold", true);
      n.missing_left = in.integer("node missing_left", 0, 1) == 1;
      n.left = in.integer("node left", 0, count - 1), n.right = in.integer("node right", 0, count - 1);
      n.value = in.number("node value");
      if (n.feature >= 0 && (n.left <= k || n.right <= k)) in.fail("a split node's children must follow it");
      tree.push_back(n);
    }
    if (const std::string fault = tree_fault(tree); !fault.empty()) in.fail("tree " + std::to_string(t) + ": " + fault);
    m.root_.push_back(static_cast<std::int32_t>(m.nodes_.size()));
    m.class_.push_back(cls);
    m.add_depth_first(tree);
  }
  in.expect_end();
  return m;
}

// Each node, then its left subtree, then its right (an explicit stack: a hostile file's chain of
// kMaxTreeNodes would overflow a recursion's).
void TreeEnsemble::add_depth_first(const std::vector<FileNode>& tree) {
  constexpr std::size_t kNone = static_cast<std::size_t>(-1);
  struct Pending {
    long node;
    std::size_t parent;  // the split whose right child this is (kNone: a left child or the root)
  };
  std::vector<Pending> stack{{0, kNone}};
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    const std::size_t self = nodes_.size();
    if (p.parent != kNone) nodes_[p.parent].right = static_cast<std::uint16_t>(self - p.parent);
    const FileNode& f = tree[static_cast<std::size_t>(p.node)];
    Node n;
    if (f.feature >= 0) {
      n.threshold = float_at_or_below(f.threshold);
      n.feature = static_cast<std::uint16_t>(f.feature) | (f.missing_left ? kMissingLeft : 0);
      stack.push_back({f.right, self});
      stack.push_back({f.left, kNone});
    } else {
      n.threshold = std::numeric_limits<float>::quiet_NaN();
    }
    nodes_.push_back(n);
    value_.push_back(f.feature >= 0 ? 0.0 : f.value);
  }
}

int TreeEnsemble::predict(const float* features, double* scores) const {
  for (std::size_t c = 0; c < baseline_.size(); ++c) scores[c] = baseline_[c];
  const Node* nodes = nodes_.data();
  for (std::size_t t = 0; t < root_.size(); ++t) {
    std::uint32_t at = static_cast<std::uint32_t>(root_[t]);
    for (;;) {
      const Node n = nodes[at];
      if (n.right == 0) break;
      const float v = features[n.feature & ~kMissingLeft];
      const bool left = v <= n.threshold || (v != v && (n.feature & kMissingLeft) != 0);
      at += left ? 1u : n.right;
    }
    scores[class_[t]] += value_[at];
  }
  int best = 0;
  for (std::size_t c = 1; c < baseline_.size(); ++c) {
    if (scores[c] > scores[best]) best = static_cast<int>(c);
  }
  return best;
}

}  // namespace fovea::trackerd::classify
