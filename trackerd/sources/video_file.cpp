// SPDX-License-Identifier: Apache-2.0
#include "sources/video_file.h"

#include "source_api/grey8.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <system_error>
#include <thread>
#include <vector>

#include <opencv2/imgproc.hpp>
#include <opencv2/videoio/registry.hpp>

namespace fovea::trackerd {

namespace {

std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// The backends to try for a file, best first. FFmpeg reads every eye-camera codec in practice and
// OpenCV's own MJPEG reader needs nothing; GStreamer is only tried when neither is built in (its
// plugin scan is slow and some plugins leak), CAP_IMAGES only for an image-sequence pattern.
std::vector<cv::VideoCaptureAPIs> file_backends(const std::string& path) {
  std::vector<cv::VideoCaptureAPIs> apis;
  if (path.find('%') != std::string::npos) apis.push_back(cv::CAP_IMAGES);
  for (const auto api : {cv::CAP_FFMPEG, cv::CAP_OPENCV_MJPEG}) {
    if (cv::videoio_registry::hasBackend(api)) apis.push_back(api);
  }
  if (apis.empty() || (apis.size() == 1 && apis[0] == cv::CAP_IMAGES)) {
    for (const auto api : cv::videoio_registry::getStreamBackends()) apis.push_back(api);
  }
  return apis;
}


}  // namespace

VideoFileSource::VideoFileSource(VideoFileOptions options, Clock clock)
    : options_(std::move(options)), clock_(clock ? std::move(clock) : Clock(steady_now_ns)) {
  const std::string& path = options_.path;
  std::error_code ec;
  const auto st = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(st)) throw std::runtime_error("video file " + path + ": no such file");
  if (std::filesystem::is_directory(st)) throw std::runtime_error("video file " + path + ": is a directory");
  // OpenCV says only "could not open"; find out first whether we may read the file at all.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    throw std::runtime_error("video file " + path + ": cannot be read (" +
                             std::error_code(errno, std::generic_category()).message() + ")");
  }
  ::close(fd);

  std::string tried;
  for (const auto api : file_backends(path)) {
    tried += (tried.empty() ? "" : ", ") + cv::videoio_registry::getBackendName(api);
    try {
      if (capture_.open(path, api) && capture_.isOpened()) break;
    } catch (const cv::Exception&) {
      // some backends throw instead of failing; try the next
    }
  }
  if (!capture_.isOpened()) {
    throw std::runtime_error("video file " + path + ": OpenCV cannot open it as a video (backends tried: " +
                             (tried.empty() ? std::string("none available") : tried) + ")");
  }
  backend_ = capture_.getBackendName();
  const double fps = capture_.get(cv::CAP_PROP_FPS);
  fps_ = std::isfinite(fps) && fps > 0 && fps < 100000 ? fps : 0.0;
  if (!read_pending()) {
    throw std::runtime_error("video file " + path + ": OpenCV opened it with backend " + backend_ +
                             " but cannot decode a frame (empty file or unsupported codec)");
  }
  char rate[32] = "";
  if (fps_ > 0) std::snprintf(rate, sizeof rate, " %.3g fps", fps_);
  const auto name = std::filesystem::path(path).filename().string();
  status_.description = "video:" + name + " " + std::to_string(pending_->image.cols) + "x" +
                        std::to_string(pending_->image.rows) + rate + " (" + backend_ +
                        (options_.realtime ? ", real time)" : ", as fast as decoded)");
}

bool VideoFileSource::read_pending() {
  pending_.reset();
  cv::Mat frame;
  try {
    if (!capture_.read(frame) || frame.empty()) return false;
  } catch (const cv::Exception&) {
    return false;  // a damaged tail ends the video like its end would
  }
  const double period_ns = 1e9 / (fps_ > 0 ? fps_ : 30.0);
  const double msec = capture_.get(cv::CAP_PROP_POS_MSEC);
  std::int64_t file_ns = 0;
  if (std::isfinite(msec) && msec >= 0 && msec < 1e12) {
    file_ns = std::llround(msec * 1e6);
  } else {
    file_ns = std::llround(static_cast<double>(index_) * period_ns);
  }
  if (index_ == 0) {
    first_file_ns_ = file_ns;
  } else if (file_ns <= last_file_ns_) {
    // The backend gave no usable position (0 or repeated): fall back to index / frame rate.
    file_ns = std::max<std::int64_t>(first_file_ns_ + std::llround(static_cast<double>(index_) * period_ns),
                       last_file_ns_ + 1);
  }
  last_file_ns_ = file_ns;
  cv::Mat grey = to_grey8(frame);
  if (grey.data == frame.data) grey = grey.clone();  // the capture reuses its buffer
  pending_ = EyeFrame{std::move(grey), file_ns - first_file_ns_, index_};
  ++index_;
  return true;
}

std::optional<EyeFrame> VideoFileSource::next(int timeout_ms) {
  if (!pending_) return std::nullopt;
  const std::int64_t now = clock_();
  if (!started_) {
    origin_ns_ = now;
    started_ = true;
  }
  const std::int64_t due = origin_ns_ + pending_->time_ns;
  if (options_.realtime && due > now) {
    const std::int64_t wait_ns = due - now;
    if (wait_ns > std::int64_t{std::max(timeout_ms, 0)} * 1'000'000) {
      std::this_thread::sleep_for(std::chrono::milliseconds(std::max(timeout_ms, 0)));
      return std::nullopt;
    }
    std::this_thread::sleep_for(std::chrono::nanoseconds(wait_ns));
  }
  EyeFrame frame = std::move(*pending_);
  frame.time_ns = due;
  const bool more = read_pending();
  std::lock_guard lock(status_mutex_);
  ++status_.frames;
  if (!more) ended_ = true;
  return frame;
}

bool VideoFileSource::ended() const {
  std::lock_guard lock(status_mutex_);
  return ended_;
}

FrameSourceStatus VideoFileSource::status() const {
  std::lock_guard lock(status_mutex_);
  return status_;
}

std::unique_ptr<FrameSource> make_video_file_source(const std::string& spec, bool realtime) {
  const std::string prefix = "video:";
  if (spec.rfind(prefix, 0) != 0 || spec.size() == prefix.size()) {
    throw std::invalid_argument("'" + spec + "' is not a video:FILE source");
  }
  return std::make_unique<VideoFileSource>(VideoFileOptions{spec.substr(prefix.size()), realtime});
}

}  // namespace fovea::trackerd
