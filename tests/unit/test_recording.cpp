// SPDX-License-Identifier: Apache-2.0
// Gaze recordings (.fgr): round trips, recovery of truncated and damaged files, the writer's
// refusal to lose stored data, and a writer killed with SIGKILL mid-stream.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <signal.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <random>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "fovea/protocol/crc32c.h"
#include "fovea/protocol/recording.h"

namespace {

using namespace fovea::protocol;
namespace fs = std::filesystem;

// ---- test data ---------------------------------------------------------------------------------

RecordingHeader test_header() {
  RecordingHeader h;
  h.device = "unit-test tracker #1";
  h.display = DisplayGeometry{2560, 1440, 0.5966, 0.3356, 0.7};
  h.nominal_rate_hz = 250.0;
  h.clock = RecordingClock::Monotonic;
  h.created_unix_ns = 1'700'000'000'123'456'789;
  h.created_clock_ns = 42'000'000'000;
  return h;
}

float uniform(std::mt19937& rng, float lo, float hi) { return std::uniform_real_distribution<float>(lo, hi)(rng); }

unsigned pick(std::mt19937& rng, unsigned lo, unsigned hi) {
  return std::uniform_int_distribution<unsigned>(lo, hi)(rng);
}

EyeData random_eye(std::mt19937& rng) {
  EyeData e;
  e.flags = static_cast<std::uint8_t>(pick(rng, 0, kEyeFlagMask));
  e.pupil_x_px = uniform(rng, 0.0f, 640.0f);
  e.pupil_y_px = uniform(rng, 0.0f, 480.0f);
  e.pupil_diameter_mm = uniform(rng, 0.0f, 8.0f);
  e.pupil_glint_x_px = uniform(rng, -20.0f, 20.0f);
  e.pupil_glint_y_px = uniform(rng, -20.0f, 20.0f);
  return e;
}

GazeSample random_sample(std::mt19937& rng, std::int64_t t) {
  GazeSample s;
  s.tracker_time_ns = t;
  s.x = uniform(rng, -0.2f, 1.2f);
  s.y = uniform(rng, -0.2f, 1.2f);
  s.x_deg = uniform(rng, -30.0f, 30.0f);
  s.y_deg = uniform(rng, -20.0f, 20.0f);
  s.angular_velocity_deg_s = uniform(rng, 0.0f, 700.0f);
  s.confidence = uniform(rng, 0.0f, 1.0f);
  s.state = static_cast<EyeMovement>(pick(rng, 0, kMaxEyeMovement));
  s.flags = static_cast<std::uint8_t>(pick(rng, 0, kGazeFlagMask));
  s.left = random_eye(rng);
  s.right = random_eye(rng);
  return s;
}

GazeEvent random_event(std::mt19937& rng, std::int64_t t) {
  GazeEvent e;
  e.kind = static_cast<EyeMovement>(pick(rng, 1, kMaxEyeMovement));
  e.phase = pick(rng, 0, 1) != 0 ? EventPhase::Start : EventPhase::End;
  e.duration_ns = e.phase == EventPhase::Start ? 0 : static_cast<std::int64_t>(pick(rng, 1'000'000, 400'000'000));
  e.start_time_ns = t - e.duration_ns;
  e.centroid_x = uniform(rng, 0.0f, 1.0f);
  e.centroid_y = uniform(rng, 0.0f, 1.0f);
  e.centroid_x_deg = uniform(rng, -25.0f, 25.0f);
  e.centroid_y_deg = uniform(rng, -15.0f, 15.0f);
  e.amplitude_deg = uniform(rng, 0.0f, 40.0f);
  e.peak_velocity_deg_s = uniform(rng, 0.0f, 900.0f);
  return e;
}

// A marker as the daemon publishes it: with the receive time, or a sender's own (earlier) time.
Marker marker_at(std::int64_t t, std::size_t i) {
  Marker m;
  m.marker_id = 1000 + i;
  m.received_ns = t;
  m.time_ns = i % 2 == 0 ? t : t - 3'000'000;
  m.flags = i % 2 == 0 ? 0 : kMarkerClientTime;
  m.label.value = "trial " + std::to_string(i) + ", \"stimulus\" \xc3\xa4";
  return m;
}

// Samples every 4 ms with an event now and then and a marker every 17th record; sequence numbers
// count up from `first_seq`.
std::vector<Record> random_records(std::size_t n, std::uint32_t seed, std::uint64_t first_seq = 0) {
  std::mt19937 rng(seed);
  std::vector<Record> out;
  out.reserve(n);
  std::int64_t t = 5'000'000'000;
  for (std::size_t i = 0; i < n; ++i) {
    t += 4'000'000;
    Record r;
    r.sequence = first_seq + i;
    if (pick(rng, 0, 3) == 0) {
      r.item = random_event(rng, t);
    } else if (i % 17 == 5) {
      r.item = marker_at(t, i);
    } else {
      r.item = random_sample(rng, t);
      if (i % 3 == 0) r.host_receive_ns = t + 700'000 + static_cast<std::int64_t>(i);  // a bridged tracker's
    }
    out.push_back(r);
  }
  return out;
}

// A cheap record that depends only on its sequence number (the killed writer's stream).
Record record_for(std::uint64_t seq) {
  Record r;
  r.sequence = seq;
  const auto t = static_cast<std::int64_t>(seq) * 4'000'000;
  const auto frac = static_cast<float>(seq % 1000) / 1000.0f;
  if (seq % 7 == 3) {
    GazeEvent e;
    e.kind = EyeMovement::Saccade;
    e.phase = EventPhase::End;
    e.start_time_ns = t - 30'000'000;
    e.duration_ns = 30'000'000;
    e.centroid_x = frac;
    e.amplitude_deg = 10.0f * frac;
    r.item = e;
  } else {
    GazeSample s;
    s.tracker_time_ns = t;
    s.x = frac;
    s.y = 1.0f - frac;
    s.confidence = frac;
    s.state = EyeMovement::Fixation;
    s.flags = kGazeValid;
    r.item = s;
  }
  return r;
}

// The bytes of a recording plus where each record starts: starts[i] is record i's offset and
// starts[n] the file size.
struct EncodedFile {
  std::vector<std::uint8_t> bytes;
  std::vector<std::size_t> starts;
};

EncodedFile encode_file(const RecordingHeader& h, const std::vector<Record>& records) {
  EncodedFile f;
  f.bytes = encode_recording_header(h);
  for (const Record& r : records) {
    f.starts.push_back(f.bytes.size());
    const std::vector<std::uint8_t> b = encode_record(r);
    f.bytes.insert(f.bytes.end(), b.begin(), b.end());
  }
  f.starts.push_back(f.bytes.size());
  return f;
}

Recording parse(const std::vector<std::uint8_t>& bytes, std::size_t size) {
  return parse_recording(std::span<const std::uint8_t>(bytes.data(), size));
}
Recording parse(const std::vector<std::uint8_t>& bytes) { return parse(bytes, bytes.size()); }

// ---- files -----------------------------------------------------------------------------------

class TempDir {
 public:
  TempDir() {
    static std::atomic<unsigned> counter{0};
    std::random_device rd;
    path_ = fs::temp_directory_path() / ("fovea-test-recording-" + std::to_string(::getpid()) + "-" +
                                         std::to_string(counter++) + "-" + std::to_string(rd()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

std::vector<std::uint8_t> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

void write_recording(const std::string& path, const RecordingHeader& h, const std::vector<Record>& records) {
  RecordingWriter w(path, h);
  for (const Record& r : records) w.append(r);
  EXPECT_EQ(w.records_written(), records.size());
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(no std::runtime_error thrown)";
}

// ---- encoding ---------------------------------------------------------------------------------

TEST(RecordingFormat, HeaderAndRecordSizes) {
  EXPECT_EQ(encode_recording_header(test_header()).size(), kRecordingHeaderSize);
  std::mt19937 rng(1);
  // sync 4 + type 1 + reserved 1 + length 2 + sequence 8 + payload + CRC 4
  EXPECT_EQ(encode_record(Record{0, random_sample(rng, 0)}).size(), 20u + 76u);
  EXPECT_EQ(encode_record(Record{0, random_event(rng, 0)}).size(), 20u + 48u);
  EXPECT_EQ(encode_record(Record{0, marker_at(0, 1)}).size(), 20u + 104u);
}

TEST(RecordingFormat, HeaderRoundTripsAllFields) {
  RecordingHeader h = test_header();
  h.device = std::string(63, 'd');
  h.clock = RecordingClock::Realtime;
  h.created_unix_ns = -5;
  h.created_clock_ns = std::numeric_limits<std::int64_t>::max();
  const Recording rec = parse(encode_recording_header(h));
  EXPECT_TRUE(rec.report.header_valid);
  EXPECT_EQ(rec.header, h);
  EXPECT_TRUE(rec.records.empty());
  EXPECT_EQ(rec.report.damaged_regions, 0u);
  EXPECT_FALSE(rec.report.truncated_tail);
}

TEST(RecordingFormat, HeaderRejectsWhatItCannotStore) {
  RecordingHeader h = test_header();
  h.device = std::string(64, 'd');
  EXPECT_THROW(encode_recording_header(h), std::invalid_argument);
  h = test_header();
  h.display.width_px = 0;
  EXPECT_THROW(encode_recording_header(h), std::invalid_argument);
}

TEST(RecordingFormat, EncodeRecordRefusesNonFiniteAndOutOfRangeValues) {
  std::mt19937 rng(2);
  GazeSample s = random_sample(rng, 1000);
  s.x = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(encode_record(Record{1, s}), std::invalid_argument);
  s = random_sample(rng, 1000);
  s.left.pupil_diameter_mm = std::numeric_limits<float>::infinity();
  EXPECT_THROW(encode_record(Record{1, s}), std::invalid_argument);
  s = random_sample(rng, 1000);
  s.confidence = 1.5f;
  EXPECT_THROW(encode_record(Record{1, s}), std::invalid_argument);
  GazeEvent e = random_event(rng, 1000);
  e.peak_velocity_deg_s = -std::numeric_limits<float>::infinity();
  EXPECT_THROW(encode_record(Record{1, e}), std::invalid_argument);
}

TEST(RecordingFormat, RecordTimeIsSampleTimeOrEventEnd) {
  GazeSample s;
  s.tracker_time_ns = 123;
  EXPECT_EQ((Record{0, s}).time_ns(), 123);
  GazeEvent e;
  e.start_time_ns = 1000;
  e.duration_ns = 250;
  EXPECT_EQ((Record{0, e}).time_ns(), 1250);
}

TEST(RecordingFormat, DescribeNamesWhatWasSkipped) {
  RecoveryReport r;
  r.header_valid = true;
  r.records = 7;
  EXPECT_EQ(r.describe(), "7 intact records");
  r.header_valid = false;
  r.damaged_regions = 2;
  r.bytes_skipped = 99;
  r.truncated_tail = true;
  const std::string d = r.describe();
  EXPECT_NE(d.find("7 intact records"), std::string::npos) << d;
  EXPECT_NE(d.find("header damaged"), std::string::npos) << d;
  EXPECT_NE(d.find("99 bytes"), std::string::npos) << d;
  EXPECT_NE(d.find("2 damaged region"), std::string::npos) << d;
  EXPECT_NE(d.find("ends inside a record"), std::string::npos) << d;
}

// ---- round trip ---------------------------------------------------------------------------------

TEST(RecordingFile, WriterAndReaderRoundTrip) {
  const TempDir dir;
  const std::string path = dir.file("roundtrip.fgr");
  const RecordingHeader h = test_header();
  const std::vector<Record> records = random_records(200, 11);
  ASSERT_GT(std::count_if(records.begin(), records.end(),
                          [](const Record& r) { return std::holds_alternative<GazeEvent>(r.item); }),
            10);
  ASSERT_GT(std::count_if(records.begin(), records.end(),
                          [](const Record& r) { return std::holds_alternative<Marker>(r.item); }),
            5);
  {
    RecordingWriter w(path, h);
    EXPECT_EQ(w.path(), path);
    for (const Record& r : records) w.append(r);
    w.sync();
    EXPECT_EQ(w.records_written(), 200u);
  }
  const Recording rec = read_recording(path);
  EXPECT_EQ(rec.header, h);
  EXPECT_EQ(rec.records, records);
  EXPECT_TRUE(rec.report.header_valid);
  EXPECT_EQ(rec.report.records, 200u);
  EXPECT_EQ(rec.report.damaged_regions, 0u);
  EXPECT_EQ(rec.report.bytes_skipped, 0u);
  EXPECT_FALSE(rec.report.truncated_tail);
  // The file holds exactly the documented bytes.
  EXPECT_EQ(read_bytes(path), encode_file(h, records).bytes);
}

// A binocular source's samples keep each eye's gaze through a file: a GAZE_EYES record after the
// sample's, joined back when read; one whose sample record was lost is counted, never misplaced.
TEST(RecordingFile, PerEyeGazeFollowsItsSampleAndIsJoinedBack) {
  const TempDir dir;
  const std::string path = dir.file("eyes.fgr");
  std::vector<Record> records;
  for (std::uint64_t i = 0; i < 4; ++i) {
    GazeSample s;
    s.tracker_time_ns = 1'000'000'000 + static_cast<std::int64_t>(i) * 4'000'000;
    s.x = 0.5f, s.y = 0.5f, s.flags = kGazeValid;
    if (i != 2) s.left_gaze = EyeGaze{kEyeGazeValid, 0.49f, 0.5f, -0.3f, 0.0f};
    if (i == 0 || i == 3) s.right_gaze = EyeGaze{kEyeGazeValid, 0.51f, 0.5f, 0.3f, 0.0f};
    records.emplace_back(100 + i, s, i == 1 ? std::optional<std::int64_t>(s.tracker_time_ns + 5'000'000) : std::nullopt);
  }
  EXPECT_EQ(encode_record(records[0]).size(), 96u + 68u) << "the sample record, then its 68-byte GAZE_EYES record";
  EXPECT_EQ(encode_record(records[2]).size(), 96u) << "no eye gaze: the sample record alone";
  {
    RecordingWriter w(path, test_header());
    for (const Record& r : records) w.append(r);
  }
  Recording rec = read_recording(path);
  EXPECT_EQ(rec.records, records);
  EXPECT_EQ(rec.report.records, 4u);
  EXPECT_EQ(rec.report.describe(), "4 intact records");

  // Damage the first sample's record: its eyes stay unjoined (not given to anything else).
  std::vector<std::uint8_t> bytes = read_bytes(path);
  bytes[kRecordingHeaderSize + 40] ^= 0xFF;
  rec = parse_recording(bytes);
  ASSERT_EQ(rec.records.size(), 3u);
  EXPECT_EQ(rec.records[0], records[1]);
  EXPECT_EQ(rec.report.eyes_unjoined, 1u);
  EXPECT_NE(rec.report.describe().find("1 per-eye record(s) without their sample"), std::string::npos)
      << rec.report.describe();
}

// ---- truncation and damage -------------------------------------------------------------------

// Write N records, cut the file at every byte offset within the last three records: the reader
// recovers exactly the records wholly inside the prefix and reports the partial tail.
TEST(RecordingRecovery, EveryCutWithinTheLastThreeRecords) {
  const RecordingHeader h = test_header();
  const std::vector<Record> records = random_records(200, 21);
  const EncodedFile f = encode_file(h, records);
  const std::size_t n = records.size();
  for (std::size_t cut = f.starts[n - 3]; cut <= f.bytes.size(); ++cut) {
    SCOPED_TRACE("cut at byte " + std::to_string(cut) + " of " + std::to_string(f.bytes.size()));
    std::size_t whole = 0;  // records entirely inside the prefix
    while (whole < n && f.starts[whole + 1] <= cut) ++whole;
    const std::size_t partial = cut - f.starts[whole];
    const Recording rec = parse(f.bytes, cut);
    EXPECT_TRUE(rec.report.header_valid);
    EXPECT_EQ(rec.header, h);
    ASSERT_EQ(rec.records.size(), whole);
    EXPECT_TRUE(std::equal(rec.records.begin(), rec.records.end(), records.begin()));
    EXPECT_EQ(rec.report.records, whole);
    EXPECT_EQ(rec.report.truncated_tail, partial != 0);
    EXPECT_EQ(rec.report.bytes_skipped, partial);
    EXPECT_EQ(rec.report.damaged_regions, partial != 0 ? 1u : 0u);
  }
}

// What the reader must find in `damaged`, derived from which bytes of the intact file changed.
struct Expected {
  std::vector<Record> records;
  bool header_valid = true;
  std::uint64_t damaged_regions = 0;
  std::uint64_t bytes_skipped = 0;
  bool truncated_tail = false;
  bool any_record_hit = false;
};

Expected expect_after_damage(const EncodedFile& f, const std::vector<Record>& records,
                             const std::vector<std::size_t>& changed) {
  const std::size_t n = records.size();
  // unit 0 is the header, unit i + 1 is record i
  std::vector<bool> hit(n + 1, false);
  bool magic_hit = false;
  for (const std::size_t pos : changed) {
    if (pos < kRecordingHeaderSize) {
      hit[0] = true;
      magic_hit = magic_hit || pos < 8;
    } else {
      const auto it = std::upper_bound(f.starts.begin(), f.starts.end(), pos);
      hit[static_cast<std::size_t>(it - f.starts.begin())] = true;  // (it - 1) is the record, +1 for the header
    }
  }
  Expected e;
  e.header_valid = !hit[0];
  if (hit[0]) e.bytes_skipped += magic_hit ? kRecordingHeaderSize : kRecordingHeaderSize - 8;
  for (std::size_t u = 0; u <= n; ++u) {
    if (hit[u] && (u == 0 || !hit[u - 1])) ++e.damaged_regions;
    if (u == 0) continue;
    if (hit[u]) {
      e.any_record_hit = true;
      e.bytes_skipped += f.starts[u] - f.starts[u - 1];
    } else {
      e.records.push_back(records[u - 1]);
    }
  }
  e.truncated_tail = hit[n];
  return e;
}

void expect_recovered(const Recording& rec, const Expected& e) {
  EXPECT_EQ(rec.report.header_valid, e.header_valid);
  ASSERT_EQ(rec.records.size(), e.records.size());
  EXPECT_EQ(rec.records, e.records);
  EXPECT_EQ(rec.report.records, e.records.size());
  if (e.any_record_hit) {
    EXPECT_GE(rec.report.damaged_regions, 1u);
  }
  EXPECT_EQ(rec.report.damaged_regions, e.damaged_regions);
  EXPECT_EQ(rec.report.bytes_skipped, e.bytes_skipped);
  EXPECT_EQ(rec.report.truncated_tail, e.truncated_tail);
}

// Flip 1..5 random bytes anywhere (header included): exactly the untouched records come back, in
// order, and the report accounts for every damaged byte run.
TEST(RecordingRecovery, RandomByteFlipsLoseOnlyTheRecordsHit) {
  const RecordingHeader h = test_header();
  const std::vector<Record> records = random_records(200, 31);
  const EncodedFile f = encode_file(h, records);
  std::mt19937 rng(20240611);
  std::size_t trials_with_header_hit = 0, trials_with_record_hit = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    std::vector<std::uint8_t> bytes = f.bytes;
    std::vector<std::size_t> changed;
    const unsigned flips = pick(rng, 1, 5);
    for (unsigned k = 0; k < flips; ++k) {
      // Half the flips land in the last few hundred bytes and the header so both ends are well covered.
      std::size_t pos = 0;
      switch (pick(rng, 0, 3)) {
        case 0: pos = pick(rng, 0, static_cast<unsigned>(kRecordingHeaderSize + 200)); break;
        case 1: pos = pick(rng, static_cast<unsigned>(f.bytes.size() - 300), static_cast<unsigned>(f.bytes.size() - 1)); break;
        default: pos = pick(rng, 0, static_cast<unsigned>(f.bytes.size() - 1)); break;
      }
      bytes[pos] = static_cast<std::uint8_t>(bytes[pos] ^ pick(rng, 1, 255));
      changed.push_back(pos);
    }
    const Expected e = expect_after_damage(f, records, changed);
    trials_with_header_hit += e.header_valid ? 0u : 1u;
    trials_with_record_hit += e.any_record_hit ? 1u : 0u;
    SCOPED_TRACE("trial " + std::to_string(trial));
    const Recording rec = parse(bytes);
    expect_recovered(rec, e);
    if (e.header_valid) {
      EXPECT_EQ(rec.header, h);
    }
    if (HasFatalFailure() || HasNonfatalFailure()) break;  // one detailed failure is enough
  }
  EXPECT_GT(trials_with_header_hit, 100u);
  EXPECT_GT(trials_with_record_hit, 1000u);
}

TEST(RecordingRecovery, DamageInTheMiddleOfARecordLosesOnlyThatRecord) {
  const std::vector<Record> records = random_records(30, 41);
  const EncodedFile f = encode_file(test_header(), records);
  for (const std::size_t victim : {std::size_t{0}, std::size_t{10}, std::size_t{28}}) {
    for (const std::size_t at : {std::size_t{0}, std::size_t{4}, std::size_t{6}, std::size_t{9}, std::size_t{40},
                                 std::size_t{63}}) {
      SCOPED_TRACE("record " + std::to_string(victim) + " byte " + std::to_string(at));
      std::vector<std::uint8_t> bytes = f.bytes;
      bytes[f.starts[victim] + at] = static_cast<std::uint8_t>(bytes[f.starts[victim] + at] ^ 0x5A);
      const Recording rec = parse(bytes);
      std::vector<Record> want = records;
      want.erase(want.begin() + static_cast<std::ptrdiff_t>(victim));
      EXPECT_TRUE(rec.report.header_valid);
      EXPECT_EQ(rec.records, want);
      EXPECT_EQ(rec.report.damaged_regions, 1u);
      EXPECT_EQ(rec.report.bytes_skipped, f.starts[victim + 1] - f.starts[victim]);
      EXPECT_FALSE(rec.report.truncated_tail);
    }
  }
}

TEST(RecordingRecovery, GarbageBetweenRecordsIsSkipped) {
  const std::vector<Record> records = random_records(20, 51);
  const EncodedFile f = encode_file(test_header(), records);
  const std::vector<std::uint8_t> false_sync = {0xF0, 0x7E, 0xA1, 0x52, 0x07, 0x00, 0x54, 0x00, 0x01};
  for (const std::size_t len : {std::size_t{1}, std::size_t{3}, std::size_t{5}, std::size_t{37}, std::size_t{0}}) {
    // len 0: a false sync marker (with a plausible type and length) instead of plain garbage
    const std::vector<std::uint8_t> junk = len == 0 ? false_sync : [len] {
      std::vector<std::uint8_t> v;
      for (std::size_t i = 0; i < len; ++i) v.push_back(static_cast<std::uint8_t>(i * 7 + 1));
      return v;
    }();
    SCOPED_TRACE(std::to_string(junk.size()) + " bytes of junk");
    std::vector<std::uint8_t> bytes(f.bytes.begin(), f.bytes.begin() + static_cast<std::ptrdiff_t>(f.starts[7]));
    bytes.insert(bytes.end(), junk.begin(), junk.end());
    bytes.insert(bytes.end(), f.bytes.begin() + static_cast<std::ptrdiff_t>(f.starts[7]), f.bytes.end());
    const Recording rec = parse(bytes);
    EXPECT_EQ(rec.records, records);
    EXPECT_EQ(rec.report.damaged_regions, 1u);
    EXPECT_EQ(rec.report.bytes_skipped, junk.size());
    EXPECT_FALSE(rec.report.truncated_tail);
    EXPECT_TRUE(rec.report.header_valid);
  }
}

TEST(RecordingRecovery, DamagedHeaderStillYieldsTheRecords) {
  const RecordingHeader h = test_header();
  const std::vector<Record> records = random_records(25, 61);
  const EncodedFile f = encode_file(h, records);
  for (const std::size_t at : {std::size_t{3}, std::size_t{8}, std::size_t{20}, std::size_t{100}, std::size_t{158}}) {
    SCOPED_TRACE("header byte " + std::to_string(at));
    std::vector<std::uint8_t> bytes = f.bytes;
    bytes[at] = static_cast<std::uint8_t>(bytes[at] ^ 0x01);
    const Recording rec = parse(bytes);
    EXPECT_FALSE(rec.report.header_valid);
    EXPECT_EQ(rec.header, RecordingHeader{});  // defaults, nothing half-trusted
    EXPECT_EQ(rec.records, records);
    EXPECT_EQ(rec.report.damaged_regions, 1u);
    EXPECT_EQ(rec.report.bytes_skipped, at < 8 ? kRecordingHeaderSize : kRecordingHeaderSize - 8);
    EXPECT_NE(rec.report.describe().find("header damaged"), std::string::npos);
  }
}

TEST(RecordingRecovery, FileThatLostItsBeginningStillYieldsTheRecords) {
  const std::vector<Record> records = random_records(12, 71);
  const EncodedFile f = encode_file(test_header(), records);
  // Starts 30 bytes into record 2.
  const std::vector<std::uint8_t> bytes(f.bytes.begin() + static_cast<std::ptrdiff_t>(f.starts[2] + 30),
                                        f.bytes.end());
  const Recording rec = parse(bytes);
  EXPECT_FALSE(rec.report.header_valid);
  EXPECT_EQ(rec.records, std::vector<Record>(records.begin() + 3, records.end()));
  EXPECT_EQ(rec.report.damaged_regions, 1u);
  EXPECT_EQ(rec.report.bytes_skipped, f.starts[3] - f.starts[2] - 30);
  EXPECT_FALSE(rec.report.truncated_tail);
}

TEST(RecordingRecovery, HeaderOnlyAndTruncatedHeader) {
  const std::vector<std::uint8_t> head = encode_recording_header(test_header());
  Recording rec = parse(head);
  EXPECT_TRUE(rec.report.header_valid);
  EXPECT_TRUE(rec.records.empty());
  EXPECT_EQ(rec.report.damaged_regions, 0u);
  // Magic present but the header cut short: a (damaged) recording with nothing in it.
  rec = parse(head, 100);
  EXPECT_FALSE(rec.report.header_valid);
  EXPECT_TRUE(rec.records.empty());
  EXPECT_EQ(rec.report.bytes_skipped, 92u);
  EXPECT_TRUE(rec.report.truncated_tail);
}

TEST(RecordingRecovery, NotARecordingThrows) {
  std::vector<std::uint8_t> garbage(3000);
  std::mt19937 rng(81);
  for (auto& b : garbage) b = static_cast<std::uint8_t>(pick(rng, 0, 255));
  EXPECT_THROW(parse(garbage), std::runtime_error);
  EXPECT_THROW(parse(garbage, 5), std::runtime_error);
  EXPECT_THROW(parse(garbage, 0), std::runtime_error);
  const std::string text = "sequence,tracker_time_ns,x,y\n0,1,0.5,0.5\n";
  EXPECT_THROW(parse_recording(std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(text.data()),
                                                             text.size())),
               std::runtime_error);
}

TEST(RecordingFile, ReadErrorsNameTheFile) {
  const TempDir dir;
  const std::string missing = dir.file("missing.fgr");
  std::string msg = error_of([&] { read_recording(missing); });
  EXPECT_NE(msg.find(missing), std::string::npos) << msg;

  const std::string empty = dir.file("empty.fgr");
  write_bytes(empty, {});
  msg = error_of([&] { read_recording(empty); });
  EXPECT_NE(msg.find(empty), std::string::npos) << msg;
  EXPECT_NE(msg.find("empty"), std::string::npos) << msg;

  const std::string garbage = dir.file("garbage.fgr");
  write_bytes(garbage, std::vector<std::uint8_t>(500, 0x33));
  msg = error_of([&] { read_recording(garbage); });
  EXPECT_NE(msg.find(garbage), std::string::npos) << msg;
  EXPECT_NE(msg.find("not a fovea recording"), std::string::npos) << msg;

  // Issue 23 item 11: a FIFO blocked `fovea-ctl info` for ever; a device or directory is no recording.
  const std::string fifo = dir.file("fifo.fgr");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  msg = error_of([&] { read_recording(fifo); });
  EXPECT_NE(msg.find("recording " + fifo + ": is a FIFO, not a regular file"), std::string::npos) << msg;
  msg = error_of([&] { read_recording("/dev/zero"); });
  EXPECT_NE(msg.find("is a character device"), std::string::npos) << msg;
}

// ---- writer: nothing already stored is lost ------------------------------------------------------

TEST(RecordingWriterTest, CreateNewRefusesToOverwrite) {
  const TempDir dir;
  const std::string path = dir.file("existing.fgr");
  write_recording(path, test_header(), random_records(10, 91));
  const std::vector<std::uint8_t> before = read_bytes(path);
  const std::string msg = error_of([&] { RecordingWriter w(path, test_header()); });
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
  EXPECT_NE(msg.find("already exists"), std::string::npos) << msg;
  EXPECT_EQ(read_bytes(path), before);

  // Also any other file that happens to have the name.
  const std::string notes = dir.file("notes.txt");
  const std::vector<std::uint8_t> text = {'k', 'e', 'e', 'p', '\n'};
  write_bytes(notes, text);
  EXPECT_THROW(RecordingWriter(std::string(notes), test_header()), std::runtime_error);
  EXPECT_EQ(read_bytes(notes), text);
}

TEST(RecordingWriterTest, InvalidHeaderCreatesNoFile) {
  const TempDir dir;
  const std::string path = dir.file("bad.fgr");
  RecordingHeader h = test_header();
  h.device = std::string(80, 'x');
  EXPECT_THROW(RecordingWriter(std::string(path), h), std::invalid_argument);
  EXPECT_FALSE(fs::exists(path));
}

TEST(RecordingWriterTest, CreateNewInMissingDirectoryNamesThePath) {
  const TempDir dir;
  const std::string path = dir.file("no/such/dir/x.fgr");
  const std::string msg = error_of([&] { RecordingWriter w(path, test_header()); });
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
}

TEST(RecordingWriterTest, AppendFailedRecordLeavesFileUnchanged) {
  const TempDir dir;
  const std::string path = dir.file("nan.fgr");
  RecordingWriter w(path, test_header());
  const std::vector<Record> records = random_records(3, 95);
  for (const Record& r : records) w.append(r);
  const std::vector<std::uint8_t> before = read_bytes(path);
  GazeSample s;
  s.y = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(w.append(Record{3, s}), std::invalid_argument);
  EXPECT_EQ(w.records_written(), 3u);
  EXPECT_EQ(read_bytes(path), before);
  EXPECT_EQ(read_recording(path).records, records);
}

TEST(RecordingFormat, OnlySamplesCarryAReceiveTime) {
  std::mt19937 rng(3);
  Record e{0, random_event(rng, 0), 5};
  EXPECT_THROW(encode_record(e), std::invalid_argument);
  const Record s{0, random_sample(rng, 0), 5};
  EXPECT_EQ(encode_record(s).size(), 20u + 8u + 76u);
}

TEST(RecordingWriterTest, AppendingToAVersionOneFileLeavesReceiveTimesOut) {
  const TempDir dir;
  const std::string path = dir.file("v1.fgr");
  // A file as version 1 wrote it: the same header with version 1 (and its CRC), records without receive times.
  std::vector<std::uint8_t> head = encode_recording_header(test_header());
  head[8] = 1;
  const std::uint32_t crc = fovea::protocol::crc32c(std::span<const std::uint8_t>(head).first(156));
  for (int i = 0; i < 4; ++i) head[156 + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(crc >> (8 * i));
  std::vector<Record> old = random_records(6, 7);
  for (Record& r : old) r.host_receive_ns.reset();
  std::vector<std::uint8_t> bytes = head;
  for (const Record& r : old) {
    const auto b = encode_record(r);
    bytes.insert(bytes.end(), b.begin(), b.end());
  }
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  ASSERT_EQ(read_recording(path).records, old) << "version-1 files are read as before";

  std::vector<Record> more = random_records(30, 8, 6);
  {
    RecordingWriter w(path, test_header(), RecordingWriter::Mode::Append);
    EXPECT_FALSE(w.stores_receive_times());
    for (const Record& r : more) w.append(r);
  }
  ASSERT_TRUE(std::any_of(more.begin(), more.end(), [](const Record& r) { return r.host_receive_ns.has_value(); }));
  for (Record& r : more) r.host_receive_ns.reset();
  old.insert(old.end(), more.begin(), more.end());
  const Recording back = read_recording(path);
  EXPECT_TRUE(back.report.header_valid);
  EXPECT_EQ(back.records, old);
}

TEST(RecordingWriterTest, AppendAddsToARecordingOfTheSameDisplay) {
  const TempDir dir;
  const std::string path = dir.file("session.fgr");
  const RecordingHeader first = test_header();
  const std::vector<Record> a = random_records(10, 101, 0);
  write_recording(path, first, a);

  RecordingHeader second = first;  // same display; other fields may differ
  second.device = "another tracker";
  second.created_unix_ns += 60'000'000'000;
  const std::vector<Record> b = random_records(5, 102, 10);
  {
    RecordingWriter w(path, second, RecordingWriter::Mode::Append);
    for (const Record& r : b) w.append(r);
    EXPECT_EQ(w.records_written(), 5u);
  }
  const Recording rec = read_recording(path);
  EXPECT_EQ(rec.header, first);  // the original header stays
  std::vector<Record> all = a;
  all.insert(all.end(), b.begin(), b.end());
  EXPECT_EQ(rec.records, all);
  EXPECT_EQ(rec.report.damaged_regions, 0u);
}

TEST(RecordingWriterTest, AppendCreatesAMissingOrEmptyFile) {
  const TempDir dir;
  const std::vector<Record> records = random_records(4, 111);
  for (const bool exists_empty : {false, true}) {
    const std::string path = dir.file(exists_empty ? "empty.fgr" : "new.fgr");
    if (exists_empty) write_bytes(path, {});
    {
      RecordingWriter w(path, test_header(), RecordingWriter::Mode::Append);
      for (const Record& r : records) w.append(r);
    }
    const Recording rec = read_recording(path);
    EXPECT_TRUE(rec.report.header_valid);
    EXPECT_EQ(rec.header, test_header());
    EXPECT_EQ(rec.records, records);
  }
}

TEST(RecordingWriterTest, AppendRefusesAnotherDisplay) {
  const TempDir dir;
  const std::string path = dir.file("session.fgr");
  write_recording(path, test_header(), random_records(10, 121));
  const std::vector<std::uint8_t> before = read_bytes(path);
  RecordingHeader other = test_header();
  other.display.viewing_distance_m = 0.6;
  const std::string msg = error_of([&] { RecordingWriter w(path, other, RecordingWriter::Mode::Append); });
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
  EXPECT_NE(msg.find("display"), std::string::npos) << msg;
  EXPECT_EQ(read_bytes(path), before);
}

TEST(RecordingWriterTest, AppendRefusesAFileWithoutAnIntactHeader) {
  const TempDir dir;
  const EncodedFile f = encode_file(test_header(), random_records(10, 131));
  std::vector<std::uint8_t> damaged = f.bytes;
  damaged[50] = static_cast<std::uint8_t>(damaged[50] ^ 0x10);
  std::vector<std::uint8_t> short_file(f.bytes.begin(), f.bytes.begin() + 100);
  const std::vector<std::uint8_t> text = {'h', 'e', 'l', 'l', 'o', '\n'};
  std::vector<std::uint8_t> headless(f.bytes.begin() + static_cast<std::ptrdiff_t>(f.starts[0]), f.bytes.end());
  int i = 0;
  for (const auto& content : {damaged, short_file, text, headless}) {
    const std::string path = dir.file("case" + std::to_string(i++) + ".fgr");
    write_bytes(path, content);
    const std::string msg =
        error_of([&] { RecordingWriter w(path, test_header(), RecordingWriter::Mode::Append); });
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find("header"), std::string::npos) << msg;
    EXPECT_EQ(read_bytes(path), content) << path;
  }
}

// Issue 23: appending to a FIFO blocked the daemon's publishing loop once the pipe was full (nobody
// reads it), and a device was written to. Neither is a recording: refused at once, by what it is.
TEST(RecordingWriterTest, AppendRefusesWhatIsNotARegularFile) {
  const TempDir dir;
  const std::string fifo = dir.file("fifo.fgr");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string subdir = dir.file("dir.fgr");
  fs::create_directory(subdir);
  for (const std::string& path : {fifo, std::string("/dev/null"), subdir}) {
    const std::string msg = error_of([&] { RecordingWriter w(path, test_header(), RecordingWriter::Mode::Append); });
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_TRUE(msg.find("not a regular file") != std::string::npos || msg.find("Is a directory") != std::string::npos)
        << msg;
  }
}

// A writer killed mid-record leaves a partial tail; appending after it keeps every intact record.
TEST(RecordingWriterTest, AppendAfterACutTailRecoversEverything) {
  const TempDir dir;
  const std::string path = dir.file("cut.fgr");
  const std::vector<Record> a = random_records(10, 141, 0);
  const EncodedFile f = encode_file(test_header(), a);
  write_bytes(path, f.bytes);
  const std::size_t cut = f.starts[9] + 33;
  fs::resize_file(path, cut);
  const std::vector<Record> b = random_records(6, 142, 10);
  {
    RecordingWriter w(path, test_header(), RecordingWriter::Mode::Append);
    for (const Record& r : b) w.append(r);
  }
  const Recording rec = read_recording(path);
  std::vector<Record> want(a.begin(), a.begin() + 9);
  want.insert(want.end(), b.begin(), b.end());
  EXPECT_EQ(rec.records, want);
  EXPECT_EQ(rec.report.damaged_regions, 1u);
  EXPECT_EQ(rec.report.bytes_skipped, 33u);
  EXPECT_FALSE(rec.report.truncated_tail);
}

// ---- kill -9 ----------------------------------------------------------------------------------

TEST(RecordingWriterTest, KilledWriterLosesAtMostTheRecordInFlight) {
  const TempDir dir;
  const std::string path = dir.file("killed.fgr");
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    try {
      RecordingWriter w(path, test_header());
      for (std::uint64_t seq = 0;; ++seq) w.append(record_for(seq));
    } catch (...) {
    }
    std::_Exit(3);
  }
  using steady = std::chrono::steady_clock;
  // Wait until the child is writing records, then give it ~200 ms (less if the file grows large).
  const auto give_up = steady::now() + std::chrono::seconds(10);
  std::error_code ec;
  while (steady::now() < give_up && !(fs::exists(path, ec) && fs::file_size(path, ec) > 1000)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const auto stop = steady::now() + std::chrono::milliseconds(200);
  while (steady::now() < stop && fs::file_size(path, ec) < (8u << 20)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ASSERT_EQ(::kill(pid, SIGKILL), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFSIGNALED(status)) << "writer exited by itself with status " << status;
  EXPECT_EQ(WTERMSIG(status), SIGKILL);

  const Recording rec = read_recording(path);
  EXPECT_TRUE(rec.report.header_valid);
  EXPECT_EQ(rec.header, test_header());
  RecordProperty("records_recovered", std::to_string(rec.records.size()));
  RecordProperty("integrity", rec.report.describe());
  EXPECT_GT(rec.records.size(), 10u);
  EXPECT_LE(rec.report.damaged_regions, 1u);
  if (rec.report.damaged_regions > 0) {
    EXPECT_TRUE(rec.report.truncated_tail);
  }
  for (std::size_t i = 0; i < rec.records.size(); ++i) {
    ASSERT_EQ(rec.records[i], record_for(i)) << "record " << i;
  }
}

}  // namespace

namespace {

TEST(RecordingHeaderValidation, RefusesWhatTheReaderWouldCallDamaged) {
  using namespace fovea::protocol;
  RecordingHeader h;
  h.device = "ok";
  EXPECT_NO_THROW(encode_recording_header(h));
  RecordingHeader bad = h;
  bad.nominal_rate_hz = std::nan("");
  EXPECT_THROW(encode_recording_header(bad), std::invalid_argument);
  bad = h;
  bad.nominal_rate_hz = -1;
  EXPECT_THROW(encode_recording_header(bad), std::invalid_argument);
  bad = h;
  bad.clock = static_cast<RecordingClock>(7);
  EXPECT_THROW(encode_recording_header(bad), std::invalid_argument);
  bad = h;
  bad.device = std::string("ab\0cd", 5);
  EXPECT_THROW(encode_recording_header(bad), std::invalid_argument);
  bad = h;
  bad.device = "line\nbreak";
  EXPECT_THROW(encode_recording_header(bad), std::invalid_argument);
}

// Issue 23 item 9: a source named with a control character (a file name, a HID product string) made
// every recording of it fail. Its device name is escaped, cut to 63 bytes without splitting an
// escape or a UTF-8 character, and then accepted by the writer.
TEST(RecordingHeaderValidation, AnySourceDescriptionMakesAValidDeviceName) {
  using namespace fovea::protocol;
  EXPECT_EQ(recording_device_name("replay:/data/a.fgr"), "replay:/data/a.fgr");
  EXPECT_EQ(recording_device_name("replay:/tmp/evil\x1b[2J\n.fgr"), "replay:/tmp/evil\\x1b[2J\\x0a.fgr");
  const std::string long_name = std::string(60, 'a') + "\x01" + "bcdef";  // the escape would straddle byte 63
  EXPECT_EQ(recording_device_name(long_name), std::string(60, 'a'));
  const std::string utf8 = std::string(61, 'a') + "\xc3\xa9\xc3\xa9";  // é at bytes 61-62, the next would not fit
  EXPECT_EQ(recording_device_name(utf8), std::string(61, 'a') + "\xc3\xa9");
  for (const std::string& d : {std::string("a\x7f\xff\x1b"), long_name, utf8, std::string(200, '\x02')}) {
    RecordingHeader h;
    h.device = recording_device_name(d);
    EXPECT_LE(h.device.size(), 63u);
    EXPECT_NO_THROW(encode_recording_header(h)) << h.device;
  }
}

}  // namespace
