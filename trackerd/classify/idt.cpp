// SPDX-License-Identifier: Apache-2.0
// I-DT, dispersion-threshold identification (Salvucci & Goldberg 2000, "Identifying fixations and
// saccades in eye-tracking protocols", ETRA, Table/Fig. "I-DT"):
//   while points remain: take a window covering the minimum duration; if its dispersion
//   D = (max x - min x) + (max y - min y) is at most the threshold, grow it until D exceeds the
//   threshold and call it a fixation; otherwise the first point is a saccade point and the window
//   slides on by one.
// Thresholds: 1.0 deg dispersion and 100 ms minimum duration, the values Salvucci & Goldberg
// suggest as a starting point (100-200 ms) and the common choice in later comparisons
// (Komogortsev et al. 2010, Blignaut 2009 recommends about 1 deg).
// Online form: a sample is held until the window that starts at or before it covers 100 ms, so the
// core's latency is the minimum duration. A window cut short by lost data is too short to decide:
// Unknown.
#include <algorithm>
#include <deque>

#include "classify/pipeline.h"

namespace fovea::trackerd::classify {
namespace {

constexpr double kDispersionDeg = 1.0;
constexpr double kMinDurationS = 0.100;

class IdtCore final : public Core {
 public:
  double latency_s() const override { return kMinDurationS; }

  void push(const Prepared& p, std::vector<Labeled>& out) override {
    if (!p.has_gaze()) {
      end_window(out);
      out.push_back({p.index, p.kind == Prepared::Kind::Blink ? Label::Blink : Label::Lost});
      return;
    }
    if (in_fixation_) {
      const double x0 = std::min(min_x_, p.x), x1 = std::max(max_x_, p.x);
      const double y0 = std::min(min_y_, p.y), y1 = std::max(max_y_, p.y);
      if ((x1 - x0) + (y1 - y0) <= kDispersionDeg) {
        min_x_ = x0, max_x_ = x1, min_y_ = y0, max_y_ = y1;
        out.push_back({p.index, Label::Fixation});
        return;
      }
      in_fixation_ = false;  // this point leaves the fixation: it starts a new window
    }
    window_.push_back(p);
    try_window(out);
  }

  void flush(std::vector<Labeled>& out) override { end_window(out); }

 private:
  void try_window(std::vector<Labeled>& out) {
    while (!window_.empty() && window_.back().t - window_.front().t >= kMinDurationS - kTimeSlackS) {
      double x0 = window_.front().x, x1 = x0, y0 = window_.front().y, y1 = y0;
      for (const Prepared& q : window_) {
        x0 = std::min(x0, q.x), x1 = std::max(x1, q.x), y0 = std::min(y0, q.y), y1 = std::max(y1, q.y);
      }
      if ((x1 - x0) + (y1 - y0) <= kDispersionDeg) {
        for (const Prepared& q : window_) out.push_back({q.index, Label::Fixation});
        window_.clear();
        in_fixation_ = true;
        min_x_ = x0, max_x_ = x1, min_y_ = y0, max_y_ = y1;
        return;
      }
      out.push_back({window_.front().index, Label::Saccade});
      window_.pop_front();
    }
  }

  void end_window(std::vector<Labeled>& out) {
    for (const Prepared& q : window_) out.push_back({q.index, Label::Unknown});
    window_.clear();
    in_fixation_ = false;
  }

  std::deque<Prepared> window_;
  bool in_fixation_ = false;
  double min_x_ = 0, max_x_ = 0, min_y_ = 0, max_y_ = 0;
};

}  // namespace

std::unique_ptr<Core> make_idt_core() { return std::make_unique<IdtCore>(); }

}  // namespace fovea::trackerd::classify
