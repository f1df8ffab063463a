// SPDX-License-Identifier: Apache-2.0
#include "gaze_samples.h"
#include "sim/calibration_viewer.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <utility>
#include <variant>

#include "classify_stage.h"
#include "service/config.h"
#include "sim/synthetic_gaze.h"

namespace fovea::trackerd::eye {

namespace {

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

void check_range(const char* name, double v, double lo, double hi) {
  if (!std::isfinite(v) || v < lo || v > hi) {
    throw std::invalid_argument(std::string("TargetFollowingOptions.") + name + " = " + num(v) + ": allowed " +
                                num(lo) + ".." + num(hi));
  }
}

// Minimum-jerk position profile (Flash & Hogan 1985): 0 -> 1 over tau in [0, 1].
double min_jerk(double tau) {
  tau = std::clamp(tau, 0.0, 1.0);
  return tau * tau * tau * (10 - 15 * tau + 6 * tau * tau);
}

protocol::Degrees lerp(protocol::Degrees a, protocol::Degrees b, double s) {
  return {a.x + (b.x - a.x) * s, a.y + (b.y - a.y) * s};
}

}  // namespace

void TargetFollowingOptions::check() const {
  check_range("rate_hz", rate_hz, 1, 10000);
  check_range("lid_transition_s", lid_transition_s, 0, 1);
  check_range("head_offset_mm.x", head_offset_mm.x, -250, 250);
  check_range("head_offset_mm.y", head_offset_mm.y, -250, 250);
  check_range("head_offset_mm.z", head_offset_mm.z, -250, 250);
  check_range("fixation_bias_deg.x", fixation_bias_deg.x, -5, 5);
  check_range("fixation_bias_deg.y", fixation_bias_deg.y, -5, 5);
  check_range("reaction_min_s", reaction_min_s, 0, 2);
  check_range("reaction_max_s", reaction_max_s, reaction_min_s, 2);
  check_range("undershoot_min", undershoot_min, 0, 0.5);
  check_range("undershoot_max", undershoot_max, undershoot_min, 0.5);
  check_range("correction_delay_min_s", correction_delay_min_s, 0, 2);
  check_range("correction_delay_max_s", correction_delay_max_s, correction_delay_min_s, 2);
  check_range("jitter_rms_deg", jitter_rms_deg, 0, 2);
  check_range("microsaccade_rate_hz", microsaccade_rate_hz, 0, 10);
  check_range("blink_interval_min_s", blink_interval_min_s, 0.5, 3600);
  check_range("blink_interval_max_s", blink_interval_max_s, blink_interval_min_s, 3600);
  check_range("blink_duration_s", blink_duration_s, 0, 0.45 * blink_interval_min_s);
}

// splitmix64, as the synthetic eye uses: the same numbers on every platform.
std::uint64_t TargetFollowingMotion::Rng::next() {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
double TargetFollowingMotion::Rng::uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
double TargetFollowingMotion::Rng::normal() {  // Box-Muller (one of the pair)
  const double u1 = 1.0 - uniform(), u2 = uniform();
  return std::sqrt(-2 * std::log(u1)) * std::cos(2 * std::numbers::pi * u2);
}

TargetFollowingMotion::TargetFollowingMotion(std::vector<calib::ScheduledTarget> schedule,
                                             TargetFollowingOptions options)
    : schedule_(std::move(schedule)),
      options_(std::move(options)),
      jitter_rng_{options_.seed * 0x2545F4914F6CDD1Dull ^ 0xCA11B8A7E5ull},
      blink_rng_{options_.seed * 0x9E3779B97F4A7C15ull ^ 0xB11A4Bull} {
  options_.check();
  if (const std::string problem = protocol::validate(options_.display); !problem.empty()) {
    throw std::invalid_argument("TargetFollowingOptions.display: " + problem);
  }
  std::stable_sort(schedule_.begin(), schedule_.end(),
                   [](const auto& a, const auto& b) { return a.onset_s < b.onset_s; });
  Rng plan{options_.seed ^ 0x7A56E7F011ull};
  const protocol::Degrees bias = options_.fixation_bias_deg;
  centre_ = {bias.x, bias.y};
  protocol::Degrees at = centre_;
  double free_from = 0;  // the eye is busy (saccading) until then
  const auto saccade_to = [&](protocol::Degrees goal, double start, int target) {
    start = std::max(start, free_from);
    const double amplitude = protocol::angle_between_deg(at, goal);
    if (!(amplitude > 1e-9)) return;
    // Primary saccade, undershooting, then the correction (skipped for tiny saccades).
    const double under = amplitude > 1.0 ? plan.uniform(options_.undershoot_min, options_.undershoot_max) : 0.0;
    const double delay = plan.uniform(options_.correction_delay_min_s, options_.correction_delay_max_s);
    PlannedSaccade p;
    p.start_s = start;
    p.from = at;
    p.to = lerp(at, goal, 1.0 - under);
    p.amplitude_deg = protocol::angle_between_deg(p.from, p.to);
    p.duration_s = saccade_duration_s(p.amplitude_deg);
    p.target = target;
    saccades_.push_back(p);
    at = p.to;
    free_from = p.start_s + p.duration_s;
    if (under > 0) {
      PlannedSaccade c;
      c.start_s = free_from + delay;
      c.from = at;
      c.to = goal;
      c.amplitude_deg = protocol::angle_between_deg(c.from, c.to);
      c.duration_s = saccade_duration_s(c.amplitude_deg);
      c.corrective = true;
      c.target = target;
      saccades_.push_back(c);
      at = goal;
      free_from = c.start_s + c.duration_s;
    }
  };
  const protocol::DisplayGeometry& d = options_.display;
  for (const calib::ScheduledTarget& t : schedule_) {
    const protocol::Normalized n{t.position_px.x / static_cast<double>(d.width_px),
                                 t.position_px.y / static_cast<double>(d.height_px)};
    const protocol::Degrees deg = protocol::normalized_to_degrees(d, n);
    saccade_to({deg.x + bias.x, deg.y + bias.y}, t.onset_s + plan.uniform(options_.reaction_min_s, options_.reaction_max_s),
               t.index);
  }
  if (!schedule_.empty()) {
    saccade_to(centre_, calib::schedule_end_s(schedule_) + plan.uniform(options_.reaction_min_s, options_.reaction_max_s),
               -1);
  }
  // The first blink: somewhere in the first interval.
  blink_start_s_ = blink_rng_.uniform(0.3 * options_.blink_interval_min_s, options_.blink_interval_max_s);
  blink_end_s_ = blink_start_s_ + options_.blink_duration_s;
}

double TargetFollowingMotion::settled_at_centre_s() const {
  return saccades_.empty() ? 0.0 : saccades_.back().start_s + saccades_.back().duration_s;
}

protocol::Degrees TargetFollowingMotion::aimed(double t) const {
  protocol::Degrees pos = centre_;
  for (const PlannedSaccade& s : saccades_) {
    if (t < s.start_s) break;
    if (t >= s.start_s + s.duration_s) {
      pos = s.to;
      continue;
    }
    return lerp(s.from, s.to, min_jerk((t - s.start_s) / s.duration_s));
  }
  return pos;
}

SyntheticEyeFrameTruth TargetFollowingMotion::next() {
  const std::uint64_t k = k_++;
  const double rate = options_.rate_hz;
  const double t = static_cast<double>(k) / rate, dt = 1.0 / rate;

  // Fixation jitter: OU drift (tau 0.4 s) + white tremor; 0.9 of the per-axis SD is drift.
  const double axis_sd = options_.jitter_rms_deg / std::sqrt(2.0);
  const double drift_sd = 0.9 * axis_sd, tremor_sd = std::sqrt(1 - 0.81) * axis_sd;
  const double a = std::exp(-dt / 0.4), kick = drift_sd * std::sqrt(1 - a * a);
  const double nx = jitter_rng_.normal(), ny = jitter_rng_.normal();
  const double tx = jitter_rng_.normal(), ty = jitter_rng_.normal();
  const double u_micro = jitter_rng_.uniform();
  if (in_micro_) {
    const double tau = (t - micro_start_s_) / micro_dur_s_;
    const double s = min_jerk(tau);
    drift_x_ = micro_from_x_ + (micro_to_x_ - micro_from_x_) * s;
    drift_y_ = micro_from_y_ + (micro_to_y_ - micro_from_y_) * s;
    if (tau >= 1) in_micro_ = false;
  } else {
    drift_x_ = drift_x_ * a + kick * nx;
    drift_y_ = drift_y_ * a + kick * ny;
    if (u_micro < options_.microsaccade_rate_hz * dt && drift_sd > 0) {
      // Back towards the point fixated: amplitude = the drift so far (plus a little overshoot).
      in_micro_ = true;
      micro_start_s_ = t;
      micro_from_x_ = drift_x_;
      micro_from_y_ = drift_y_;
      micro_to_x_ = -0.2 * drift_x_ + 0.3 * drift_sd * tx;
      micro_to_y_ = -0.2 * drift_y_ + 0.3 * drift_sd * ty;
      micro_dur_s_ = saccade_duration_s(std::hypot(micro_to_x_ - micro_from_x_, micro_to_y_ - micro_from_y_));
    }
  }
  const protocol::Degrees base = aimed(t);
  protocol::Degrees g{base.x + drift_x_ + (in_micro_ ? 0.0 : tremor_sd * tx),
                      base.y + drift_y_ + (in_micro_ ? 0.0 : tremor_sd * ty)};

  // Blinks.
  while (t >= blink_end_s_) {
    prev_blink_end_s_ = blink_end_s_;
    blink_start_s_ += blink_rng_.uniform(options_.blink_interval_min_s, options_.blink_interval_max_s);
    blink_end_s_ = blink_start_s_ + options_.blink_duration_s;
  }
  SyntheticEyeFrameTruth out;
  out.blink = t >= blink_start_s_ && t < blink_end_s_;
  if (out.blink) {
    out.openness = 0;
  } else if (options_.lid_transition_s > 0) {
    const double distance = std::min(blink_start_s_ - t, t - prev_blink_end_s_);
    out.openness = std::clamp(distance / options_.lid_transition_s, 0.0, 1.0);
  }
  out.time_ns = options_.start_time_ns + std::llround(static_cast<double>(k) * 1e9 / rate);
  out.sequence = k;
  out.gaze_deg = g;
  out.gaze = protocol::degrees_to_normalized(options_.display, g);
  const cv::Point3d& o = options_.head_offset_mm;
  out.rotation = (o.x == 0 && o.y == 0 && o.z == 0) ? screen_to_eye_rotation(options_.display, g)
                                                    : screen_to_eye_rotation(options_.display, g, o);
  return out;
}

// ---- session ---------------------------------------------------------------------------------

CalibrationSession simulate_calibration_session(const CalibrationSessionOptions& o) {
  if (!(o.tail_s >= 0 && o.tail_s <= 60)) throw std::invalid_argument("tail_s " + num(o.tail_s) + ": allowed 0..60");
  SyntheticEyeFramesOptions fo;
  fo.eye = o.eye;
  fo.rate_hz = o.rate_hz;
  fo.display = o.display;
  fo.start_time_ns = o.start_time_ns;
  fo.realtime = false;
  fo.calibration_script = o.schedule;
  fo.head_offset_mm = o.head_offset_mm;
  fo.fixation_bias_deg = o.fixation_bias_deg;
  auto frames = std::make_unique<SyntheticEyeFrames>(fo);
  SyntheticEyeFrames* fp = frames.get();

  // As the daemon builds it (daemon.cpp make_source, synthetic-eye) from the default [eye] config.
  const service::EyeConfig defaults;
  EyePipelineOptions po;
  po.detector.coarse_downscale = defaults.pupil_downscale;
  po.detector.roi_tracking = defaults.pupil_roi;
  po.detector.leds = fo.eye.leds;
  po.eye = parse_eye_side(defaults.side);
  po.display = o.display;
  po.nominal_rate_hz = o.rate_hz;
  po.mm_per_px = fp->mm_per_px();
  po.map = fp->pupil_glint_map();
  po.detector.blink_aspect = fp->blink_aspect();

  CalibrationSession out;
  out.factory_blink_aspect = fp->blink_aspect();
  const std::vector<calib::ScheduledTarget> schedule = fp->schedule();
  out.session_s = calib::schedule_end_s(schedule);
  out.targets = calib::place_schedule(schedule, o.start_time_ns);
  EyePipelineSource source(std::move(frames), std::move(po));
  out.source_description = source.description();
  ClassifyStage stage(o.classifier_method, o.rate_hz, o.display);
  out.classifier_description = stage.description();

  const auto n = static_cast<std::uint64_t>(std::ceil((out.session_s + o.tail_s) * o.rate_hz));
  std::vector<GazeItem> staged;
  for (std::uint64_t i = 0; i < n;) {
    const std::optional<GazeItem> item = source.next();
    if (!item) {
      if (source.ended()) break;
      continue;
    }
    if (std::holds_alternative<protocol::GazeSample>(*item)) {
      out.truth.push_back(fp->last_truth());
      ++i;
    }
    staged.clear();
    stage.process(*item, staged);
    for (GazeItem& g : staged) out.published.push_back(std::move(g));
  }
  staged.clear();
  stage.flush(staged);
  for (GazeItem& g : staged) out.published.push_back(std::move(g));
  for (const GazeItem& g : out.published) {
    if (const auto* s = std::get_if<protocol::GazeSample>(&g)) out.samples.push_back(*s);
    if (const auto* e = std::get_if<protocol::GazeEvent>(&g)) out.events.push_back(*e);
  }
  return out;
}

const char* to_string(CalibrationInput input) {
  return input == CalibrationInput::PupilGlint ? "pupil-glint" : "screen";
}

std::vector<calib::RawSample> raw_samples(std::span<const protocol::GazeSample> samples, CalibrationInput input,
                                          const protocol::DisplayGeometry& display, EyeSide eye) {
  return calib::to_raw_samples(
      samples, input == CalibrationInput::PupilGlint ? calib::GazeInput::PupilGlint : calib::GazeInput::Screen,
      eye == EyeSide::Left, display);
}

cv::Point3d parse_head_offset(const std::string& text) {
  double v[3] = {0, 0, 0};
  std::size_t pos = 0;
  const auto bad = [&](const std::string& why) {
    return std::invalid_argument("head offset \"" + text + "\": " + why +
                                 "; expected X,Y,Z in millimetres (x right, y down, z towards the screen), each "
                                 "-250..250, e.g. 25,-15,40");
  };
  for (int i = 0; i < 3; ++i) {
    const std::size_t end = text.find(',', pos);
    if ((i < 2) != (end != std::string::npos)) throw bad("not three comma-separated numbers");
    const std::string part = text.substr(pos, end == std::string::npos ? std::string::npos : end - pos);
    const auto r = std::from_chars(part.data(), part.data() + part.size(), v[i]);
    if (part.empty() || r.ec != std::errc{} || r.ptr != part.data() + part.size()) {
      throw bad("\"" + part + "\" is not a number");
    }
    if (!std::isfinite(v[i]) || std::abs(v[i]) > 250) throw bad("\"" + part + "\" is out of range");
    pos = end + 1;
  }
  return {v[0], v[1], v[2]};
}

}  // namespace fovea::trackerd::eye
