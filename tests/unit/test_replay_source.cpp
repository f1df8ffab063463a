// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include "sources/replay_source.h"
#include "sim/synthetic_gaze.h"

using namespace fovea;
using namespace fovea::trackerd;

namespace {
protocol::Recording make_recording(int samples, double rate) {
  protocol::Recording rec;
  rec.header.device = "test";
  rec.header.nominal_rate_hz = rate;
  SyntheticGazeOptions o;
  o.rate_hz = rate;
  o.start_time_ns = 123'000'000'000;  // some other machine's clock
  SyntheticGaze g(o);
  std::uint64_t seq = 0;
  int n = 0;
  while (n < samples) {
    const auto item = g.next();
    if (std::holds_alternative<protocol::GazeSample>(*item)) ++n;
    std::visit([&](const auto& v) { rec.records.push_back(protocol::Record{seq++, v}); }, *item);
  }
  return rec;
}
}  // namespace

TEST(ReplaySource, RebasesTimeAndKeepsSpacing) {
  const auto rec = make_recording(100, 250);
  ReplayOptions o;
  o.start_time_ns = 5'000'000'000;
  ReplaySource src(o, rec);
  std::vector<std::int64_t> times;
  while (auto item = src.next()) {
    if (const auto* s = std::get_if<protocol::GazeSample>(&*item)) times.push_back(s->tracker_time_ns);
  }
  ASSERT_EQ(times.size(), 100u);
  EXPECT_EQ(times.front(), 5'000'000'000);
  for (std::size_t i = 1; i < times.size(); ++i) EXPECT_EQ(times[i] - times[i - 1], 4'000'000);
}

TEST(ReplaySource, RecordedReceiveTimesAndMarkersAreRebasedWithTheSamples) {
  auto rec = make_recording(20, 250);
  for (auto& r : rec.records) {
    if (const auto* s = std::get_if<protocol::GazeSample>(&r.item)) r.host_receive_ns = s->tracker_time_ns + 7'000'000;
  }
  protocol::Marker m;
  m.marker_id = 1;
  m.time_ns = m.received_ns = rec.records[3].time_ns();
  m.label.value = "trial 1";
  rec.records.insert(rec.records.begin() + 4, protocol::Record{0, m});
  ReplayOptions o;
  o.start_time_ns = 5'000'000'000;
  o.speed = 2.0;
  ReplaySource src(o, rec);
  std::size_t samples = 0;
  std::vector<protocol::Marker> markers;
  std::int64_t sample_after_marker = -1;
  while (auto item = src.next()) {
    for (const auto& mk : src.take_markers()) markers.push_back(mk);
    const auto* s = std::get_if<protocol::GazeSample>(&*item);
    if (s != nullptr && !markers.empty() && sample_after_marker < 0) sample_after_marker = s->tracker_time_ns;
    if (s == nullptr) {
      EXPECT_FALSE(src.last_receive_ns());
      continue;
    }
    ++samples;
    ASSERT_TRUE(src.last_receive_ns());
    EXPECT_EQ(*src.last_receive_ns() - s->tracker_time_ns, 3'500'000) << "7 ms at twice the speed";
  }
  EXPECT_EQ(samples, 20u);
  ASSERT_EQ(markers.size(), 1u) << "the recording's marker comes out with the item after it";
  EXPECT_EQ(markers[0].label.value, "trial 1");
  EXPECT_EQ(markers[0].time_ns, markers[0].received_ns);
  EXPECT_LE(markers[0].time_ns, sample_after_marker) << "rebased like the samples: not after the sample it preceded";
  EXPECT_GT(markers[0].time_ns, 5'000'000'000);
  EXPECT_EQ(src.status_detail(), "1 markers replayed");

  // A marker after the last sample is met by the next() that finds the end: take_markers has it.
  auto tail = make_recording(5, 250);
  protocol::Marker last = m;
  last.time_ns = last.received_ns = tail.records.back().time_ns() + 1'000'000;
  last.label.value = "end";
  tail.records.push_back(protocol::Record{1, last});
  ReplaySource end_src(o, tail);
  while (end_src.next()) {
    EXPECT_TRUE(end_src.take_markers().empty());
  }
  const auto after = end_src.take_markers();
  ASSERT_EQ(after.size(), 1u);
  EXPECT_EQ(after[0].label.value, "end");
}

TEST(ReplaySource, SpeedFactorAndLoopKeepTimeMonotonic) {
  const auto rec = make_recording(50, 100);
  ReplayOptions o;
  o.speed = 2.0;
  o.loop = true;
  ReplaySource src(o, rec);
  std::int64_t last = INT64_MIN;
  std::vector<std::int64_t> sample_times;
  for (int i = 0; i < 400; ++i) {
    const auto item = src.next();
    ASSERT_TRUE(item);
    const std::int64_t t = due_time_ns(*item);
    EXPECT_GE(t, last);
    last = t;
    if (const auto* s = std::get_if<protocol::GazeSample>(&*item)) sample_times.push_back(s->tracker_time_ns);
  }
  EXPECT_GE(src.loops_completed(), 2u);
  for (std::size_t i = 1; i < sample_times.size(); ++i) {
    EXPECT_EQ(sample_times[i] - sample_times[i - 1], 5'000'000) << "10 ms at 2x is 5 ms, across loop seams too";
  }
  EXPECT_DOUBLE_EQ(src.nominal_rate_hz(), 200.0);
}

// Issue 23 item 12: times near +-2^63 wrapped in the replay's arithmetic.
TEST(ReplaySource, RefusesTimesThatWouldWrap) {
  ReplayOptions o;
  o.path = "wrap.fgr";
  for (const std::int64_t t : {INT64_MAX, INT64_MIN, (std::int64_t{1} << 61) + 1}) {
    auto rec = make_recording(10, 250);
    std::get<protocol::GazeSample>(rec.records.back().item).tracker_time_ns = t;
    try {
      ReplaySource s(o, rec);
      ADD_FAILURE() << t;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("recording wrap.fgr: record " + std::to_string(rec.records.size() - 1) +
                                           " has the time " + std::to_string(t) + " ns"),
                std::string::npos)
          << e.what();
    }
  }
  auto rec = make_recording(10, 250);
  protocol::GazeEvent e;
  e.start_time_ns = 0;
  e.duration_ns = INT64_MAX;
  rec.records.push_back(protocol::Record{999, e});
  EXPECT_THROW(ReplaySource(o, rec), std::runtime_error);
}

TEST(ReplaySource, RefusesBadSpeedAndEmptyRecordings) {
  const auto rec = make_recording(10, 250);
  ReplayOptions o;
  o.speed = 0;
  EXPECT_THROW(ReplaySource(o, rec), std::runtime_error);
  o.speed = 1;
  protocol::Recording empty;
  o.path = "empty.fgr";
  try {
    ReplaySource s(o, empty);
    ADD_FAILURE();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("empty.fgr"), std::string::npos);
  }
  o.path = "/nonexistent/gaze.fgr";
  try {
    ReplaySource s(o);
    ADD_FAILURE();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/gaze.fgr"), std::string::npos);
  }
}
