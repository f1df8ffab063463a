#pragma once
// Where a control command may write (issue 23 item 2: a root-run daemon created a root-owned file in
// /etc for any local user, and "../" walked out of any directory). record-start's path is confined
// to one directory: a relative path is taken relative to it, an absolute one must lie inside it, no
// ".." may leave it, and its parent directory, resolved through any symbolic links, must still be
// inside it. The file itself is created with O_CREAT | O_EXCL (RecordingWriter), which never
// follows a symbolic link.
#include <string>

namespace fovea::trackerd::service {

// The path for `requested` inside `dir`, or throws std::runtime_error naming both and what is wrong
// (escaped: the request comes from a client). `command` and `dir_name` name the request and the
// directory in the message.
std::string confined_path(const std::string& requested, const std::string& dir,
                          const std::string& command = "record-start",
                          const std::string& dir_name = "recordings directory");

}  // namespace fovea::trackerd::service
