// SPDX-License-Identifier: Apache-2.0
#pragma once
// The eye pipeline as a daemon source: frames from an eye camera, an eye video or the synthetic
// eye go through the pupil/glint detector (eye/eye_detector.h), and each frame becomes one gaze
// sample carrying the configured eye's pupil and pupil–glint data. Screen gaze needs a map from
// the pupil–glint vector to the screen: the synthetic eye brings its factory calibration; for
// cameras and videos the calibration maps arrive with step 5, and until one is loaded their samples
// carry pupil data with gaze marked invalid (kGazeValid clear).
//
// Invalid gaze follows the HID source: flags clear, x/y hold the last valid position (the screen
// centre before the first), never NaN. A frame the detector calls a blink (no pupil, or a pupil
// ellipse flatter than minor/major 0.7, Lee 2009 §3.5.2) has state Blink and invalid gaze; the
// online classifier then labels the gap (trackerd/CLASSIFY.md).
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "eye/eye_detector.h"
#include "source_api/frame_source.h"
#include "source_api/gaze_source.h"

namespace fovea::trackerd::eye {

enum class EyeSide { Left, Right };
// "left" | "right"; throws std::invalid_argument naming the value and the allowed ones.
EyeSide parse_eye_side(const std::string& text);
const char* to_string(EyeSide side);

// Raw eye measurement to screen: the pupil–glint vector (pupil centre minus glint reference,
// eye-camera pixels) to normalised screen coordinates. May return non-finite values (the source
// then marks the sample invalid).
struct PupilGlintMap {
  std::string description;  // for the log: "synthetic eye factory calibration (poly2, 81 points, ...)"
  std::function<protocol::Normalized(cv::Point2d)> to_screen;
};

struct EyePipelineOptions {
  DetectorSettings detector;
  EyeSide eye = EyeSide::Right;         // which EyeData of the sample the measurement fills
  protocol::DisplayGeometry display;    // normalised screen -> degrees
  double nominal_rate_hz = 0;           // frame rate when known (0: unknown)
  double mm_per_px = 0;                 // pupil size scale at the eye; 0: unknown (diameter published as 0)
  std::optional<PupilGlintMap> map;     // none: gaze stays invalid (pupil data is still published)
};

// Detection counts, for the daemon's status line and log.
struct EyePipelineCounts {
  std::uint64_t frames = 0;       // frames run through the detector
  std::uint64_t pupils = 0;       // frames with a pupil found (and not a blink)
  std::uint64_t blinks = 0;       // frames the detector called a blink (includes "no pupil")
  std::uint64_t gaze = 0;         // samples published with kGazeValid
};

class EyePipelineSource final : public GazeSource {
 public:
  // Validates the detector settings (throws std::invalid_argument naming the field).
  EyePipelineSource(std::unique_ptr<FrameSource> frames, EyePipelineOptions options);

  std::string description() const override { return description_; }
  protocol::DisplayGeometry display() const override { return options_.display; }
  double nominal_rate_hz() const override { return options_.nominal_rate_hz; }
  // Waits up to 100 ms for a frame; nullopt when none came (ended() says whether for good).
  std::optional<GazeItem> next() override;
  bool ended() const override { return frames_->ended(); }
  std::string problem() const override;
  std::string status_detail() const override;
  bool makes_eye_frames() const override { return true; }
  void show_eye_frames(protocol::ViewerFeedServer* frames) override { frames_out_ = frames; }

  FrameSourceStatus frame_status() const { return frames_->status(); }
  EyePipelineCounts counts() const { return counts_; }

 private:
  protocol::GazeSample to_sample(const EyeMeasurement& m, std::int64_t time_ns);
  void show(const EyeFrame& frame, const EyeMeasurement& m, std::int64_t detect_ns);

  std::unique_ptr<FrameSource> frames_;
  EyePipelineOptions options_;
  EyeDetector detector_;
  std::string description_;
  EyePipelineCounts counts_;
  protocol::Normalized hold_{0.5, 0.5};  // last valid gaze, held while invalid
  protocol::ViewerFeedServer* frames_out_ = nullptr;  // viewers of the eye images; null: none
};

}  // namespace fovea::trackerd::eye
