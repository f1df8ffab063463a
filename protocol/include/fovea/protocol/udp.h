// SPDX-License-Identifier: Apache-2.0
#pragma once
// IPv4 UDP endpoints and sockets: the thin OS layer under GazeServer and GazeClient.
#include <netinet/in.h>

#include <cstdint>
#include <span>
#include <string>

namespace fovea::protocol {

struct Endpoint {
  std::uint32_t ip = 0;  // host byte order
  std::uint16_t port = 0;
  friend bool operator==(const Endpoint&, const Endpoint&) = default;
  sockaddr_in to_sockaddr() const;
  static Endpoint from_sockaddr(const sockaddr_in& sa);
  std::string to_string() const;
  bool is_multicast() const { return (ip >> 28) == 0xE; }
};

// "HOST:PORT", "HOST" (default_port) or ":PORT"; HOST is a dotted quad or a name resolved to IPv4.
// Throws std::invalid_argument naming the text and what is wrong with it.
Endpoint parse_endpoint(const std::string& text, std::uint16_t default_port);

class UdpSocket {
 public:
  UdpSocket() = default;
  // Binds to `local` (port 0: ephemeral). reuse_address lets several receivers share a multicast port.
  // Throws std::system_error naming the address on failure.
  static UdpSocket bind(Endpoint local, bool reuse_address = false);
  UdpSocket(UdpSocket&& o) noexcept : fd_(o.fd_) { o.fd_ = -1; }
  UdpSocket& operator=(UdpSocket&& o) noexcept;
  UdpSocket(const UdpSocket&) = delete;
  UdpSocket& operator=(const UdpSocket&) = delete;
  ~UdpSocket();

  int fd() const { return fd_; }
  bool valid() const { return fd_ >= 0; }
  Endpoint local_endpoint() const;

  // Returns false if the datagram could not be sent (the error is left in errno).
  bool send_to(const Endpoint& to, std::span<const std::uint8_t> data) const;
  // Sends one datagram to many endpoints with as few system calls as possible (sendmmsg).
  // Returns how many were handed to the kernel.
  std::size_t send_to_many(std::span<const Endpoint> to, std::span<const std::uint8_t> data) const;
  // Waits up to timeout_ms for a datagram; returns its size, 0 on timeout. Datagrams larger than
  // `buffer` are reported with their full size (> buffer.size()) so the caller can reject them.
  std::size_t receive(std::span<std::uint8_t> buffer, Endpoint& from, int timeout_ms) const;

  void join_multicast(std::uint32_t group_ip, std::uint32_t interface_ip) const;
  void set_multicast_output(std::uint8_t ttl, std::uint32_t interface_ip, bool loopback) const;
  void set_receive_buffer(int bytes) const;

 private:
  explicit UdpSocket(int fd) : fd_(fd) {}
  int fd_ = -1;
};

}  // namespace fovea::protocol
