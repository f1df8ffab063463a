// SPDX-License-Identifier: Apache-2.0
#pragma once
// What the daemon's two local sockets share (the control socket, the eye-frame socket): a
// SOCK_SEQPACKET Unix-domain socket file, created with a given mode, that replaces a stale file
// of an earlier run but never a live one, nor anything that is not a socket. `what` names the
// socket in errors ("control socket", "eye-frame socket").
#include <sys/types.h>
#include <sys/un.h>

#include <string>

namespace fovea::protocol::local {

sockaddr_un address_of(const std::string& path, const std::string& what);

// An owned file descriptor.
class Fd {
 public:
  explicit Fd(int fd = -1) : fd_(fd) {}
  ~Fd();
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  int release() {
    const int f = fd_;
    fd_ = -1;
    return f;
  }

 private:
  int fd_;
};

// Binds and listens (non-blocking, close-on-exec) at `path` with `mode`; the file never exists
// with a wider mode than `mode`. Throws std::system_error or std::runtime_error naming the path.
int listen_at(const std::string& path, mode_t mode, int backlog, const std::string& what);

// Connects (blocking, close-on-exec); -1 with errno set when it cannot.
int connect_to(const std::string& path);

}  // namespace fovea::protocol::local
