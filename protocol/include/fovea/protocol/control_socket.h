// SPDX-License-Identifier: Apache-2.0
#pragma once
// Local operator control (PROTOCOL.md §6, DEVICES.md "Who may control the daemon"): the daemon's
// privileged commands (reload, record-start, record-stop, calibration-load) arrive through a
// Unix-domain socket whose file permissions say who may send them, as gpsd's /run/gpsd.sock and
// chronyd's socket do: the daemon's user and its group (mode 0660 in a 0750 directory), nobody else.
// UDP control, authorised by source address only, is off unless an operator allows networks.
//
// SOCK_SEQPACKET: one connection per request, one CONTROL_REQUEST message and one CONTROL_REPLY
// (the gaze protocol's own encoding), boundaries kept, and the sender known by its credentials
// (SO_PEERCRED) for the log. A connection that sends nothing, or something else, is closed after
// a second without blocking the next one for longer; requests are served one at a time, and beyond
// kMaxRequestsPerSecond they are answered Refused without being executed.
#include <sys/types.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "fovea/protocol/messages.h"
#include "fovea/protocol/udp.h"

namespace fovea::protocol {

struct PeerCredentials {
  pid_t pid = 0;
  uid_t uid = 0;
  gid_t gid = 0;
  std::string to_string() const;  // "pid P uid U gid G"
};

using LocalControlHandler = std::function<ControlReply(const ControlRequest&, const PeerCredentials&)>;

class ControlSocket {
 public:
  struct Stats {
    std::uint64_t requests = 0;   // answered (ok, failed or refused by the handler)
    std::uint64_t malformed = 0;  // not one CONTROL_REQUEST: closed unanswered
    std::uint64_t timed_out = 0;  // connected and sent nothing within the receive timeout
    std::uint64_t rate_limited = 0;  // answered "too many", not executed
  };
  // Requests beyond this rate (a burst of as many is allowed) are answered Refused and not executed,
  // so a flood cannot keep the publishing loop busy executing commands.
  static constexpr double kMaxRequestsPerSecond = 50;

  // Creates the socket at `path` (mode `mode`; a stale socket of an earlier run is replaced, a live
  // one or anything that is not a socket is refused) and starts serving. Throws std::system_error
  // or std::runtime_error naming the path.
  ControlSocket(const std::string& path, mode_t mode, LocalControlHandler handler, int receive_timeout_ms = 1000);
  ~ControlSocket();  // stops serving and removes the socket file
  ControlSocket(const ControlSocket&) = delete;
  ControlSocket& operator=(const ControlSocket&) = delete;

  const std::string& path() const { return path_; }
  Stats stats() const;

 private:
  void serve();
  void serve_one(int fd);
  std::string path_;
  LocalControlHandler handler_;
  int receive_timeout_ms_;
  int listen_fd_ = -1;
  int stop_fd_ = -1;  // eventfd: wakes the thread to stop
  std::atomic<std::uint64_t> requests_{0}, malformed_{0}, timed_out_{0}, rate_limited_{0};
  double tokens_ = kMaxRequestsPerSecond;  // the serving thread's token bucket
  std::int64_t tokens_at_ns_ = 0;
  std::thread thread_;
};

// Sends `request` to the daemon's control socket at `path` and waits up to timeout_ms for the
// reply. nullopt with `error` set (naming the path: not found, permission denied, no answer, ...).
std::optional<ControlReply> send_local_control(const std::string& path, const ControlRequest& request, int timeout_ms,
                                               std::string& error);

// Where a daemon serving gaze on `port` puts its control socket by default, and where a client on
// the same host looks, in this order: /run/fovea/control-PORT.sock (the system service's
// RuntimeDirectory), then $XDG_RUNTIME_DIR/fovea/control-PORT.sock, then /tmp/fovea-UID/control-PORT.sock.
// A daemon takes the first whose directory it can create or write; run as a service, $RUNTIME_DIRECTORY wins.
std::vector<std::string> control_socket_candidates(std::uint16_t port);
std::string default_control_socket(std::uint16_t port);

// What fovea-ctl and fovea-calibrate do: through `socket` when one is named; else, for a daemon on
// this host (a loopback `server`), through the first of its candidate sockets that exists; else
// over UDP to `server` (which a daemon answers only from networks it allows). `via` says which.
std::optional<ControlReply> send_control_to_daemon(const Endpoint& server, const std::string& socket,
                                                   const ControlRequest& request, int timeout_ms, std::string& error,
                                                   std::string& via);

}  // namespace fovea::protocol
