// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/viewer_feed.h"

#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/wire.h"
#include "local_socket.h"

namespace fovea::protocol {

using wire::load_le;
using wire::store_le;

namespace {

constexpr std::array<std::uint8_t, 4> kMagic{'F', 'V', 'E', 'F'};
constexpr std::array<std::uint8_t, 4> kStatusMagic{'F', 'V', 'S', 'T'};
constexpr std::uint8_t kVersion = 1;

// Field offsets (PROTOCOL.md §17.2).
enum Off : std::size_t {
  kOffMagic = 0, kOffVersion = 4, kOffFlags = 5, kOffHeaderSize = 6, kOffFrame = 8, kOffTime = 16,
  kOffDetect = 24, kOffSourceW = 28, kOffSourceH = 30, kOffWidth = 32, kOffHeight = 34, kOffPupil = 36,
  kOffConfidence = 56, kOffRoi = 60, kOffGlintCount = 76, kOffGlints = 80,
};

bool finite(float v) { return std::isfinite(v); }

void check_info(const EyeFrameInfo& i) {
  const float values[] = {i.pupil_x, i.pupil_y, i.pupil_major, i.pupil_minor, i.pupil_angle_deg, i.confidence,
                          i.roi_x, i.roi_y, i.roi_width, i.roi_height};
  if (!std::all_of(std::begin(values), std::end(values), finite)) {
    throw std::invalid_argument("eye frame: a non-finite value in the detection result");
  }
  if (i.glint_count > kMaxEyeGlints) throw std::invalid_argument("eye frame: more than 8 glints");
  for (std::size_t g = 0; g < i.glint_count; ++g) {
    if (!finite(i.glint_x[g]) || !finite(i.glint_y[g])) throw std::invalid_argument("eye frame: a non-finite glint");
  }
  if ((i.flags & ~kEyeFrameFlagsMask) != 0) throw std::invalid_argument("eye frame: undefined flag bits");
}

// Whole-factor box downscale (factor >= 2).
void downscale(const std::uint8_t* src, int w, int h, std::size_t stride, int factor, std::vector<std::uint8_t>& out,
               int& out_w, int& out_h) {
  out_w = w / factor;
  out_h = h / factor;
  out.resize(static_cast<std::size_t>(out_w) * static_cast<std::size_t>(out_h));
  const unsigned area = static_cast<unsigned>(factor * factor);
  for (int y = 0; y < out_h; ++y) {
    for (int x = 0; x < out_w; ++x) {
      unsigned sum = 0;
      for (int dy = 0; dy < factor; ++dy) {
        const std::uint8_t* row = src + static_cast<std::size_t>(y * factor + dy) * stride + x * factor;
        for (int dx = 0; dx < factor; ++dx) sum += row[dx];
      }
      out[static_cast<std::size_t>(y) * static_cast<std::size_t>(out_w) + static_cast<std::size_t>(x)] =
          static_cast<std::uint8_t>((sum + area / 2) / area);
    }
  }
}

}  // namespace

std::vector<std::uint8_t> encode_eye_frame(const EyeFrameInfo& info, std::uint16_t width, std::uint16_t height,
                                           std::span<const std::uint8_t> pixels) {
  if (width == 0 || height == 0 || width > kMaxEyeFrameSide || height > kMaxEyeFrameSide) {
    throw std::invalid_argument("eye frame: image " + std::to_string(width) + "x" + std::to_string(height) +
                                " (allowed 1..1024 each)");
  }
  const std::size_t n = static_cast<std::size_t>(width) * height;
  if (pixels.size() != n) throw std::invalid_argument("eye frame: pixel count does not match the size");
  check_info(info);
  std::vector<std::uint8_t> out(kEyeFrameHeaderSize + n, 0);
  std::span<std::uint8_t> b(out);
  std::copy(kMagic.begin(), kMagic.end(), out.begin());
  out[kOffVersion] = kVersion;
  out[kOffFlags] = info.flags;
  store_le<std::uint16_t>(b, kOffHeaderSize, static_cast<std::uint16_t>(kEyeFrameHeaderSize));
  store_le(b, kOffFrame, info.frame);
  store_le(b, kOffTime, info.time_ns);
  store_le(b, kOffDetect, info.detect_ns);
  store_le(b, kOffSourceW, info.source_width);
  store_le(b, kOffSourceH, info.source_height);
  store_le(b, kOffWidth, width);
  store_le(b, kOffHeight, height);
  const float pupil[] = {info.pupil_x, info.pupil_y, info.pupil_major, info.pupil_minor, info.pupil_angle_deg};
  for (std::size_t k = 0; k < 5; ++k) store_le(b, kOffPupil + 4 * k, pupil[k]);
  store_le(b, kOffConfidence, info.confidence);
  const float roi[] = {info.roi_x, info.roi_y, info.roi_width, info.roi_height};
  for (std::size_t k = 0; k < 4; ++k) store_le(b, kOffRoi + 4 * k, roi[k]);
  out[kOffGlintCount] = info.glint_count;
  for (std::size_t g = 0; g < info.glint_count; ++g) {
    store_le(b, kOffGlints + 8 * g, info.glint_x[g]);
    store_le(b, kOffGlints + 8 * g + 4, info.glint_y[g]);
  }
  std::copy(pixels.begin(), pixels.end(), out.begin() + kEyeFrameHeaderSize);
  return out;
}

std::optional<EyeFrameMessage> decode_eye_frame(std::span<const std::uint8_t> b, std::string& error) {
  const auto fail = [&](std::string why) -> std::optional<EyeFrameMessage> {
    error = "eye frame: " + std::move(why);
    return std::nullopt;
  };
  if (b.size() < kEyeFrameHeaderSize) return fail("shorter than its 144-byte header");
  if (!std::equal(kMagic.begin(), kMagic.end(), b.begin())) return fail("bad magic (not FVEF)");
  if (b[kOffVersion] != kVersion) return fail("version " + std::to_string(b[kOffVersion]) + " (1 understood)");
  if (load_le<std::uint16_t>(b, kOffHeaderSize) != kEyeFrameHeaderSize) return fail("header size is not 144");
  EyeFrameMessage m;
  EyeFrameInfo& i = m.info;
  i.flags = b[kOffFlags];
  if ((i.flags & ~kEyeFrameFlagsMask) != 0) return fail("undefined flag bits set");
  i.frame = load_le<std::uint64_t>(b, kOffFrame);
  i.time_ns = load_le<std::int64_t>(b, kOffTime);
  i.detect_ns = load_le<std::uint32_t>(b, kOffDetect);
  i.source_width = load_le<std::uint16_t>(b, kOffSourceW);
  i.source_height = load_le<std::uint16_t>(b, kOffSourceH);
  m.width = load_le<std::uint16_t>(b, kOffWidth);
  m.height = load_le<std::uint16_t>(b, kOffHeight);
  if (m.width == 0 || m.height == 0 || m.width > kMaxEyeFrameSide || m.height > kMaxEyeFrameSide) {
    return fail("image " + std::to_string(m.width) + "x" + std::to_string(m.height) + " (allowed 1..1024 each)");
  }
  if (b.size() != kEyeFrameHeaderSize + static_cast<std::size_t>(m.width) * m.height) {
    return fail("length " + std::to_string(b.size()) + " does not match a " + std::to_string(m.width) + "x" +
                std::to_string(m.height) + " image");
  }
  float* pupil[] = {&i.pupil_x, &i.pupil_y, &i.pupil_major, &i.pupil_minor, &i.pupil_angle_deg};
  for (std::size_t k = 0; k < 5; ++k) *pupil[k] = load_le<float>(b, kOffPupil + 4 * k);
  i.confidence = load_le<float>(b, kOffConfidence);
  float* roi[] = {&i.roi_x, &i.roi_y, &i.roi_width, &i.roi_height};
  for (std::size_t k = 0; k < 4; ++k) *roi[k] = load_le<float>(b, kOffRoi + 4 * k);
  i.glint_count = b[kOffGlintCount];
  if (i.glint_count > kMaxEyeGlints) return fail("more than 8 glints");
  if (b[77] != 0 || b[78] != 0 || b[79] != 0) return fail("reserved bytes 77..79 not zero");
  for (std::size_t g = 0; g < kMaxEyeGlints; ++g) {
    const float x = load_le<float>(b, kOffGlints + 8 * g), y = load_le<float>(b, kOffGlints + 8 * g + 4);
    if (g >= i.glint_count) {
      if (x != 0 || y != 0) return fail("unused glint slots not zero");
      continue;
    }
    i.glint_x[g] = x;
    i.glint_y[g] = y;
  }
  try {
    check_info(i);
  } catch (const std::invalid_argument& e) {
    error = e.what();
    return std::nullopt;
  }
  m.pixels.assign(b.begin() + kEyeFrameHeaderSize, b.end());
  return m;
}

std::vector<std::uint8_t> encode_daemon_status(const std::string& json) {
  if (json.size() > kMaxStatusJson) throw std::invalid_argument("daemon status: longer than 16384 bytes");
  if (json.find('\0') != std::string::npos) throw std::invalid_argument("daemon status: a NUL byte in the text");
  std::vector<std::uint8_t> out(kStatusHeaderSize + json.size(), 0);
  std::copy(kStatusMagic.begin(), kStatusMagic.end(), out.begin());
  out[4] = kVersion;
  store_le<std::uint16_t>(std::span(out), 6, static_cast<std::uint16_t>(json.size()));
  std::copy(json.begin(), json.end(), out.begin() + kStatusHeaderSize);
  return out;
}

std::optional<ViewerMessage> decode_viewer_message(std::span<const std::uint8_t> b, std::string& error) {
  if (b.size() < 4 || !std::equal(kStatusMagic.begin(), kStatusMagic.end(), b.begin())) {
    auto frame = decode_eye_frame(b, error);
    if (!frame) return std::nullopt;
    return ViewerMessage{std::move(*frame)};
  }
  const auto fail = [&](std::string why) -> std::optional<ViewerMessage> {
    error = "daemon status: " + std::move(why);
    return std::nullopt;
  };
  if (b.size() < kStatusHeaderSize) return fail("shorter than its 8-byte header");
  if (b[4] != kVersion) return fail("version " + std::to_string(b[4]) + " (1 understood)");
  if (b[5] != 0) return fail("reserved byte 5 not zero");
  const std::size_t n = load_le<std::uint16_t>(b, 6);
  if (n > kMaxStatusJson || b.size() != kStatusHeaderSize + n) {
    return fail("length " + std::to_string(b.size()) + " does not match its text's " + std::to_string(n) + " bytes");
  }
  std::string json(b.begin() + kStatusHeaderSize, b.end());
  if (json.find('\0') != std::string::npos) return fail("a NUL byte in the text");
  return ViewerMessage{DaemonStatusMessage{std::move(json)}};
}

std::string viewer_socket_for(const std::string& control_socket) {
  const std::string suffix = ".sock";
  if (control_socket.size() > suffix.size() &&
      control_socket.compare(control_socket.size() - suffix.size(), suffix.size(), suffix) == 0) {
    return control_socket.substr(0, control_socket.size() - suffix.size()) + "-viewer.sock";
  }
  return control_socket + "-viewer";
}

// ---- the daemon's side ------------------------------------------------------------------------

ViewerFeedServer::ViewerFeedServer(const std::string& path, mode_t mode, ViewerFeedOptions options)
    : path_(path), options_(options) {
  if (!(options_.max_rate_hz > 0) || options_.max_width == 0 || options_.max_height == 0 || options_.max_readers == 0 ||
      options_.max_width > kMaxEyeFrameSide || options_.max_height > kMaxEyeFrameSide) {
    throw std::invalid_argument("viewer socket: rate > 0, size 1..1024 and at least one reader are needed");
  }
  local::Fd fd(local::listen_at(path, mode, 16, "viewer socket"));
  wake_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (wake_fd_ < 0) {
    ::unlink(path.c_str());
    throw std::system_error(errno, std::generic_category(), "viewer socket: eventfd");
  }
  listen_fd_ = fd.release();
  thread_ = std::thread([this] { serve(); });
}

ViewerFeedServer::~ViewerFeedServer() {
  stop_.store(true);
  const std::uint64_t one = 1;
  if (::write(wake_fd_, &one, sizeof one) < 0) {
    // An eventfd cannot be full after one write; nothing else to do.
  }
  if (thread_.joinable()) thread_.join();
  for (int fd : reader_fds_) ::close(fd);
  ::close(listen_fd_);
  ::close(wake_fd_);
  ::unlink(path_.c_str());
}

ViewerFeedServer::Stats ViewerFeedServer::stats() const {
  return {readers_.load(), offered_.load(), sent_.load(), dropped_.load(), refused_.load(), statuses_.load()};
}

bool ViewerFeedServer::wants(std::int64_t time_ns) const {
  if (readers_.load(std::memory_order_relaxed) == 0 || slot_full_.load(std::memory_order_acquire)) return false;
  const std::int64_t last = last_offer_ns_.load(std::memory_order_relaxed);
  const auto period = static_cast<std::int64_t>(1e9 / options_.max_rate_hz);
  return time_ns < last || time_ns - last >= period;  // a clock that went back (a looped file) starts again
}

void ViewerFeedServer::offer(const EyeFrameInfo& info, const std::uint8_t* pixels, int width, int height,
                           std::size_t stride) {
  if (pixels == nullptr || width <= 0 || height <= 0 || stride < static_cast<std::size_t>(width)) return;
  if (!wants(info.time_ns)) return;
  // The copy here is the loop's only cost (the sender downscales and encodes), bounded by the rate.
  slot_info_ = info;
  slot_width_ = width;
  slot_height_ = height;
  slot_pixels_.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y) {
    std::memcpy(slot_pixels_.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(width),
                pixels + static_cast<std::size_t>(y) * stride, static_cast<std::size_t>(width));
  }
  last_offer_ns_.store(info.time_ns, std::memory_order_relaxed);
  ++offered_;
  slot_full_.store(true, std::memory_order_release);
  const std::uint64_t one = 1;
  if (::write(wake_fd_, &one, sizeof one) < 0) {
    // EAGAIN only if the counter were near overflow; the sender is woken by the stop path anyway.
  }
}

void ViewerFeedServer::serve() {
  while (!stop_.load()) {
    std::array<pollfd, 2> fds{pollfd{listen_fd_, POLLIN, 0}, pollfd{wake_fd_, POLLIN, 0}};
    // Readers that hang up are noticed when a send fails, and at least once a second here.
    if (::poll(fds.data(), fds.size(), 1000) < 0 && errno != EINTR) return;
    if (stop_.load()) return;
    if ((fds[0].revents & POLLIN) != 0) accept_readers();
    if ((fds[1].revents & POLLIN) != 0) {
      std::uint64_t n = 0;
      if (::read(wake_fd_, &n, sizeof n) < 0) {
        // Nothing to drain (another wake raced us).
      }
    }
    if (slot_full_.load(std::memory_order_acquire)) send_slot();
    send_status();
    // Drop readers that have gone away even when no frame comes.
    std::erase_if(reader_fds_, [this](int fd) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 0) > 0 && (p.revents & (POLLHUP | POLLERR | POLLIN)) != 0) {
        char byte = 0;
        // Readers send nothing: any data, or end of stream, ends the connection.
        if (::recv(fd, &byte, 1, MSG_DONTWAIT) >= 0 || (errno != EAGAIN && errno != EWOULDBLOCK)) {
          ::close(fd);
          return true;
        }
      }
      return false;
    });
    readers_.store(reader_fds_.size());
  }
}

void ViewerFeedServer::accept_readers() {
  for (;;) {
    const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) return;
    if (reader_fds_.size() >= options_.max_readers) {
      ::close(fd);
      ++refused_;
      continue;
    }
    ::setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &options_.send_buffer_bytes, sizeof options_.send_buffer_bytes);
    reader_fds_.push_back(fd);
    readers_.store(reader_fds_.size());
  }
}

void ViewerFeedServer::send_slot() {
  const int factor = std::max({1, (slot_width_ + options_.max_width - 1) / options_.max_width,
                               (slot_height_ + options_.max_height - 1) / options_.max_height});
  // A frame that fits goes from the slot as it is; a larger one is downscaled first.
  std::vector<std::uint8_t> small;
  int w = slot_width_, h = slot_height_;
  if (factor > 1) {
    downscale(slot_pixels_.data(), slot_width_, slot_height_, static_cast<std::size_t>(slot_width_), factor, small, w, h);
  }
  const std::span<const std::uint8_t> pixels = factor > 1 ? std::span<const std::uint8_t>(small) : slot_pixels_;
  std::vector<std::uint8_t> bytes;
  try {
    if (w > 0 && h > 0) bytes = encode_eye_frame(slot_info_, static_cast<std::uint16_t>(w), static_cast<std::uint16_t>(h), pixels);
  } catch (const std::invalid_argument&) {
    bytes.clear();  // a detection result that cannot go on the wire: this frame is not shown
  }
  slot_full_.store(false, std::memory_order_release);
  if (bytes.empty()) return;
  send_to_readers(bytes, sent_);
}

void ViewerFeedServer::publish_status(std::string json) {
  if (readers_.load(std::memory_order_relaxed) == 0) return;
  {
    std::lock_guard lock(status_mutex_);
    status_ = std::move(json);
  }
  const std::uint64_t one = 1;
  if (::write(wake_fd_, &one, sizeof one) < 0) {
    // See offer().
  }
}

void ViewerFeedServer::send_status() {
  std::string json;
  {
    std::lock_guard lock(status_mutex_);
    json.swap(status_);
  }
  if (json.empty()) return;
  std::vector<std::uint8_t> bytes;
  try {
    bytes = encode_daemon_status(json);
  } catch (const std::invalid_argument&) {
    ++dropped_;
    return;
  }
  send_to_readers(bytes, statuses_);
}

// A reader whose buffer is full misses this message; one that has gone is forgotten.
void ViewerFeedServer::send_to_readers(const std::vector<std::uint8_t>& bytes, std::atomic<std::uint64_t>& sent) {
  std::erase_if(reader_fds_, [&](int fd) {
    if (::send(fd, bytes.data(), bytes.size(), MSG_DONTWAIT | MSG_NOSIGNAL) >= 0) {
      ++sent;
      return false;
    }
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS || errno == EMSGSIZE) {
      ++dropped_;
      return false;
    }
    ::close(fd);  // gone
    return true;
  });
  readers_.store(reader_fds_.size());
}

// ---- a reader ---------------------------------------------------------------------------------

ViewerFeedReader::ViewerFeedReader(const std::string& path) : buffer_(kEyeFrameHeaderSize + kMaxEyeFrameSide * kMaxEyeFrameSide + 1) {
  fd_ = local::connect_to(path);
  if (fd_ < 0) {
    const int e = errno;
    throw std::runtime_error("viewer socket " + escape_for_log(path) + ": " +
                             (e == EACCES ? std::string("permission denied (the viewer feed needs the daemon's group)")
                              : e == ENOENT || e == ECONNREFUSED
                                  ? std::string("not there (is fovea-trackerd running here, with this control socket?)")
                                  : std::string(std::strerror(e))));
  }
}

ViewerFeedReader::~ViewerFeedReader() {
  if (fd_ >= 0) ::close(fd_);
}

std::optional<ViewerMessage> ViewerFeedReader::next(int timeout_ms) {
  if (closed_) return std::nullopt;
  pollfd p{fd_, POLLIN, 0};
  if (::poll(&p, 1, timeout_ms) <= 0) return std::nullopt;
  const ssize_t n = ::recv(fd_, buffer_.data(), buffer_.size(), MSG_DONTWAIT | MSG_TRUNC);
  if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) {
    closed_ = true;
    return std::nullopt;
  }
  if (n < 0) return std::nullopt;
  if (static_cast<std::size_t>(n) > buffer_.size()) {
    ++rejected_;
    last_error_ = "viewer message: longer than the largest allowed";
    return std::nullopt;
  }
  std::string error;
  auto m = decode_viewer_message(std::span<const std::uint8_t>(buffer_.data(), static_cast<std::size_t>(n)), error);
  if (!m) {
    ++rejected_;
    last_error_ = error;
  }
  return m;
}

}  // namespace fovea::protocol
