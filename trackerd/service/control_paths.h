// SPDX-License-Identifier: Apache-2.0
#pragma once
// Where a control command may write (issue 23 item 2: a root-run daemon created a root-owned file in
// /etc for any local user, and "../" walked out of any directory). record-start's path is confined
// to one directory: a relative path is taken relative to it, an absolute one must lie inside it, no
// ".." may leave it, and its parent directory, resolved through any symbolic links, must still be
// inside it. The file itself is created with O_CREAT | O_EXCL (RecordingWriter), which never
// follows a symbolic link.
#include <stdexcept>
#include <string>

namespace fovea::trackerd::service {

// A path refused by confined_path: what() names the request, the path (escaped) and the reason, for
// the log; reason() is the reason alone, for a 63-byte control reply to the client who knows the path.
class PathRefused : public std::runtime_error {
 public:
  PathRefused(const std::string& what, std::string reason) : std::runtime_error(what), reason_(std::move(reason)) {}
  const std::string& reason() const { return reason_; }

 private:
  std::string reason_;
};

// The path for `requested` inside `dir`, or throws PathRefused naming both and what is wrong
// (escaped: the request comes from a client). `command` and `dir_name` name the request and the
// directory in the message.
std::string confined_path(const std::string& requested, const std::string& dir,
                          const std::string& command = "record-start",
                          const std::string& dir_name = "recordings directory");

}  // namespace fovea::trackerd::service
