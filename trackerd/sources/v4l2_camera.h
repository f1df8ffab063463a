// SPDX-License-Identifier: Apache-2.0
#pragma once
// `camera:/dev/videoN` — an eye camera captured through the kernel's V4L2 API: capabilities,
// format/size/frame-rate negotiation (GREY, YUYV, MJPG), mmap streaming buffers, driver buffer
// timestamps as frame time, exposure and gain when the driver offers them.
//
// Start-up errors throw CameraError (the daemon exits non-zero with its message). A device lost
// while running (unplugged: ENODEV) makes status() unhealthy with the reason, next() returns
// nullopt, and next() tries to re-open the device once per retry interval without blocking.
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "source_api/frame_source.h"
#include "sources/v4l2_device.h"

struct v4l2_buffer;  // <linux/videodev2.h>

namespace fovea::trackerd {

class CameraError : public std::runtime_error {
 public:
  enum class Kind {
    missing,          // ENOENT: no such node
    permission,       // EACCES/EPERM
    busy,             // EBUSY: another program streams from it
    unsupported,      // no mode fovea can read matches the request
    not_capture,      // not a V4L2 capture device with streaming I/O
    disconnected,     // ENODEV: unplugged
    io,               // anything else
  };
  CameraError(Kind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

struct V4l2CameraOptions {
  std::string device = "/dev/video0";
  // 0 = best the device offers: the highest frame rate, then GREY > YUYV > MJPG, then the largest
  // size. Non-zero width/height must match a mode exactly; a non-zero fps picks the mode whose
  // rate is closest to it (within 0.5 fps).
  std::uint32_t width = 0, height = 0;
  double fps = 0;
  std::uint32_t buffers = 4;
  // Set V4L2_CID_EXPOSURE_ABSOLUTE (units of 100 us; switches auto exposure to manual) / V4L2_CID_GAIN
  // when the driver offers the control (clamped to its range); otherwise notes() says so.
  std::optional<std::int32_t> exposure, gain;
  int retry_interval_ms = 1000;
};

// One capture mode: format, size and frame interval (interval 0/0 when the driver does not list
// intervals).
struct CameraMode {
  std::uint32_t fourcc = 0;
  std::uint32_t width = 0, height = 0;
  std::uint32_t interval_num = 0, interval_den = 0;  // seconds per frame = num/den
  double fps() const { return interval_num == 0 ? 0.0 : static_cast<double>(interval_den) / interval_num; }
};

// "GREY", "YUYV", "MJPG", ...
std::string fourcc_name(std::uint32_t fourcc);
// "GREY 640x480@120", "YUYV 1280x720@30", "MJPG 1920x1080@7.5", "GREY 640x480" (no interval listed)
std::string describe_mode(const CameraMode& mode);
std::string describe_modes(const std::vector<CameraMode>& modes);
// The mode V4l2Camera picks for the options among the modes it can read (GREY/YUYV/MJPG);
// nullopt when none matches.
std::optional<CameraMode> choose_mode(const std::vector<CameraMode>& modes, const V4l2CameraOptions& options);

class V4l2Camera final : public FrameSource {
 public:
  using Clock = std::function<std::int64_t()>;  // CLOCK_MONOTONIC ns
  // Opens, negotiates and starts streaming; throws CameraError naming the device on failure.
  explicit V4l2Camera(V4l2CameraOptions options, std::shared_ptr<V4l2Device> device = real_v4l2_device(),
                      std::shared_ptr<const VideoNodeDirectory> nodes = nullptr, Clock clock = nullptr);
  ~V4l2Camera() override;
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  FrameSourceStatus status() const override;
  std::optional<EyeFrame> next(int timeout_ms) override;

  // Every mode the device lists (including formats fovea cannot read), as found at the last open.
  std::vector<CameraMode> supported_modes() const;
  CameraMode mode() const;
  // What the driver offers and what was set: "exposure_absolute 1..5000 (set 100), gain 0..255",
  // "no exposure/gain controls"; plus notes such as "driver gives no monotonic timestamps".
  std::vector<std::string> notes() const;
  std::uint64_t reconnects() const;

 private:
  struct Buffer {
    void* data = nullptr;
    std::size_t length = 0;
  };
  void open_device();   // throws CameraError; on success the camera is streaming
  // open_device()'s stages, in order; a failing stage throws CameraError.
  void query_capabilities();
  void choose_listed_mode();
  void set_format();
  void set_frame_rate();
  std::uint32_t request_buffers();
  void map_buffers(std::uint32_t count);
  void start_streaming(std::uint32_t count);
  void report_streaming();
  void close_device();  // unmaps, STREAMOFF, closes; never throws
  void lose_device(const std::string& problem);
  std::optional<EyeFrame> try_dequeue(int timeout_ms);
  // try_dequeue()'s stages.
  std::string camera_label() const;
  bool dequeue_buffer(int timeout_ms, v4l2_buffer& b);
  std::uint64_t continue_sequence(std::uint32_t seq);
  std::int64_t frame_time_ns(const v4l2_buffer& b);
  bool decode_luminance(const v4l2_buffer& b, cv::Mat& image) const;
  [[noreturn]] void fail(int error, const std::string& during);
  std::vector<CameraMode> enumerate_modes();
  void apply_controls();

  V4l2CameraOptions options_;
  std::shared_ptr<V4l2Device> device_;
  std::shared_ptr<const VideoNodeDirectory> nodes_;
  Clock clock_;

  int fd_ = -1;
  bool streaming_ = false;
  std::vector<Buffer> buffers_;
  std::string card_;
  CameraMode mode_;
  std::uint32_t bytes_per_line_ = 0, image_size_ = 0;
  std::vector<CameraMode> modes_;
  std::vector<std::string> notes_;
  bool stamped_on_arrival_ = false;

  // Frame sequence: continuous across re-opens (the driver restarts at 0).
  bool have_sequence_ = false;    // a frame of the current stream was seen
  bool sequence_started_ = false;  // a frame was ever seen
  std::uint32_t last_driver_sequence_ = 0;
  std::uint64_t sequence_base_ = 0, last_sequence_ = 0;

  std::int64_t next_retry_ns_ = 0;
  std::uint64_t reconnects_ = 0;

  mutable std::mutex status_mutex_;  // status() may be read from another thread
  FrameSourceStatus status_;
};

// camera:/dev/videoN[?width=..&height=..&fps=..&buffers=..&exposure=..&gain=..]; throws
// std::invalid_argument for a malformed spec and CameraError when the camera cannot be started.
V4l2CameraOptions parse_camera_spec(const std::string& spec);
std::unique_ptr<FrameSource> make_camera_source(const std::string& spec);

}  // namespace fovea::trackerd
