// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/control_socket.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/codec.h"
#include "local_socket.h"

namespace fovea::protocol {

namespace {

std::system_error sys_error(const std::string& what) { return {errno, std::generic_category(), what}; }

using local::Fd;

void set_timeouts(int fd, int ms) {
  const timeval tv{ms / 1000, (ms % 1000) * 1000};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
}

// A private directory we own (0700): created if missing; refused if it is a link, not ours, or
// open to others (someone could swap the socket).
bool private_directory(const std::string& dir) {
  if (::mkdir(dir.c_str(), 0700) != 0 && errno != EEXIST) return false;
  struct stat st {};
  if (::lstat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode) || st.st_uid != ::geteuid()) return false;
  return (st.st_mode & 0022) == 0;
}

}  // namespace

std::string PeerCredentials::to_string() const {
  return "pid " + std::to_string(pid) + " uid " + std::to_string(uid) + " gid " + std::to_string(gid);
}

ControlSocket::ControlSocket(const std::string& path, mode_t mode, LocalControlHandler handler, int receive_timeout_ms)
    : path_(path), handler_(std::move(handler)), receive_timeout_ms_(receive_timeout_ms) {
  Fd fd(local::listen_at(path, mode, 8, "control socket"));
  stop_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (stop_fd_ < 0) {
    ::unlink(path.c_str());
    throw sys_error("control socket: eventfd");
  }
  listen_fd_ = fd.release();
  thread_ = std::thread([this] { serve(); });
}

ControlSocket::~ControlSocket() {
  const std::uint64_t one = 1;
  if (::write(stop_fd_, &one, sizeof one) < 0) {
    // The eventfd cannot be full with one write; nothing else to do.
  }
  if (thread_.joinable()) thread_.join();
  ::close(listen_fd_);
  ::close(stop_fd_);
  ::unlink(path_.c_str());
}

ControlSocket::Stats ControlSocket::stats() const {
  return {requests_.load(), malformed_.load(), timed_out_.load(), rate_limited_.load()};
}

void ControlSocket::serve() {
  for (;;) {
    std::array<pollfd, 2> fds{pollfd{listen_fd_, POLLIN, 0}, pollfd{stop_fd_, POLLIN, 0}};
    if (::poll(fds.data(), fds.size(), -1) < 0) {
      if (errno == EINTR) continue;
      return;
    }
    if (fds[1].revents != 0) return;
    if ((fds[0].revents & POLLIN) == 0) continue;
    Fd conn(::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC));
    if (conn.get() < 0) continue;  // EAGAIN (another accept won) or a client that gave up
    serve_one(conn.get());
  }
}

void ControlSocket::serve_one(int fd) {
  set_timeouts(fd, receive_timeout_ms_);
  PeerCredentials who;
  ucred cred{};
  socklen_t len = sizeof cred;
  if (::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) == 0) who = {cred.pid, cred.uid, cred.gid};
  std::array<std::uint8_t, kMaxDatagramSize + 1> buf{};
  const ssize_t n = ::recv(fd, buf.data(), buf.size(), 0);
  if (n < 0) {
    ++(errno == EAGAIN || errno == EWOULDBLOCK ? timed_out_ : malformed_);
    return;
  }
  Message m;
  if (static_cast<std::size_t>(n) > kMaxDatagramSize ||
      !decode(std::span<const std::uint8_t>(buf.data(), static_cast<std::size_t>(n)), m) ||
      m.header.type != MessageType::ControlRequest) {
    ++malformed_;
    return;
  }
  const auto& req = std::get<ControlRequest>(m.payload);
  ControlReply answer{req.command, ControlResult::Failed, {}};
  const std::int64_t now = monotonic_ns();
  tokens_ = std::min(kMaxRequestsPerSecond,
                     tokens_ + kMaxRequestsPerSecond * static_cast<double>(now - tokens_at_ns_) * 1e-9);
  tokens_at_ns_ = now;
  if (tokens_ < 1) {
    ++rate_limited_;
    answer.result = ControlResult::Refused;
    answer.message.value = "too many control requests; nothing was done";
  } else {
    tokens_ -= 1;
    try {
      answer = handler_(req, who);
      answer.command = req.command;
    } catch (const std::exception& e) {
      answer.message.value = e.what();
    }
  }
  if (answer.message.value.size() >= decltype(answer.message)::capacity) {
    answer.message.value = answer.message.value.substr(0, decltype(answer.message)::capacity - 4) + "...";
  }
  Message out{Header{}, answer};
  out.header.sequence = m.header.sequence;
  out.header.origin_time_ns = monotonic_ns();
  const std::vector<std::uint8_t> bytes = encode(out);
  ++requests_;
  (void)::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL);
}

std::optional<ControlReply> send_local_control(const std::string& path, const ControlRequest& request, int timeout_ms,
                                               std::string& error) {
  const std::string name = "control socket " + escape_for_log(path);
  Fd fd(local::connect_to(path));
  if (fd.get() < 0) {
    error = name + ": " + (errno == EACCES ? std::string("permission denied (control needs the daemon's group)")
                                          : std::string(std::strerror(errno)));
    return std::nullopt;
  }
  set_timeouts(fd.get(), timeout_ms);
  Message m{Header{}, request};
  m.header.sequence = 1;
  m.header.origin_time_ns = monotonic_ns();
  const std::vector<std::uint8_t> bytes = encode(m);
  if (::send(fd.get(), bytes.data(), bytes.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(bytes.size())) {
    error = name + ": send: " + std::strerror(errno);
    return std::nullopt;
  }
  std::array<std::uint8_t, kMaxDatagramSize> buf{};
  const ssize_t n = ::recv(fd.get(), buf.data(), buf.size(), 0);
  Message reply;
  if (n <= 0 || !decode(std::span<const std::uint8_t>(buf.data(), static_cast<std::size_t>(n)), reply) ||
      reply.header.type != MessageType::ControlReply) {
    error = name + ": " + (n < 0 ? "no answer within " + std::to_string(timeout_ms) + " ms" : std::string("no valid reply"));
    return std::nullopt;
  }
  return std::get<ControlReply>(reply.payload);
}

std::optional<ControlReply> send_control_to_daemon(const Endpoint& server, const std::string& socket,
                                                   const ControlRequest& request, int timeout_ms, std::string& error,
                                                   std::string& via) {
  std::string path = socket;
  if (path.empty() && (server.ip >> 24) == 127) {
    for (const std::string& c : control_socket_candidates(server.port)) {
      struct stat st {};
      if (::lstat(c.c_str(), &st) == 0 && S_ISSOCK(st.st_mode)) {
        path = c;
        break;
      }
    }
  }
  if (!path.empty()) {
    via = "control socket " + escape_for_log(path);
    return send_local_control(path, request, timeout_ms, error);
  }
  via = "UDP " + server.to_string();
  std::optional<ControlReply> r = GazeClient::send_control(server, request, timeout_ms);
  if (!r) error = "no answer from " + server.to_string() + " within " + std::to_string(timeout_ms) + " ms";
  return r;
}

std::vector<std::string> control_socket_candidates(std::uint16_t port) {
  const std::string file = "/control-" + std::to_string(port) + ".sock";
  std::vector<std::string> out{"/run/fovea" + file};
  if (const char* x = std::getenv("XDG_RUNTIME_DIR"); x != nullptr && x[0] == '/') {
    out.push_back(std::string(x) + "/fovea" + file);
  }
  out.push_back("/tmp/fovea-" + std::to_string(::geteuid()) + file);
  return out;
}

std::string default_control_socket(std::uint16_t port) {
  const std::string file = "/control-" + std::to_string(port) + ".sock";
  if (const char* rd = std::getenv("RUNTIME_DIRECTORY"); rd != nullptr && rd[0] == '/') {
    const std::string first(rd, std::strcspn(rd, ":"));  // systemd lists several with ':'
    return first + file;
  }
  if (::geteuid() == 0) {
    if (::mkdir("/run/fovea", 0750) == 0 || errno == EEXIST) return "/run/fovea" + file;
  }
  if (const char* x = std::getenv("XDG_RUNTIME_DIR"); x != nullptr && x[0] == '/') {
    if (private_directory(std::string(x) + "/fovea")) return std::string(x) + "/fovea" + file;
  }
  const std::string tmp = "/tmp/fovea-" + std::to_string(::geteuid());
  if (private_directory(tmp)) return tmp + file;
  throw std::runtime_error("no directory for the control socket: " + tmp +
                           " exists and is not a private directory of this user (give --control-socket)");
}

}  // namespace fovea::protocol
