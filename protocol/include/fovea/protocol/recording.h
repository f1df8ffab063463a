// SPDX-License-Identifier: Apache-2.0
#pragma once
// Gaze recordings (.fgr): a header, then append-only length-prefixed records each guarded by a
// CRC-32C. Byte layout in protocol/RECORDING.md. A reader recovers every intact record of a file
// that was truncated or damaged anywhere, and reports what it skipped.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "fovea/protocol/display_geometry.h"
#include "fovea/protocol/messages.h"

namespace fovea::protocol {

inline constexpr std::size_t kRecordingHeaderSize = 160;
// Version 2 added the sample records' host receive time; version 1 files are read as before, and
// appended to without it.
inline constexpr std::uint16_t kRecordingVersion = 2;

enum class RecordingClock : std::uint8_t { Monotonic = 0, Realtime = 1 };

struct RecordingHeader {
  std::string device;  // at most 63 bytes, no control characters (recording_device_name makes one)
  DisplayGeometry display;
  double nominal_rate_hz = 0;
  RecordingClock clock = RecordingClock::Monotonic;
  std::int64_t created_unix_ns = 0;   // wall clock when the file was created
  std::int64_t created_clock_ns = 0;  // the record clock at that moment (maps record times to wall time)
  friend bool operator==(const RecordingHeader&, const RecordingHeader&) = default;
};

struct Record {
  using Item = std::variant<GazeSample, GazeEvent, Marker>;
  Record() = default;
  Record(std::uint64_t seq, Item it, std::optional<std::int64_t> receive_ns = std::nullopt)
      : sequence(seq), item(std::move(it)), host_receive_ns(receive_ns) {}

  std::uint64_t sequence = 0;  // of the item's own stream (samples, events and markers are numbered apart)
  Item item;
  // Samples only: when the daemon received the sample from the tracker, on the record clock (the
  // sample's tracker_time_ns is the tracker's own timestamp mapped to that clock). Unset for sources
  // whose samples carry the host's time already, and in version-1 files.
  std::optional<std::int64_t> host_receive_ns;
  friend bool operator==(const Record&, const Record&) = default;
  std::int64_t time_ns() const;  // sample time, event end time, or marker time
};

// A source's description as a header's device name: control characters and bytes that are not UTF-8
// escaped (\\xNN), cut to 63 bytes without splitting a character (issue 23 item 9: a file name or a
// HID product string with a control character made every recording of that source fail).
std::string recording_device_name(const std::string& description);

std::vector<std::uint8_t> encode_recording_header(const RecordingHeader& h);
// A record's bytes; a sample with per-eye gaze is followed by its GAZE_EYES record (RECORDING.md).
std::vector<std::uint8_t> encode_record(const Record& r);

class RecordingWriter {
 public:
  enum class Mode { CreateNew, Append };
  // CreateNew refuses to replace an existing file. Append requires the existing header to be intact
  // and to describe the same display; it creates the file if missing. Throws std::runtime_error
  // naming the file and the reason.
  RecordingWriter(const std::string& path, const RecordingHeader& header, Mode mode = Mode::CreateNew);
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  // One write(2) per record, so a killed writer loses at most the record in flight.
  void append(const Record& r);
  void sync();  // fdatasync
  std::uint64_t records_written() const { return written_; }
  // False when appending to a version-1 file: receive times are then left out, as that version has none.
  bool stores_receive_times() const { return receive_times_; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
  std::uint64_t written_ = 0;
  bool receive_times_ = true;
};

struct RecoveryReport {
  bool header_valid = false;
  std::uint64_t records = 0;
  std::uint64_t damaged_regions = 0;   // runs of bytes that were not intact records
  std::uint64_t bytes_skipped = 0;     // total bytes in those runs
  bool truncated_tail = false;         // the file ends inside a record
  std::uint64_t eyes_unjoined = 0;     // GAZE_EYES records whose sample record was not just before them
  std::string describe() const;
};

struct Recording {
  RecordingHeader header;
  std::vector<Record> records;
  RecoveryReport report;
};

// Parses a recording held in memory. Never throws on damaged content: what is intact is returned,
// the rest is counted in the report. Throws std::runtime_error only when `data` is not a recording
// at all (no header magic and no recognisable record).
Recording parse_recording(std::span<const std::uint8_t> data);
// Larger recordings are refused (an hour at 1000 Hz is ~400 MB; the parsed records take more).
inline constexpr std::size_t kMaxRecordingBytes = std::size_t{4} << 30;
// Reads a regular file of at most kMaxRecordingBytes (a FIFO, device or directory is refused at
// once; a file that shrinks while it is read is read as far as it goes); throws std::runtime_error
// naming the file if it cannot be read or is not a recording.
Recording read_recording(const std::string& path);

}  // namespace fovea::protocol
