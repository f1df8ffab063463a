// SPDX-License-Identifier: Apache-2.0
#include "service/control_paths.h"

#include <filesystem>
#include <stdexcept>

#include "fovea/protocol/bounded_file.h"

namespace fovea::trackerd::service {

namespace fs = std::filesystem;

namespace {

// `inner` equals `outer` or lies below it (both lexically normal and absolute).
bool within(const fs::path& inner, const fs::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i) {
    if (o->empty()) continue;  // a trailing separator
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

}  // namespace

std::string confined_path(const std::string& requested, const std::string& dir, const std::string& command,
                          const std::string& dir_name) {
  const auto fail = [&](const std::string& why) {
    return PathRefused(command + " " + protocol::escape_for_log(requested) + ": " + why, why);
  };
  if (requested.empty()) throw fail("empty path");
  std::error_code ec;
  const fs::path root = fs::weakly_canonical(fs::absolute(dir, ec), ec);
  if (ec || !fs::is_directory(root)) throw fail("the " + dir_name + " " + dir + " does not exist");
  const fs::path p = fs::path(requested).is_absolute() ? fs::path(requested) : root / requested;
  const fs::path normal = p.lexically_normal();
  if (!normal.has_filename()) throw fail("names a directory, not a file");
  if (!within(normal, root) || normal == root) {
    throw fail("outside the " + dir_name + " " + root.string() + " (give a name inside it)");
  }
  // The parent must exist and, with its symbolic links resolved, still lie inside.
  const fs::path parent = fs::canonical(normal.parent_path(), ec);
  if (ec) throw fail("its directory " + protocol::escape_for_log(normal.parent_path().string()) + " does not exist");
  if (!within(parent, root)) throw fail("its directory leads out of the " + dir_name + " " + root.string());
  return (parent / normal.filename()).string();
}

}  // namespace fovea::trackerd::service
