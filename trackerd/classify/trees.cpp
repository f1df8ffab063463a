// SPDX-License-Identifier: Apache-2.0
#include "classify/trees.h"

#include <charconv>
#include <cmath>
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

}  // namespace

TreeEnsemble TreeEnsemble::parse(const std::string& text, const std::string& origin,
                                 const std::vector<std::string>& expected_features, int first_line) {
  Tokens in(text, origin, first_line);
  in.expect("fovea-trees");
  if (in.integer("format version", 0, kMaxCount) != 1) in.fail("format version is not 1");
  const std::vector<std::string> features = names(in, "features", 4096);
  if (features != expected_features) {
    in.fail("the model was trained on other features than this build computes (" + std::to_string(features.size()) +
            " named, " + std::to_string(expected_features.size()) + " expected): retrain it");
  }
  TreeEnsemble m;
  m.classes_ = names(in, "classes", 64);
  in.expect("baseline");
  for (std::size_t c = 0; c < m.classes_.size(); ++c) m.baseline_.push_back(in.number("baseline"));
  in.expect("trees");
  const long trees = in.integer("tree count", 1, kMaxCount);
  for (long t = 0; t < trees; ++t) {
    in.expect("tree");
    const int cls = static_cast<int>(in.integer("tree class", 0, static_cast<long>(m.classes_.size()) - 1));
    const long count = in.integer("node count", 1, kMaxCount);
    const int root = static_cast<int>(m.nodes_.size());
    for (long k = 0; k < count; ++k) {
      Node n;
      n.feature = static_cast<int>(in.integer("node feature", -1, static_cast<long>(features.size()) - 1));
      const double threshold = in.number("node threshold", true);
      n.missing_left = in.integer("node missing_left", 0, 1) == 1;
      const long left = in.integer("node left", 0, count - 1), right = in.integer("node right", 0, count - 1);
      const double value = in.number("node value");
      if (n.feature >= 0 && (left <= k || right <= k)) in.fail("a split node's children must follow it");
      n.left = root + static_cast<int>(left);
      n.right = root + static_cast<int>(right);
      n.value = n.feature >= 0 ? threshold : value;
      m.nodes_.push_back(n);
    }
    m.trees_.push_back({cls, root});
  }
  in.expect_end();
  return m;
}

int TreeEnsemble::predict(const float* features, double* scores) const {
  for (std::size_t c = 0; c < baseline_.size(); ++c) scores[c] = baseline_[c];
  for (const Tree& t : trees_) {
    const Node* n = &nodes_[static_cast<std::size_t>(t.root)];
    while (n->feature >= 0) {
      const double x = features[n->feature];
      const bool left = std::isnan(x) ? n->missing_left : x <= n->value;
      n = &nodes_[static_cast<std::size_t>(left ? n->left : n->right)];
    }
    scores[t.cls] += n->value;
  }
  int best = 0;
  for (std::size_t c = 1; c < baseline_.size(); ++c) {
    if (scores[c] > scores[best]) best = static_cast<int>(c);
  }
  return best;
}

}  // namespace fovea::trackerd::classify
