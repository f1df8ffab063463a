// SPDX-License-Identifier: Apache-2.0
#pragma once
// GazeClient: subscribes to a fovea-trackerd stream, keeps the subscription alive, resubscribes by
// itself when the daemon restarts, and measures what it receives.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "fovea/protocol/codec.h"
#include "fovea/protocol/messages.h"
#include "fovea/protocol/sequence_tracker.h"
#include "fovea/protocol/udp.h"

namespace fovea::protocol {

struct ClientOptions {
  Endpoint server{0x7F000001, kDefaultPort};
  std::uint32_t streams = kStreamSamples | kStreamEvents;
  std::uint32_t requested_lease_ms = 5000;
  std::uint32_t heartbeat_interval_ms = 500;  // also bounds how fast a daemon restart is noticed
  std::uint32_t retry_interval_ms = 200;      // HELLO/SUBSCRIBE retransmission while not subscribed
  std::string name = "fovea-client";
  // Receive samples from this multicast group instead of unicast (events stay unicast). Group
  // datagrams are accepted only from the server's IP address.
  std::optional<Endpoint> multicast_group;
  std::uint32_t multicast_interface_ip = 0;
  std::size_t queue_capacity = 4096;  // for poll(); the oldest are dropped when full
};

// What a callback receives besides the message itself.
struct Arrival {
  std::uint64_t sequence = 0;
  std::int64_t receive_ns = 0;   // client clock
  std::int64_t latency_ns = 0;   // receive time minus the server's send time mapped to our clock
  // GAZE_SAMPLE: when the sample reached the daemon from the tracker (the header's origin time, on
  // the daemon's clock like tracker_time_ns; equal to it for sources without a clock of their own).
  std::int64_t host_receive_ns = 0;
};

struct ClientStats {
  SequenceCounts samples;
  SequenceCounts events;
  SequenceCounts markers;
  SequenceCounts provisional;  // provisional events and retractions (kStreamProvisional)
  std::uint64_t markers_sent = 0;         // by mark(), retransmissions not counted
  std::uint64_t markers_confirmed = 0;    // came back on the marker stream
  std::uint64_t markers_unconfirmed = 0;  // given up after kMarkerAttempts sends without a copy back
  std::uint64_t eye_samples = 0;       // samples delivered with their GAZE_EYES (kStreamEyes)
  std::uint64_t rejected = 0;          // datagrams that failed to decode or came from elsewhere
  std::uint64_t queue_dropped = 0;
  std::uint64_t subscriptions = 0;     // successful SUBSCRIBED, first one included
  std::uint64_t errors_received = 0;
  std::optional<ErrorCode> last_error;  // the last ERROR the server sent (why it refused, if it did)
  std::int64_t clock_offset_ns = 0;    // server clock minus client clock
  std::int64_t clock_round_trip_ns = -1;
  // Latency over the most recent samples (window of 65536): publish on the server to arrival here.
  std::int64_t latency_p50_ns = 0, latency_p99_ns = 0, latency_max_ns = 0;
  std::size_t latency_count = 0;
};

class GazeClient {
 public:
  using SampleCallback = std::function<void(const GazeSample&, const Arrival&)>;
  using EventCallback = std::function<void(const GazeEvent&, const Arrival&)>;
  using MarkerCallback = std::function<void(const Marker&, const Arrival&)>;
  static constexpr int kMarkerAttempts = 8;  // a marker is sent again every 250 ms until confirmed

  explicit GazeClient(ClientOptions options);
  ~GazeClient();  // unsubscribes and stops
  GazeClient(const GazeClient&) = delete;
  GazeClient& operator=(const GazeClient&) = delete;

  // Callbacks run on the client's receive thread; set them before start().
  void on_sample(SampleCallback cb) { on_sample_ = std::move(cb); }
  void on_event(EventCallback cb) { on_event_ = std::move(cb); }
  void on_marker(MarkerCallback cb) { on_marker_ = std::move(cb); }
  void start();
  void stop();  // sends UNSUBSCRIBE when subscribed

  bool wait_subscribed(int timeout_ms);
  bool subscribed() const { return subscribed_.load(); }
  std::optional<Subscribed> session() const;
  std::optional<GazeSample> latest_sample() const;
  // Moves up to `max` queued samples (oldest first) into `out`; returns how many.
  std::size_t poll(std::vector<std::pair<GazeSample, Arrival>>& out, std::size_t max = SIZE_MAX);
  ClientStats stats() const;
  // Full latency record (nanoseconds) since start, for reports; bounded to 10^7 entries.
  std::vector<std::int64_t> latencies() const;

  // Sends an experiment marker (PROTOCOL.md §4.17) and returns its id; thread-safe. Without a time
  // the daemon stamps it when it arrives; with `client_time_ns` (this host's CLOCK_MONOTONIC, e.g.
  // a display flip's time) it is mapped to the daemon's clock through TIME_SYNC. When the
  // subscription includes kStreamMarkers, the marker is sent again until its copy comes back on
  // that stream (or kMarkerAttempts sends), across a daemon restart too; otherwise it is sent once.
  // Throws std::invalid_argument for a label that is empty, longer than 63 bytes, not UTF-8 or with
  // control characters, and std::logic_error when not subscribed, or (with a time) before the
  // clock offset is known.
  std::uint64_t mark(const std::string& label, std::optional<std::int64_t> client_time_ns = std::nullopt);
  // mark()'s label check alone (std::invalid_argument naming the offending byte), for callers that
  // want to refuse a label before they connect.
  static void check_marker_label(const std::string& label);
  // The marker's copy as the daemon published it, once it came back (needs kStreamMarkers).
  std::optional<Marker> wait_marker(std::uint64_t marker_id, int timeout_ms);
  // True once a TIME_SYNC exchange has given the clock offset.
  bool clock_known() const;
  // TIME_SYNC exchanges counted this session. The first kClockBurst go out 50 ms apart, so once
  // this reaches kClockBurst the offset is the least-delay one of them (one exchange alone can be
  // off by half a round trip that a loaded host stretched).
  std::uint32_t clock_exchanges() const;
  static constexpr std::uint32_t kClockBurst = 4;

  // One-shot request/reply helpers (no subscription), used by `fovea-ctl status`.
  static std::optional<StatusReply> query_status(const Endpoint& server, int timeout_ms);
  // Sends an operator command (CONTROL_REQUEST, PROTOCOL.md §4.15) and waits for its reply;
  // nullopt when none came within `timeout_ms`. Throws std::invalid_argument when the request
  // cannot be encoded (an argument longer than 63 bytes).
  static std::optional<ControlReply> send_control(const Endpoint& server, const ControlRequest& request,
                                                  int timeout_ms);

 private:
  void loop();
  void send(Payload p);
  void handle(const Message& m, std::int64_t now);
  void handle_gaze(const Message& m, std::int64_t now);
  void handle_marker(const Message& m, std::int64_t now);
  void handle_eyes(const Message& m);
  void attach_eyes(GazeSample& s, std::uint64_t sequence);  // mutex_ held
  void resend_markers(std::int64_t now);
  void on_time_sync(const TimeSyncReply& t, std::int64_t now);
  void begin_handshake(std::int64_t now, bool fresh);

  ClientOptions options_;
  UdpSocket socket_;
  UdpSocket multicast_socket_;
  SampleCallback on_sample_;
  EventCallback on_event_;
  MarkerCallback on_marker_;

  enum class State { Hello, Subscribe, Subscribed };
  State state_ = State::Hello;
  std::uint64_t nonce_ = 0;
  Cookie cookie_{};
  std::atomic<std::uint64_t> request_seq_{0};  // send() runs on the loop and in mark()
  std::atomic<std::int64_t> last_sent_ns_{0};
  std::int64_t retry_after_ns_ = 0;  // after a refusal (TooManySubscribers, UnsupportedVersion)
  std::int64_t last_heard_ns_ = 0;  // last HEARTBEAT reply or stream datagram from the server
  std::int64_t next_time_sync_ns_ = 0;
  std::uint32_t time_syncs_done_ = 0;

  mutable std::mutex mutex_;
  std::condition_variable subscribed_cv_;
  std::optional<Subscribed> session_;
  std::optional<GazeSample> latest_;
  std::optional<std::pair<std::uint64_t, GazeEyes>> pending_eyes_;  // the last GAZE_EYES, until its sample
  std::deque<std::pair<GazeSample, Arrival>> queue_;
  SequenceTracker sample_seq_, event_seq_, marker_seq_, provisional_seq_;
  struct PendingMarker {
    Marker marker;  // session_id filled in when sent
    std::int64_t sent_ns = 0;
    int attempts = 0;
  };
  std::vector<PendingMarker> pending_markers_;
  std::deque<Marker> confirmed_markers_;  // the last 64 of ours that came back
  std::condition_variable marker_cv_;
  ClientStats stats_;
  std::vector<std::int64_t> latency_ring_;
  std::size_t latency_next_ = 0;
  std::vector<std::int64_t> latency_all_;
  struct SyncSample { std::int64_t offset, delay; };
  std::deque<SyncSample> sync_samples_;
  std::deque<std::int64_t> sync_sent_;  // client_send_ns of the requests awaiting a reply (the last few)

  DecodeCounters rejected_;
  std::atomic<bool> subscribed_{false};
  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace fovea::protocol

namespace fovea {
using protocol::GazeClient;  // the client library's public name
}  // namespace fovea
