// SPDX-License-Identifier: Apache-2.0
#pragma once
// The viewer feed (PROTOCOL.md §17): what a local viewer such as `fovea-monitor` needs besides the
// gaze stream, through a Unix-domain socket beside the control socket and with the same
// permissions (the daemon's user and group):
//  - EYE_FRAME: the eye camera's frames, downscaled and rate-limited, each with what the detector
//    found in it (eye images are the user's face, and the gaze protocol's 512-byte datagrams are no
//    place for them);
//  - DAEMON_STATUS: once a second, the daemon's state as JSON (source, its problem, calibration and
//    its validation, recording, LSL outlet), which the 160-byte STATUS_REPLY has no room for.
//
// SOCK_SEQPACKET: a reader connects and receives one message per frame or status, boundaries kept;
// it sends nothing. The publishing loop only copies a frame into a free slot (when a reader is
// connected and the rate allows) and never waits: a sender thread downscales and sends, and a
// reader whose socket buffer is full misses that message (counted) rather than delay anyone.
#include <sys/types.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <variant>
#include <vector>

namespace fovea::protocol {

inline constexpr std::size_t kEyeFrameHeaderSize = 144;
inline constexpr std::size_t kMaxEyeGlints = 8;
inline constexpr std::uint16_t kMaxEyeFrameSide = 1024;  // image width and height on the wire
inline constexpr std::size_t kStatusHeaderSize = 8;
inline constexpr std::size_t kMaxStatusJson = 16384;       // bytes of DAEMON_STATUS text

// EYE_FRAME flags.
inline constexpr std::uint8_t kEyeFramePupil = 0x01;      // a pupil was found (the ellipse is valid)
inline constexpr std::uint8_t kEyeFrameBlink = 0x02;      // the detector called the frame a blink
inline constexpr std::uint8_t kEyeFrameGlint = 0x04;      // the pupil-glint vector was valid
inline constexpr std::uint8_t kEyeFrameRoi = 0x08;        // found within the tracked search region
inline constexpr std::uint8_t kEyeFrameFlagsMask = 0x0F;

// What the detector made of one frame, in the camera's pixels (the source image, not the
// downscaled one: multiply by image/source size to draw).
struct EyeFrameInfo {
  std::uint64_t frame = 0;          // the daemon's count of frames detected (gaps: frames not sent)
  std::int64_t time_ns = 0;         // capture time, daemon's CLOCK_MONOTONIC (as the gaze sample's)
  std::uint32_t detect_ns = 0;      // the detector's time for this frame
  std::uint8_t flags = 0;
  std::uint16_t source_width = 0, source_height = 0;
  float pupil_x = 0, pupil_y = 0;   // ellipse centre, pixels (pixel i covers [i, i+1))
  float pupil_major = 0, pupil_minor = 0;  // full axis lengths, pixels
  float pupil_angle_deg = 0;        // major axis from +x towards +y, [0, 180)
  float confidence = 0;             // [0, 1]
  float roi_x = 0, roi_y = 0, roi_width = 0, roi_height = 0;  // the region searched last (0 size: none)
  std::uint8_t glint_count = 0;     // <= kMaxEyeGlints
  float glint_x[kMaxEyeGlints] = {}, glint_y[kMaxEyeGlints] = {};
  friend bool operator==(const EyeFrameInfo&, const EyeFrameInfo&) = default;
};

struct EyeFrameMessage {
  EyeFrameInfo info;
  std::uint16_t width = 0, height = 0;  // of the image that follows
  std::vector<std::uint8_t> pixels;      // width * height, 8-bit grey, row-major, top row first
};

// DAEMON_STATUS: a JSON object (UTF-8), PROTOCOL.md §17.4 lists its fields.
struct DaemonStatusMessage {
  std::string json;
};

using ViewerMessage = std::variant<EyeFrameMessage, DaemonStatusMessage>;

// Throws std::invalid_argument for a size out of range, non-finite values, or too many glints.
std::vector<std::uint8_t> encode_eye_frame(const EyeFrameInfo& info, std::uint16_t width, std::uint16_t height,
                                           std::span<const std::uint8_t> pixels);
// nullopt, with `error` naming the field, for anything PROTOCOL.md §17 rejects.
std::optional<EyeFrameMessage> decode_eye_frame(std::span<const std::uint8_t> bytes, std::string& error);
// Throws std::invalid_argument for text over kMaxStatusJson bytes or with a NUL byte.
std::vector<std::uint8_t> encode_daemon_status(const std::string& json);
// Either message; nullopt with `error` for anything else.
std::optional<ViewerMessage> decode_viewer_message(std::span<const std::uint8_t> bytes, std::string& error);

// The eye-frame socket that goes with a control socket: the same directory and name, "-viewer" before
// ".sock" (/run/fovea/control-47800.sock -> /run/fovea/control-47800-viewer.sock).
std::string viewer_socket_for(const std::string& control_socket);

struct ViewerFeedOptions {
  double max_rate_hz = 30;          // per the whole stream; frames beyond it are not copied
  std::uint16_t max_width = 320, max_height = 240;  // larger frames are downscaled by a whole factor
  std::size_t max_readers = 8;      // further connections are closed at once
  int send_buffer_bytes = 1 << 20;  // per reader: about 13 frames of 320x240
};

class ViewerFeedServer {
 public:
  struct Stats {
    std::size_t readers = 0;
    std::uint64_t offered = 0;   // frames copied from the loop
    std::uint64_t sent = 0;      // messages handed to readers' sockets (one per reader and frame)
    std::uint64_t dropped = 0;   // a reader's buffer was full: it missed that frame
    std::uint64_t refused = 0;   // connections beyond max_readers
    std::uint64_t statuses = 0;  // DAEMON_STATUS messages sent (one per reader)
  };

  // Creates the socket at `path` with `mode` (a stale socket of an earlier run is replaced; a live
  // one, or anything that is not a socket, is refused). Throws naming the path.
  ViewerFeedServer(const std::string& path, mode_t mode, ViewerFeedOptions options = {});
  ~ViewerFeedServer();  // stops and removes the socket file
  ViewerFeedServer(const ViewerFeedServer&) = delete;
  ViewerFeedServer& operator=(const ViewerFeedServer&) = delete;

  // The publishing loop's side; both are cheap and never block. `wants` is true when a reader is
  // connected, the rate allows a frame at `time_ns`, and the last one has been sent.
  bool wants(std::int64_t time_ns) const;
  // Copies the frame (8-bit grey, `stride` bytes per row) if wants(info.time_ns); else ignores it.
  void offer(const EyeFrameInfo& info, const std::uint8_t* pixels, int width, int height, std::size_t stride);
  // Readers connected (the loop composes a status only for someone).
  std::size_t readers() const { return readers_.load(std::memory_order_relaxed); }
  // Hands a DAEMON_STATUS to the sender (the newest replaces one not yet sent). Text that cannot be
  // sent (too long) is dropped and counted.
  void publish_status(std::string json);

  const std::string& path() const { return path_; }
  Stats stats() const;

 private:
  void serve();
  void accept_readers();
  void send_slot();
  void send_status();
  void send_to_readers(const std::vector<std::uint8_t>& bytes, std::atomic<std::uint64_t>& sent);

  std::string path_;
  ViewerFeedOptions options_;
  int listen_fd_ = -1;
  int wake_fd_ = -1;  // eventfd: a frame is ready, or stop
  std::atomic<bool> stop_{false};
  std::atomic<std::size_t> readers_{0};
  std::atomic<bool> slot_full_{false};
  std::atomic<std::int64_t> last_offer_ns_{INT64_MIN / 2};
  // The slot: written by the loop while slot_full_ is false, read by the sender while it is true.
  EyeFrameInfo slot_info_;
  int slot_width_ = 0, slot_height_ = 0;
  std::vector<std::uint8_t> slot_pixels_;
  std::mutex status_mutex_;
  std::string status_;  // the newest status not yet sent; empty: none
  std::vector<int> reader_fds_;  // the sender thread's only
  std::atomic<std::uint64_t> offered_{0}, sent_{0}, dropped_{0}, refused_{0}, statuses_{0};
  std::thread thread_;
};

// A reader of the viewer socket (fovea-monitor). Throws naming the path when it cannot connect
// (missing, permission denied: the viewer feed needs the daemon's group).
class ViewerFeedReader {
 public:
  explicit ViewerFeedReader(const std::string& path);
  ~ViewerFeedReader();
  ViewerFeedReader(const ViewerFeedReader&) = delete;
  ViewerFeedReader& operator=(const ViewerFeedReader&) = delete;
  // Waits up to timeout_ms. nullopt: no frame yet (closed() says whether the daemon went away);
  // a message that does not decode is counted in rejected() and skipped.
  std::optional<ViewerMessage> next(int timeout_ms);
  bool closed() const { return closed_; }
  std::uint64_t rejected() const { return rejected_; }
  const std::string& last_error() const { return last_error_; }

 private:
  int fd_ = -1;
  bool closed_ = false;
  std::uint64_t rejected_ = 0;
  std::string last_error_;
  std::vector<std::uint8_t> buffer_;
};

}  // namespace fovea::protocol
