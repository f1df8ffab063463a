// SPDX-License-Identifier: Apache-2.0
// read_bounded_file and escape_for_log (fovea/protocol/bounded_file.h): what a hostile local user
// can name instead of a file (/dev/zero, a FIFO without a writer, a directory, a symbolic link, a
// huge file) is refused at once by what it is, and what they can put in a path reaches a log or a
// terminal escaped.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "fovea/protocol/bounded_file.h"
#include "temp_dir.h"

using fovea::protocol::BoundedRead;
using fovea::protocol::escape_for_log;
using fovea::protocol::read_bounded_file;

namespace {

using fovea::test::TempDir;

std::string refusal(const std::string& path, const BoundedRead& o = {}) {
  try {
    read_bounded_file(path, o);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(read)";
}

void write(const std::filesystem::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

}  // namespace

TEST(BoundedFile, ReadsARegularFileWhole) {
  TempDir d;
  const std::string text = std::string(200000, 'x') + "end";
  write(d.path / "a.json", text);
  EXPECT_EQ(read_bounded_file((d.path / "a.json").string()), text);
  write(d.path / "empty", "");
  EXPECT_EQ(read_bounded_file((d.path / "empty").string()), "");
}

TEST(BoundedFile, RefusesAFileOverTheLimitNamingBothSizes) {
  TempDir d;
  write(d.path / "big", std::string(1001, 'x'));
  const std::string e = refusal((d.path / "big").string(), {.max_bytes = 1000, .what = "calibration file"});
  EXPECT_NE(e.find("calibration file " + (d.path / "big").string()), std::string::npos) << e;
  EXPECT_NE(e.find("1001 bytes; the limit is 1000"), std::string::npos) << e;
  write(d.path / "ok", std::string(1000, 'x'));
  EXPECT_EQ(read_bounded_file((d.path / "ok").string(), {.max_bytes = 1000}).size(), 1000u);
}

// /dev/zero would never end; a FIFO without a writer would block the reader until one appears.
TEST(BoundedFile, RefusesDevicesFifosAndDirectoriesAtOnce) {
  TempDir d;
  const auto fifo = d.path / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_NE(refusal("/dev/zero").find("is a character device, not a regular file"), std::string::npos);
  EXPECT_NE(refusal(fifo.string()).find("is a FIFO, not a regular file"), std::string::npos);
  EXPECT_NE(refusal(d.path.string()).find("is a directory"), std::string::npos);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(2));
}

TEST(BoundedFile, SymbolicLinksAreRefusedWhenAsked) {
  TempDir d;
  write(d.path / "target", "hello");
  std::filesystem::create_symlink(d.path / "target", d.path / "link");
  EXPECT_EQ(read_bounded_file((d.path / "link").string()), "hello");
  const std::string e = refusal((d.path / "link").string(), {.follow_symlinks = false});
  EXPECT_NE(e.find("is a symbolic link"), std::string::npos) << e;
}

TEST(BoundedFile, MissingAndUnnamedFilesAreNamed) {
  EXPECT_NE(refusal("/nonexistent/fovea.json").find("file /nonexistent/fovea.json: not found"), std::string::npos);
  EXPECT_NE(refusal("").find("empty path"), std::string::npos);
  EXPECT_NE(refusal(std::string("a\0b", 3)).find("NUL byte"), std::string::npos);
}

TEST(BoundedFile, ErrorsEscapeThePath) {
  const std::string e = refusal("/nonexistent/evil\n2026-01-01 [info] forged\x1b[2J");
  EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  EXPECT_EQ(e.find('\x1b'), std::string::npos) << e;
  EXPECT_NE(e.find("evil\\x0a2026"), std::string::npos) << e;
}

TEST(EscapeForLog, KeepsPrintableTextAndUtf8AndEscapesTheRest) {
  EXPECT_EQ(escape_for_log("calib/ok.json"), "calib/ok.json");
  EXPECT_EQ(escape_for_log("caf\xc3\xa9"), "caf\xc3\xa9");                 // é stays
  EXPECT_EQ(escape_for_log("a\nb\rc\td"), "a\\x0ab\\x0dc\\x09d");
  EXPECT_EQ(escape_for_log("\x1b[31mred"), "\\x1b[31mred");
  EXPECT_EQ(escape_for_log("\xc2\x9b" "2J"), "\\xc2\\x9b2J");              // C1 CSI, as UTF-8
  EXPECT_EQ(escape_for_log("\xff\xfe"), "\\xff\\xfe");                    // not UTF-8
  EXPECT_EQ(escape_for_log("\xe2\x82"), "\\xe2\\x82");                    // truncated sequence
  EXPECT_EQ(escape_for_log("back\\slash"), "back\\\\slash");               // unambiguous
  EXPECT_EQ(escape_for_log(std::string(10, 'x'), 4), "xxxx...");
  EXPECT_EQ(escape_for_log(std::string("a\0b", 3)), "a\\x00b");
}
