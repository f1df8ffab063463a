// SPDX-License-Identifier: Apache-2.0
#include "classify/provisional.h"

#include <algorithm>
#include <cmath>

#include "classify/pipeline.h"

namespace fovea::trackerd::classify {
namespace {

constexpr double kNoiseWindowS = 1.0;       // the quiet speeds of the last second (as ivvt's noise window)
constexpr double kNoisePriorDeg = 0.05;     // position noise of a typical video tracker, until measured
constexpr double kPriorK = 4;               // the prior's threshold: 4 sigma_v of that noise
constexpr std::size_t kNoiseMinSpeeds = 32;
constexpr std::size_t kNoiseEvery = 16;     // the threshold is refreshed every 16 samples
constexpr std::size_t kNoiseMaxSpeeds = 4096;
constexpr double kMadToSigma = 1.4826;      // median absolute deviation -> SD of a normal distribution

bool finite_gaze(const Sample& s) {
  return s.valid && std::isfinite(s.x_deg) && std::isfinite(s.y_deg) && std::abs(s.x_deg) <= 90 &&
         std::abs(s.y_deg) <= 90;
}

}  // namespace

void ProvisionalDetector::reset() {
  recent_.clear();
  state_ = State::Quiet;
  peak_ = 0;
}

void ProvisionalDetector::push(const Sample& s, std::vector<ProvisionalEvent>& out) {
  if (!std::isfinite(s.t_s) || (!recent_.empty() && s.t_s <= recent_.back().t)) return;
  if (!finite_gaze(s)) {
    reset();  // a blink or a loss: the final labels say which; nothing provisional spans it
    return;
  }
  if (!recent_.empty()) {
    const Point& prev = recent_.back();
    const double jump = angle_between_deg(prev.x, prev.y, s.x_deg, s.y_deg);
    if (jump > o_.min_artifact_jump_deg && jump / (s.t_s - prev.t) > o_.max_eye_speed_deg_s) return;
  }
  recent_.push_back(Point{s.t_s, s.x_deg, s.y_deg, 0});
  while (recent_.size() > 3 && recent_.front().t < s.t_s - o_.walk_back_s - o_.window_s - kTimeSlackS) {
    recent_.pop_front();
  }
  if (recent_.size() < 2) return;
  Point& p = recent_.back();
  velocity(p);
  if (state_ == State::Quiet) add_quiet_speed(p);
  advance(p, recent_[recent_.size() - 2].v, out);
}

// The onset / landing state machine on the newest point (prev_v: the speed of the point before it).
void ProvisionalDetector::advance(const Point& p, double prev_v, std::vector<ProvisionalEvent>& out) {
  const double t = threshold_;
  switch (state_) {
    case State::Quiet:
      if (p.v > t && !(have_landing_ && p.t - last_landing_t_ < o_.refractory_s - kTimeSlackS)) {
        crossing_ = p;
        if (p.v > 2 * t) {
          start_saccade(crossing_, p.t, out);
        } else {
          state_ = State::Rising;
        }
      }
      break;
    case State::Rising:
      if (p.v > t) {
        start_saccade(crossing_, p.t, out);
        peak_ = std::max(peak_, p.v);
      } else {
        state_ = State::Quiet;
      }
      break;
    case State::InSaccade:
    case State::Landing:
      if (p.t - onset_.t > o_.max_saccade_s + kTimeSlackS) {
        state_ = State::Blocked;
      } else if (state_ == State::InSaccade && p.v < t / 2) {
        landing_ = p;
        state_ = State::Landing;
      } else if (state_ == State::InSaccade && prev_v < peak_ / 2 && p.v > prev_v) {
        // A local minimum under half the peak: the eye has landed and oscillates (ivvt's offset rule).
        landing_ = recent_[recent_.size() - 2];
        state_ = State::Landing;
      } else if (p.v >= std::max(t, peak_ / 2)) {
        state_ = State::InSaccade;  // still moving (or the landing did not hold)
      }
      if (state_ == State::Landing && p.t - landing_.t >= o_.hold_s - kTimeSlackS) land(p.t, out);
      peak_ = std::max(peak_, p.v);
      break;
    case State::Blocked:
      if (p.v < t / 2) state_ = State::Quiet;
      break;
  }
}

void ProvisionalDetector::velocity(Point& newest) {
  // Least-squares slope over the trailing window (at least the last two points).
  std::size_t first = recent_.size() - 2;
  while (first > 0 && recent_[first - 1].t >= newest.t - o_.window_s - kTimeSlackS) --first;
  double mt = 0, mx = 0, my = 0;
  const std::size_t n = recent_.size() - first;
  for (std::size_t j = first; j < recent_.size(); ++j) mt += recent_[j].t, mx += recent_[j].x, my += recent_[j].y;
  mt /= static_cast<double>(n), mx /= static_cast<double>(n), my /= static_cast<double>(n);
  double stt = 0, sxt = 0, syt = 0;
  for (std::size_t j = first; j < recent_.size(); ++j) {
    const double dt = recent_[j].t - mt;
    stt += dt * dt;
    sxt += dt * (recent_[j].x - mx);
    syt += dt * (recent_[j].y - my);
  }
  // The true angular speed at the newest point (tangent_vector), as ivvt's.
  const TangentVector w = stt > 0 ? tangent_vector(newest.x, newest.y, sxt / stt, syt / stt) : TangentVector{};
  newest.v = std::hypot(w.x, w.y);
  const double prior = stt > 0 ? kPriorK * kNoisePriorDeg / std::sqrt(stt) : 0;
  threshold_ = std::max(o_.peak_floor_deg_s, measured_ ? speed_threshold_ : prior);
}

void ProvisionalDetector::add_quiet_speed(const Point& p) {
  // The detector's own speeds while the eye is quiet: their spread is the velocity noise as this
  // velocity estimate sees it, white or coloured (a tracker's filter colours it, and a noise level
  // taken from second differences then underestimates the slow part that a 10 ms slope keeps).
  speeds_.push_back(p.v);
  speed_t_.push_back(p.t);
  while (!speed_t_.empty() &&
         (speed_t_.front() < p.t - kNoiseWindowS - kTimeSlackS || speeds_.size() > kNoiseMaxSpeeds)) {
    speed_t_.pop_front();
    speeds_.pop_front();
  }
  if (speeds_.size() < kNoiseMinSpeeds || ++since_update_ < kNoiseEvery) return;
  since_update_ = 0;
  std::vector<double> v(speeds_.begin(), speeds_.end());
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  const double median = *mid;
  for (double& x : v) x = std::abs(x - median);
  std::nth_element(v.begin(), mid, v.end());
  speed_threshold_ = median + o_.peak_k * kMadToSigma * *mid;
  measured_ = true;
}

void ProvisionalDetector::start_saccade(const Point& crossing, double emitted_s, std::vector<ProvisionalEvent>& out) {
  // Onset: the last point before the crossing that was below T/2 (within walk_back_s), else the
  // earliest one kept.
  onset_ = crossing;
  for (auto it = recent_.rbegin(); it != recent_.rend(); ++it) {
    if (it->t >= crossing.t || it->t < crossing.t - o_.walk_back_s - kTimeSlackS) continue;
    onset_ = *it;
    if (it->v < threshold_ / 2) break;
  }
  state_ = State::InSaccade;
  peak_ = crossing.v;
  ProvisionalEvent e;
  e.kind = Label::Saccade;
  e.phase = Phase::Start;
  e.onset_s = e.t_s = onset_.t;
  e.emitted_s = emitted_s;
  e.x_deg = onset_.x;
  e.y_deg = onset_.y;
  out.push_back(e);
}

void ProvisionalDetector::land(double emitted_s, std::vector<ProvisionalEvent>& out) {
  ProvisionalEvent end;
  end.kind = Label::Saccade;
  end.phase = Phase::End;
  end.onset_s = onset_.t;
  end.t_s = landing_.t;
  end.emitted_s = emitted_s;
  end.x_deg = landing_.x;
  end.y_deg = landing_.y;
  end.amplitude_deg = angle_between_deg(onset_.x, onset_.y, landing_.x, landing_.y);
  end.peak_deg_s = peak_;
  out.push_back(end);
  ProvisionalEvent fix = end;
  fix.kind = Label::Fixation;
  fix.phase = Phase::Start;
  fix.onset_s = landing_.t;
  fix.amplitude_deg = 0;
  fix.peak_deg_s = 0;
  out.push_back(fix);
  state_ = State::Quiet;
  have_landing_ = true;
  last_landing_t_ = landing_.t;
}

void ProvisionalCheck::final_event(Label kind, Phase phase, double t_s) {
  for (auto it = pending_.begin(); it != pending_.end(); ++it) {
    if (it->kind == kind && it->phase == phase && std::abs(it->t_s - t_s) <= tolerance_s_ + kTimeSlackS) {
      pending_.erase(it);
      ++confirmed_;
      return;
    }
  }
}

void ProvisionalCheck::final_upto(double t_s, std::vector<ProvisionalEvent>& retracted) {
  for (auto it = pending_.begin(); it != pending_.end();) {
    if (it->t_s + tolerance_s_ + kTimeSlackS < t_s) {
      retracted.push_back(*it);
      ++retracted_;
      it = pending_.erase(it);
    } else {
      ++it;
    }
  }
}

std::vector<ProvisionalEvent> provisional_events(const std::vector<Sample>& samples, ProvisionalOptions o) {
  ProvisionalDetector d(o);
  std::vector<ProvisionalEvent> out;
  for (const auto& s : samples) d.push(s, out);
  return out;
}

}  // namespace fovea::trackerd::classify
