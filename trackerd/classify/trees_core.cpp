// SPDX-License-Identifier: Apache-2.0
// The learned method, `gbt` (issue 43): each sample's multi-scale features (features.h) go through a
// gradient-boosted tree ensemble (trees.h) trained on human-coded recordings by
// bench/train_classifier.py. A sample is scored once the stream has reached the features' reach past it
// and labelled once its smoothing window (kSmoothLongS) is scored too; ivvt's marks beside it give
// the PSO and the small saccades the trees leave in fixations. Samples without gaze keep the front
// end's blink/lost.
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <deque>
#include <limits>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "classify/context.h"
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

// One sample's scores on their way to a label.
struct Scored {
  Labeled out;       // index and, for a sample without gaze, its front-end label
  double t = 0;
  bool gaze = false;
  bool noise_as_blink = false;  // TreesModel::noise_is_blink
  std::uint64_t run = 0;      // gaze run: a sample without gaze ends one
  std::array<double, kMaxTreeClasses> p{};  // class probabilities
};

// Three streaming steps, each waiting only as long as the next needs: the first stage scores a
// sample once the stream has reached its features' reach (reach_) past it; the second (where the model has one,
// or context features are asked for) once the first has scored the look-ahead past it; smoothing
// labels it once its window (kSmoothLongS, online after a second stage kSmoothLongAfterContextS) has
// been through both.
class TreesCore final : public Core {
 public:
  TreesCore(std::shared_ptr<const GbtModel> model, const protocol::DisplayGeometry& display, GbtOptions options)
      : model_(std::move(model)),
        display_(display),
        smooth_(!options.trees_only && model_),
        frame_(model_ ? &model_->frame(options.offline) : nullptr),
        reach_(model_ ? model_->reach_s(options.offline) : options.reach_s > 0 ? options.reach_s : kFeatureReachS),
        context_(model_ && !options.context_only ? model_->context(options.offline) : nullptr),
        staged_(context_ != nullptr || options.context_sink),
        lookahead_s_(context_ ? model_->lookahead_s(options.offline) : staged_ ? kContextReachS : 0.0),
        smooth_long_s_(context_ && !options.offline ? kSmoothLongAfterContextS : kSmoothLongS),
        classes_(frame_ ? frame_->class_count() : 0),
        weights_(chain_weights(options)),
        hold_params_(chain_hold(options)),
        hold_(hold_params_.hold_s, hold_params_.min_s),
        frame_sink_(std::move(options.frame_sink)),
        context_sink_(std::move(options.context_sink)) {}

  void push(const Prepared& p, std::vector<Labeled>& out) override {
    newest_t_ = p.t;
    if (p.kind != Prepared::Kind::Gaze) loss_times_.push_back(p.t);
    buf_.push_back(p);
    window_.push(p);
    while (next_ < buf_.size() && buf_[next_].t + reach_ <= p.t) score_next(out);
    trim();
    if (staged_) contextualize(out, false);
    if (smooth_) label_smoothed(out, false);
  }
  void flush(std::vector<Labeled>& out) override {
    while (next_ < buf_.size()) score_next(out);
    buf_.clear();
    window_.clear();
    next_ = 0;
    if (staged_) contextualize(out, true);
    ctx_.clear();  // the stream has ended: no later context may reach back into it
    ctx_next_ = 0;
    cursor_.reset();
    if (smooth_) label_smoothed(out, true);
  }
  double latency_s() const override { return smoothed_latency_s() + hold_.max_wait_s(); }

 private:
  // The features and the first stage's scores of the next sample, on to the second stage or
  // straight to a label (trees only) or to smoothing.
  void score_next(std::vector<Labeled>& out) {
    const Prepared& p = buf_[next_];
    ContextSample c;
    window_.features(next_, display_, c.frame.data(), reach_);
    if (frame_sink_) frame_sink_(p.index, c.frame.data());
    Scored s;
    s.out = {p.index, p.kind == Prepared::Kind::Lost ? Label::Lost : Label::Blink};
    s.t = c.t = p.t;
    s.gaze = c.gaze = p.has_gaze();
    if (!s.gaze) ++run_;
    s.run = run_;
    ++next_;
    if (s.gaze) s.noise_as_blink = TreesModel::noise_is_blink(c.frame.data(), reach_);
    if (s.gaze && !model_) s.out.label = Label::Unknown;
    if (s.gaze && model_) frame_->probabilities(c.frame.data(), c.p.data());
    if (staged_) {
      push_context(ctx_, c, classes_);
      pending_.push_back(s);
      return;
    }
    if (s.gaze && model_) {
      if (!smooth_) s.out.label = frame_->label(c.frame.data(), s.noise_as_blink);
      s.p = c.p;
    }
    deliver(s, out);
  }
  // The second stage of every first-stage-scored sample whose look-ahead has been scored too (all,
  // at the end of the stream).
  void contextualize(std::vector<Labeled>& out, bool all) {
    std::array<float, kMaxContextFeatures> f;
    // Every sample up to the look-ahead has been scored once the stream has reached the features'
    // reach past it (also where it paused: nothing later can fall within the look-ahead).
    while (ctx_next_ < ctx_.size() && (all || newest_t_ >= ctx_[ctx_next_].t + lookahead_s_ + kContextSlackS + reach_)) {
      context_features(ctx_, ctx_next_, classes_, lookahead_s_, f.data(), &cursor_);
      Scored s = pending_.front();
      pending_.pop_front();
      if (context_sink_) context_sink_(s.out.index, f.data());
      if (s.gaze && context_) {
        if (smooth_) {
          context_->probabilities(f.data(), s.p.data());
        } else {
          s.out.label = context_->label(f.data(), s.noise_as_blink);
        }
      } else if (s.gaze && model_) {  // context features asked for, but no second stage to use them
        s.p = ctx_[ctx_next_].p;
        if (!smooth_) s.out.label = frame_->label(ctx_[ctx_next_].frame.data(), s.noise_as_blink);
      }
      ++ctx_next_;
      deliver(s, out);
    }
    // Keep what the next sample's context reaches back to, and the one just before.
    const double next_t = ctx_next_ < ctx_.size() ? ctx_[ctx_next_].t : ctx_.empty() ? 0.0 : ctx_.back().t;
    while (ctx_next_ >= 2 && next_t - ctx_[1].t >= kContextReachS) {
      ctx_.pop_front();
      cursor_.dropped_front(1);
      --ctx_next_;
    }
  }
  void deliver(const Scored& s, std::vector<Labeled>& out) {
    if (smooth_) {
      scored_.push_back(s);
    } else {
      out.push_back(s.out);
    }
  }
  // Labels every scored sample whose smoothing window is complete: the stream has reached the
  // latency past it (every sample within the long window after it has arrived and been scored), or a
  // later gaze run has begun (everything, at the end of the stream).
  void label_smoothed(std::vector<Labeled>& out, bool all) {
    const TreesModel& last = context_ ? *context_ : *frame_;
    while (labelled_ < scored_.size()) {
      const Scored& s = scored_[labelled_];
      if (!all && scored_.back().run == s.run && s.t > newest_t_ - smoothed_latency_s()) break;
      OnsetHold::Item h{s.out, s.t, s.run, false};
      if (s.gaze) {
        std::array<double, kMaxTreeClasses> near{}, wide{};
        window_mean(labelled_, kSmoothShortS, last.class_count(), near);
        window_mean(labelled_, smooth_long_s_, last.class_count(), wide);
        h.l.label = last.smoothed_label(near.data(), wide.data(), weights_.data(),
                                        s.noise_as_blink || loss_near(s.t));
        h.doubtful = h.l.label == Label::Fixation && pursuit_doubt(last, wide);
      }
      if (hold_params_.hold_s > 0) {
        hold_.push(h);
      } else {
        out.push_back(h.l);
      }
      ++labelled_;
    }
    if (hold_params_.hold_s > 0) hold_.release(out, all);
    while (!loss_times_.empty() && labelled_ < scored_.size() &&
           loss_times_.front() <= scored_[labelled_].t - kNoiseNearLossS) {
      loss_times_.pop_front();
    }
    // Keep what the next label's window reaches back to.
    while (labelled_ > 0 &&
           (labelled_ == scored_.size() || scored_[labelled_].t - scored_.front().t > smooth_long_s_ - kTimeSlackS)) {
      scored_.pop_front();
      --labelled_;
    }
  }
  // Whether a loss of data lies within kNoiseNearLossS of t, one the front end filled in too: the
  // features' times to a loss see neither a filled gap (a short blink's) nor a loss beyond their
  // reach (the daemon's: 64 ms ahead). A smoothed label is made once the stream is past that (112 ms
  // online) or a loss has come, so the samples pushed since tell the whole 100 ms.
  bool loss_near(double t) const {
    const auto first = std::upper_bound(loss_times_.begin(), loss_times_.end(), t - kNoiseNearLossS);
    return first != loss_times_.end() && *first < t + kNoiseNearLossS;
  }
  // How far behind the newest sample a smoothed label is made (before any hold).
  double smoothed_latency_s() const {
    // Each wait is as long as the sample furthest ahead that its step takes in: the context's up to
    // its slack past the look-ahead, the smoothing's short of the window's half by its slack.
    return reach_ + (staged_ ? lookahead_s_ + kContextSlackS : 0.0) + (smooth_ ? smooth_long_s_ - kTimeSlackS : 0.0);
  }
  // A fixation is doubtful where pursuit's weighted mean in the long window comes within
  // the hold's ratio of fixation's: the pursuit may be starting, before its evidence wins.
  bool pursuit_doubt(const TreesModel& last, const std::array<double, kMaxTreeClasses>& wide) const {
    const std::size_t p = last.class_of(Label::Pursuit), f = last.class_of(Label::Fixation);
    if (hold_params_.hold_s <= 0 || p >= last.class_count() || f >= last.class_count()) return false;
    return wide[p] * weights_[p] >= hold_params_.ratio * wide[f] * weights_[f];
  }
  // The chain's hold, or the options' instead; none without smoothing (trees_only).
  PursuitHold chain_hold(const GbtOptions& options) const {
    if (!smooth_) return {};
    if (options.pursuit_hold) return *options.pursuit_hold;
    return model_ && context_ ? model_->hold(options.offline) : PursuitHold{};
  }
  // The mean class probabilities over the samples of j's gaze run less than half away from it: the
  // windows are open, so the labels wait for no sample beyond the window's half (kTimeSlackS).
  // The classes past `classes` stay 0.
  void window_mean(std::size_t j, double half, std::size_t classes, std::array<double, kMaxTreeClasses>& mean) const {
    const Scored& c = scored_[j];
    double n = 0;
    const auto add = [&](const Scored& s) {
      for (std::size_t k = 0; k < classes; ++k) mean[k] += s.p[k];
      n += 1;
    };
    add(c);
    const double reach = half - kTimeSlackS;
    for (std::size_t k = j; k-- > 0 && scored_[k].run == c.run && c.t - scored_[k].t <= reach;) add(scored_[k]);
    for (std::size_t k = j + 1; k < scored_.size() && scored_[k].run == c.run && scored_[k].t - c.t <= reach; ++k) {
      add(scored_[k]);
    }
    for (std::size_t k = 0; k < classes; ++k) mean[k] /= n;
  }
  // The weights the smoothing's long window gives the last stage's classes (GbtModel::weights).
  std::array<double, kMaxTreeClasses> chain_weights(const GbtOptions& options) const {
    std::array<double, kMaxTreeClasses> w;
    w.fill(1.0);
    if (!model_) return w;
    if (context_) {  // a chain's weights are its second stage's (without it every class weighs 1)
      const std::vector<double> given = model_->weights(options.offline);
      std::copy(given.begin(), given.end(), w.begin());
    }
    const TreesModel& last = context_ ? *context_ : *frame_;
    if (const std::size_t pursuit = last.class_of(Label::Pursuit); options.pursuit_weight > 0 && pursuit < w.size()) {
      w[pursuit] = options.pursuit_weight;
    }
    return w;
  }
  // Keep what the next sample's features reach back to: the samples within kFeatureReachS before
  // it and the one just beyond (interpolation's other end).
  void trim() {
    while (next_ >= 2 && buf_[next_].t - buf_[1].t >= kFeatureReachS) {
      buf_.pop_front();
      window_.pop_front(1);
      --next_;
    }
  }
  std::shared_ptr<const GbtModel> model_;
  protocol::DisplayGeometry display_;
  bool smooth_;
  const TreesModel* frame_;    // the chain's first stage (owned by model_), or null
  double reach_;               // how far ahead its features reach (features.h)
  const TreesModel* context_;  // the second stage used (owned by model_), or null
  bool staged_;                // whether samples go through the second stage's buffer
  double lookahead_s_;
  double smooth_long_s_;       // the long smoothing window (trees_core.h)
  std::size_t classes_;        // the first stage's
  std::array<double, kMaxTreeClasses> weights_;  // the last stage's classes' in the smoothing
  PursuitHold hold_params_;  // chain_hold
  OnsetHold hold_;
  FeatureSink frame_sink_, context_sink_;
  std::deque<Prepared> buf_;
  FeatureWindow window_;  // the same samples as buf_, with the running sums of their features
  std::size_t next_ = 0;  // the first sample not yet scored
  std::deque<ContextSample> ctx_;
  std::size_t ctx_next_ = 0;   // the first of ctx_ not through the second stage
  ContextCursor cursor_;       // where ctx_next_'s context searches start
  std::deque<Scored> pending_;  // ctx_[ctx_next_...]'s own
  std::deque<Scored> scored_;
  std::size_t labelled_ = 0;  // the first of scored_ not yet labelled
  std::uint64_t run_ = 0;
  double newest_t_ = 0;          // the newest pushed sample's time
  std::deque<double> loss_times_;  // lost or filled samples' times, from kNoiseNearLossS before the first unlabelled
};

// The trees and ivvt side by side on the same prepared samples: the trees' labels, with two of
// ivvt's marks (make_ivvt_marks_core: its saccade and PSO marks alone) where the trees' coders and
// others label differently:
//  - where ivvt finds a post-saccadic oscillation (Nystrom & Holmqvist 2010's rule, ivvt.cpp) and
//    the trees say fixation, pso; with PsoConvention::Onset also where they say saccade. GazeCom's
//    coders have no PSO class (the trees learned to run the saccade into its first part and count
//    the rest into the fixation); the EyeLink coder and Andersson et al. 2017's (the Lund set) label
//    it apart from its onset. After the trees' saccade (Separate, the default) GazeCom's saccades
//    keep their ends (held out, saccade F1 0.851 -> 0.887) and the EyeLink set its PSO class (mean
//    fixation+saccade kappa 0.836; from the onset 0.861, without a PSO class 0.827);
//  - a saccade of ivvt's that lies wholly within the trees' fixation, saccade: GazeCom's expert,
//    whom the trees learned from, leaves most saccades under 1 degree unmarked, which the EyeLink
//    coder marks (of the 199 such saccades on the EyeLink set 171 are the coder's; kappa 0.83 ->
//    0.86; on GazeCom 133 of 589, saccade F1 -0.006). Only saccades up to kAddedSaccadeMaxS are
//    taken: the pair waits for a saccade's end before it decides, within a bounded latency. Nor one
//    the noise before it could make (clears_the_noise): on GazeCom (every 4th recording) that leaves
//    out 126 of the 450 the expert does not mark and 9 of the 122 it does; on the EyeLink set 3 of 27
//    and none of the coder's 171 (bench/RESULTS.md, "Small saccades the noise could make").
// Both cores label in input order, so their outputs pair up index by index. ivvt's marks are final
// within 80 ms, where its full labels wait up to 310 ms for the pursuit test gbt does not use, so
// the pair waits for the trees only.
class WithIvvtMarksCore final : public Core {
 public:
  WithIvvtMarksCore(std::unique_ptr<Core> trees, std::unique_ptr<Core> ivvt, bool pso_from_onset)
      : trees_(std::move(trees)), ivvt_(std::move(ivvt)), pso_from_onset_(pso_from_onset) {}
  void push(const Prepared& p, std::vector<Labeled>& out) override {
    pending_.push_back({p.t, p.x, p.y, p.kind == Prepared::Kind::Gaze});
    trees_->push(p, from_trees_);
    ivvt_->push(p, from_ivvt_);
    pair_up(out, false);
  }
  void flush(std::vector<Labeled>& out) override {
    trees_->flush(from_trees_);
    ivvt_->flush(from_ivvt_);
    pair_up(out, true);
  }
  double latency_s() const override {
    return std::max(trees_->latency_s(), ivvt_->latency_s() + kAddedSaccadeMaxS);
  }

 private:
  static constexpr double kAddedSaccadeMaxS = 0.050;  // a 2-degree saccade lasts about 30 ms
  static constexpr double kNoiseWindowS = 0.100;
  static constexpr double kSpeedHalfS = 0.010;  // ivvt's velocity window (ivvt.cpp, kVelHalfS)
  static constexpr double kMinAmplitudeOverNoise = 2.0;
  struct Sample {
    double t, x, y;
    bool gaze;  // measured (not filled in, not lost)
  };

  void pair_up(std::vector<Labeled>& out, bool flushing) {
    while (t_at_ < from_trees_.size() && i_at_ < from_ivvt_.size()) {
      const Label ivvt = from_ivvt_[i_at_].label;
      if (ivvt == Label::Saccade && !in_ivvt_saccade_ && !decide_saccade(flushing)) break;
      in_ivvt_saccade_ = ivvt == Label::Saccade;
      Labeled l = from_trees_[t_at_];
      if (added_left_ > 0) {
        l.label = Label::Saccade;
        --added_left_;
      } else if (ivvt == Label::Pso && (l.label == Label::Fixation || (pso_from_onset_ && l.label == Label::Saccade))) {
        l.label = Label::Pso;
      }
      out.push_back(l);
      ++t_at_, ++i_at_;
      remember_paired();
    }
    drop_paired(from_trees_, t_at_);
    drop_paired(from_ivvt_, i_at_);
  }
  // At the first sample of one of ivvt's saccades: true once decided, with added_left_ = its length
  // if the trees call every sample of it fixation; false while its end or the trees' labels of it
  // are not in yet.
  bool decide_saccade(bool flushing) {
    std::size_t n = 0;  // the saccade's length, as far as ivvt's marks go
    while (i_at_ + n < from_ivvt_.size() && from_ivvt_[i_at_ + n].label == Label::Saccade) ++n;
    // Most of ivvt's saccades are the trees' too: known at once, without waiting for their end.
    for (std::size_t k = 0; k < n && t_at_ + k < from_trees_.size(); ++k) {
      if (from_trees_[t_at_ + k].label != Label::Fixation) return true;
    }
    if (pending_[n - 1].t - pending_[0].t > kAddedSaccadeMaxS) return true;  // too long to be added
    const bool ended = i_at_ + n < from_ivvt_.size() || flushing;
    if (!ended || t_at_ + n > from_trees_.size()) return false;  // it may yet end; the trees are behind
    if (clears_the_noise(n)) added_left_ = n;
    return true;
  }
  // Whether the saccade of the first n pending samples moves the gaze kMinAmplitudeOverNoise times as
  // far as the noise of the kNoiseWindowS before it would in its duration: the RMS of ivvt's speed
  // (slope over +-kSpeedHalfS) there. A speed, not a sample-to-sample distance: noise a higher rate
  // averages away does not count (1000 Hz + 0.05 deg on the EyeLink set: 9 of the coder's 181 cut).
  // True where the amplitude or the noise is unknown.
  bool clears_the_noise(std::size_t n) const {
    const Sample &first = pending_[0], &last = pending_[n - 1];
    if (!first.gaze || !last.gaze || before_.empty()) return true;
    std::vector<Sample> around(before_.begin(), before_.end());
    for (std::size_t k = 0; k < pending_.size() && pending_[k].t <= first.t + kSpeedHalfS; ++k) {
      around.push_back(pending_[k]);
    }
    double sum = 0;
    int speeds = 0;
    for (const Sample& at : before_) {
      if (!at.gaze || at.t < first.t - (kNoiseWindowS - kSpeedHalfS)) continue;
      const double v = least_squares_speed(around, at.t);
      if (!std::isfinite(v)) continue;
      sum += v * v;
      ++speeds;
    }
    if (speeds < 2) return true;
    const double interval = n > 1 ? (last.t - first.t) / static_cast<double>(n - 1) : first.t - before_.back().t;
    const double duration = interval * static_cast<double>(n);
    return std::hypot(last.x - first.x, last.y - first.y) >= kMinAmplitudeOverNoise * std::sqrt(sum / speeds) * duration;
  }
  // |slope| of the measured positions within +-kSpeedHalfS of time t (NaN with fewer than 3).
  static double least_squares_speed(const std::vector<Sample>& around, double t) {
    double st = 0, sx = 0, sy = 0;
    int count = 0;
    for (const Sample& p : around) {
      if (!p.gaze || std::abs(p.t - t) > kSpeedHalfS) continue;
      st += p.t, sx += p.x, sy += p.y;
      ++count;
    }
    if (count < 3) return std::numeric_limits<double>::quiet_NaN();
    const double mt = st / count, mx = sx / count, my = sy / count;
    double stt = 0, stx = 0, sty = 0;
    for (const Sample& p : around) {
      if (!p.gaze || std::abs(p.t - t) > kSpeedHalfS) continue;
      stt += (p.t - mt) * (p.t - mt), stx += (p.t - mt) * (p.x - mx), sty += (p.t - mt) * (p.y - my);
    }
    return stt > 0 ? std::hypot(stx / stt, sty / stt) : std::numeric_limits<double>::quiet_NaN();
  }
  // The paired sample moves from pending_ to before_, which keeps kNoiseWindowS of them.
  void remember_paired() {
    before_.push_back(pending_.front());
    pending_.pop_front();
    while (before_.front().t < before_.back().t - kNoiseWindowS) before_.pop_front();
  }
  // The cores' latencies differ, so one side always holds unpaired labels (the trees' side about
  // 100-300 ms of them): drop what was paired once it is half of the side, not at every sample (that moved the
  // ~200 others to the front for every sample at 1000 Hz), nor only when a side is empty (the other
  // would grow without end).
  static void drop_paired(std::vector<Labeled>& v, std::size_t& at) {
    if (2 * at < v.size()) return;
    v.erase(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(at));
    at = 0;
  }
  std::unique_ptr<Core> trees_, ivvt_;
  bool pso_from_onset_;              // PsoConvention::Onset: ivvt's PSO cuts the trees' saccade
  std::vector<Labeled> from_trees_, from_ivvt_;
  std::size_t t_at_ = 0, i_at_ = 0;  // the first of each not yet paired
  std::deque<Sample> pending_;       // the pushed samples, from the first not yet paired
  std::deque<Sample> before_;        // the paired samples of the last kNoiseWindowS
  bool in_ivvt_saccade_ = false;     // the last paired sample was one of ivvt's saccade
  std::size_t added_left_ = 0;       // samples of a taken saccade of ivvt's still to pair
};

}  // namespace

namespace builtin {
// The model compiled into this build (trackerd/classify/models/, embedded by CMake).
extern const char* const kModelName;
extern const std::string kModelText;
}  // namespace builtin

TreesModel::TreesModel(TreeEnsemble trees, const std::string& origin) : trees_(std::move(trees)) {
  if (trees_.class_names().size() > kMaxTreeClasses) {
    throw std::invalid_argument(origin + ": " + std::to_string(trees_.class_names().size()) + " classes (at most " +
                                std::to_string(kMaxTreeClasses) + ")");
  }
  for (const std::string& c : trees_.class_names()) labels_.push_back(label_of_class(c, origin));
}

TreesModel::TreesModel(const std::string& text, const std::string& origin)
    : TreesModel(TreeEnsemble::parse(text, origin, feature_names()), origin) {}

Label TreesModel::label(const float* features, bool noise_as_blink) const {
  double scores[kMaxTreeClasses];
  return named(static_cast<std::size_t>(trees_.predict(features, scores)), noise_as_blink);
}

std::size_t TreesModel::class_of(Label l) const {
  return static_cast<std::size_t>(std::find(labels_.begin(), labels_.end(), l) - labels_.begin());
}

Label TreesModel::named(std::size_t c, bool noise_as_blink) const {
  // Away from a loss and off-screen gaze the coders' noise is GazeCom's own: odd stretches of gaze,
  // no movement. Calling them the likeliest movement instead (an earlier rule, from when the trees
  // called an EyeLink 1000's large saccades noise: they no longer do since they also learn copies
  // recorded as other trackers would) put fixations where the coders have none.
  return labels_[c] == Label::Blink && !noise_as_blink ? Label::Unknown : labels_[c];
}

void TreesModel::probabilities(const float* features, double* p) const {
  const std::size_t k = labels_.size();
  trees_.predict(features, p);
  const double top = *std::max_element(p, p + k);
  double sum = 0;
  for (std::size_t c = 0; c < k; ++c) sum += p[c] = std::exp(p[c] - top);  // softmax, as scikit-learn's
  for (std::size_t c = 0; c < k; ++c) p[c] /= sum;
}

Label TreesModel::smoothed_label(const double* near, const double* wide, const double* weights,
                                 bool noise_as_blink) const {
  const std::size_t k = labels_.size();
  const std::size_t saccade = class_of(Label::Saccade);
  if (saccade < k && std::max_element(near, near + k) == near + saccade) return Label::Saccade;
  double rest[kMaxTreeClasses];
  for (std::size_t c = 0; c < k; ++c) rest[c] = wide[c] * weights[c];  // GbtModel::weights
  if (saccade < k) rest[saccade] = -1;  // the short window said no saccade
  return named(static_cast<std::size_t>(std::max_element(rest, rest + k) - rest), noise_as_blink);
}

bool TreesModel::noise_is_blink(const float* frame_features, double reach_s) {
  static const std::size_t before = feature_index("loss_before_s"), after = feature_index("loss_after_s"),
                           offscreen = feature_index("offscreen_deg");
  // The time to the next loss is capped at the reach, exactly (features.cpp): a loss at the cap is
  // no loss seen. Without this the daemon's 64 ms reach made every noise sample a blink.
  const auto ahead = static_cast<float>(std::min(kNoiseNearLossS, reach_s));
  return static_cast<double>(frame_features[before]) < kNoiseNearLossS || frame_features[after] < ahead ||
         frame_features[offscreen] > 0;
}

namespace {

// The first word of a model's text, past comments and blank lines, and its line.
std::pair<std::string, int> first_word(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    std::istringstream words(line);
    std::string w;
    if (words >> w && w[0] != '#') return {w, n};
  }
  return {"", 1};
}

}  // namespace

GbtModel::GbtModel(const std::string& text, const std::string& origin) {
  const auto [word, line] = first_word(text);
  if (word == "fovea-trees") {  // the first stage alone
    frame_ = std::make_unique<TreesModel>(text, origin);
    return;
  }
  const auto fail = [&origin](int at, const std::string& what) {
    throw std::invalid_argument(origin + ":" + std::to_string(at) + ": " + what);
  };
  if (word != "fovea-gbt") fail(line, "expected 'fovea-gbt' or 'fovea-trees', found '" + word + "'");
  std::istringstream in(text);
  std::string l, header, body;
  int n = 0, header_line = 0;
  const auto end_stage = [&] {
    if (!header.empty()) add_stage(header, body, origin, header_line);
    body.clear();
  };
  while (std::getline(in, l)) {
    ++n;
    std::istringstream words(l);
    std::string w;
    words >> w;
    if (n == line) {
      std::string version;
      if (!(words >> version) || version != "1") fail(n, "format version is not 1");
      body.clear();
    } else if (w == "stage") {
      end_stage();
      header = l;
      header_line = n;
    } else if (header.empty() && !w.empty() && w[0] != '#' && n > line) {
      fail(n, "expected 'stage', found '" + w + "'");
    } else {
      body += l;
    }
    body += '\n';  // blank lines keep the ensemble's line numbers
  }
  end_stage();
  if (!frame_) fail(n, "no 'stage frame'");
}

namespace {

// What a second stage's header gives after its look-ahead: 'weights W_1 ... W_K' and
// 'hold HOLD_S RATIO MIN_S', each at most once, in either order (trees_core.h, GbtModel).
struct ChainOptions {
  std::vector<double> weights;
  bool has_weights = false;
  PursuitHold hold;
};

bool finite_number(const std::string& w, double& v) {
  const auto [end, err] = std::from_chars(w.data(), w.data() + w.size(), v);
  return err == std::errc() && end == w.data() + w.size() && std::isfinite(v);
}

ChainOptions parse_chain_options(const std::vector<std::string>& rest, const std::string& stage,
                                 const std::function<void(const std::string&)>& fail) {
  ChainOptions c;
  for (std::size_t i = 0; i < rest.size();) {
    if ((rest[i] == "weights" && c.has_weights) || (rest[i] == "hold" && c.hold.hold_s > 0)) {
      fail(stage + " has a second '" + rest[i] + "'");
    }
    if (rest[i] == "weights") {
      c.has_weights = true;
      for (++i; i < rest.size() && rest[i] != "hold" && rest[i] != "weights"; ++i) {
        double v = 0;
        if (!finite_number(rest[i], v) || v <= 0) fail(stage + ": weight '" + rest[i] + "' is not a positive number");
        c.weights.push_back(v);
      }
    } else if (rest[i] == "hold") {
      if (i + 3 >= rest.size()) fail(stage + ": 'hold' takes three numbers: HOLD_S RATIO MIN_S");
      double* const fields[3] = {&c.hold.hold_s, &c.hold.ratio, &c.hold.min_s};
      for (std::size_t k = 0; k < 3; ++k) {
        if (!finite_number(rest[i + 1 + k], *fields[k])) {
          fail(stage + ": 'hold' takes three numbers: HOLD_S RATIO MIN_S, not '" + rest[i + 1 + k] + "'");
        }
      }
      if (const std::string err = check(c.hold); !err.empty() || c.hold.hold_s == 0) {
        fail(stage + ": " + (err.empty() ? std::string("a hold of 0 s") : err));
      }
      i += 4;
    } else {
      fail(stage + " takes a look-ahead and then only 'weights' and 'hold', not '" + rest[i] + "'");
    }
  }
  return c;
}

}  // namespace

void GbtModel::add_stage(const std::string& header, const std::string& text, const std::string& origin, int line) {
  std::istringstream words(header);
  std::string stage, name, extra;
  double lookahead = 0;
  words >> stage >> name;
  const auto fail = [&](const std::string& what) {
    throw std::invalid_argument(origin + ":" + std::to_string(line) + ": " + what);
  };
  // The ensemble's own lines start after the header; body holds one line per line of the file from
  // there (the header's own line is blank in it).
  if (name == "frame") {
    if (frame_) fail("a second 'stage frame'");
    if (words >> extra) fail("'stage frame' takes nothing after it");
    frame_ = std::make_unique<TreesModel>(TreeEnsemble::parse(text, origin, feature_names(), line), origin);
    return;
  }
  if (name != "frame-online" && name != "online" && name != "offline") {
    fail("stage '" + name + "' is none of frame, frame-online, online, offline");
  }
  if (!frame_) fail("'stage " + name + "' before 'stage frame'");
  if (name == "frame-online") {
    if (frame_online_) fail("a second 'stage frame-online'");
    if (online_) fail("'stage frame-online' after 'stage online' (whose features it gives)");
    double reach = 0;
    if (!(words >> reach) || !(reach > 0 && reach <= kFeatureReachS) || (words >> extra)) {
      fail("'stage frame-online' needs one reach ahead in seconds, in (0, " + std::to_string(kFeatureReachS) + "]");
    }
    frame_online_ = std::make_unique<TreesModel>(TreeEnsemble::parse(text, origin, feature_names(), line), origin);
    if (frame_online_->trees().class_names() != frame_->trees().class_names()) {
      fail("'stage frame-online' has other classes than 'stage frame'");
    }
    frame_online_reach_s_ = reach;
    return;
  }
  const bool has_lookahead = static_cast<bool>(words >> lookahead);
  std::vector<std::string> rest;
  for (std::string w; has_lookahead && words >> w;) rest.push_back(w);
  const ChainOptions chain = parse_chain_options(rest, "'stage " + name + "'", fail);
  if (!(lookahead > 0 && lookahead <= kContextReachS)) {
    fail("'stage " + name + "' needs one look-ahead in seconds, in (0, " + std::to_string(kContextReachS) + "]");
  }
  std::unique_ptr<TreesModel>& slot = name == "online" ? online_ : offline_;
  if (slot) fail("a second 'stage " + name + "'");
  slot = std::make_unique<TreesModel>(
      TreeEnsemble::parse(text, origin, context_feature_names(frame_->trees().class_names()), line), origin);
  (name == "online" ? online_lookahead_s_ : offline_lookahead_s_) = lookahead;
  if (chain.has_weights && chain.weights.size() != slot->class_count()) {
    fail("'stage " + name + "' has " + std::to_string(chain.weights.size()) + " weights for its " +
         std::to_string(slot->class_count()) + " classes");
  }
  (name == "online" ? online_weights_ : offline_weights_) = chain.weights;
  (name == "online" ? online_hold_ : offline_hold_) = chain.hold;
}

std::vector<double> GbtModel::weights(bool offline) const {
  const TreesModel* last = context(offline);
  const std::vector<double>& given = offline ? offline_weights_ : online_weights_;
  if (!given.empty()) return given;
  return std::vector<double>(last ? last->class_count() : frame(offline).class_count(), 1.0);
}

std::shared_ptr<const GbtModel> builtin_gbt_model() {
  static const std::shared_ptr<const GbtModel> model =
      std::make_shared<const GbtModel>(builtin::kModelText, std::string("built-in model ") + builtin::kModelName);
  return model;
}

std::shared_ptr<const GbtModel> load_gbt_model(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument("model " + path + ": cannot be read");
  std::ostringstream text;
  text << in.rdbuf();
  return std::make_shared<const GbtModel>(text.str(), path);
}

std::unique_ptr<OnlineClassifier> make_trees_pipeline(std::shared_ptr<const GbtModel> model,
                                                      const protocol::DisplayGeometry& display, GbtOptions options) {
  // The trees learned the lid's artefact around blinks from the coders' noise labels (and the
  // loss times among the features): the front end's lid rule would only overrule them.
  FrontendOptions o;
  o.lid_opening_max_s = 0;
  const bool with_marks = options.pso != PsoConvention::None && !options.trees_only;
  const bool from_onset = options.pso == PsoConvention::Onset;
  std::unique_ptr<Core> trees = std::make_unique<TreesCore>(std::move(model), display, std::move(options));
  if (!with_marks) return std::make_unique<Pipeline>("gbt", o, std::move(trees));
  return std::make_unique<Pipeline>(
      "gbt", o, std::make_unique<WithIvvtMarksCore>(std::move(trees), make_ivvt_marks_core(), from_onset));
}

namespace {

// Runs the pipeline over samples, each sink call's row into a matrix of `width` columns.
std::vector<float> matrix_of(const std::vector<Sample>& samples, std::size_t width,
                             const std::function<std::unique_ptr<OnlineClassifier>(FeatureSink)>& make) {
  std::vector<float> m(samples.size() * width, std::numeric_limits<float>::quiet_NaN());
  auto pipeline = make([&](std::uint64_t index, const float* f) {
    std::copy(f, f + width, m.begin() + static_cast<std::ptrdiff_t>(index * width));
  });
  std::vector<Labeled> out;
  for (const Sample& s : samples) {
    pipeline->push(s, out);
    out.clear();
  }
  pipeline->flush(out);
  return m;
}

}  // namespace

std::vector<float> feature_matrix(const std::vector<Sample>& samples, const protocol::DisplayGeometry& display,
                                  double reach_s) {
  if (!(reach_s > 0 && reach_s <= kFeatureReachS)) {
    throw std::invalid_argument("the features' reach ahead must be in (0, " + std::to_string(kFeatureReachS) + "] s");
  }
  return matrix_of(samples, kFeatureCount, [&](FeatureSink sink) {
    GbtOptions o;
    o.trees_only = true;
    o.reach_s = reach_s;
    o.frame_sink = std::move(sink);
    return make_trees_pipeline(nullptr, display, std::move(o));
  });
}

std::vector<float> context_matrix(const std::vector<Sample>& samples, const protocol::DisplayGeometry& display,
                                  std::shared_ptr<const GbtModel> model, bool offline) {
  const std::size_t width = context_feature_names(model->frame().trees().class_names()).size();
  return matrix_of(samples, width, [&](FeatureSink sink) {
    GbtOptions o;
    o.trees_only = true;
    o.offline = offline;
    o.context_only = true;
    o.context_sink = std::move(sink);
    return make_trees_pipeline(model, display, std::move(o));
  });
}

// Pursuit onsets called late (GbtOptions::pursuit_hold_s): a doubtful fixation's verdict comes
// from the labels after it in its gaze run. Through doubtful fixations alone, within hold_s a
// pursuit begins that lasts min_run_s: the fixation is that pursuit's start. Anything else first
// (a sure fixation, a saccade, a loss, another run), the hold running out, or a shorter pursuit
// followed by anything but doubtful fixations: it stays a fixation.
std::optional<Label> OnsetHold::verdict(std::size_t head) const {
  const Item& h = held_[head];
  std::optional<double> pursuit_from;  // where the pursuit now being followed began
  for (std::size_t k = head + 1; k < held_.size(); ++k) {
    const Item& later = held_[k];
    if (later.run != h.run || (!pursuit_from && later.t - h.t > hold_s_)) return Label::Fixation;
    if (later.l.label == Label::Pursuit) {
      if (!pursuit_from) pursuit_from = later.t;
      if (later.t - *pursuit_from >= min_run_s_) return Label::Pursuit;
    } else if (later.doubtful) {
      pursuit_from.reset();  // a pursuit too short to confirm, then doubt again: go on looking
    } else {
      return Label::Fixation;
    }
  }
  return std::nullopt;
}

void OnsetHold::release(std::vector<Labeled>& out, bool all) {
  while (!held_.empty()) {
    Item& head = held_.front();
    if (head.doubtful) {
      const std::optional<Label> v = verdict(0);
      if (!v && !all) return;  // undecided: wait for more labels
      head.l.label = v.value_or(Label::Fixation);
    }
    out.push_back(head.l);
    held_.pop_front();
  }
}

}  // namespace fovea::trackerd::classify
