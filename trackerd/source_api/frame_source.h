// SPDX-License-Identifier: Apache-2.0
#pragma once
// A source of eye-camera frames (V4L2 camera, recorded eye video, the synthetic eye). The eye
// pipeline (eye/eye_source.h: pupil and corneal-glint detection, then a calibration map) turns
// each frame into a gaze sample.
#include <cstdint>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

namespace fovea::trackerd {

struct EyeFrame {
  cv::Mat image;              // 8-bit single channel (GREY); colour inputs are converted
  std::int64_t time_ns = 0;   // capture time on CLOCK_MONOTONIC (driver buffer timestamp for V4L2)
  std::uint64_t sequence = 0; // driver/frame sequence number; gaps mean dropped frames
};

struct FrameSourceStatus {
  std::string description;    // e.g. "camera:/dev/video0 640x480 GREY 120 fps"
  bool healthy = true;        // false while the device is missing/busy and being retried
  std::string problem;        // why not healthy, naming the device and what it supports
  std::uint64_t frames = 0, dropped = 0;
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual FrameSourceStatus status() const = 0;
  // Waits up to timeout_ms for the next frame; nullopt on timeout, at end of a file, or while the
  // device is unavailable (status() says which).
  virtual std::optional<EyeFrame> next(int timeout_ms) = 0;
  virtual bool ended() const { return false; }  // a file source that reached its end
};

}  // namespace fovea::trackerd
