// SPDX-License-Identifier: Apache-2.0
#include "sim/synthetic_eye_frames.h"

#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "sim/calibration_viewer.h"
#include "fovea/protocol/clock.h"

namespace fovea::trackerd::eye {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

void sleep_until(std::int64_t t_ns) {
  const timespec ts{static_cast<time_t>(t_ns / 1'000'000'000), static_cast<long>(t_ns % 1'000'000'000)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

}  // namespace

// The eye looks from (0, 0, 0) at the screen point (ox, oy, d) (x right, y down, z towards the
// screen), ox = d tan(x_deg), oy = d tan(y_deg) (protocol::normalized_to_degrees: theta = atan(offset
// / d) per axis). SyntheticEye turns the optical axis first by yaw about the head's vertical axis,
// then by pitch about the turned horizontal axis (Fick gimbal): axis = (cos p sin y, sin p, cos p cos y).
EyeRotation screen_to_eye_rotation(const protocol::DisplayGeometry& display, protocol::Degrees gaze) {
  const double d = display.viewing_distance_m;
  const double ox = d * std::tan(gaze.x * kDeg), oy = d * std::tan(gaze.y * kDeg);
  return {std::atan2(ox, d) / kDeg, std::atan2(oy, std::hypot(ox, d)) / kDeg};
}

protocol::Degrees eye_rotation_to_screen(const protocol::DisplayGeometry& display, EyeRotation r) {
  (void)display;  // the angles do not depend on the distance: both are directions from the eye
  const double y = r.yaw_deg * kDeg, p = r.pitch_deg * kDeg;
  const double ax = std::cos(p) * std::sin(y), ay = std::sin(p), az = std::cos(p) * std::cos(y);
  return {std::atan2(ax, az) / kDeg, std::atan2(ay, az) / kDeg};
}

EyeRotation screen_to_eye_rotation(const protocol::DisplayGeometry& display, protocol::Degrees gaze,
                                   cv::Point3d head_offset_mm) {
  // The screen point in the calibration position's frame (mm), then seen from the displaced eye.
  const double d = display.viewing_distance_m * 1000.0;
  const double px = d * std::tan(gaze.x * kDeg) - head_offset_mm.x;
  const double py = d * std::tan(gaze.y * kDeg) - head_offset_mm.y;
  const double pz = d - head_offset_mm.z;
  return {std::atan2(px, pz) / kDeg, std::atan2(py, std::hypot(px, pz)) / kDeg};
}

SyntheticEyeOptions with_head_offset(SyntheticEyeOptions o, const protocol::DisplayGeometry& display,
                                     cv::Point3d offset) {
  for (const double c : {offset.x, offset.y, offset.z}) {
    if (!std::isfinite(c) || std::abs(c) > 250) {
      throw std::invalid_argument("head offset (" + std::to_string(offset.x) + ", " + std::to_string(offset.y) + ", " +
                                  std::to_string(offset.z) + ") mm: allowed finite, |each| <= 250");
    }
  }
  if (offset.x == 0 && offset.y == 0 && offset.z == 0) return o;
  const double d = display.viewing_distance_m * 1000.0;
  const cv::Point3d c = o.camera.position_mm;
  const double scale = std::sqrt(c.x * c.x + c.y * c.y + c.z * c.z) / d;
  o.camera.position_mm -= offset * scale;
  o.camera.look_at_mm -= offset * scale;
  return o;
}

SyntheticEyeOptions with_hard_conditions(SyntheticEyeOptions o) {
  o.noise_sigma = 10;
  o.motion_blur_px = 2;
  o.eyelid_cover = 0.3;
  o.glasses_reflection = true;
  o.illumination_gradient = 0.4;
  return o;
}

bool has_hard_conditions(const SyntheticEyeOptions& o) {
  const SyntheticEyeOptions h = with_hard_conditions(o);
  return o.noise_sigma == h.noise_sigma && o.motion_blur_px == h.motion_blur_px && o.eyelid_cover == h.eyelid_cover &&
         o.glasses_reflection == h.glasses_reflection && o.illumination_gradient == h.illumination_gradient;
}

namespace {
// Eye rotations looking at a grid x grid of screen points covering the screen, corners included.
std::vector<EyeRotation> screen_grid(const protocol::DisplayGeometry& display, int grid) {
  std::vector<EyeRotation> out;
  for (int i = 0; i < grid; ++i) {
    for (int j = 0; j < grid; ++j) {
      const protocol::Normalized n{static_cast<double>(i) / (grid - 1), static_cast<double>(j) / (grid - 1)};
      out.push_back(screen_to_eye_rotation(display, protocol::normalized_to_degrees(display, n)));
    }
  }
  return out;
}
}  // namespace

calib::Poly2Map fit_factory_map(const SyntheticEye& eye, const protocol::DisplayGeometry& display, int grid) {
  if (grid < 3) throw std::invalid_argument("factory calibration grid " + std::to_string(grid) + ": at least 3");
  std::vector<calib::Correspondence> points;
  for (const EyeRotation& r : screen_grid(display, grid)) {
    const EyeTruth t = eye.project(r.yaw_deg, r.pitch_deg, 1.0);
    if (t.closed) continue;
    points.push_back({{t.pupil_glint.x, t.pupil_glint.y}, {r.yaw_deg, r.pitch_deg}});
  }
  return calib::Poly2Map::fit(points);
}

PupilGlintMap factory_pupil_glint_map(const calib::Poly2Map& map, const protocol::DisplayGeometry& display) {
  PupilGlintMap m;
  m.description = "the synthetic eye's factory calibration (" + map.describe() + ", to eye rotation in degrees)";
  m.to_screen = [map, display](cv::Point2d v) {
    const calib::Point r = map.apply({v.x, v.y});
    // Beyond +-80 deg the rotation has no screen point worth reporting (and tan() runs away).
    if (!(std::abs(r.x) < 80 && std::abs(r.y) < 80)) {
      return protocol::Normalized{std::numeric_limits<double>::quiet_NaN(), 0.0};
    }
    return protocol::degrees_to_normalized(display, eye_rotation_to_screen(display, {r.x, r.y}));
  };
  return m;
}

double factory_blink_aspect(const SyntheticEye& eye, const protocol::DisplayGeometry& display) {
  double flattest = 1;
  for (const EyeRotation& r : screen_grid(display, 9)) {
    const EyeTruth t = eye.project(r.yaw_deg, r.pitch_deg, 1.0);
    if (!t.closed && t.pupil.major > 0) flattest = std::min(flattest, t.pupil.aspect());
  }
  return std::min(0.7, 0.9 * flattest);
}

double pupil_mm_per_px(const SyntheticEye& eye) {
  const EyeTruth t = eye.project(0, 0, 1.0);
  if (t.closed || !(t.pupil.major > 0) || !(t.pupil_radius_mm > 0)) return 0;
  const double s = 2 * t.pupil_radius_mm / t.pupil.major;
  return std::isfinite(s) ? s : 0.0;
}

// ---- motion ----------------------------------------------------------------------------------

namespace {
SyntheticGazeOptions viewer_options(double rate_hz, std::uint64_t seed, const protocol::DisplayGeometry& display,
                                    std::int64_t start_time_ns) {
  SyntheticGazeOptions o;
  o.rate_hz = rate_hz;
  o.seed = seed;
  o.display = display;
  o.start_time_ns = start_time_ns;
  o.noise_deg = 0;  // the eye's true gaze: tracker noise comes from the images and the detector
  return o;
}
}  // namespace

SyntheticEyeMotion::SyntheticEyeMotion(double rate_hz, std::uint64_t seed, const protocol::DisplayGeometry& display,
                                       std::int64_t start_time_ns, double lid_transition_s)
    : display_(display),
      gaze_(viewer_options(rate_hz, seed, display, start_time_ns)),
      lid_ns_(std::max<std::int64_t>(0, std::llround(lid_transition_s * 1e9))) {}

void SyntheticEyeMotion::fill(std::int64_t until_ns) {
  while (ahead_.empty() || ahead_.back().time_ns < until_ns) {
    const std::optional<GazeItem> item = gaze_.next();
    if (!item) return;  // never: the synthetic viewer does not end
    const auto* s = std::get_if<protocol::GazeSample>(&*item);
    if (s == nullptr) continue;  // its events are not needed here
    Ahead a;
    a.time_ns = s->tracker_time_ns;
    a.deg = {s->x_deg, s->y_deg};
    a.norm = {s->x, s->y};
    a.blink = s->state == protocol::EyeMovement::Blink;
    ahead_.push_back(a);
  }
}

SyntheticEyeFrameTruth SyntheticEyeMotion::next() {
  if (ahead_.empty()) fill(INT64_MIN);
  fill(ahead_.front().time_ns + lid_ns_);
  const Ahead now = ahead_.front();
  ahead_.pop_front();

  SyntheticEyeFrameTruth t;
  t.time_ns = now.time_ns;
  t.sequence = sequence_++;
  t.gaze_deg = now.deg;
  t.gaze = now.norm;
  t.rotation = screen_to_eye_rotation(display_, now.deg);
  t.blink = now.blink;
  if (now.blink) {
    last_blink_ns_ = now.time_ns;
    t.openness = 0;
  } else if (lid_ns_ > 0) {
    // Lids close over lid_ns_ before a blink and open over lid_ns_ after it.
    std::int64_t distance = INT64_MAX;
    if (last_blink_ns_ != INT64_MIN) distance = now.time_ns - last_blink_ns_;
    for (const Ahead& a : ahead_) {
      if (a.time_ns - now.time_ns >= distance) break;
      if (a.blink) {
        distance = a.time_ns - now.time_ns;
        break;
      }
    }
    t.openness = distance >= lid_ns_ ? 1.0 : static_cast<double>(distance) / static_cast<double>(lid_ns_);
  }
  return t;
}

// ---- frames ----------------------------------------------------------------------------------

namespace {
SyntheticEyeFramesOptions checked(SyntheticEyeFramesOptions o) {
  if (!(o.rate_hz >= 1 && o.rate_hz <= 1000)) {
    throw std::invalid_argument("synthetic-eye: rate " + std::to_string(o.rate_hz) + " Hz is outside 1..1000");
  }
  if (o.eye.width < 32 || o.eye.height < 32 || o.eye.width > 4096 || o.eye.height > 4096) {
    throw std::invalid_argument("synthetic-eye: image size " + std::to_string(o.eye.width) + "x" +
                                std::to_string(o.eye.height) + " is outside 32x32..4096x4096");
  }
  return o;
}
}  // namespace

SyntheticEyeFrames::SyntheticEyeFrames(SyntheticEyeFramesOptions options)
    : options_(checked(std::move(options))),
      eye_(with_head_offset(options_.eye, options_.display, options_.head_offset_mm)),
      // The factory calibration and blink threshold belong to the tracker at its calibration
      // position (the nominal eye), whatever the head offset.
      factory_map_(fit_factory_map(SyntheticEye(options_.eye), options_.display)),
      blink_aspect_(factory_blink_aspect(SyntheticEye(options_.eye), options_.display)),
      mm_per_px_(pupil_mm_per_px(SyntheticEye(options_.eye))) {
  if (options_.calibration_script) {
    schedule_ = calib::make_schedule(options_.display.width_px, options_.display.height_px,
                                     *options_.calibration_script);
    TargetFollowingOptions to;
    to.rate_hz = options_.rate_hz;
    to.seed = options_.eye.seed;
    to.display = options_.display;
    to.start_time_ns = 0;
    to.lid_transition_s = options_.lid_transition_s;
    to.head_offset_mm = options_.head_offset_mm;
    to.fixation_bias_deg = options_.fixation_bias_deg;
    script_ = std::make_unique<TargetFollowingMotion>(schedule_, to);
  } else {
    motion_ = std::make_unique<SyntheticEyeMotion>(options_.rate_hz, options_.eye.seed, options_.display, 0,
                                                   options_.lid_transition_s);
  }
  char buf[160];
  std::snprintf(buf, sizeof buf, "synthetic-eye %dx%d %.0f Hz (seed %llu, %zu LEDs%s)", options_.eye.width,
                options_.eye.height, options_.rate_hz, static_cast<unsigned long long>(options_.eye.seed),
                options_.eye.leds.positions_mm.size(), has_hard_conditions(options_.eye) ? ", hard" : "");
  status_.description = buf;
}

SyntheticEyeFrames::~SyntheticEyeFrames() = default;

SyntheticEyeFrameTruth SyntheticEyeFrames::next_truth() {
  if (script_) return script_->next();
  SyntheticEyeFrameTruth t = motion_->next();
  const cv::Point3d& o = options_.head_offset_mm;
  if (o.x != 0 || o.y != 0 || o.z != 0) t.rotation = screen_to_eye_rotation(options_.display, t.gaze_deg, o);
  return t;
}

FrameSourceStatus SyntheticEyeFrames::status() const {
  std::lock_guard lock(status_mutex_);
  return status_;
}

std::optional<EyeFrame> SyntheticEyeFrames::next(int timeout_ms) {
  if (!origin_ns_) origin_ns_ = options_.start_time_ns.value_or(protocol::monotonic_ns());
  // The same times as the viewer's samples (SyntheticGaze::step), offset to the origin.
  const auto due_of = [&](std::uint64_t k) {
    return *origin_ns_ + std::llround(static_cast<double>(k) * 1e9 / options_.rate_hz);
  };
  std::uint64_t skipped = 0;
  if (options_.realtime) {
    const std::int64_t now = protocol::monotonic_ns();
    const auto period_ns = static_cast<std::int64_t>(1e9 / options_.rate_hz);
    // Behind by more than two periods: skip to the newest frame, as a camera drops frames.
    while (now - due_of(index_) > 2 * period_ns) {
      (void)next_truth();
      ++index_;
      ++skipped;
    }
    const std::int64_t due = due_of(index_);
    if (due - now > std::int64_t{std::max(timeout_ms, 0)} * 1'000'000) {
      if (skipped > 0) {
        std::lock_guard lock(status_mutex_);
        status_.dropped += skipped;
      }
      sleep_until(now + std::int64_t{std::max(timeout_ms, 0)} * 1'000'000);
      return std::nullopt;
    }
    sleep_until(due);
  }
  truth_ = next_truth();
  ++index_;
  EyeFrame frame;
  frame.image = eye_.render(truth_.rotation.yaw_deg, truth_.rotation.pitch_deg, truth_.openness, &render_truth_);
  truth_.time_ns += *origin_ns_;
  frame.time_ns = truth_.time_ns;
  frame.sequence = truth_.sequence;
  std::lock_guard lock(status_mutex_);
  ++status_.frames;
  status_.dropped += skipped;
  return frame;
}

}  // namespace fovea::trackerd::eye
