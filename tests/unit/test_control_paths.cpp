// SPDX-License-Identifier: Apache-2.0
// confined_path (trackerd/service/control_paths.h): record-start writes only inside its directory.
// Issue 23 item 2: a root-run daemon created a root-owned file in /etc for any local user, and
// "../" walked out of the working directory.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <stdexcept>
#include <string>

#include "service/control_paths.h"

using fovea::trackerd::service::confined_path;
namespace fs = std::filesystem;

namespace {

struct Dirs {
  fs::path root, outside;
  Dirs() {
    char a[] = "/tmp/fovea-confined-XXXXXX";
    char b[] = "/tmp/fovea-outside-XXXXXX";
    root = fs::canonical(::mkdtemp(a));
    outside = fs::canonical(::mkdtemp(b));
    fs::create_directories(root / "sub");
    fs::create_directory_symlink(outside, root / "escape");
  }
  ~Dirs() {
    fs::remove_all(root);
    fs::remove_all(outside);
  }
};

std::string refusal(const std::string& requested, const fs::path& dir) {
  try {
    return "(allowed: " + confined_path(requested, dir.string()) + ")";
  } catch (const std::runtime_error& e) {
    return e.what();
  }
}

}  // namespace

TEST(ConfinedPath, NamesInsideTheDirectoryAreAllowed) {
  Dirs d;
  EXPECT_EQ(confined_path("a.fgr", d.root.string()), (d.root / "a.fgr").string());
  EXPECT_EQ(confined_path("sub/b.fgr", d.root.string()), (d.root / "sub/b.fgr").string());
  EXPECT_EQ(confined_path("sub/../c.fgr", d.root.string()), (d.root / "c.fgr").string());
  EXPECT_EQ(confined_path((d.root / "sub/d.fgr").string(), d.root.string()), (d.root / "sub/d.fgr").string());
}

TEST(ConfinedPath, EverythingOutsideIsRefusedByName) {
  Dirs d;
  EXPECT_NE(refusal("/etc/fovea-owned.fgr", d.root).find("record-start /etc/fovea-owned.fgr: outside the recordings "
                                                          "directory " + d.root.string()),
            std::string::npos);
  EXPECT_NE(refusal("../x.fgr", d.root).find("outside the recordings directory"), std::string::npos);
  EXPECT_NE(refusal("sub/../../x.fgr", d.root).find("outside"), std::string::npos);
  EXPECT_NE(refusal(d.root.string() + "-sibling/x.fgr", d.root).find("outside"), std::string::npos);  // prefix trap
  EXPECT_NE(refusal(".", d.root).find("names a directory"), std::string::npos);                         // the dir itself
  EXPECT_NE(refusal("escape/x.fgr", d.root).find("leads out of the recordings directory"), std::string::npos);
  EXPECT_NE(refusal("nosuch/x.fgr", d.root).find("does not exist"), std::string::npos);
  EXPECT_NE(refusal("", d.root).find("empty path"), std::string::npos);
  EXPECT_NE(refusal("../x\n[info] forged", d.root).find("x\\x0a[info] forged"), std::string::npos);
  EXPECT_FALSE(fs::exists(d.outside / "x.fgr"));
}
