// SPDX-License-Identifier: Apache-2.0
#include "sim/synthetic_gaze.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

namespace fovea::trackerd {

using protocol::Degrees;
using protocol::EventPhase;
using protocol::EyeMovement;
using protocol::GazeEvent;
using protocol::GazeSample;

std::int64_t due_time_ns(const GazeItem& item) {
  if (const auto* s = std::get_if<GazeSample>(&item)) return s->tracker_time_ns;
  const auto& e = std::get<GazeEvent>(item);
  return e.phase == EventPhase::Start ? e.start_time_ns : e.start_time_ns + e.duration_ns;
}

double saccade_duration_s(double amplitude_deg) { return (2.2 * amplitude_deg + 21.0) / 1000.0; }

double saccade_peak_velocity(double amplitude_deg) { return 600.0 * (1.0 - std::exp(-amplitude_deg / 9.0)); }

namespace {

constexpr double kPi = std::numbers::pi;
constexpr std::size_t kProfileSteps = 256;

// Peak-to-mean ratio of the velocity profile sin(pi s)^p over s in [0, 1]:
// mean = Gamma((p+1)/2) / (sqrt(pi) Gamma(p/2 + 1)).
double peak_factor(double p) {
  return std::sqrt(kPi) * std::tgamma(p / 2.0 + 1.0) / std::tgamma((p + 1.0) / 2.0);
}

// Cumulative, normalized position profile whose velocity is sin(pi s)^p, with p chosen so the peak
// velocity matches `peak_deg_s` for the given amplitude and duration. Real saccades have bell-shaped
// velocity profiles whose peak-to-mean ratio lies between about 1.4 and 2.
std::vector<double> saccade_profile(double amplitude_deg, double duration_s, double peak_deg_s) {
  const double wanted = std::clamp(peak_deg_s * duration_s / amplitude_deg, 1.32, 1.99);
  double lo = 0.5, hi = 2.0;  // peak_factor is increasing in p: 1.31 at 0.5, 2.0 at 2
  for (int i = 0; i < 40; ++i) {
    const double mid = 0.5 * (lo + hi);
    (peak_factor(mid) < wanted ? lo : hi) = mid;
  }
  const double p = 0.5 * (lo + hi);
  std::vector<double> cum(kProfileSteps + 1, 0.0);
  // Integrate with the midpoint rule over fine sub-steps.
  constexpr int kSub = 8;
  for (std::size_t i = 0; i < kProfileSteps; ++i) {
    double acc = 0;
    for (int j = 0; j < kSub; ++j) {
      const double s = (static_cast<double>(i) + (j + 0.5) / kSub) / kProfileSteps;
      acc += std::pow(std::sin(kPi * s), p);
    }
    cum[i + 1] = cum[i] + acc;
  }
  for (double& c : cum) c /= cum.back();
  return cum;
}

double angle_between_deg(double ax, double ay, double bx, double by) {
  return protocol::angle_between_deg({ax, ay}, {bx, by});
}

// Position along a saccade profile at normalized time u in [0, 1], linearly interpolated.
double profile_at(const std::vector<double>& profile, double u) {
  const double x = std::clamp(u, 0.0, 1.0) * kProfileSteps;
  const auto i = std::min(static_cast<std::size_t>(x), kProfileSteps - 1);
  return profile[i] + (profile[i + 1] - profile[i]) * (x - static_cast<double>(i));
}

// Bouzat et al. 2018's pupil oscillator in 1/s^2 and 1/s (Schweitzer & Rolfs's 0.032 /ms^2, 0.15 /ms),
// integrated in steps of 0.1 ms (under a hundredth of its period at any sample rate).
constexpr double kPupilStiffness = 0.032e6;
constexpr double kPupilDamping = 0.15e3;
constexpr std::int64_t kPupilStepNs = 100'000;
// A PSO lasts, in the ground truth, while the oscillation's velocity envelope exceeds 5 deg/s, the
// ground-truth velocity criterion of Schweitzer & Rolfs's simulator (an amplitude of 0.028 deg); the
// saccade itself, in the truth, lasts until the tracked pupil stops moving on in its direction at
// that speed (update_pso_truth).
constexpr double kPsoEndDegS = 5.0;
// Of a blink's tracked lid movement (blink_eye_movements), the part on each side of the pupil loss.
constexpr double kLidTrackedS = 0.030;

}  // namespace

PowerLawNoise::PowerLawNoise(double alpha, std::size_t taps) : h_(std::max<std::size_t>(1, taps)), history_(h_.size()) {
  if (!(alpha >= 0 && alpha <= 2)) {
    char what[96];
    std::snprintf(what, sizeof what, "spectral slope alpha = %g: must lie in [0, 2]", alpha);
    throw std::invalid_argument(what);
  }
  h_[0] = 1;
  for (std::size_t k = 1; k < h_.size(); ++k) {
    h_[k] = h_[k - 1] * (static_cast<double>(k) - 1 + alpha / 2) / static_cast<double>(k);
  }
  double energy = 0;
  for (const double c : h_) energy += c * c;
  scale_ = 1 / std::sqrt(energy);
}

double PowerLawNoise::next(double white) {
  head_ = head_ == 0 ? history_.size() - 1 : head_ - 1;
  history_[head_] = white;
  // The ring from head_ (the newest draw) to its end, then from its start: no index wraps per tap.
  double sum = 0;
  const std::size_t n = history_.size(), first = n - head_;
  for (std::size_t k = 0; k < first; ++k) sum += h_[k] * history_[head_ + k];
  for (std::size_t k = first; k < n; ++k) sum += h_[k] * history_[k - first];
  return scale_ * sum;
}

SyntheticGaze::SyntheticGaze(SyntheticGazeOptions options)
    : options_(options), rng_(options.seed), eye_rng_(options.seed ^ 0x9E3779B97F4A7C15ULL) {
  if (options_.noise_alpha != 0) {  // NaN and negatives too: the filter refuses them
    const auto taps = static_cast<std::size_t>(std::max(16.0, options_.rate_hz));  // one second
    noise_x_.emplace(options_.noise_alpha, taps);
    noise_y_.emplace(options_.noise_alpha, taps);
  }
  Segment first;
  first.phase = Phase::Fixation;
  first.duration_s = 0.3;
  start_segment(first, options_.start_time_ns);
}

std::string SyntheticGaze::description() const {
  char buf[96];
  std::snprintf(buf, sizeof buf, "synthetic (seed %llu, %.0f Hz%s)", static_cast<unsigned long long>(options_.seed),
                options_.rate_hz, options_.binocular ? ", binocular" : "");
  return buf;
}

bool SyntheticGaze::on_screen(const Vec2& deg, double margin) const {
  const auto n = protocol::degrees_to_normalized(options_.display, Degrees{deg.x, deg.y});
  return n.x >= margin && n.x <= 1 - margin && n.y >= margin && n.y <= 1 - margin;
}

SyntheticGaze::Vec2 SyntheticGaze::random_target(const Vec2& from) {
  // Saccade amplitudes in free viewing are mostly small: gamma(2, 3.5 deg), at least 1 deg.
  std::gamma_distribution<double> amplitude(2.0, 3.5);
  for (int attempt = 0; attempt < 50; ++attempt) {
    const double a = std::max(1.0, amplitude(rng_));
    const double dir = uniform_(rng_) * 2 * kPi;
    const Vec2 to{from.x + a * std::cos(dir), from.y + a * std::sin(dir)};
    if (on_screen(to, 0.05)) return to;
  }
  // Near an edge: jump towards the middle of the screen instead.
  return {from.x * 0.3, from.y * 0.3};
}

SyntheticGaze::Segment SyntheticGaze::plan_saccade(const Vec2& from, const Vec2& to) const {
  Segment s;
  s.phase = Phase::Saccade;
  s.from = from;
  s.to = to;
  const double amplitude = angle_between_deg(from.x, from.y, to.x, to.y);
  s.duration_s = saccade_duration_s(amplitude);
  s.profile = saccade_profile(amplitude, s.duration_s, saccade_peak_velocity(amplitude));
  return s;
}

// With catch_up_saccades: a pursuit segment of the eye at gain 0.9, for 200-400 ms or what is left;
// `carrier` holds the target's velocity and position and the pursuit time left.
SyntheticGaze::Segment SyntheticGaze::plan_pursuit(Segment carrier, const Vec2& from) {
  constexpr double kGain = 0.9;
  Segment s = std::move(carrier);
  s.phase = Phase::Pursuit;
  s.from = from;
  s.duration_s = std::min(s.pursuit_left_s, 0.2 + 0.2 * uniform_(rng_));
  s.pursuit_left_s -= s.duration_s;
  s.velocity = {kGain * s.target_velocity.x, kGain * s.target_velocity.y};
  s.to = {from.x + s.velocity.x * s.duration_s, from.y + s.velocity.y * s.duration_s};
  s.target_end = {s.target_end.x + s.target_velocity.x * s.duration_s, s.target_end.y + s.target_velocity.y * s.duration_s};
  s.profile.clear();
  return s;
}

// After a stretch of lagging pursuit: a catch-up saccade to 10 % beyond the target (then pursuit
// again); after the catch-up saccade: pursuit again. False when the pursuit is over.
bool SyntheticGaze::continue_pursuit(const Segment& finished, Segment& next) {
  if (!options_.catch_up_saccades || finished.pursuit_left_s <= 0) return false;
  if (finished.phase == Phase::Pursuit) {
    const Vec2 lag{finished.target_end.x - finished.to.x, finished.target_end.y - finished.to.y};
    const Vec2 aim{finished.to.x + 1.1 * lag.x, finished.to.y + 1.1 * lag.y};
    next = plan_saccade(finished.to, aim);
    next.target_velocity = finished.target_velocity;
    next.pursuit_left_s = std::max(0.0, finished.pursuit_left_s - next.duration_s);
    next.target_end = {finished.target_end.x + finished.target_velocity.x * next.duration_s,
                       finished.target_end.y + finished.target_velocity.y * next.duration_s};
    return true;
  }
  if (finished.phase == Phase::Saccade) {
    next = plan_pursuit(finished, finished.to);
    return next.duration_s > 0;
  }
  return false;
}

SyntheticGaze::Segment SyntheticGaze::plan_after(const Segment& finished) {
  const Vec2 here = finished.to;
  Segment s;
  s.from = here;
  s.to = here;
  if (continue_pursuit(finished, s)) return s;
  if (finished.phase == Phase::Fixation && options_.microsaccades_per_s > 0 &&
      uniform_(rng_) < 1.0 - std::exp(-options_.microsaccades_per_s * finished.duration_s)) {
    // A microsaccade in the fixation (it ends the fixation segment; a new one follows it).
    const double amplitude = std::clamp(0.3 * std::exp(0.5 * gauss_(rng_)), 0.1, 1.0);
    const double dir = uniform_(rng_) * 2 * kPi;
    return plan_saccade(here, {here.x + amplitude * std::cos(dir), here.y + amplitude * std::sin(dir)});
  }
  if (finished.phase != Phase::Fixation) {
    // Every movement ends in a fixation: log-normal duration, median 250 ms, within 150-600 ms.
    s.phase = Phase::Fixation;
    s.duration_s = std::clamp(0.25 * std::exp(0.35 * gauss_(rng_)), 0.15, 0.6);
    return s;
  }
  const double u = uniform_(rng_);
  if (u < 0.07) {
    Segment b = plan_blink();
    b.from = b.to = here;
    return b;
  } else if (u < 0.14) {
    s.phase = Phase::Pursuit;
    s.duration_s = 0.4 + 0.8 * uniform_(rng_);
    const double speed = 5 + 15 * uniform_(rng_);  // deg/s
    double dir = uniform_(rng_) * 2 * kPi;
    for (int attempt = 0; attempt < 16; ++attempt, dir += kPi / 8) {
      s.velocity = {speed * std::cos(dir), speed * std::sin(dir)};
      s.to = {here.x + s.velocity.x * s.duration_s, here.y + s.velocity.y * s.duration_s};
      if (on_screen(s.to, 0.05)) break;
    }
    if (!on_screen(s.to, 0.05)) {  // nowhere to go: make it a short fixation instead
      s.phase = Phase::Fixation;
      s.to = here;
      s.duration_s = 0.2;
    } else if (options_.catch_up_saccades) {
      // The target moves as planned; the eye follows it in lagging stretches and catch-up saccades.
      s.target_velocity = s.velocity;
      s.target_end = here;
      s.pursuit_left_s = s.duration_s;
      return plan_pursuit(s, here);
    }
  } else {
    return plan_saccade(here, random_target(here));
  }
  return s;
}

// A blink of 100-300 ms; with blink_eye_movements, its dip and the part in which the pupil is lost.
SyntheticGaze::Segment SyntheticGaze::plan_blink() {
  Segment s;
  s.phase = Phase::Blink;
  s.duration_s = 0.1 + 0.2 * uniform_(rng_);
  s.covered_to_s = s.duration_s;
  if (options_.blink_eye_movements) {
    const double dip = 1 + uniform_(rng_);  // Riggs et al. 1987: 1-2 deg downward
    s.dip = {0, dip};
    s.profile = saccade_profile(dip, saccade_duration_s(dip), saccade_peak_velocity(dip));
    s.covered_from_s = kLidTrackedS;
    s.covered_to_s = s.duration_s - kLidTrackedS;
  }
  return s;
}

SyntheticGaze::Vec2 SyntheticGaze::position_in_segment(double t) {
  const Segment& s = segment_;
  switch (s.phase) {
    case Phase::Fixation:
      return s.from;
    case Phase::Blink: {
      if (s.profile.empty()) return s.from;
      const double d = saccade_duration_s(s.dip.y);  // down in d, back in d
      const double f = t < d ? profile_at(s.profile, t / d) : 1 - profile_at(s.profile, (t - d) / d);
      return {s.from.x + s.dip.x * f, s.from.y + s.dip.y * f};
    }
    case Phase::Pursuit:
      return {s.from.x + s.velocity.x * t, s.from.y + s.velocity.y * t};
    case Phase::Saccade: {
      const double f = profile_at(s.profile, t / s.duration_s);
      return {s.from.x + (s.to.x - s.from.x) * f, s.from.y + (s.to.y - s.from.y) * f};
    }
  }
  return s.from;
}

GazeEvent SyntheticGaze::make_event(EventPhase phase, std::int64_t t_ns) const {
  GazeEvent e;
  switch (segment_.phase) {
    case Phase::Fixation: e.kind = EyeMovement::Fixation; break;
    case Phase::Saccade: e.kind = EyeMovement::Saccade; break;
    case Phase::Pursuit: e.kind = EyeMovement::Pursuit; break;
    case Phase::Blink: e.kind = EyeMovement::Blink; break;
  }
  e.phase = phase;
  e.start_time_ns = segment_start_ns_;
  e.duration_ns = phase == EventPhase::Start ? 0 : std::max<std::int64_t>(0, t_ns - segment_start_ns_);
  Vec2 c = segment_.from;
  if (phase == EventPhase::End) {
    if (segment_.phase == Phase::Saccade) {
      c = segment_.to;  // landing point
    } else if (sum_count_ > 0) {
      c = {sum_pos_.x / static_cast<double>(sum_count_), sum_pos_.y / static_cast<double>(sum_count_)};
    }
    e.amplitude_deg = static_cast<float>(angle_between_deg(segment_.from.x, segment_.from.y, segment_.to.x,
                                                           segment_.to.y));
    e.peak_velocity_deg_s = static_cast<float>(peak_velocity_);
  }
  const auto n = protocol::degrees_to_normalized(options_.display, Degrees{c.x, c.y});
  e.centroid_x = static_cast<float>(n.x);
  e.centroid_y = static_cast<float>(n.y);
  e.centroid_x_deg = static_cast<float>(c.x);
  e.centroid_y_deg = static_cast<float>(c.y);
  return e;
}

void SyntheticGaze::start_segment(Segment s, std::int64_t t_ns) {
  segment_ = std::move(s);
  if (segment_.phase == Phase::Saccade) {
    saccade_ended_ = false;
    pupil_motion_ = PupilMotion::None;
    const double a = std::hypot(segment_.to.x - segment_.from.x, segment_.to.y - segment_.from.y);
    saccade_dir_ = a > 0 ? Vec2{(segment_.to.x - segment_.from.x) / a, (segment_.to.y - segment_.from.y) / a} : Vec2{};
  }
  segment_start_ns_ = t_ns;
  drift_ = {};
  sum_pos_ = {};
  sum_count_ = 0;
  peak_velocity_ = 0;
  pending_.push_back(make_event(EventPhase::Start, t_ns));
}

void SyntheticGaze::end_segment(std::int64_t t_ns) {
  if (segment_.phase == Phase::Saccade) saccade_ended_ = true;
  segment_.to = segment_.phase == Phase::Fixation || segment_.phase == Phase::Blink
                    ? Vec2{segment_.from.x + drift_.x, segment_.from.y + drift_.y}
                    : segment_.to;
  pending_.push_back(make_event(EventPhase::End, t_ns));
}

void SyntheticGaze::step() {
  const double dt = 1.0 / options_.rate_hz;
  const auto t_ns = options_.start_time_ns +
                    static_cast<std::int64_t>(std::llround(static_cast<double>(sample_index_) * 1e9 * dt));
  ++sample_index_;

  if (options_.post_saccadic_oscillations) move_pupil_to(t_ns);
  const double t = advance_segments_to(t_ns);
  const Vec2 eye = true_eye_position(t, t_ns, dt);
  const double velocity = track_true_eye(eye, dt);
  update_pso_truth(t);
  // What the tracker sees is the pupil, which rings inside the iris after a saccade (the eye
  // cameras' pupil and pupil-glint vector too: the glint moves with the eyeball's cornea).
  const Vec2 offset = pupil_offset();
  const Vec2 tracked{eye.x + offset.x, eye.y + offset.y};
  GazeSample s = measured_sample(t_ns, tracked, velocity);
  add_pupil_and_eye_cameras(s, tracked, dt, t);
  if (options_.binocular) add_eye_gaze(s);
  pending_.push_back(s);
}

// Bouzat et al. 2018's Eq. 2 in absolute coordinates, p'' = -k (p - x) - gamma (p' - x'), with x the
// eyeball's position (the planned path plus its drift so far, continuous across segments): steps the
// pupil from the last sample to t_ns, moving the segments on as it goes (the same segments and
// events, in the same order, as advance_segments_to(t_ns) alone).
void SyntheticGaze::move_pupil_to(std::int64_t t_ns) {
  const auto eyeball_at = [&](std::int64_t when_ns) {
    const double t = advance_segments_to(when_ns);
    const Vec2 p = position_in_segment(t);
    return Vec2{p.x + drift_.x, p.y + drift_.y};
  };
  if (!have_pupil_) {
    eyeball_ = pupil_ = eyeball_at(t_ns);
    pupil_ns_ = t_ns;
    have_pupil_ = true;
    return;
  }
  while (pupil_ns_ < t_ns) {
    const std::int64_t step_ns = std::min(kPupilStepNs, t_ns - pupil_ns_);
    const double h = static_cast<double>(step_ns) * 1e-9;
    pupil_ns_ += step_ns;
    const Vec2 x = eyeball_at(pupil_ns_);
    eyeball_v_ = {(x.x - eyeball_.x) / h, (x.y - eyeball_.y) / h};
    eyeball_ = x;
    // Semi-implicit Euler: the velocity first, then the position with the new velocity.
    pupil_v_.x += h * (-kPupilStiffness * (pupil_.x - x.x) - kPupilDamping * (pupil_v_.x - eyeball_v_.x));
    pupil_v_.y += h * (-kPupilStiffness * (pupil_.y - x.y) - kPupilDamping * (pupil_v_.y - eyeball_v_.y));
    pupil_.x += h * pupil_v_.x;
    pupil_.y += h * pupil_v_.y;
  }
}

// Where the tracked pupil is relative to the eyeball, deg (zero without post_saccadic_oscillations).
SyntheticGaze::Vec2 SyntheticGaze::pupil_offset() const {
  if (!have_pupil_) return {};
  return {pupil_.x - eyeball_.x, pupil_.y - eyeball_.y};
}

// Past the eyeball's peak velocity (half-way through its saccade), the saccade lasts, in the truth,
// while the tracked pupil still moves on in its direction at kPsoEndDegS or more: Schweitzer &
// Rolfs's signed criterion, so a sampled speed cannot step over the zero at the turn. The pupil may
// turn before the eyeball stops (it runs ahead while the eyeball decelerates) or after (the tail,
// judged relative to the eyeball, which may pursue on).
// Then the PSO, while the oscillation's velocity envelope, sqrt(v^2 + k y^2) for the pupil's offset
// y and relative velocity v, exceeds kPsoEndDegS; the next saccade ends it.
void SyntheticGaze::update_pso_truth(double t) {
  const bool saccade = segment_.phase == Phase::Saccade;
  if (!options_.post_saccadic_oscillations || (!saccade && !saccade_ended_)) {
    pupil_motion_ = PupilMotion::None;
    return;
  }
  const Vec2 v{pupil_v_.x - eyeball_v_.x, pupil_v_.y - eyeball_v_.y};  // relative to the eyeball
  if (pupil_motion_ != PupilMotion::Oscillation) {
    const bool past_peak = !saccade || t >= segment_.duration_s / 2;
    // After the eyeball's saccade, relative to the eyeball (which may pursue on in that direction).
    const Vec2 moving = saccade ? pupil_v_ : v;
    const double forward = moving.x * saccade_dir_.x + moving.y * saccade_dir_.y;
    if (!past_peak || forward >= kPsoEndDegS) {
      pupil_motion_ = saccade ? PupilMotion::None : PupilMotion::SaccadeTail;
      return;
    }
  }
  const Vec2 y = pupil_offset();
  const double envelope = std::sqrt(v.x * v.x + v.y * v.y + kPupilStiffness * (y.x * y.x + y.y * y.y));
  pupil_motion_ = envelope > kPsoEndDegS ? PupilMotion::Oscillation : PupilMotion::None;
  if (pupil_motion_ == PupilMotion::None) saccade_ended_ = false;
}

// Ends every segment that is over by t_ns and plans the next; returns t_ns's time into the current one, s.
double SyntheticGaze::advance_segments_to(std::int64_t t_ns) {
  double t = static_cast<double>(t_ns - segment_start_ns_) * 1e-9;
  while (t >= segment_.duration_s) {
    const std::int64_t end_ns = segment_start_ns_ + static_cast<std::int64_t>(std::llround(segment_.duration_s * 1e9));
    end_segment(end_ns);
    const Segment finished = segment_;
    start_segment(plan_after(finished), end_ns);
    t = static_cast<double>(t_ns - segment_start_ns_) * 1e-9;
  }
  return t;
}

// Fixational eye movements: slow drift (random walk, ~0.1 deg/s^0.5) and tremor (~90 Hz, a few
// arc seconds, far below tracker noise but present).
SyntheticGaze::Vec2 SyntheticGaze::true_eye_position(double t, std::int64_t t_ns, double dt) {
  if (segment_.phase == Phase::Fixation) {
    const double drift_sigma = 0.1 * std::sqrt(dt);
    drift_.x += drift_sigma * gauss_(rng_);
    drift_.y += drift_sigma * gauss_(rng_);
  }
  Vec2 eye = position_in_segment(t);
  eye.x += drift_.x;
  eye.y += drift_.y;
  const double tremor = 0.003 * std::sin(2 * kPi * 90 * static_cast<double>(t_ns) * 1e-9);
  eye.x += tremor;
  return eye;
}

// The noise-free angular velocity, deg/s, and the segment's running peak velocity and centroid
// that its End event reports.
double SyntheticGaze::track_true_eye(const Vec2& eye, double dt) {
  double velocity = 0;
  if (have_last_) velocity = angle_between_deg(last_true_.x, last_true_.y, eye.x, eye.y) / dt;
  last_true_ = eye;
  have_last_ = true;
  peak_velocity_ = std::max(peak_velocity_, velocity);
  sum_pos_.x += eye.x;
  sum_pos_.y += eye.y;
  ++sum_count_;
  return velocity;
}

// The tracker's gaze estimate: the tracked position (the eye, or the pupil with
// post_saccadic_oscillations) plus noise, doubled during saccades, labelled with the movement that
// produced it.
GazeSample SyntheticGaze::measured_sample(std::int64_t t_ns, const Vec2& tracked, double velocity) {
  GazeSample s;
  s.tracker_time_ns = t_ns;
  const double noise = segment_.phase == Phase::Saccade ? 2 * options_.noise_deg : options_.noise_deg;
  double nx = gauss_(rng_), ny = gauss_(rng_);
  if (noise_x_) {
    nx = noise_x_->next(nx);
    ny = noise_y_->next(ny);
  }
  const Vec2 measured{tracked.x + noise * nx, tracked.y + noise * ny};
  const auto n = protocol::degrees_to_normalized(options_.display, Degrees{measured.x, measured.y});
  s.x = static_cast<float>(n.x);
  s.y = static_cast<float>(n.y);
  s.x_deg = static_cast<float>(measured.x);
  s.y_deg = static_cast<float>(measured.y);
  s.angular_velocity_deg_s = static_cast<float>(velocity);
  switch (segment_.phase) {
    case Phase::Fixation: s.state = EyeMovement::Fixation; break;
    case Phase::Saccade: s.state = EyeMovement::Saccade; break;
    case Phase::Pursuit: s.state = EyeMovement::Pursuit; break;
    case Phase::Blink: s.state = EyeMovement::Blink; break;
  }
  return s;
}

// Validity, confidence and per-eye data; a blink invalidates the samples in which the lid covers the
// pupil. The pupil and confidence draws happen during blinks too, so the random sequence does not
// depend on them.
void SyntheticGaze::add_pupil_and_eye_cameras(GazeSample& s, const Vec2& eye, double dt, double t) {
  const bool blinking = segment_.phase == Phase::Blink && t >= segment_.covered_from_s && t < segment_.covered_to_s;
  // Pupil diameter wanders slowly between about 3 and 4.4 mm (hippus and luminance changes).
  pupil_phase_ += dt * 2 * kPi * 0.1;
  const double pupil_mm = 3.7 + 0.5 * std::sin(pupil_phase_) + 0.05 * gauss_(rng_);
  const double confidence = std::clamp((segment_.phase == Phase::Saccade ? 0.8 : 0.97) + 0.02 * gauss_(rng_), 0.0, 1.0);
  if (blinking) {
    s.flags = 0;
    s.confidence = 0;
    s.left = {};
    s.right = {};
  } else {
    s.flags = protocol::kGazeValid;
    s.confidence = static_cast<float>(confidence);
    s.left = eye_camera_data(eye, pupil_mm, +3.0);
    s.right = eye_camera_data(eye, pupil_mm, -3.0);
  }
}

// Each eye's point: the sample's point -/+ an independent offset per axis (left -, right +), drawn
// for every sample (blinks too) so the stream does not depend on validity.
void SyntheticGaze::add_eye_gaze(GazeSample& s) {
  std::normal_distribution<double> unit(0.0, 1.0);  // scaled below: noise_deg may be 0
  const Vec2 d{options_.noise_deg * unit(eye_rng_), options_.noise_deg * unit(eye_rng_)};
  if ((s.flags & protocol::kGazeValid) == 0) return;
  const auto eye = [&](double sign) {
    const Degrees deg{static_cast<double>(s.x_deg) + sign * d.x, static_cast<double>(s.y_deg) + sign * d.y};
    const auto n = protocol::degrees_to_normalized(options_.display, deg);
    return protocol::EyeGaze{protocol::kEyeGazeValid, static_cast<float>(n.x), static_cast<float>(n.y),
                             static_cast<float>(deg.x), static_cast<float>(deg.y)};
  };
  s.left_gaze = eye(-1);
  s.right_gaze = eye(+1);
}

// A 640x480 eye camera per eye; the pupil moves ~4 px per degree and the pupil-glint vector
// ~0.9 px per degree, roughly linear in gaze angle as in video trackers.
protocol::EyeData SyntheticGaze::eye_camera_data(const Vec2& eye, double pupil_mm, double vergence_px) {
  protocol::EyeData e;
  e.flags = protocol::kEyePupilValid | protocol::kEyeGlintValid;
  e.pupil_x_px = static_cast<float>(320 + 4.0 * eye.x + vergence_px + 0.3 * gauss_(rng_));
  e.pupil_y_px = static_cast<float>(240 + 4.0 * eye.y + 0.3 * gauss_(rng_));
  e.pupil_diameter_mm = static_cast<float>(std::max(0.5, pupil_mm));
  e.pupil_glint_x_px = static_cast<float>(0.9 * eye.x + 0.05 * gauss_(rng_));
  e.pupil_glint_y_px = static_cast<float>(0.9 * eye.y + 0.05 * gauss_(rng_));
  return e;
}

std::optional<GazeItem> SyntheticGaze::next() {
  if (pending_.empty()) step();
  GazeItem item = pending_.front();
  pending_.pop_front();
  return item;
}

}  // namespace fovea::trackerd
