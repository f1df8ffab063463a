// SPDX-License-Identifier: Apache-2.0
#include "local_socket.h"

#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include "fovea/protocol/bounded_file.h"

namespace fovea::protocol::local {

namespace {

std::system_error sys_error(const std::string& what) { return {errno, std::generic_category(), what}; }

// A socket file left by a daemon that died is replaced; one a live daemon answers on, or a path
// that is not a socket, is not.
void clear_stale_socket(const std::string& path, const std::string& what) {
  const std::string name = what + " " + escape_for_log(path);
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return;
    throw sys_error(name);
  }
  if (!S_ISSOCK(st.st_mode)) throw std::runtime_error(name + ": exists and is not a socket; not replaced");
  Fd probe(connect_to(path));
  if (probe.get() >= 0) {
    throw std::runtime_error(name + ": another fovea-trackerd answers on it (choose another --port or --control-socket)");
  }
  if (::unlink(path.c_str()) != 0) throw sys_error(name + ": removing a stale socket");
}

}  // namespace

Fd::~Fd() {
  if (fd_ >= 0) ::close(fd_);
}

sockaddr_un address_of(const std::string& path, const std::string& what) {
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof a.sun_path) {
    throw std::runtime_error(what + " " + escape_for_log(path) + ": a path of 1 to " +
                             std::to_string(sizeof a.sun_path - 1) + " bytes is needed");
  }
  std::memcpy(a.sun_path, path.data(), path.size());
  return a;
}

int connect_to(const std::string& path) {
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof a.sun_path) {
    errno = ENAMETOOLONG;
    return -1;
  }
  std::memcpy(a.sun_path, path.data(), path.size());
  Fd fd(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0));
  if (fd.get() < 0 || ::connect(fd.get(), reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) return -1;
  return fd.release();
}

int listen_at(const std::string& path, mode_t mode, int backlog, const std::string& what) {
  const std::string name = what + " " + escape_for_log(path);
  const sockaddr_un a = address_of(path, what);
  clear_stale_socket(path, what);
  Fd fd(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC | SOCK_NONBLOCK, 0));
  if (fd.get() < 0) throw sys_error(name);
  // The file is created with the umask's mode: nobody but the owner for the moment until chmod.
  const mode_t old = ::umask(0177);
  const int bound = ::bind(fd.get(), reinterpret_cast<const sockaddr*>(&a), sizeof a);
  const int bind_errno = errno;
  ::umask(old);
  if (bound != 0) {
    errno = bind_errno;
    throw sys_error(name + ": bind");
  }
  if (::chmod(path.c_str(), mode) != 0 || ::listen(fd.get(), backlog) != 0) {
    const std::system_error e = sys_error(name);
    ::unlink(path.c_str());
    throw e;
  }
  return fd.release();
}

}  // namespace fovea::protocol::local
