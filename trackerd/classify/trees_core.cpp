// SPDX-License-Identifier: Apache-2.0
// The learned method, `gbt` (issue 43): each sample's multi-scale features (features.h) go through a
// gradient-boosted tree ensemble (trees.h) trained on human-coded recordings by
// bench/train_classifier.py. A sample is labelled once the stream has reached kFeatureReachS past
// it, so the core's latency is that reach; samples without gaze keep the front end's blink/lost.
#include <algorithm>
#include <cmath>
#include <limits>
#include <deque>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "classify/features.h"
#include "classify/pipeline.h"
#include "classify/trees.h"
#include "classify/trees_core.h"

namespace fovea::trackerd::classify {
namespace {

Label label_of_class(const std::string& name, const std::string& origin) {
  static const std::pair<const char*, Label> known[] = {
      {"fixation", Label::Fixation}, {"saccade", Label::Saccade}, {"pso", Label::Pso},   {"pursuit", Label::Pursuit},
      {"noise", Label::Blink},       {"blink", Label::Blink},     {"lost", Label::Lost},
  };
  for (const auto& [n, l] : known) {
    if (name == n) return l;
  }
  throw std::invalid_argument(origin + ": class '" + name +
                              "' is none of fixation, saccade, pso, pursuit, noise, blink, lost");
}

class TreesCore final : public Core {
 public:
  TreesCore(std::shared_ptr<const TreesModel> model, const protocol::DisplayGeometry& display, FeatureSink sink)
      : model_(std::move(model)), display_(display), sink_(std::move(sink)) {}

  void push(const Prepared& p, std::vector<Labeled>& out) override {
    buf_.push_back(p);
    while (next_ < buf_.size() && buf_[next_].t + kFeatureReachS <= p.t) label_next(out);
    trim();
  }
  void flush(std::vector<Labeled>& out) override {
    while (next_ < buf_.size()) label_next(out);
    buf_.clear();
    next_ = 0;
  }
  double latency_s() const override { return kFeatureReachS; }

 private:
  void label_next(std::vector<Labeled>& out) {
    const Prepared& p = buf_[next_];
    float f[kFeatureCount];
    sample_features(buf_, next_, display_, f);
    if (sink_) sink_(p.index, f);
    Label label = p.kind == Prepared::Kind::Lost ? Label::Lost : Label::Blink;
    if (p.has_gaze()) label = model_ ? model_->label(f) : Label::Unknown;
    out.push_back({p.index, label});
    ++next_;
  }
  // Keep what the next sample's features reach back to: the samples within kFeatureReachS before
  // it and the one just beyond (interpolation's other end).
  void trim() {
    while (next_ >= 2 && buf_[next_].t - buf_[1].t >= kFeatureReachS) {
      buf_.pop_front();
      --next_;
    }
  }
  std::shared_ptr<const TreesModel> model_;
  protocol::DisplayGeometry display_;
  FeatureSink sink_;
  std::deque<Prepared> buf_;
  std::size_t next_ = 0;  // the first sample not yet labelled
};

// The trees and ivvt side by side on the same prepared samples: the trees' labels, but where ivvt
// finds a post-saccadic oscillation (Nystrom & Holmqvist 2010's rule, ivvt.cpp) and the trees say
// saccade or fixation, pso. GazeCom's coders have no PSO class (the trees learned to count it into
// the saccade or the fixation); the EyeLink coder and Andersson et al. 2017's (the Lund set) label it
// apart, and a saccade that swallows its PSO costs their saccade and fixation agreement (on the
// EyeLink set, fixation+saccade kappa 0.79 -> 0.83 with this). Both cores label in input order, so
// their outputs pair up index by index.
class WithPsoCore final : public Core {
 public:
  WithPsoCore(std::unique_ptr<Core> trees, std::unique_ptr<Core> ivvt) : trees_(std::move(trees)), ivvt_(std::move(ivvt)) {}
  void push(const Prepared& p, std::vector<Labeled>& out) override {
    trees_->push(p, from_trees_);
    ivvt_->push(p, from_ivvt_);
    pair_up(out);
  }
  void flush(std::vector<Labeled>& out) override {
    trees_->flush(from_trees_);
    ivvt_->flush(from_ivvt_);
    pair_up(out);
  }
  double latency_s() const override { return std::max(trees_->latency_s(), ivvt_->latency_s()); }

 private:
  void pair_up(std::vector<Labeled>& out) {
    const std::size_t n = std::min(from_trees_.size() - t_at_, from_ivvt_.size() - i_at_);
    for (std::size_t k = 0; k < n; ++k) {
      Labeled l = from_trees_[t_at_ + k];
      const Label ivvt = from_ivvt_[i_at_ + k].label;
      if (ivvt == Label::Pso && (l.label == Label::Saccade || l.label == Label::Fixation)) l.label = Label::Pso;
      out.push_back(l);
    }
    t_at_ += n, i_at_ += n;
    compact(from_trees_, t_at_);
    compact(from_ivvt_, i_at_);
  }
  static void compact(std::vector<Labeled>& v, std::size_t& at) {
    if (at == v.size()) {
      v.clear();
      at = 0;
    }
  }
  std::unique_ptr<Core> trees_, ivvt_;
  std::vector<Labeled> from_trees_, from_ivvt_;
  std::size_t t_at_ = 0, i_at_ = 0;  // the first of each not yet paired
};

}  // namespace

namespace builtin {
// The model compiled into this build (trackerd/classify/models/, embedded by CMake).
extern const char* const kModelName;
extern const std::string kModelText;
}  // namespace builtin

TreesModel::TreesModel(const std::string& text, const std::string& origin)
    : trees_(TreeEnsemble::parse(text, origin, feature_names())) {
  for (const std::string& c : trees_.class_names()) labels_.push_back(label_of_class(c, origin));
}

Label TreesModel::label(const float* features) const {
  double scores[64];
  const auto best = static_cast<std::size_t>(trees_.predict(features, scores));
  if (labels_[best] != Label::Blink || noise_allowed(features)) return labels_[best];
  // Elsewhere the coders' noise is GazeCom's own: odd stretches of gaze. On other trackers what
  // looks like it is mostly fast, large saccades (an EyeLink 1000's at 1000 Hz went to noise by the
  // thousand): the front end already removes what no eye can do, so here the best class that is a
  // movement wins.
  std::size_t movement = labels_.size();
  for (std::size_t c = 0; c < labels_.size(); ++c) {
    if (labels_[c] != Label::Blink && labels_[c] != Label::Lost && (movement == labels_.size() || scores[c] > scores[movement])) {
      movement = c;
    }
  }
  return movement < labels_.size() ? labels_[movement] : labels_[best];
}

bool TreesModel::noise_allowed(const float* features) {
  static const std::size_t before = feature_index("loss_before_s"), after = feature_index("loss_after_s"),
                           offscreen = feature_index("offscreen_deg");
  return static_cast<double>(std::min(features[before], features[after])) < kNoiseNearLossS || features[offscreen] > 0;
}

std::shared_ptr<const TreesModel> builtin_trees_model() {
  static const std::shared_ptr<const TreesModel> model =
      std::make_shared<const TreesModel>(builtin::kModelText, std::string("built-in model ") + builtin::kModelName);
  return model;
}

std::shared_ptr<const TreesModel> load_trees_model(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument("model " + path + ": cannot be read");
  std::ostringstream text;
  text << in.rdbuf();
  return std::make_shared<const TreesModel>(text.str(), path);
}

std::unique_ptr<OnlineClassifier> make_trees_pipeline(std::shared_ptr<const TreesModel> model,
                                                      const protocol::DisplayGeometry& display, bool with_pso,
                                                      FeatureSink sink) {
  // The trees learned the lid's artefact around blinks from the coders' noise labels (and the
  // loss times among the features): the front end's lid rule would only overrule them.
  FrontendOptions o;
  o.lid_opening_max_s = 0;
  std::unique_ptr<Core> trees = std::make_unique<TreesCore>(std::move(model), display, std::move(sink));
  return std::make_unique<Pipeline>(
      "gbt", o, with_pso ? std::make_unique<WithPsoCore>(std::move(trees), make_ivvt_core()) : std::move(trees));
}

std::vector<float> feature_matrix(const std::vector<Sample>& samples, const protocol::DisplayGeometry& display) {
  std::vector<float> m(samples.size() * kFeatureCount, std::numeric_limits<float>::quiet_NaN());
  auto pipeline = make_trees_pipeline(nullptr, display, false, [&](std::uint64_t index, const float* f) {
    std::copy(f, f + kFeatureCount, m.begin() + static_cast<std::ptrdiff_t>(index * kFeatureCount));
  });
  std::vector<Labeled> out;
  for (const Sample& s : samples) {
    pipeline->push(s, out);
    out.clear();
  }
  pipeline->flush(out);
  return m;
}

}  // namespace fovea::trackerd::classify
