// SPDX-License-Identifier: Apache-2.0
#include "eye/eye_source.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "fovea/protocol/clock.h"
#include "fovea/protocol/viewer_feed.h"

namespace fovea::trackerd::eye {

using protocol::GazeSample;

EyeSide parse_eye_side(const std::string& text) {
  if (text == "left") return EyeSide::Left;
  if (text == "right") return EyeSide::Right;
  throw std::invalid_argument("eye \"" + text + "\": allowed left, right");
}

const char* to_string(EyeSide side) { return side == EyeSide::Left ? "left" : "right"; }

namespace {

DetectorSettings validated(DetectorSettings s) {
  s.validate();
  return s;
}

bool finite(cv::Point2d p) { return std::isfinite(p.x) && std::isfinite(p.y); }

}  // namespace

EyePipelineSource::EyePipelineSource(std::unique_ptr<FrameSource> frames, EyePipelineOptions options)
    : frames_(std::move(frames)), options_(std::move(options)), detector_(validated(options_.detector)) {
  if (!frames_) throw std::invalid_argument("eye pipeline: no frame source");
  description_ = frames_->status().description + ", " + to_string(options_.eye) + " eye";
  if (options_.map && options_.map->to_screen) {
    spdlog::info("{}: eye pipeline, gaze from the pupil-glint vector through {}", description_,
                 options_.map->description);
  } else {
    options_.map.reset();
    spdlog::warn("{}: eye pipeline runs and publishes pupil and glint data, but there is no calibration map from the "
                 "pupil-glint vector to the screen yet (calibration maps arrive with step 5): gaze stays invalid "
                 "(kGazeValid clear) until a calibration is loaded",
                 description_);
  }
}

std::optional<GazeItem> EyePipelineSource::next() {
  std::optional<EyeFrame> frame = frames_->next(100);
  if (!frame) return std::nullopt;
  const std::int64_t t0 = protocol::monotonic_ns();
  const EyeMeasurement m = detector_.detect(frame->image);
  const std::int64_t detect_ns = protocol::monotonic_ns() - t0;
  if (frames_out_ != nullptr && frames_out_->wants(frame->time_ns)) show(*frame, m, detect_ns);
  return to_sample(m, frame->time_ns);
}

// The frame and the detector's result, for viewers (PROTOCOL.md §17): what the sample carries, plus
// the ellipse, the glints and where the search looked.
void EyePipelineSource::show(const EyeFrame& frame, const EyeMeasurement& m, std::int64_t detect_ns) {
  const cv::Mat& image = frame.image;
  if (image.type() != CV_8UC1 || image.cols > 65535 || image.rows > 65535) return;
  protocol::EyeFrameInfo info;
  info.frame = counts_.frames;
  info.time_ns = frame.time_ns;
  info.detect_ns = static_cast<std::uint32_t>(std::clamp<std::int64_t>(detect_ns, 0, UINT32_MAX));
  info.source_width = static_cast<std::uint16_t>(image.cols);
  info.source_height = static_cast<std::uint16_t>(image.rows);
  const auto f = [](double v) { return std::isfinite(v) ? static_cast<float>(v) : 0.0f; };
  if (m.pupil_found) {
    info.flags |= protocol::kEyeFramePupil;
    info.pupil_x = f(m.pupil.centre.x);
    info.pupil_y = f(m.pupil.centre.y);
    info.pupil_major = f(m.pupil.major);
    info.pupil_minor = f(m.pupil.minor);
    info.pupil_angle_deg = f(m.pupil.angle_deg);
  }
  if (m.blink) info.flags |= protocol::kEyeFrameBlink;
  if (m.pupil_glint_valid) info.flags |= protocol::kEyeFrameGlint;
  if (m.used_roi) info.flags |= protocol::kEyeFrameRoi;
  info.confidence = f(std::clamp(m.confidence, 0.0, 1.0));
  info.roi_x = static_cast<float>(m.search_region.x);
  info.roi_y = static_cast<float>(m.search_region.y);
  info.roi_width = static_cast<float>(m.search_region.width);
  info.roi_height = static_cast<float>(m.search_region.height);
  for (const Glint& g : m.glints) {
    if (info.glint_count == protocol::kMaxEyeGlints) break;
    info.glint_x[info.glint_count] = f(g.centre.x);
    info.glint_y[info.glint_count] = f(g.centre.y);
    ++info.glint_count;
  }
  frames_out_->offer(info, image.ptr<std::uint8_t>(0), image.cols, image.rows, image.step[0]);
}

GazeSample EyePipelineSource::to_sample(const EyeMeasurement& m, std::int64_t time_ns) {
  GazeSample s;
  s.tracker_time_ns = time_ns;
  ++counts_.frames;
  if (m.blink) ++counts_.blinks;

  protocol::EyeData e;
  const bool pupil = m.pupil_found && !m.blink && finite(m.pupil.centre);
  if (pupil) {
    ++counts_.pupils;
    e.flags |= protocol::kEyePupilValid;
    e.pupil_x_px = static_cast<float>(m.pupil.centre.x);
    e.pupil_y_px = static_cast<float>(m.pupil.centre.y);
    const double diameter = options_.mm_per_px > 0 ? m.pupil.major * options_.mm_per_px : 0.0;
    const bool plausible = std::isfinite(diameter) && diameter > 0 && diameter < 100;
    e.pupil_diameter_mm = plausible ? static_cast<float>(diameter) : 0.0f;
    if (m.pupil_glint_valid && finite(m.pupil_glint)) {
      e.flags |= protocol::kEyeGlintValid;
      e.pupil_glint_x_px = static_cast<float>(m.pupil_glint.x);
      e.pupil_glint_y_px = static_cast<float>(m.pupil_glint.y);
    }
  }
  (options_.eye == EyeSide::Left ? s.left : s.right) = e;
  s.confidence = std::isfinite(m.confidence) ? static_cast<float>(std::clamp(m.confidence, 0.0, 1.0)) : 0.0f;
  s.state = m.blink ? protocol::EyeMovement::Blink : protocol::EyeMovement::Unknown;

  bool valid = false;
  protocol::Normalized n = hold_;
  if (options_.map && (e.flags & protocol::kEyeGlintValid) != 0) {
    const protocol::Normalized mapped = options_.map->to_screen(m.pupil_glint);
    // Off-screen gaze is real (looking past an edge), a wild value is not: keep within a screen's
    // size beyond each edge, as the HID source does.
    if (std::isfinite(mapped.x) && std::isfinite(mapped.y) && mapped.x >= -1 && mapped.x <= 2 && mapped.y >= -1 &&
        mapped.y <= 2) {
      const protocol::Degrees d = protocol::normalized_to_degrees(options_.display, mapped);
      if (std::isfinite(d.x) && std::isfinite(d.y)) {
        valid = true;
        n = mapped;
        hold_ = mapped;
      }
    }
  }
  const protocol::Degrees d = protocol::normalized_to_degrees(options_.display, n);
  s.x = static_cast<float>(n.x);
  s.y = static_cast<float>(n.y);
  s.x_deg = std::isfinite(d.x) ? static_cast<float>(d.x) : 0.0f;
  s.y_deg = std::isfinite(d.y) ? static_cast<float>(d.y) : 0.0f;
  s.flags = valid ? protocol::kGazeValid : 0;
  if (valid) ++counts_.gaze;
  return s;
}

std::string EyePipelineSource::problem() const {
  const FrameSourceStatus st = frames_->status();
  return st.healthy ? std::string() : st.problem;
}

std::string EyePipelineSource::status_detail() const {
  const FrameSourceStatus st = frames_->status();
  char buf[200];
  std::snprintf(buf, sizeof buf, "%llu frames (%llu dropped), pupil in %llu, blinks %llu, gaze valid %llu%s",
                static_cast<unsigned long long>(counts_.frames), static_cast<unsigned long long>(st.dropped),
                static_cast<unsigned long long>(counts_.pupils), static_cast<unsigned long long>(counts_.blinks),
                static_cast<unsigned long long>(counts_.gaze), options_.map ? "" : " (no calibration)");
  return buf;
}

}  // namespace fovea::trackerd::eye
