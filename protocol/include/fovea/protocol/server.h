// SPDX-License-Identifier: Apache-2.0
#pragma once
// GazeServer: the publishing side of the gaze protocol. It answers the handshake, keeps leases,
// and sends every published sample/event to each subscriber by unicast and, optionally, to a
// multicast group.
#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "fovea/protocol/codec.h"
#include "fovea/protocol/cookie.h"
#include "fovea/protocol/messages.h"
#include "fovea/protocol/udp.h"

namespace fovea::protocol {

struct MulticastTarget {
  Endpoint group;               // e.g. 239.255.47.80:47801
  std::uint8_t ttl = 1;
  std::uint32_t interface_ip = 0;  // 0: kernel's choice
};
// "GROUP:PORT"; throws std::invalid_argument when GROUP is not in 224.0.0.0/4 or PORT is missing.
MulticastTarget parse_multicast(const std::string& text);

// An IPv4 network in CIDR notation ("127.0.0.0/8", "192.168.1.20/32", or a bare address = /32).
struct Ipv4Cidr {
  std::uint32_t network = 0;  // host byte order, host bits cleared
  std::uint8_t prefix = 32;   // 0..32
  bool contains(std::uint32_t ip) const;
  std::string to_string() const;
  friend bool operator==(const Ipv4Cidr&, const Ipv4Cidr&) = default;
};
// Throws std::invalid_argument naming the text and the expected form. Host bits set below the
// prefix ("10.1.2.3/8") are an error: they usually mean a typo in the prefix length.
Ipv4Cidr parse_cidr(const std::string& text);
bool allowed(const std::vector<Ipv4Cidr>& list, std::uint32_t ip);

struct ServerOptions {
  Endpoint listen{0x7F000001, kDefaultPort};  // 127.0.0.1:47800
  std::uint32_t default_lease_ms = 5000;
  std::uint32_t min_lease_ms = 200;
  // A minute: ample for a client that heartbeats every 500 ms, short enough that sessions a client
  // abandoned (or a flood of them) free their slots soon (issue 23 item 4: 10-minute leases asked
  // for by one process locked everyone else out for 10 minutes).
  std::uint32_t max_lease_ms = 60'000;
  std::uint32_t cookie_lifetime_ms = 10'000;
  std::size_t max_subscribers = 256;
  // Sessions one source address may hold, so that one host cannot take the whole table. (Local
  // processes share 127.0.0.1, but may also bind other loopback addresses: the lease cap bounds
  // what they can hold on to.)
  std::size_t max_subscribers_per_address = 64;
  std::optional<MulticastTarget> multicast;
  DisplayGeometry display;
  double nominal_rate_hz = 0;
  std::string source_name;
  // Who may send CONTROL_REQUEST over UDP; everyone else is refused and counted. A source address
  // is all that is checked, so the default is nobody: a daemon takes commands through its local
  // control socket (control_socket.h), whose file permissions say who.
  std::vector<Ipv4Cidr> control_allow;
  // MARKER (PROTOCOL.md §4.17): what one session may send, as a token bucket (a burst of this many,
  // refilled at this rate), and how far a sender's own time may lie from the receive time.
  double marker_rate_per_s = 100;
  std::int64_t marker_max_time_offset_ns = 60'000'000'000;
};

struct SubscriberInfo {
  std::uint64_t session_id = 0;
  Endpoint address;
  std::uint32_t streams = 0;
  std::uint32_t lease_ms = 0;
  std::int64_t expires_ns = 0;
};

struct ServerStats {
  std::uint64_t samples_published = 0;
  std::uint64_t events_published = 0;
  std::uint64_t datagrams_sent = 0;
  std::uint64_t send_failures = 0;
  std::uint64_t datagrams_rejected = 0;  // failed to decode
  std::uint64_t requests_refused = 0;    // decoded, answered with ERROR
  std::uint64_t unexpected_messages = 0; // decoded but not a request (e.g. a GAZE_SAMPLE sent to us)
  std::uint64_t leases_expired = 0;
  std::uint64_t control_requests = 0;  // CONTROL_REQUEST from allowed addresses (handled or failed)
  std::uint64_t control_refused = 0;   // CONTROL_REQUEST from outside the allow-list, never executed
  std::uint64_t markers_published = 0;
  std::uint64_t markers_refused = 0;    // no session, rate limited or implausible time: answered ERROR
  std::uint64_t markers_repeated = 0;   // retransmissions of a marker already published
  std::size_t subscribers = 0;
};

// Executes an operator command; called on the server's control thread without the server's lock
// held (so it may call the server's setters), only for requests from allowed addresses.
using ControlHandler = std::function<ControlReply(const ControlRequest&, const Endpoint& from)>;
// Told of each marker as it was published (session_id 0, the server's times) and its sequence
// number; called on the control thread with the server's lock held, so it must not call the server.
using MarkerHandler = std::function<void(const Marker&, std::uint64_t sequence)>;

class GazeServer {
 public:
  // Binds the socket (throws std::system_error naming the address) and starts the control thread.
  explicit GazeServer(ServerOptions options);
  ~GazeServer();
  GazeServer(const GazeServer&) = delete;
  GazeServer& operator=(const GazeServer&) = delete;

  Endpoint local_endpoint() const { return socket_.local_endpoint(); }

  // Assign the next sequence number of their stream and send to every subscriber of it.
  // `sample.tracker_time_ns` becomes the header's origin time. Thread-safe. Returns the sequence
  // number the item was sent with.
  std::uint64_t publish(const GazeSample& sample);
  // The same, for a sample that reached the daemon at `host_receive_ns` (its clock), later than the
  // tracker's own timestamp says: that time becomes the header's origin time (PROTOCOL.md §2).
  std::uint64_t publish(const GazeSample& sample, std::int64_t host_receive_ns);
  // A marker of the daemon's own (a replayed recording's) on the marker stream, as if a client had
  // sent it: session_id 0; the marker handler is told too.
  std::uint64_t publish(const Marker& marker);
  std::uint64_t publish(const GazeEvent& event);

  void set_source_state(SourceState s) { source_state_.store(s); }
  // A changed geometry is sent at once to every session in an unasked SUBSCRIBED (PROTOCOL.md
  // §4.5): their normalized coordinates mean another screen from the next sample on.
  void set_display(const DisplayGeometry& g);
  void set_nominal_rate(double hz);
  // Live changes (e.g. on a configuration reload); existing sessions keep their address and
  // sequence numbers and lease. A lower max_subscribers refuses new sessions but drops none; a new
  // default lease applies to subscriptions that do not ask for a lease of their own from now on.
  void set_limits(std::uint32_t default_lease_ms, std::size_t max_subscribers);
  void set_control_allow(std::vector<Ipv4Cidr> allow);
  std::vector<Ipv4Cidr> control_allow() const;
  void on_control(ControlHandler handler);
  void on_marker(MarkerHandler handler);
  ServerStats stats() const;
  std::vector<SubscriberInfo> subscribers() const;
  const DecodeCounters& decode_counters() const { return rejected_; }
  // Called (on the control thread) when subscribers come and go; for logging.
  void on_subscriber_change(std::function<void(const SubscriberInfo&, const char* what)> cb);

  void stop();

 private:
  void control_loop();
  void handle(const Message& m, const Endpoint& from, std::int64_t received_ns);
  void handle_control(const Message& m, const Endpoint& from);
  // The per-request stages of handle(); all run with mutex_ held by handle().
  void handle_subscribe(const Subscribe& sub, std::uint64_t seq, const Endpoint& from, std::int64_t received_ns);
  void handle_heartbeat(const Heartbeat& hb, std::uint64_t seq, const Endpoint& from, std::int64_t received_ns);
  void handle_unsubscribe(const Unsubscribe& un, const Endpoint& from);
  std::uint64_t send_marker(const std::unique_lock<std::mutex>& held, const Marker& published);
  void send_eyes(const std::unique_lock<std::mutex>& held, const GazeSample& sample, std::int64_t origin_ns);
  void send_to_subscribers(const std::unique_lock<std::mutex>& held, std::uint32_t stream_bit, std::uint64_t sequence,
                           std::int64_t origin_ns, const Payload& p, bool to_group);
  void handle_marker(const std::unique_lock<std::mutex>& held, const Marker& marker, std::uint64_t seq,
                     const Endpoint& from, std::int64_t received_ns);
  SubscriberInfo& new_session(const Endpoint& from);
  Subscribed subscribed_reply(const SubscriberInfo& session) const;
  StatusReply status_reply(std::int64_t received_ns) const;
  void reply(const Endpoint& to, std::uint64_t sequence, Payload payload, std::int64_t origin_ns = 0);
  void refuse(const Endpoint& to, std::uint64_t sequence, MessageType request, ErrorCode code);
  void expire_leases(std::int64_t now_ns);
  std::uint32_t clamp_lease(std::uint32_t requested) const;
  // Sends one message of a stream to its subscribers. `held` is the caller's lock of mutex_ (checked in
  // debug builds): sequence numbers and subscriber lists must not change while a message goes out.
  std::uint64_t send_stream(const std::unique_lock<std::mutex>& held, std::uint32_t stream_bit, std::uint64_t& sequence,
                            std::int64_t origin_ns, const Payload& p);

  ServerOptions options_;
  UdpSocket socket_;
  UdpSocket multicast_socket_;
  CookieJar cookies_;
  std::int64_t started_ns_;
  std::atomic<SourceState> source_state_{SourceState::Running};

  mutable std::mutex mutex_;  // guards everything below
  std::unordered_map<std::uint64_t, SubscriberInfo> sessions_;
  std::uint64_t next_sample_seq_ = 0;
  std::uint64_t next_event_seq_ = 0;
  std::uint64_t next_marker_seq_ = 0;
  std::uint64_t next_provisional_seq_ = 0;
  // Per session: the marker token bucket, and the last markers it published (so a retransmission
  // is answered with the same copy, not published twice). Entries of ended sessions are dropped
  // when leases are checked.
  struct MarkerState {
    double tokens = 0;
    std::int64_t refilled_ns = 0;
    struct Sent { std::uint64_t marker_id, sequence; Marker published; };
    std::deque<Sent> recent;  // at most 32
  };
  std::unordered_map<std::uint64_t, MarkerState> marker_state_;
  MarkerHandler on_marker_;
  ServerStats stats_;
  std::vector<Endpoint> targets_;  // scratch for publish
  std::function<void(const SubscriberInfo&, const char*)> on_change_;
  ControlHandler on_control_;
  // Replies to the last few control requests, so a retransmitted request (its reply was lost) is
  // answered again instead of executed twice.
  struct RecentControl {
    Endpoint from;
    std::uint64_t sequence = 0;
    ControlRequest request;
    ControlReply reply;
  };
  std::vector<RecentControl> recent_control_;  // control thread only

  DecodeCounters rejected_;
  std::atomic<bool> running_{true};
  std::thread thread_;
};

}  // namespace fovea::protocol
