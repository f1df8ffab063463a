// SPDX-License-Identifier: Apache-2.0
// fovea-trackerd --source lsl:NAME against a liblsl outlet (issue 27, source), opened by a tracker's
// app in its own process (tests/tools/lsl_tracker_app.cpp): a known
// trajectory in pixels with XDF channel metadata, the outlet's timestamps pushed in bursts, NaN and
// low-confidence samples; the daemon's recording must hold the same positions and validity on the
// outlet's timestamps (confidence gated by default, or not with min_confidence=0), and it must read
// the stream again after the outlet restarts. A stream of strings is refused by name. Discovery stays
// on this machine (LSLAPICFG, set in test_lsl_outlet.cpp for the whole binary).
#include <gtest/gtest.h>
#include <lsl_cpp.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <string>
#include <thread>

#include "fovea/protocol/recording.h"
#include "process.h"
#include "temp_dir.h"

namespace {

using fovea::test::exit_status;
using fovea::test::read_text;
using fovea::test::TempDir;
using fovea::test::wait_for;
namespace protocol = fovea::protocol;

constexpr double kRate = 250;

// The tracker's app in its own process (tests/tools/lsl_tracker_app.cpp): it opens its outlet at
// once and pushes samples [from, to) of the trajectory once `go` holds t0; it quits after them, or,
// with a `quit` file, once that exists. Its exit status lands in `rc`.
void start_tracker_app(const std::string& name, int from, int to, const std::filesystem::path& go,
                       const std::string& quit, const std::filesystem::path& rc, const std::string& mode = "") {
  const std::string cmd = std::string(FOVEA_LSL_TRACKER_APP_PATH) + " " + name + " " + std::to_string(from) + " " +
                          std::to_string(to) + " " + go.string() + " " + quit + (mode.empty() ? "" : " " + mode);
  ASSERT_EQ(exit_status("(" + cmd + "; echo $? >" + rc.string() + ") &"), 0);
}

// Writes t0 to `go` whole (the app polls for the file).
void say_go(const std::filesystem::path& go, double t0) {
  const auto part = go.string() + ".part";
  std::ofstream(part) << std::to_string(t0) << "\n";
  std::filesystem::rename(part, go);
}

bool wait_for_text(const std::filesystem::path& log, const std::string& text, std::size_t times, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    const std::string s = read_text(log);
    std::size_t n = 0;
    for (std::size_t at = s.find(text); at != std::string::npos; at = s.find(text, at + 1)) ++n;
    if (n >= times) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

TEST(LslSource, ReadsTheTrackersTrajectoryOnItsTimestampsAndAfterTheOutletRestarts) {
  TempDir d("fovea-lsl-src");
  const std::string name = "tracker-" + std::to_string(::getpid());
  const auto go1 = d.path / "go1", go2 = d.path / "go2", quit = d.path / "quit";
  start_tracker_app(name, 0, 500, go1, "-", d.path / "app1.rc");
  const int port = fovea::test::free_udp_port();
  const auto log = d.path / "daemon.log", rc = d.path / "daemon.rc", fgr = d.path / "daemon.fgr";
  // No min_confidence: the stream declares a Confidence channel, so the default threshold applies.
  const std::string cmd = std::string(FOVEA_TRACKERD_PATH) + " --source 'lsl:" + name +
                          "' --duration 9 --port " + std::to_string(port) + " --record " + fgr.string();
  ASSERT_EQ(exit_status("(" + cmd + " 2>" + log.string() + "; echo $? >" + rc.string() + ") &"), 0);
  ASSERT_TRUE(wait_for_text(log, "reading \"" + name + "\"", 1, 10)) << read_text(log);
  EXPECT_NE(read_text(log).find("confidence in channel 2: gaze below 0.6 is invalid (the default"), std::string::npos)
      << "the default threshold is not said at start: " << read_text(log);

  const double t0 = lsl::local_clock();
  say_go(go1, t0);
  ASSERT_TRUE(wait_for(d.path / "app1.rc", 20));  // the tracker's app quits...
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  start_tracker_app(name, 500, 750, go2, quit.string(), d.path / "app2.rc");  // ... and comes back
  ASSERT_TRUE(wait_for_text(log, "reading \"" + name + "\"", 2, 10)) << read_text(log);
  say_go(go2, t0);
  ASSERT_TRUE(wait_for(rc, 20)) << read_text(log);
  std::ofstream(quit) << "0\n";  // the daemon is done: the app may quit
  ASSERT_TRUE(wait_for(d.path / "app2.rc", 20));
  EXPECT_EQ(read_text(rc), "0\n") << read_text(log);
  // The outlet's restart is one loss; a tracker app stalled past 1 s on a loaded machine makes another
  // (seen once in a CI rehearsal: "2 losses", every sample still there), which is not what this tests.
  std::smatch losses;
  const std::string text = read_text(log);
  ASSERT_TRUE(std::regex_search(text, losses, std::regex("([0-9]+) losses"))) << "no loss count in the status: " << text;
  EXPECT_GE(std::stoi(losses[1]), 1) << "the loss is not in the status: " << text;

  std::map<std::int64_t, protocol::GazeSample> recorded;
  for (const auto& r : protocol::read_recording(fgr.string()).records)
    if (const auto* s = std::get_if<protocol::GazeSample>(&r.item)) recorded[s->tracker_time_ns] = *s;
  // The daemon's time = the outlet's + liblsl's clock correction (tens of microseconds on one host).
  std::size_t found = 0, valid = 0;
  for (int k = 0; k < 750; ++k) {
    const auto t = static_cast<std::int64_t>(std::llround((t0 + k / kRate) * 1e9));
    auto it = recorded.lower_bound(t - 500'000);
    if (it == recorded.end() || it->first > t + 500'000) continue;
    ++found;
    const protocol::GazeSample& s = it->second;
    const bool expect_valid = k % 25 != 7 && k % 25 != 13;
    ASSERT_EQ((s.flags & protocol::kGazeValid) != 0, expect_valid) << "sample " << k;
    if (expect_valid) {
      ++valid;
      EXPECT_NEAR(static_cast<double>(s.x) * 1920.0, 100.0 + k, 1e-3) << "sample " << k;
      EXPECT_NEAR(static_cast<double>(s.y) * 1080.0, 200.0 + 0.5 * k, 1e-3) << "sample " << k;
    }
    EXPECT_TRUE(s.left.flags & protocol::kEyePupilValid);
    EXPECT_NEAR(s.left.pupil_diameter_mm, 3.0 + 0.001 * k, 1e-4);
    EXPECT_FLOAT_EQ(s.right.pupil_diameter_mm, 3.5f);
  }
  EXPECT_GE(found, 742u) << "of 750 pushed (99 %)";
  EXPECT_GT(valid, 650u);
  std::size_t after_restart = 0;
  for (const auto& [t, s] : recorded) after_restart += t > static_cast<std::int64_t>((t0 + 499.5 / kRate) * 1e9);
  // The second app pushes its 250 samples in bursts of 10, 40 ms apart, as soon as it is told to go
  // (their times are past); a burst pushed before the daemon's inlet has its data connection again is
  // not delivered, which a loaded machine makes happen (240 seen in a CI rehearsal).
  EXPECT_GE(after_restart, 225u) << "samples after the outlet came back";
}

TEST(LslSource, ChannelsTheMetadataDoesNotNameAreAProblemUntilTheSpecGivesThem) {
  TempDir d("fovea-lsl-src");
  const std::string name = "bare-" + std::to_string(::getpid());
  start_tracker_app(name, 0, 1500, d.path / "go", "-", d.path / "app.rc", "--bare");
  const auto log = d.path / "daemon.log";
  const std::string base = std::string(FOVEA_TRACKERD_PATH) + " --duration 3 --port " +
                           std::to_string(fovea::test::free_udp_port()) + " --source 'lsl:" + name;
  say_go(d.path / "go", lsl::local_clock());
  exit_status(base + "' 2>" + log.string());
  EXPECT_NE(read_text(log).find("names no ScreenX/ScreenY channels"), std::string::npos) << read_text(log);
  EXPECT_NE(read_text(log).find("?x=I&y=J&units=pixels|normalized"), std::string::npos) << read_text(log);
  exit_status(base + "?x=0&y=1&units=pixels' 2>" + log.string());
  EXPECT_NE(read_text(log).find("x/y pixels (channels 0, 1) from the spec"), std::string::npos) << read_text(log);
  EXPECT_TRUE(wait_for(d.path / "app.rc", 20));
}

TEST(LslSource, MinConfidenceZeroPublishesLowConfidenceGazeAsValid) {
  TempDir d("fovea-lsl-src");
  const std::string name = "noconf-" + std::to_string(::getpid());
  start_tracker_app(name, 0, 250, d.path / "go", "-", d.path / "app.rc");
  const auto log = d.path / "daemon.log", rc = d.path / "daemon.rc", fgr = d.path / "daemon.fgr";
  const std::string cmd = std::string(FOVEA_TRACKERD_PATH) + " --source 'lsl:" + name + "?min_confidence=0' --duration 4 --port " +
                          std::to_string(fovea::test::free_udp_port()) + " --record " + fgr.string();
  ASSERT_EQ(exit_status("(" + cmd + " 2>" + log.string() + "; echo $? >" + rc.string() + ") &"), 0);
  ASSERT_TRUE(wait_for_text(log, "reading \"" + name + "\"", 1, 10)) << read_text(log);
  EXPECT_NE(read_text(log).find("confidence in channel 2, not gated (min_confidence=0)"), std::string::npos) << read_text(log);
  const double t0 = lsl::local_clock();
  say_go(d.path / "go", t0);
  ASSERT_TRUE(wait_for(rc, 20)) << read_text(log);
  EXPECT_TRUE(wait_for(d.path / "app.rc", 20));
  std::size_t low = 0, low_valid = 0;
  for (const auto& r : protocol::read_recording(fgr.string()).records) {
    const auto* s = std::get_if<protocol::GazeSample>(&r.item);
    if (s == nullptr || !(s->confidence < 0.5f)) continue;
    ++low;
    low_valid += (s->flags & protocol::kGazeValid) != 0;
  }
  EXPECT_GE(low, 9u) << "the app sends confidence 0.2 every 25th sample (10 of 250)";
  EXPECT_EQ(low_valid, low) << "min_confidence=0 turns the gate off";
}

// An outlet of type Gaze whose channels are strings: every sample used to be published as valid
// gaze at (0, 0). It is refused at start with its format named, or, found later, is the source's
// problem, and nothing is published from it.
TEST(LslSource, AStreamOfStringsIsRefusedNamingItsFormat) {
  TempDir d("fovea-lsl-src");
  const std::string name = "strings-" + std::to_string(::getpid());
  start_tracker_app(name, 0, 500, d.path / "go", "-", d.path / "app.rc", "--strings");
  say_go(d.path / "go", lsl::local_clock());
  const auto log = d.path / "daemon.log";
  const std::string base = std::string(FOVEA_TRACKERD_PATH) + " --port " +
                           std::to_string(fovea::test::free_udp_port()) + " --source 'lsl:";
  EXPECT_NE(exit_status(base + name + "' --duration 3 2>" + log.string()), 0) << read_text(log);
  EXPECT_NE(read_text(log).find("its channels are strings (channel format string)"), std::string::npos) << read_text(log);
  EXPECT_TRUE(wait_for(d.path / "app.rc", 20));

  // Started before the stream exists (--rate): the same words become its problem, nothing is valid.
  const std::string late = name + "-late";
  const auto log2 = d.path / "daemon2.log", rc2 = d.path / "daemon2.rc", fgr = d.path / "daemon2.fgr";
  const std::string cmd = base + late + "' --rate 250 --duration 5 --record " + fgr.string();
  ASSERT_EQ(exit_status("(" + cmd + " 2>" + log2.string() + "; echo $? >" + rc2.string() + ") &"), 0);
  ASSERT_TRUE(wait_for_text(log2, "no such LSL stream", 1, 10)) << read_text(log2);
  start_tracker_app(late, 0, 500, d.path / "go2", "-", d.path / "app2.rc", "--strings");
  say_go(d.path / "go2", lsl::local_clock());
  ASSERT_TRUE(wait_for(rc2, 20)) << read_text(log2);
  EXPECT_NE(read_text(log2).find("\"" + late + "\": its channels are strings (channel format string)"), std::string::npos)
      << read_text(log2);
  std::size_t valid = 0;
  for (const auto& r : protocol::read_recording(fgr.string()).records) {
    if (const auto* s = std::get_if<protocol::GazeSample>(&r.item)) valid += (s->flags & protocol::kGazeValid) != 0;
  }
  EXPECT_EQ(valid, 0u);
  EXPECT_TRUE(wait_for(d.path / "app2.rc", 20));
}

// An outlet that declares 60 Hz and pushes as fast as it can (it once gave 392,351 samples and
// 96,678 events in 7 s): the daemon publishes at most 4x the declared rate, says so in its log and
// status, and its samples keep increasing times.
TEST(LslSource, AFloodIsCappedAtFourTimesTheDeclaredRateAndSaidSo) {
  TempDir d("fovea-lsl-src");
  const std::string name = "flood-" + std::to_string(::getpid());
  constexpr int kFloodMs = 2500;
  start_tracker_app(name, 0, kFloodMs, d.path / "go", "-", d.path / "app.rc", "--flood");
  const auto log = d.path / "daemon.log", rc = d.path / "daemon.rc", fgr = d.path / "daemon.fgr";
  const std::string cmd = std::string(FOVEA_TRACKERD_PATH) + " --source 'lsl:" + name + "' --duration 6 --port " +
                          std::to_string(fovea::test::free_udp_port()) + " --record " + fgr.string();
  ASSERT_EQ(exit_status("(" + cmd + " 2>" + log.string() + "; echo $? >" + rc.string() + ") &"), 0);
  ASSERT_TRUE(wait_for_text(log, "reading \"" + name + "\"", 1, 10)) << read_text(log);
  say_go(d.path / "go", lsl::local_clock());
  ASSERT_TRUE(wait_for(rc, 20)) << read_text(log);
  EXPECT_TRUE(wait_for(d.path / "app.rc", 20));
  EXPECT_EQ(read_text(rc), "0\n") << read_text(log);
  const std::string text = read_text(log);
  EXPECT_NE(text.find("60 Hz declared"), std::string::npos) << "no flood warning naming the declared rate: " << text;
  EXPECT_NE(text.find("dropped over the 4x cap"), std::string::npos) << "no dropped count at stop: " << text;

  std::size_t samples = 0, events = 0;
  std::int64_t last = 0;
  for (const auto& r : protocol::read_recording(fgr.string()).records) {
    if (const auto* s = std::get_if<protocol::GazeSample>(&r.item)) {
      ++samples;
      EXPECT_GE(s->tracker_time_ns, last);
      last = s->tracker_time_ns;
    } else if (std::holds_alternative<protocol::GazeEvent>(r.item)) {
      ++events;
    }
  }
  // The flood lasts 2.5 s: at most 4 x 60 Hz over it, plus the bucket's one second of 60 samples,
  // plus slack for the pull loop's timing.
  const double cap = 4 * 60 * (kFloodMs / 1000.0 + 0.5) + 60;
  EXPECT_GT(samples, 300u) << "the flood's samples up to the cap are published";
  EXPECT_LE(static_cast<double>(samples), cap) << samples << " samples published from a 60 Hz stream in "
                                               << kFloodMs << " ms";
  EXPECT_LE(events, samples / 2) << events << " events from " << samples << " samples";
}

}  // namespace
