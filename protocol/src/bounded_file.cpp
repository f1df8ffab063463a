// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/bounded_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace fovea::protocol {

namespace {

std::string kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

// Length of a valid UTF-8 sequence starting at s[i] (2..4), or 0.
std::size_t utf8_sequence(const std::string& s, std::size_t i) {
  const auto c = static_cast<unsigned char>(s[i]);
  std::size_t n = 0;
  unsigned min = 0;
  unsigned cp = 0;
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2, cp = c & 0x1Fu, min = 0x80;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3, cp = c & 0x0Fu, min = 0x800;
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4, cp = c & 0x07u, min = 0x10000;
  } else {
    return 0;
  }
  if (i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    const auto t = static_cast<unsigned char>(s[i + k]);
    if ((t & 0xC0u) != 0x80u) return 0;
    cp = (cp << 6) | (t & 0x3Fu);
  }
  if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  // C1 controls (U+0080..U+009F) move a terminal as the C0 ones do.
  if (cp >= 0x80 && cp <= 0x9F) return 0;
  return n;
}

}  // namespace

std::string read_bounded_file(const std::string& path, const BoundedRead& o) {
  const std::string name = o.what + " " + escape_for_log(path);
  const auto fail = [&](const std::string& why) { return std::runtime_error(name + ": " + why); };
  if (path.empty()) throw fail("empty path");
  if (path.find('\0') != std::string::npos) throw fail("the path contains a NUL byte");
  // O_NONBLOCK: opening a FIFO without a writer must not wait for one (it is refused below).
  const int flags = O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY | (o.follow_symlinks ? 0 : O_NOFOLLOW);
  Fd fd(::open(path.c_str(), flags));
  if (fd.get() < 0) {
    const int err = errno;
    if (err == ELOOP && !o.follow_symlinks) throw fail("is a symbolic link (not followed)");
    throw fail(err == ENOENT ? std::string("not found") : std::string("cannot open: ") + std::strerror(err));
  }
  struct stat st {};
  if (::fstat(fd.get(), &st) != 0) throw fail(std::string("cannot stat: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw fail("is " + kind_of(st.st_mode) + ", not a regular file");
  if (st.st_size < 0 || static_cast<std::size_t>(st.st_size) > o.max_bytes) {
    throw fail("is " + std::to_string(st.st_size) + " bytes; the limit is " + std::to_string(o.max_bytes));
  }
  std::string out;
  out.reserve(static_cast<std::size_t>(st.st_size));
  char buf[65536];
  for (;;) {
    const ssize_t n = ::read(fd.get(), buf, sizeof buf);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw fail(std::string("read error: ") + std::strerror(errno));
    }
    if (n == 0) break;
    if (out.size() + static_cast<std::size_t>(n) > o.max_bytes) {
      throw fail("grew past the limit of " + std::to_string(o.max_bytes) + " bytes while it was read");
    }
    out.append(buf, static_cast<std::size_t>(n));
  }
  return out;
}

namespace {

// escape_for_log's rule, stopping after max_chars input characters ("..." appended) or before an
// escaped character would take the output past max_bytes (never splitting one).
std::string escape(const std::string& text, std::size_t max_chars, std::size_t max_bytes) {
  static const char* hex = "0123456789abcdef";
  std::string out, piece;
  std::size_t chars = 0;
  for (std::size_t i = 0; i < text.size(); ++chars) {
    if (chars == max_chars) {
      out += "...";
      break;
    }
    const auto c = static_cast<unsigned char>(text[i]);
    std::size_t used = 1;
    if (c == '\\') {
      piece = "\\\\";
    } else if (c >= 0x20 && c < 0x7F) {
      piece.assign(1, static_cast<char>(c));
    } else if (const std::size_t n = c >= 0x80 ? utf8_sequence(text, i) : 0; n > 0) {
      piece.assign(text, i, n);
      used = n;
    } else {
      piece = {'\\', 'x', hex[c >> 4], hex[c & 0xF]};
    }
    if (out.size() + piece.size() > max_bytes) break;
    out += piece;
    i += used;
  }
  return out;
}

}  // namespace

std::string escape_for_log(const std::string& text, std::size_t max_chars) {
  return escape(text, max_chars, std::string::npos);
}

std::string escape_to_fit(const std::string& text, std::size_t max_bytes) {
  return escape(text, std::string::npos, max_bytes);
}

bool printable_utf8(const std::string& text, std::size_t* bad_at) {
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    const std::size_t n = c >= 0x80 ? utf8_sequence(text, i) : (c >= 0x20 && c < 0x7F ? 1 : 0);
    if (n == 0) {
      if (bad_at != nullptr) *bad_at = i;
      return false;
    }
    i += n;
  }
  return true;
}

}  // namespace fovea::protocol
