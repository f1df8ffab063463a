// SPDX-License-Identifier: Apache-2.0
// I-VT after the Tobii I-VT fixation filter (Olsen 2012, "The Tobii I-VT Fixation Filter",
// Tobii Technology white paper), with its default parameters:
//   gap fill-in       linear interpolation over gaps up to 75 ms        (front end, §2.4)
//   noise reduction   off                                                (§2.2-2.3)
//   velocity          angle between the first and last sample of a 20 ms window centred on the
//                     sample, over the time between them (at least one neighbour each side, so a
//                     60 Hz tracker uses the two adjacent samples)
//   classifier        velocity > 30 deg/s: saccade, otherwise fixation; no velocity: unknown
//   merge             adjacent fixations separated by at most 75 ms and 0.5 deg become one (§2.6)
//   discard           fixations shorter than 60 ms become unknown ("unclassified", §2.7)
// Sample labels keep the saccade label outside fixations; I-VT has no pursuit or PSO.
//
// Online form and latency. Velocity needs 10 ms of lookahead. The event-level steps need more: a
// fixation is held until it has lasted 60 ms; a non-fixation run after it is held until it exceeds
// 75 ms (no merge possible) or the next fixation starts; the merge test then waits until that next
// fixation has lasted 60 ms or ended and compares the first fixation's mean position with the mean
// of the next one's samples so far (Tobii compares whole fixations; waiting for the whole next
// fixation would make the latency unbounded). Worst case: 10 + 60 + 75 + 60 = 205 ms.
#include <cmath>
#include <deque>

#include "classify/pipeline.h"

namespace fovea::trackerd::classify {
namespace {

constexpr double kHalfWindowS = 0.010;      // Olsen 2012: 20 ms velocity window
constexpr double kThresholdDegS = 30.0;     // Olsen 2012: I-VT threshold
constexpr double kMergeMaxGapS = 0.075;     // Olsen 2012: max time between fixations
constexpr double kMergeMaxAngleDeg = 0.5;   // Olsen 2012: max angle between fixations
constexpr double kMinFixationS = 0.060;     // Olsen 2012: minimum fixation duration

class IvtCore final : public Core {
 public:
  double latency_s() const override {
    return kHalfWindowS + kMinFixationS + kMergeMaxGapS + kMinFixationS + 2 * kTimeSlackS;
  }

  void push(const Prepared& p, std::vector<Labeled>& out) override {
    if (!p.has_gaze()) {
      drain_run(out);
      event_step(p, p.kind == Prepared::Kind::Blink ? Label::Blink : Label::Lost, out);
      return;
    }
    run_.push_back(p);
    while (next_ < run_.size() && run_.back().t > run_[next_].t + kHalfWindowS + kTimeSlackS) {
      velocity_for(next_++, out);
    }
    trim();
  }

  void flush(std::vector<Labeled>& out) override {
    drain_run(out);
    switch (phase_) {
      case Phase::None: break;
      case Phase::InFix: finalize_fixation(); break;
      case Phase::InGap: resolve_no_merge(); break;
      case Phase::InF2:
        decide_merge();
        finalize_fixation();
        break;
    }
    phase_ = Phase::None;
    emit_ready(out);
  }

 private:
  // --- velocity (stage A) ---
  void drain_run(std::vector<Labeled>& out) {
    while (next_ < run_.size()) velocity_for(next_++, out);
    run_.clear();
    next_ = 0;
  }

  void velocity_for(std::size_t i, std::vector<Labeled>& out) {
    const double t = run_[i].t;
    std::size_t a = i, b = i;
    while (a > 0 && run_[a - 1].t >= t - kHalfWindowS - kTimeSlackS) --a;
    if (a == i && i > 0) a = i - 1;
    while (b + 1 < run_.size() && run_[b + 1].t <= t + kHalfWindowS + kTimeSlackS) ++b;
    if (b == i && i + 1 < run_.size()) b = i + 1;
    Label raw = Label::Unknown;
    if (a != b) {
      const double v = angle_between_deg(run_[a].x, run_[a].y, run_[b].x, run_[b].y) / (run_[b].t - run_[a].t);
      raw = v > kThresholdDegS ? Label::Saccade : Label::Fixation;
    }
    event_step(run_[i], raw, out);
  }

  void trim() {
    // Keep what the next window can reach: samples within 10 ms before it, and its left neighbour.
    const double ref = next_ < run_.size() ? run_[next_].t : run_.back().t;
    while (next_ >= 2 && run_[1].t < ref - kHalfWindowS - kTimeSlackS) {
      run_.pop_front();
      --next_;
    }
  }

  // --- merge and discard (stage C) ---
  enum class Role : std::uint8_t { Done, E, G, F2 };  // current fixation, gap after it, next fixation
  struct Pending {
    std::uint64_t index;
    Label label;
    Role role;
    bool decided;
  };
  struct Accum {
    double t0 = 0, t1 = 0, sx = 0, sy = 0;
    double n = 0;
    void add(const Prepared& p) {
      if (n == 0) t0 = p.t;
      t1 = p.t;
      sx += p.x;
      sy += p.y;
      n += 1;
    }
    double duration() const { return t1 - t0; }
  };
  enum class Phase : std::uint8_t { None, InFix, InGap, InF2 };

  void event_step(const Prepared& p, Label raw, std::vector<Labeled>& out) {
    const bool fix = raw == Label::Fixation;
    const bool gaze = p.has_gaze();
    for (bool again = true; again;) {
      again = false;
      switch (phase_) {
        case Phase::None:
          if (fix) {
            e_ = {};
            e_.add(p);
            confirmed_ = false;
            pending_.push_back({p.index, Label::Fixation, Role::E, false});
            phase_ = Phase::InFix;
            settle_fixation();
          } else {
            pending_.push_back({p.index, raw, Role::Done, true});
          }
          break;
        case Phase::InFix:
          if (fix) {
            e_.add(p);
            pending_.push_back({p.index, Label::Fixation, Role::E, false});
            settle_fixation();
          } else if (!gaze) {
            finalize_fixation();
            again = true;
          } else {
            pending_.push_back({p.index, raw, Role::G, false});
            phase_ = Phase::InGap;
            if (p.t - e_.t1 > kMergeMaxGapS + kTimeSlackS) resolve_no_merge();
          }
          break;
        case Phase::InGap:
          if (!gaze || p.t - e_.t1 > kMergeMaxGapS + kTimeSlackS) {
            resolve_no_merge();
            again = true;
          } else if (fix) {
            f2_ = {};
            f2_.add(p);
            pending_.push_back({p.index, Label::Fixation, Role::F2, false});
            phase_ = Phase::InF2;
            if (f2_.duration() >= kMinFixationS - kTimeSlackS) decide_merge();
          } else {
            pending_.push_back({p.index, raw, Role::G, false});
          }
          break;
        case Phase::InF2:
          if (fix) {
            f2_.add(p);
            pending_.push_back({p.index, Label::Fixation, Role::F2, false});
            if (f2_.duration() >= kMinFixationS - kTimeSlackS) decide_merge();
          } else {
            decide_merge();  // the next fixation ended early: decide on what it had
            again = true;
          }
          break;
      }
    }
    emit_ready(out);
  }

  // Once the current fixation has lasted the minimum, its samples are final.
  void settle_fixation() {
    if (e_.duration() >= kMinFixationS - kTimeSlackS) confirmed_ = true;
    if (!confirmed_) return;
    for (auto it = pending_.rbegin(); it != pending_.rend() && it->role == Role::E; ++it) {
      it->decided = true;
      it->label = Label::Fixation;
    }
  }

  void finalize_fixation() {
    // Shorter ones are discarded.
    const Label l = e_.duration() >= kMinFixationS - kTimeSlackS ? Label::Fixation : Label::Unknown;
    for (Pending& q : pending_) {
      if (q.role != Role::E) continue;
      if (!q.decided) q.label = l;
      q.decided = true;
      q.role = Role::Done;
    }
    phase_ = Phase::None;
  }

  void resolve_no_merge() {
    finalize_fixation();
    for (Pending& q : pending_) {
      if (q.role != Role::G) continue;
      q.decided = true;  // keeps its own label (saccade or unknown)
      q.role = Role::Done;
    }
    phase_ = Phase::None;
  }

  void decide_merge() {
    const double angle = angle_between_deg(e_.sx / e_.n, e_.sy / e_.n, f2_.sx / f2_.n, f2_.sy / f2_.n);
    if (angle <= kMergeMaxAngleDeg) {
      for (Pending& q : pending_) {
        if (q.role == Role::G) q.label = Label::Fixation;
        if (q.role == Role::G || q.role == Role::F2) q.role = Role::E;
      }
      e_.t1 = f2_.t1;
      e_.sx += f2_.sx;
      e_.sy += f2_.sy;
      e_.n += f2_.n;
    } else {
      resolve_no_merge();
      for (Pending& q : pending_) {
        if (q.role == Role::F2) q.role = Role::E;
      }
      e_ = f2_;
      confirmed_ = false;
    }
    phase_ = Phase::InFix;
    settle_fixation_all();
  }

  void settle_fixation_all() {
    if (e_.duration() >= kMinFixationS - kTimeSlackS) confirmed_ = true;
    if (!confirmed_) return;
    for (Pending& q : pending_) {
      if (q.role == Role::E) {
        q.decided = true;
        q.label = Label::Fixation;
      }
    }
  }

  void emit_ready(std::vector<Labeled>& out) {
    while (!pending_.empty() && pending_.front().decided) {
      out.push_back({pending_.front().index, pending_.front().label});
      pending_.pop_front();
    }
  }

  std::deque<Prepared> run_;  // the current run of gaze samples (history + awaiting velocity)
  std::size_t next_ = 0;      // next sample in run_ that needs its velocity
  std::deque<Pending> pending_;
  Phase phase_ = Phase::None;
  Accum e_, f2_;
  bool confirmed_ = false;
};

}  // namespace

std::unique_ptr<Core> make_ivt_core() { return std::make_unique<IvtCore>(); }

}  // namespace fovea::trackerd::classify
