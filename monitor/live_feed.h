// SPDX-License-Identifier: Apache-2.0
#pragma once
// What fovea-monitor shows, gathered from the daemon as any client would (MONITOR.md "Data"):
//  - the gaze stream (GazeClient: samples, final and provisional events, markers), sent to the
//    pages in batches BATCH_HZ times a second;
//  - the viewer feed (the Unix socket beside the control socket, PROTOCOL.md §17): eye frames,
//    JPEG-encoded here (never in the daemon), and the daemon's detailed status;
//  - STATUS_REPLY once a second, with what this client measures itself (rate, loss, clock offset
//    and drift, latency).
// Page commands (markers, recording start/stop) are run on a worker thread, and only when this
// user may use the daemon's control socket.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "fovea/protocol/client.h"
#include "fovea/protocol/viewer_feed.h"
#include "web_server.h"

namespace fovea::monitor {

struct FeedOptions {
  protocol::Endpoint server{0x7F000001, protocol::kDefaultPort};
  std::string control_socket;  // "": the daemon's default places for its port
  std::string viewer_socket;   // "": beside the control socket
  double batch_hz = 60;        // gaze batches per second to the pages
  int jpeg_quality = 80;
};

struct FeedStats {
  std::uint64_t samples = 0, events = 0, batches = 0, eye_frames = 0, daemon_statuses = 0, commands = 0;
  std::int64_t jpeg_ns_total = 0;  // time spent encoding eye frames
  bool viewer_connected = false;
  std::string viewer_problem;      // why there is no viewer feed (socket missing, permission denied)
};

class LiveFeed {
 public:
  // Subscribes and starts its threads; what it gathers goes to `web`.
  LiveFeed(FeedOptions options, WebServer& web);
  ~LiveFeed();
  LiveFeed(const LiveFeed&) = delete;
  LiveFeed& operator=(const LiveFeed&) = delete;

  // For a page that just connected: hello, and the latest status, daemon status and eye frame.
  std::vector<Outgoing> opening_messages();
  // A page's command (JSON text); the reply goes to that page only.
  void on_page_message(WebServer::SessionId session, std::string text);
  FeedStats stats() const;
  const std::string& control_socket() const { return control_socket_; }
  const std::string& viewer_socket() const { return viewer_socket_; }
  bool controls() const;

 private:
  struct PendingSample {
    protocol::GazeSample sample;
    protocol::Arrival arrival;
  };
  struct Command {
    WebServer::SessionId session;
    std::string text;
  };
  void batch_loop();
  void viewer_loop();
  void status_loop();
  void send_batch();
  void send_status();
  void on_eye_frame(const protocol::EyeFrameMessage& frame);
  void on_daemon_status(const std::string& json);
  std::string run_command(const std::string& text);
  void remember(std::shared_ptr<const std::string>& slot, const std::shared_ptr<const std::string>& value);

  FeedOptions options_;
  WebServer& web_;
  std::string control_socket_, viewer_socket_;
  protocol::GazeClient client_;

  mutable std::mutex mutex_;  // guards everything below up to the threads
  std::vector<PendingSample> samples_;
  std::vector<protocol::GazeEvent> events_;
  std::vector<protocol::Marker> markers_;
  std::shared_ptr<const std::string> last_status_, last_daemon_, last_frame_;
  FeedStats stats_;
  std::deque<Command> commands_;
  std::condition_variable commands_cv_;
  // What the status loop measures between its runs.
  std::uint64_t dropouts_ = 0;
  bool last_valid_ = false;
  std::optional<std::pair<std::int64_t, std::int64_t>> first_offset_;  // (client time, offset) at the first sync

  std::atomic<bool> stop_{false};
  std::thread batch_thread_, viewer_thread_, status_thread_;
};

// The page's JSON for one sample row and one event (exposed for tests).
std::string sample_row_json(const protocol::GazeSample& s);
std::string event_json(const protocol::GazeEvent& e);

}  // namespace fovea::monitor
