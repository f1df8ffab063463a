// SPDX-License-Identifier: Apache-2.0
#include "sources/v4l2_camera.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numeric>
#include <optional>
#include <span>
#include <system_error>
#include <thread>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "source_api/image_header.h"

namespace fovea::trackerd {

namespace {

constexpr int kMaxEnumerations = 256;  // guards the ENUM_* loops against a driver that never says EINVAL

std::int64_t steady_now_ns() {
  // steady_clock is CLOCK_MONOTONIC on Linux, the clock V4L2 monotonic buffer timestamps use.
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::string errno_text(int error) { return std::error_code(error, std::generic_category()).message(); }

std::string format_fps(double fps) {
  char buf[32];
  if (std::abs(fps - std::round(fps)) < 0.005) {
    std::snprintf(buf, sizeof buf, "%.0f", fps);
  } else {
    std::snprintf(buf, sizeof buf, "%.3g", fps);
  }
  return buf;
}

bool readable_format(std::uint32_t fourcc) {
  return fourcc == V4L2_PIX_FMT_GREY || fourcc == V4L2_PIX_FMT_YUYV || fourcc == V4L2_PIX_FMT_MJPEG;
}

int format_preference(std::uint32_t fourcc) {  // lower is better: IR eye cameras deliver luminance
  if (fourcc == V4L2_PIX_FMT_GREY) return 0;
  if (fourcc == V4L2_PIX_FMT_YUYV) return 1;
  return 2;
}

// A frame interval as a reduced fraction num/den seconds for a frame rate (1000ths of a frame/s).
std::pair<std::uint32_t, std::uint32_t> interval_for_fps(double fps) {
  const auto den = static_cast<std::uint32_t>(std::llround(fps * 1000.0));
  const std::uint32_t num = 1000;
  const std::uint32_t g = std::gcd(num, den);
  return {num / g, den / g};
}

// Buffer `index` of the capture queue, memory-mapped: what QUERYBUF and QBUF are asked about.
v4l2_buffer mmap_capture_buffer(std::uint32_t index) {
  v4l2_buffer b{};
  b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  b.memory = V4L2_MEMORY_MMAP;
  b.index = index;
  return b;
}

}  // namespace

std::string fourcc_name(std::uint32_t fourcc) {
  std::string s;
  for (int i = 0; i < 4; ++i) {
    const auto c = static_cast<char>((fourcc >> (8 * i)) & 0xFFu);
    s += (c >= 32 && c < 127) ? c : '?';
  }
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

std::string describe_mode(const CameraMode& mode) {
  std::string s = fourcc_name(mode.fourcc) + " " + std::to_string(mode.width) + "x" + std::to_string(mode.height);
  if (mode.interval_num != 0 && mode.interval_den != 0) s += "@" + format_fps(mode.fps());
  return s;
}

std::string describe_modes(const std::vector<CameraMode>& modes) {
  std::string s;
  for (const auto& m : modes) {
    if (!s.empty()) s += ", ";
    s += describe_mode(m);
  }
  return s.empty() ? "no modes" : s;
}

std::optional<CameraMode> choose_mode(const std::vector<CameraMode>& modes, const V4l2CameraOptions& options) {
  std::vector<CameraMode> candidates;
  for (const auto& m : modes) {
    if (!readable_format(m.fourcc)) continue;
    if (options.width != 0 && m.width != options.width) continue;
    if (options.height != 0 && m.height != options.height) continue;
    // A mode without a listed interval may still run at the wanted rate: S_PARM decides.
    if (options.fps > 0 && m.fps() > 0 && std::abs(m.fps() - options.fps) > 0.5) continue;
    candidates.push_back(m);
  }
  if (candidates.empty()) return std::nullopt;
  const auto better = [&](const CameraMode& a, const CameraMode& b) {
    if (options.fps > 0) {
      const double da = a.fps() > 0 ? std::abs(a.fps() - options.fps) : 1.0;
      const double db = b.fps() > 0 ? std::abs(b.fps() - options.fps) : 1.0;
      if (da != db) return da < db;
    } else if (a.fps() != b.fps()) {
      return a.fps() > b.fps();
    }
    if (format_preference(a.fourcc) != format_preference(b.fourcc)) {
      return format_preference(a.fourcc) < format_preference(b.fourcc);
    }
    return std::uint64_t{a.width} * a.height > std::uint64_t{b.width} * b.height;
  };
  return *std::min_element(candidates.begin(), candidates.end(), better);
}

V4l2Camera::V4l2Camera(V4l2CameraOptions options, std::shared_ptr<V4l2Device> device,
                       std::shared_ptr<const VideoNodeDirectory> nodes, Clock clock)
    : options_(std::move(options)),
      device_(std::move(device)),
      nodes_(nodes ? std::move(nodes) : std::make_shared<SysfsVideoNodes>()),
      clock_(clock ? std::move(clock) : Clock(steady_now_ns)) {
  if (options_.buffers == 0 || options_.buffers > 32) {
    throw std::invalid_argument("camera " + options_.device + ": buffer count " + std::to_string(options_.buffers) +
                                " is outside 1..32");
  }
  if (options_.retry_interval_ms < 0) options_.retry_interval_ms = 0;
  status_.description = "camera:" + options_.device;
  open_device();
}

V4l2Camera::~V4l2Camera() { close_device(); }

void V4l2Camera::fail(int error, const std::string& during) {
  const std::string& dev = options_.device;
  const std::string label = card_.empty() ? dev : dev + " (" + card_ + ")";
  switch (error) {
    case ENOENT:
      throw CameraError(CameraError::Kind::missing, "camera " + dev + ": no such device (video devices present: " +
                                                        describe_video_nodes(nodes_->list()) + ")");
    case EACCES:
    case EPERM:
      throw CameraError(CameraError::Kind::permission,
                        "camera " + label + ": permission denied (" + during +
                            "); add the daemon's user to the 'video' group (sudo usermod -aG video USER, then log "
                            "in again) or install a udev rule such as SUBSYSTEM==\"video4linux\", GROUP=\"video\", "
                            "MODE=\"0660\"");
    case EBUSY:
      throw CameraError(CameraError::Kind::busy, "camera " + label + " is busy (another program is using it; `fuser " +
                                                     dev + "` shows which) at " + during);
    case ENODEV:
    case ENXIO:
      throw CameraError(CameraError::Kind::disconnected,
                        "camera " + label + ": device disconnected (" + errno_text(error) + " at " + during + ")");
    default:
      throw CameraError(CameraError::Kind::io, "camera " + label + ": " + during + " failed: " + errno_text(error));
  }
}

std::vector<CameraMode> V4l2Camera::enumerate_modes() {
  std::vector<CameraMode> modes;
  // The driver's current size, for drivers that do not enumerate sizes.
  v4l2_format current{};
  current.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  const bool have_current = device_->ioctl(fd_, VIDIOC_G_FMT, &current) == 0;

  for (std::uint32_t fi = 0; fi < kMaxEnumerations; ++fi) {
    v4l2_fmtdesc desc{};
    desc.index = fi;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (const int r = device_->ioctl(fd_, VIDIOC_ENUM_FMT, &desc); r < 0) {
      if (r == -ENODEV) fail(ENODEV, "VIDIOC_ENUM_FMT");
      break;
    }
    std::vector<std::pair<std::uint32_t, std::uint32_t>> sizes;
    for (std::uint32_t si = 0; si < kMaxEnumerations; ++si) {
      v4l2_frmsizeenum fs{};
      fs.index = si;
      fs.pixel_format = desc.pixelformat;
      if (device_->ioctl(fd_, VIDIOC_ENUM_FRAMESIZES, &fs) < 0) break;
      if (fs.type == V4L2_FRMSIZE_TYPE_DISCRETE) {
        sizes.emplace_back(fs.discrete.width, fs.discrete.height);
        continue;
      }
      // Stepwise/continuous: the largest size, and the wanted one when it lies on the grid.
      const auto& sw = fs.stepwise;
      sizes.emplace_back(sw.max_width, sw.max_height);
      const std::uint32_t w = options_.width, h = options_.height;
      if (w >= sw.min_width && w <= sw.max_width && h >= sw.min_height && h <= sw.max_height &&
          (sw.step_width == 0 || (w - sw.min_width) % sw.step_width == 0) &&
          (sw.step_height == 0 || (h - sw.min_height) % sw.step_height == 0) && (w != sw.max_width || h != sw.max_height)) {
        sizes.emplace_back(w, h);
      }
      break;
    }
    if (sizes.empty() && have_current) sizes.emplace_back(current.fmt.pix.width, current.fmt.pix.height);

    for (const auto& [w, h] : sizes) {
      CameraMode base{desc.pixelformat, w, h, 0, 0};
      std::size_t added = 0;
      for (std::uint32_t ii = 0; ii < kMaxEnumerations; ++ii) {
        v4l2_frmivalenum iv{};
        iv.index = ii;
        iv.pixel_format = desc.pixelformat;
        iv.width = w;
        iv.height = h;
        if (device_->ioctl(fd_, VIDIOC_ENUM_FRAMEINTERVALS, &iv) < 0) break;
        if (iv.type == V4L2_FRMIVAL_TYPE_DISCRETE) {
          if (iv.discrete.numerator == 0 || iv.discrete.denominator == 0) continue;
          CameraMode m = base;
          m.interval_num = iv.discrete.numerator;
          m.interval_den = iv.discrete.denominator;
          modes.push_back(m);
          ++added;
          continue;
        }
        // Stepwise/continuous: the fastest and slowest rates, and the wanted one when in range.
        const auto& sw = iv.stepwise;
        if (sw.min.numerator == 0 || sw.min.denominator == 0 || sw.max.numerator == 0 || sw.max.denominator == 0) break;
        CameraMode fastest = base, slowest = base;
        fastest.interval_num = sw.min.numerator;
        fastest.interval_den = sw.min.denominator;
        slowest.interval_num = sw.max.numerator;
        slowest.interval_den = sw.max.denominator;
        modes.push_back(fastest);
        ++added;
        if (options_.fps >= 0.001 && options_.fps < fastest.fps() && options_.fps > slowest.fps()) {
          CameraMode wanted = base;
          std::tie(wanted.interval_num, wanted.interval_den) = interval_for_fps(options_.fps);
          modes.push_back(wanted);
        }
        if (slowest.fps() != fastest.fps()) modes.push_back(slowest);
        break;
      }
      if (added == 0) modes.push_back(base);
    }
  }
  return modes;
}

void V4l2Camera::apply_controls() {
  struct Wanted {
    std::uint32_t id;
    const char* name;
    std::optional<std::int32_t> value;
  };
  const Wanted wanted[] = {{V4L2_CID_EXPOSURE_ABSOLUTE, "exposure_absolute", options_.exposure},
                           {V4L2_CID_GAIN, "gain", options_.gain}};
  std::string offered;
  for (const auto& w : wanted) {
    v4l2_queryctrl q{};
    q.id = w.id;
    const int r = device_->ioctl(fd_, VIDIOC_QUERYCTRL, &q);
    if (r == -ENODEV) fail(ENODEV, "VIDIOC_QUERYCTRL");
    const bool available = r == 0 && (q.flags & V4L2_CTRL_FLAG_DISABLED) == 0;
    if (!available) {
      if (w.value) notes_.push_back(std::string(w.name) + " requested but the camera offers no such control");
      continue;
    }
    std::string text = std::string(w.name) + " " + std::to_string(q.minimum) + ".." + std::to_string(q.maximum) +
                       " (default " + std::to_string(q.default_value) + ")";
    if (w.value) {
      const std::int32_t value = std::clamp(*w.value, q.minimum, q.maximum);
      if (w.id == V4L2_CID_EXPOSURE_ABSOLUTE) {
        // UVC cameras ignore the absolute exposure while auto exposure is on.
        v4l2_control manual{V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL};
        if (const int m = device_->ioctl(fd_, VIDIOC_S_CTRL, &manual); m == -ENODEV) fail(ENODEV, "VIDIOC_S_CTRL");
      }
      v4l2_control c{w.id, value};
      const int s = device_->ioctl(fd_, VIDIOC_S_CTRL, &c);
      if (s == -ENODEV) fail(ENODEV, "VIDIOC_S_CTRL");
      if (s < 0) {
        text += ", setting " + std::to_string(value) + " failed: " + errno_text(-s);
      } else {
        text += ", set " + std::to_string(value);
        if (value != *w.value) text += " (clamped from " + std::to_string(*w.value) + ")";
      }
    }
    offered += (offered.empty() ? "" : ", ") + text;
  }
  notes_.push_back(offered.empty() ? "no exposure/gain controls" : offered);
}

// The node must be a V4L2 capture device with streaming I/O; otherwise a CameraError says what it
// is instead (a UVC camera's metadata node is the usual mistake).
void V4l2Camera::query_capabilities() {
  v4l2_capability cap{};
  if (const int r = device_->ioctl(fd_, VIDIOC_QUERYCAP, &cap); r < 0) {
    if (r == -ENOTTY || r == -EINVAL) {
      throw CameraError(CameraError::Kind::not_capture,
                        "camera " + options_.device + " is not a V4L2 device (VIDIOC_QUERYCAP: " + errno_text(-r) +
                            "); video devices present: " + describe_video_nodes(nodes_->list()));
    }
    fail(-r, "VIDIOC_QUERYCAP");
  }
  card_.assign(reinterpret_cast<const char*>(cap.card),
               strnlen(reinterpret_cast<const char*>(cap.card), sizeof cap.card));
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0) {
    throw CameraError(CameraError::Kind::not_capture,
                      "camera " + options_.device + " (" + card_ +
                          ") is not a video capture device (a UVC camera's second node carries metadata); video "
                          "devices present: " +
                          describe_video_nodes(nodes_->list()));
  }
  if ((caps & V4L2_CAP_STREAMING) == 0) {
    throw CameraError(CameraError::Kind::not_capture,
                      "camera " + options_.device + " (" + card_ + ") does not support streaming (mmap) capture");
  }
}

// The mode the options ask for among those the device lists (modes_), or a CameraError naming
// what was wanted and what the device offers.
void V4l2Camera::choose_listed_mode() {
  modes_ = enumerate_modes();
  const auto chosen = choose_mode(modes_, options_);
  if (!chosen) {
    std::string wanted;
    if (options_.width != 0 || options_.height != 0) {
      wanted = (options_.width ? std::to_string(options_.width) : "*") + "x" +
               (options_.height ? std::to_string(options_.height) : "*");
    }
    if (options_.fps > 0) wanted += (wanted.empty() ? "" : "@") + format_fps(options_.fps) + " fps";
    const bool any_readable =
        std::any_of(modes_.begin(), modes_.end(), [](const CameraMode& m) { return readable_format(m.fourcc); });
    std::string message = "camera " + options_.device + " (" + card_ + "): ";
    message += any_readable ? "no GREY, YUYV or MJPG mode matches " + (wanted.empty() ? "the request" : wanted)
                            : "offers no format fovea can read (fovea reads GREY, YUYV, MJPG)";
    message += "; it supports: " + describe_modes(modes_);
    throw CameraError(CameraError::Kind::unsupported, message);
  }
  mode_ = *chosen;
}

// S_FMT with the chosen mode: the driver may adjust the size (noted; mode_ follows it) but not the
// pixel format. The row stride is kept at least one row of pixels whatever bytesperline it reports.
void V4l2Camera::set_format() {
  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = mode_.width;
  fmt.fmt.pix.height = mode_.height;
  fmt.fmt.pix.pixelformat = mode_.fourcc;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (const int r = device_->ioctl(fd_, VIDIOC_S_FMT, &fmt); r < 0) fail(-r, "VIDIOC_S_FMT");
  if (fmt.fmt.pix.pixelformat != mode_.fourcc) {
    throw CameraError(CameraError::Kind::unsupported,
                      "camera " + options_.device + " (" + card_ + "): asked for " + describe_mode(mode_) +
                          ", the driver gave " + fourcc_name(fmt.fmt.pix.pixelformat) +
                          "; it supports: " + describe_modes(modes_));
  }
  if (fmt.fmt.pix.width != mode_.width || fmt.fmt.pix.height != mode_.height) {
    notes_.push_back("asked for " + std::to_string(mode_.width) + "x" + std::to_string(mode_.height) +
                     ", the driver gave " + std::to_string(fmt.fmt.pix.width) + "x" +
                     std::to_string(fmt.fmt.pix.height));
    mode_.width = fmt.fmt.pix.width;
    mode_.height = fmt.fmt.pix.height;
  }
  const std::uint32_t min_bpl = mode_.fourcc == V4L2_PIX_FMT_YUYV ? 2 * mode_.width : mode_.width;
  bytes_per_line_ = std::max(fmt.fmt.pix.bytesperline, min_bpl);
  image_size_ = fmt.fmt.pix.sizeimage;
}

// Frame rate: only when the driver allows it (V4L2_CAP_TIMEPERFRAME); read back what it chose.
void V4l2Camera::set_frame_rate() {
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (device_->ioctl(fd_, VIDIOC_G_PARM, &parm) == 0 && (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME) != 0 &&
      mode_.interval_num != 0) {
    parm.parm.capture.timeperframe.numerator = mode_.interval_num;
    parm.parm.capture.timeperframe.denominator = mode_.interval_den;
    if (const int r = device_->ioctl(fd_, VIDIOC_S_PARM, &parm); r < 0) fail(-r, "VIDIOC_S_PARM");
    const auto& tpf = parm.parm.capture.timeperframe;
    if (tpf.numerator != 0 && tpf.denominator != 0) {
      mode_.interval_num = tpf.numerator;
      mode_.interval_den = tpf.denominator;
    }
  } else if (mode_.interval_num != 0) {
    notes_.push_back("the driver does not let fovea set the frame rate");
  }
}

// REQBUFS for options_.buffers mmap buffers; returns how many the driver gave (it may give fewer
// or more, never 0 here).
std::uint32_t V4l2Camera::request_buffers() {
  v4l2_requestbuffers req{};
  req.count = options_.buffers;
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (const int r = device_->ioctl(fd_, VIDIOC_REQBUFS, &req); r < 0) fail(-r, "VIDIOC_REQBUFS");
  if (req.count == 0) {
    throw CameraError(CameraError::Kind::io, "camera " + options_.device + " (" + card_ +
                                                 "): the driver gave no capture buffers (out of memory?)");
  }
  return req.count;
}

// Each buffer into buffers_ as soon as it is mapped, so close_device() unmaps what a failure leaves.
void V4l2Camera::map_buffers(std::uint32_t count) {
  for (std::uint32_t i = 0; i < count; ++i) {
    v4l2_buffer b = mmap_capture_buffer(i);
    if (const int r = device_->ioctl(fd_, VIDIOC_QUERYBUF, &b); r < 0) fail(-r, "VIDIOC_QUERYBUF");
    Buffer buffer;
    buffer.length = b.length;
    if (const int r = device_->mmap(fd_, b.length, b.m.offset, &buffer.data); r < 0) fail(-r, "mmap");
    buffers_.push_back(buffer);
  }
}

// Every buffer queued before STREAMON, so the driver has somewhere to capture into from the start.
void V4l2Camera::start_streaming(std::uint32_t count) {
  for (std::uint32_t i = 0; i < count; ++i) {
    v4l2_buffer b = mmap_capture_buffer(i);
    if (const int r = device_->ioctl(fd_, VIDIOC_QBUF, &b); r < 0) fail(-r, "VIDIOC_QBUF");
  }
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (const int r = device_->ioctl(fd_, VIDIOC_STREAMON, &type); r < 0) fail(-r, "VIDIOC_STREAMON");
  streaming_ = true;
}

// What the camera streams, as status() describes it; healthy again after a reconnect.
void V4l2Camera::report_streaming() {
  std::string description = "camera:" + options_.device + " " + std::to_string(mode_.width) + "x" +
                            std::to_string(mode_.height) + " " + fourcc_name(mode_.fourcc);
  if (mode_.fps() > 0) description += " " + format_fps(mode_.fps()) + " fps";
  if (!card_.empty()) description += " (" + card_ + ")";
  std::lock_guard lock(status_mutex_);
  status_.description = description;
  status_.healthy = true;
  status_.problem.clear();
}

void V4l2Camera::open_device() {
  card_.clear();
  notes_.clear();
  stamped_on_arrival_ = false;
  have_sequence_ = false;
  const int fd = device_->open(options_.device, O_RDWR | O_NONBLOCK);
  if (fd < 0) fail(-fd, "open");
  fd_ = fd;
  try {
    query_capabilities();
    choose_listed_mode();
    set_format();
    set_frame_rate();
    apply_controls();
    const std::uint32_t count = request_buffers();
    map_buffers(count);
    start_streaming(count);
  } catch (...) {
    close_device();
    throw;
  }
  report_streaming();
}

void V4l2Camera::close_device() {
  if (fd_ < 0) return;
  if (streaming_) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    device_->ioctl(fd_, VIDIOC_STREAMOFF, &type);
    streaming_ = false;
  }
  for (const auto& b : buffers_) device_->munmap(b.data, b.length);
  if (!buffers_.empty()) {
    v4l2_requestbuffers req{};  // release the driver's buffers (after unmapping)
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    device_->ioctl(fd_, VIDIOC_REQBUFS, &req);
  }
  buffers_.clear();
  device_->close(fd_);
  fd_ = -1;
}

void V4l2Camera::lose_device(const std::string& problem) {
  close_device();
  next_retry_ns_ = clock_() + std::int64_t{options_.retry_interval_ms} * 1'000'000;
  std::lock_guard lock(status_mutex_);
  status_.healthy = false;
  status_.problem = problem + "; retrying every " + format_fps(options_.retry_interval_ms / 1000.0) + " s";
}

std::optional<EyeFrame> V4l2Camera::next(int timeout_ms) {
  if (!streaming_) {
    const std::int64_t now = clock_();
    if (now >= next_retry_ns_) {
      try {
        open_device();
        ++reconnects_;
      } catch (const std::exception& e) {
        lose_device(e.what());
      }
    }
    if (!streaming_) {
      // Wait as a frame would have been waited for, but never past the next retry.
      const std::int64_t until_retry_ms = std::max<std::int64_t>(0, (next_retry_ns_ - now) / 1'000'000);
      const std::int64_t wait_ms = std::min<std::int64_t>(std::max(timeout_ms, 0), until_retry_ms);
      if (wait_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(wait_ms));
      return std::nullopt;
    }
  }
  return try_dequeue(timeout_ms);
}

// "camera /dev/video0 (Card)": how the lost-device problems in status() name the camera.
std::string V4l2Camera::camera_label() const {
  return "camera " + options_.device + (card_.empty() ? "" : " (" + card_ + ")");
}

// Waits up to timeout_ms for a filled buffer and dequeues it into `b`; false when none came, or
// when the device was lost (lose_device() has then recorded why).
bool V4l2Camera::dequeue_buffer(int timeout_ms, v4l2_buffer& b) {
  const int revents = device_->poll(fd_, POLLIN, timeout_ms);
  if (revents == 0 || revents == -EINTR) return false;
  if (revents < 0) {
    lose_device(camera_label() + ": poll failed: " + errno_text(-revents));
    return false;
  }
  b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  b.memory = V4L2_MEMORY_MMAP;
  if (const int r = device_->ioctl(fd_, VIDIOC_DQBUF, &b); r < 0) {
    if (r == -EAGAIN && (revents & (POLLERR | POLLHUP | POLLNVAL)) == 0) return false;
    const int error = r == -EAGAIN ? ENODEV : -r;  // POLLERR with nothing to dequeue: the device is gone
    if (error == ENODEV || error == ENXIO) {
      lose_device(camera_label() + ": device disconnected (" + errno_text(error) + " at VIDIOC_DQBUF)");
    } else {
      lose_device(camera_label() + ": VIDIOC_DQBUF failed: " + errno_text(error));
    }
    return false;
  }
  if (b.index >= buffers_.size()) {
    lose_device(camera_label() + ": the driver returned buffer " + std::to_string(b.index) + " of " +
                std::to_string(buffers_.size()));
    return false;
  }
  return true;
}

// Sequence: gaps are frames the driver dropped; a restart (re-open) continues our numbering.
// Returns the frames dropped just before this one; last_sequence_ becomes this frame's number.
std::uint64_t V4l2Camera::continue_sequence(std::uint32_t seq) {
  std::uint64_t dropped = 0;
  if (!have_sequence_ || seq <= last_driver_sequence_) {
    // Unsigned wrap-around is intended: base + seq is the continued number.
    sequence_base_ = (sequence_started_ ? last_sequence_ + 1 : seq) - seq;
    sequence_started_ = true;
    have_sequence_ = true;
  } else if (seq > last_driver_sequence_ + 1) {
    dropped = seq - last_driver_sequence_ - 1;
  }
  last_driver_sequence_ = seq;
  last_sequence_ = sequence_base_ + seq;
  return dropped;
}

// Frame time on CLOCK_MONOTONIC: the driver's buffer timestamp when it is a monotonic one, else the
// arrival time (noted once per open).
std::int64_t V4l2Camera::frame_time_ns(const v4l2_buffer& b) {
  std::int64_t time_ns = 0;
  const bool monotonic = (b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC &&
                         (b.timestamp.tv_sec != 0 || b.timestamp.tv_usec != 0);
  if (monotonic) {
    time_ns = std::int64_t{b.timestamp.tv_sec} * 1'000'000'000 + std::int64_t{b.timestamp.tv_usec} * 1000;
  } else {
    time_ns = clock_();
    if (!stamped_on_arrival_) {
      stamped_on_arrival_ = true;
      notes_.push_back("the driver gives no monotonic buffer timestamps; frames are stamped on arrival");
    }
  }
  return time_ns;
}

// The dequeued buffer's luminance as an 8-bit image of its own (the buffer goes back to the driver);
// false when the frame is corrupt: flagged by the driver, an undecodable JPEG, or shorter than the
// negotiated rows.
bool V4l2Camera::decode_luminance(const v4l2_buffer& b, cv::Mat& image) const {
  const Buffer& buffer = buffers_[b.index];
  const std::size_t used = std::min<std::size_t>(b.bytesused != 0 ? b.bytesused : buffer.length, buffer.length);
  const int w = static_cast<int>(mode_.width), h = static_cast<int>(mode_.height);
  bool corrupt = (b.flags & V4L2_BUF_FLAG_ERROR) != 0;
  if (!corrupt) {
    if (mode_.fourcc == V4L2_PIX_FMT_MJPEG) {
      // A frame must declare the negotiated size before it is decoded: a device (or a USB/IP peer)
      // sending a small JPEG that declares a huge image would otherwise make the decoder allocate
      // for it (issue 23 item 6). decode_image_bounded also catches OpenCV's exceptions.
      const std::span<const std::uint8_t> bytes(static_cast<const std::uint8_t*>(buffer.data), used);
      const std::optional<ImageHeader> header = read_image_header(bytes);
      std::string why;
      if (header && header->width == mode_.width && header->height == mode_.height) {
        image = decode_image_bounded(bytes, cv::IMREAD_GRAYSCALE, std::uint64_t{mode_.width} * mode_.height, why);
      } else {
        image.release();
      }
      corrupt = image.empty();
    } else {
      const std::size_t pixel_bytes = mode_.fourcc == V4L2_PIX_FMT_YUYV ? 2 : 1;
      const std::size_t needed =
          h > 0 ? std::size_t{bytes_per_line_} * static_cast<std::size_t>(h - 1) + pixel_bytes * mode_.width : 0;
      corrupt = h <= 0 || w <= 0 || used < needed;
      if (!corrupt) {
        if (mode_.fourcc == V4L2_PIX_FMT_YUYV) {
          // Y0 U Y1 V: the luminance is every other byte, channel 0 of a two-channel view.
          const cv::Mat yuyv(h, w, CV_8UC2, buffer.data, bytes_per_line_);
          cv::extractChannel(yuyv, image, 0);
        } else {
          image = cv::Mat(h, w, CV_8UC1, buffer.data, bytes_per_line_).clone();
        }
      }
    }
  }
  return !corrupt;
}

std::optional<EyeFrame> V4l2Camera::try_dequeue(int timeout_ms) {
  v4l2_buffer b{};
  if (!dequeue_buffer(timeout_ms, b)) return std::nullopt;
  const std::uint64_t dropped = continue_sequence(b.sequence);
  const std::int64_t time_ns = frame_time_ns(b);
  cv::Mat image;
  const bool corrupt = !decode_luminance(b, image);

  if (const int r = device_->ioctl(fd_, VIDIOC_QBUF, &b); r < 0) {
    lose_device(r == -ENODEV ? camera_label() + ": device disconnected (" + errno_text(ENODEV) + " at VIDIOC_QBUF)"
                             : camera_label() + ": VIDIOC_QBUF failed: " + errno_text(-r));
    std::lock_guard lock(status_mutex_);
    status_.dropped += dropped;
    return std::nullopt;
  }

  std::lock_guard lock(status_mutex_);
  status_.dropped += dropped + (corrupt ? 1 : 0);
  if (corrupt) return std::nullopt;
  ++status_.frames;
  return EyeFrame{std::move(image), time_ns, last_sequence_};
}

FrameSourceStatus V4l2Camera::status() const {
  std::lock_guard lock(status_mutex_);
  return status_;
}

std::vector<CameraMode> V4l2Camera::supported_modes() const { return modes_; }
CameraMode V4l2Camera::mode() const { return mode_; }
std::vector<std::string> V4l2Camera::notes() const { return notes_; }
std::uint64_t V4l2Camera::reconnects() const { return reconnects_; }

V4l2CameraOptions parse_camera_spec(const std::string& spec) {
  const std::string prefix = "camera:";
  if (spec.rfind(prefix, 0) != 0) throw std::invalid_argument("'" + spec + "' is not a camera:/dev/videoN source");
  V4l2CameraOptions o;
  const std::string rest = spec.substr(prefix.size());
  const auto q = rest.find('?');
  o.device = rest.substr(0, q);
  if (o.device.empty()) throw std::invalid_argument("camera source '" + spec + "' names no device (camera:/dev/videoN)");
  if (q == std::string::npos) return o;
  const std::string query = rest.substr(q + 1);
  std::size_t pos = 0;
  while (pos <= query.size()) {
    const auto amp = std::min(query.find('&', pos), query.size());
    const std::string item = query.substr(pos, amp - pos);
    pos = amp + 1;
    if (item.empty()) continue;
    const auto eq = item.find('=');
    const std::string key = item.substr(0, eq), value = eq == std::string::npos ? "" : item.substr(eq + 1);
    const auto bad = [&](const std::string& range) {
      return std::invalid_argument("camera source '" + spec + "': " + key + "='" + value + "' is not " + range);
    };
    const auto integer = [&](std::int64_t lo, std::int64_t hi) {
      std::int64_t v = 0;
      const auto r = std::from_chars(value.data(), value.data() + value.size(), v);
      if (value.empty() || r.ec != std::errc{} || r.ptr != value.data() + value.size() || v < lo || v > hi) {
        throw bad("an integer in " + std::to_string(lo) + ".." + std::to_string(hi));
      }
      return v;
    };
    if (key == "width") {
      o.width = static_cast<std::uint32_t>(integer(0, 16384));
    } else if (key == "height") {
      o.height = static_cast<std::uint32_t>(integer(0, 16384));
    } else if (key == "buffers") {
      o.buffers = static_cast<std::uint32_t>(integer(1, 32));
    } else if (key == "exposure") {
      o.exposure = static_cast<std::int32_t>(integer(INT32_MIN, INT32_MAX));
    } else if (key == "gain") {
      o.gain = static_cast<std::int32_t>(integer(INT32_MIN, INT32_MAX));
    } else if (key == "fps") {
      double v = 0;
      const auto r = std::from_chars(value.data(), value.data() + value.size(), v);
      if (value.empty() || r.ec != std::errc{} || r.ptr != value.data() + value.size() || !(v >= 0) || v > 10000) {
        throw bad("a frame rate in 0..10000");
      }
      o.fps = v;
    } else {
      throw std::invalid_argument("camera source '" + spec + "': unknown option '" + key +
                                  "' (allowed: width, height, fps, buffers, exposure, gain)");
    }
  }
  return o;
}

std::unique_ptr<FrameSource> make_camera_source(const std::string& spec) {
  return std::make_unique<V4l2Camera>(parse_camera_spec(spec));
}

}  // namespace fovea::trackerd
