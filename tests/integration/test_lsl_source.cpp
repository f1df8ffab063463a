// fovea-trackerd --source lsl:NAME against a liblsl outlet in this test (issue 27, source): a known
// trajectory in pixels with XDF channel metadata, the outlet's timestamps pushed in bursts, NaN and
// low-confidence samples; the daemon's recording must hold the same positions and validity on the
// outlet's timestamps, and it must read the stream again after the outlet restarts. Discovery stays
// on this machine (LSLAPICFG, set in test_lsl_outlet.cpp for the whole binary).
#include <gtest/gtest.h>
#include <lsl_cpp.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

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

std::unique_ptr<lsl::stream_outlet> tracker_outlet(const std::string& name, bool with_metadata) {
  lsl::stream_info info(name, "Gaze", 5, kRate, lsl::cf_float32, name + "-" + std::to_string(lsl::local_clock()));
  if (with_metadata) {
    lsl::xml_element chns = info.desc().append_child("channels");
    const char* rows[][4] = {{"gx", "both", "ScreenX", "pixels"},
                             {"gy", "both", "ScreenY", "pixels"},
                             {"conf", "both", "Confidence", "normalized"},
                             {"pl", "left", "Diameter", "mm"},
                             {"pr", "right", "Diameter", "mm"}};
    for (const auto& r : rows) {
      chns.append_child("channel").append_child_value("label", r[0]).append_child_value("eye", r[1])
          .append_child_value("type", r[2]).append_child_value("unit", r[3]);
    }
  }
  return std::make_unique<lsl::stream_outlet>(info);
}

// Sample k of the trajectory: NaN every 25th from 7, confidence 0.2 every 25th from 13.
std::vector<float> sample(int k) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  return {k % 25 == 7 ? nan : 100.0f + static_cast<float>(k), 200.0f + 0.5f * static_cast<float>(k),
          k % 25 == 13 ? 0.2f : 0.9f, 3.0f + 0.001f * static_cast<float>(k), 3.5f};
}

// Pushes samples [from, to) on the grid t0 + k / rate, in bursts of 10 every 40 ms.
void push_bursts(lsl::stream_outlet& outlet, double t0, int from, int to) {
  for (int k = from; k < to; k += 10) {
    for (int j = k; j < std::min(k + 10, to); ++j) outlet.push_sample(sample(j), t0 + j / kRate, j + 1 == std::min(k + 10, to));
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
  }
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
  auto outlet = tracker_outlet(name, true);
  const int port = fovea::test::random_port();
  const auto log = d.path / "daemon.log", rc = d.path / "daemon.rc", fgr = d.path / "daemon.fgr";
  const std::string cmd = std::string(FOVEA_TRACKERD_PATH) + " --source 'lsl:" + name +
                          "?min_confidence=0.5' --duration 9 --port " + std::to_string(port) + " --record " + fgr.string();
  ASSERT_EQ(exit_status("(" + cmd + " 2>" + log.string() + "; echo $? >" + rc.string() + ") &"), 0);
  ASSERT_TRUE(wait_for_text(log, "reading \"" + name + "\"", 1, 10)) << read_text(log);

  const double t0 = lsl::local_clock();
  push_bursts(*outlet, t0, 0, 500);
  outlet.reset();  // the tracker's app closes...
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  outlet = tracker_outlet(name, true);  // ... and comes back: a new outlet of the same name
  ASSERT_TRUE(wait_for_text(log, "reading \"" + name + "\"", 2, 10)) << read_text(log);
  push_bursts(*outlet, t0, 500, 750);
  ASSERT_TRUE(wait_for(rc, 20)) << read_text(log);
  EXPECT_EQ(read_text(rc), "0\n") << read_text(log);
  EXPECT_NE(read_text(log).find("1 losses"), std::string::npos) << "the loss is not in the status: " << read_text(log);

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
  EXPECT_GE(after_restart, 245u) << "samples after the outlet came back";
}

TEST(LslSource, ChannelsTheMetadataDoesNotNameAreAProblemUntilTheSpecGivesThem) {
  TempDir d("fovea-lsl-src");
  const std::string name = "bare-" + std::to_string(::getpid());
  auto outlet = tracker_outlet(name, false);
  const auto log = d.path / "daemon.log";
  const std::string base = std::string(FOVEA_TRACKERD_PATH) + " --duration 3 --port " +
                           std::to_string(fovea::test::random_port()) + " --source 'lsl:" + name;
  std::thread pusher([&] { push_bursts(*outlet, lsl::local_clock(), 0, 1500); });
  exit_status(base + "' 2>" + log.string());
  EXPECT_NE(read_text(log).find("names no ScreenX/ScreenY channels"), std::string::npos) << read_text(log);
  EXPECT_NE(read_text(log).find("?x=I&y=J&units=pixels|normalized"), std::string::npos) << read_text(log);
  exit_status(base + "?x=0&y=1&units=pixels' 2>" + log.string());
  EXPECT_NE(read_text(log).find("x/y pixels (channels 0, 1) from the spec"), std::string::npos) << read_text(log);
  pusher.join();
}

}  // namespace
