#pragma once
// Makes an eye-camera frame source (camera:, video:) a daemon source. Turning eye images into gaze
// is the eye pipeline's job (step 4), which this build does not have yet: the daemon opens and
// captures from the device (so device errors are reported exactly), counts frames, reports
// health in its status and logs, and publishes no gaze samples from it.
#include <memory>

#include "sources/frame_source.h"
#include "sources/gaze_source.h"

namespace fovea::trackerd {

class FrameCaptureSource final : public GazeSource {
 public:
  FrameCaptureSource(std::unique_ptr<FrameSource> frames, const protocol::DisplayGeometry& display);
  std::string description() const override;
  protocol::DisplayGeometry display() const override { return display_; }
  double nominal_rate_hz() const override { return 0; }
  // Captures for up to 100 ms and returns nullopt (no gaze without the eye pipeline).
  std::optional<GazeItem> next() override;
  bool ended() const override { return frames_->ended(); }
  FrameSourceStatus status() const { return frames_->status(); }
  std::string problem() const override {
    const FrameSourceStatus s = frames_->status();
    return s.healthy ? std::string() : s.problem;
  }

 private:
  std::unique_ptr<FrameSource> frames_;
  protocol::DisplayGeometry display_;
  std::string description_;
};

}  // namespace fovea::trackerd
