#include "sources/frame_capture_source.h"

#include <spdlog/spdlog.h>

namespace fovea::trackerd {

FrameCaptureSource::FrameCaptureSource(std::unique_ptr<FrameSource> frames, const protocol::DisplayGeometry& display)
    : frames_(std::move(frames)), display_(display), description_(frames_->status().description) {
  spdlog::warn("{}: frames are captured, but gaze from eye images needs the eye pipeline (pupil and glint "
               "detection, step 4), which this build does not have: no gaze samples will be published",
               description_);
}

std::string FrameCaptureSource::description() const { return description_; }

std::optional<GazeItem> FrameCaptureSource::next() {
  frames_->next(100);
  return std::nullopt;
}

}  // namespace fovea::trackerd
