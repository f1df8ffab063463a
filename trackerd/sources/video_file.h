// SPDX-License-Identifier: Apache-2.0
#pragma once
// `video:FILE` — a recorded eye video read through OpenCV's VideoCapture. Frames are converted to
// 8-bit grey and stamped on the daemon's CLOCK_MONOTONIC: the first frame at the time the source
// delivers it, each later one offset by its time in the file (CAP_PROP_POS_MSEC; where the backend
// reports none, frame index / frame rate). In real-time mode next() paces frames to those times; in
// fast mode (tests, offline processing) it delivers them as fast as they decode, with the same
// spacing in their timestamps.
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <opencv2/videoio.hpp>

#include "source_api/frame_source.h"

namespace fovea::trackerd {

struct VideoFileOptions {
  std::string path;
  bool realtime = true;
};

class VideoFileSource final : public FrameSource {
 public:
  using Clock = std::function<std::int64_t()>;  // CLOCK_MONOTONIC ns
  // Opens the file and decodes its first frame; throws std::runtime_error naming the file when it
  // is missing, unreadable, or OpenCV cannot decode it (naming the backends tried).
  explicit VideoFileSource(VideoFileOptions options, Clock clock = nullptr);

  FrameSourceStatus status() const override;
  std::optional<EyeFrame> next(int timeout_ms) override;
  bool ended() const override;

  double file_fps() const { return fps_; }
  std::string backend() const { return backend_; }

 private:
  bool read_pending();  // decodes the next frame into pending_; false at the end

  VideoFileOptions options_;
  Clock clock_;
  cv::VideoCapture capture_;
  std::string backend_;
  double fps_ = 0;
  std::optional<EyeFrame> pending_;  // decoded, time in file (ns from the first frame)
  std::int64_t first_file_ns_ = 0, last_file_ns_ = -1;
  std::uint64_t index_ = 0;
  std::int64_t origin_ns_ = 0;  // daemon time of the first frame; set when it is delivered
  bool started_ = false;
  bool ended_ = false;

  mutable std::mutex status_mutex_;
  FrameSourceStatus status_;
};

// video:FILE; throws std::invalid_argument for a spec that is not video:..., and std::runtime_error
// (naming the file) when it cannot be opened.
std::unique_ptr<FrameSource> make_video_file_source(const std::string& spec, bool realtime);

}  // namespace fovea::trackerd
