// SPDX-License-Identifier: Apache-2.0
// The seed's rule, Lee 2009 §3.5.2 (data analysis of the attention-tracking experiment, a 60 Hz
// tracker): a sample whose pupil ellipse aspect ratio is below 0.7 is a blink (handled by the
// front end); otherwise the "velocity" is the change in normalized screen position since the last
// sample: below 0.03 fixation, above 0.1 saccade, in between drift. We have no drift label, so drift
// is reported as pursuit (slow, non-saccadic movement), which is what a consumer of the label wants.
//
// Lee's thresholds are per frame at 60 Hz. To keep their meaning at other rates we compare the
// displacement scaled to one 60 Hz frame: d * (1/60 s) / dt, i.e. speeds of 1.8 and 6 normalized
// units per second. The rule is causal (backward difference): no latency of its own. The first
// sample after lost data has no velocity: Unknown.
#include <cmath>

#include "classify/pipeline.h"

namespace fovea::trackerd::classify {
namespace {

constexpr double kFrameS = 1.0 / 60.0;
constexpr double kFixationPerFrame = 0.03;  // Lee 2009 §3.5.2
constexpr double kSaccadePerFrame = 0.1;    // Lee 2009 §3.5.2

class LeeCore final : public Core {
 public:
  explicit LeeCore(const protocol::DisplayGeometry& d) : display_(d) {}
  double latency_s() const override { return 0; }

  void push(const Prepared& p, std::vector<Labeled>& out) override {
    if (!p.has_gaze()) {
      have_prev_ = false;
      out.push_back({p.index, p.kind == Prepared::Kind::Blink ? Label::Blink : Label::Lost});
      return;
    }
    const auto n = protocol::degrees_to_normalized(display_, protocol::Degrees{p.x, p.y});
    Label label = Label::Unknown;
    if (have_prev_) {
      const double per_frame = std::hypot(n.x - prev_.x, n.y - prev_.y) * kFrameS / (p.t - prev_t_);
      label = per_frame < kFixationPerFrame ? Label::Fixation
              : per_frame > kSaccadePerFrame ? Label::Saccade
                                             : Label::Pursuit;
    }
    prev_ = n;
    prev_t_ = p.t;
    have_prev_ = true;
    out.push_back({p.index, label});
  }
  void flush(std::vector<Labeled>&) override {}

 private:
  protocol::DisplayGeometry display_;
  bool have_prev_ = false;
  protocol::Normalized prev_;
  double prev_t_ = 0;
};

}  // namespace

std::unique_ptr<Core> make_lee_core(const protocol::DisplayGeometry& display) {
  return std::make_unique<LeeCore>(display);
}

}  // namespace fovea::trackerd::classify
