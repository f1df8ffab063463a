// SPDX-License-Identifier: Apache-2.0
#pragma once
// Reading a file a hostile local user may name (a control request's path, a configuration's, a
// command line's): only a regular file, of bounded size, without blocking and, where asked, without
// following a symbolic link. /dev/zero, a FIFO without a writer, a directory or a socket are refused
// at once by what they are, never read; a file that grows past the limit while it is read is refused
// rather than read on. Every error names the path and what is wrong with it.
#include <cstddef>
#include <string>

namespace fovea::protocol {

struct BoundedRead {
  std::size_t max_bytes = 16u << 20;  // larger files are refused (the error names both sizes)
  bool follow_symlinks = true;        // false: a symbolic link as the last component is refused (O_NOFOLLOW)
  std::string what = "file";          // what the file is, for the error: "calibration file", ...
};

// The whole file. Throws std::runtime_error "<what> <path>: <reason>".
std::string read_bounded_file(const std::string& path, const BoundedRead& options = {});

// Printable for a log line or a terminal: control characters, DEL and bytes that are not UTF-8 as
// \xNN, backslash as \\, at most max_chars characters of the input (then "..." ).
std::string escape_for_log(const std::string& text, std::size_t max_chars = 256);
// The same escaping, as much of `text` as fits in max_bytes without splitting an escape or a UTF-8
// character: for fixed-size fields (a recording's 63-byte device name).
std::string escape_to_fit(const std::string& text, std::size_t max_bytes);
// Whether `text` needs no escaping at all: valid UTF-8 without control characters (C0, DEL, C1).
// Backslashes are printable. The byte offset of the first offending byte goes to `bad_at`.
bool printable_utf8(const std::string& text, std::size_t* bad_at = nullptr);

}  // namespace fovea::protocol
