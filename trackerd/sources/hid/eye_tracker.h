// SPDX-License-Identifier: Apache-2.0
#pragma once
// The eye-tracker mapping: finds the usages of the HID "Eye and Head Trackers" page (0x12) in a
// parsed report descriptor — gaze point, eye positions, sensor timestamp and status in the Input
// report, screen size, sampling frequency and status in the Feature reports — and decodes raw
// reports by those locations (never by fixed offsets).
//
// Units (HUTRR74, and Microsoft's reference eye-tracker drivers, which are what consumer trackers
// implement for Windows eye control): positions and sizes in micrometres; the gaze point on the
// screen plane from the screen's top-left corner, x right, y down; the sensor timestamp in
// microseconds. A descriptor that declares a Unit (SI or English linear length, time) is honoured
// instead, with its exponent and physical range.
#include <cstdint>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "fovea/protocol/display_geometry.h"
#include "fovea/protocol/messages.h"
#include "sources/hid/report_descriptor.h"

namespace fovea::trackerd::hid {

// Where one value lies in a report: an element of a field, or for a counter split over several
// elements (Microsoft's reference descriptor declares the timestamp as 8 one-byte elements) the
// consecutive elements joined little-endian.
struct ValueLocation {
  ReportType type = ReportType::Input;
  std::uint8_t report_id = 0;
  std::uint32_t bit_offset = 0;  // in the report data (after the report ID byte)
  std::uint32_t bit_size = 0;    // 1..64
  bool is_signed = false;
  std::int64_t logical_min = 0, logical_max = 0;
  std::int64_t physical_min = 0, physical_max = 0;
  std::uint32_t unit = 0;
  std::int8_t unit_exponent = 0;
  std::size_t descriptor_offset = 0;  // of the main item, for messages

  // Raw value from report data (after the report ID byte); nullopt if out of bounds.
  std::optional<std::int64_t> raw(std::span<const std::uint8_t> data) const;
  bool in_logical_range(std::int64_t raw) const { return raw >= logical_min && raw <= logical_max; }
};

// Metres per logical unit step mapping; nullopt when the field's unit is not a length.
// No unit: micrometres (the page's convention).
std::optional<double> length_m(const ValueLocation& loc, std::int64_t raw);
// Seconds per counter tick of a timestamp field; nullopt when its unit is not a time.
std::optional<double> tick_seconds(const ValueLocation& loc);

struct EyeLocations {
  ValueLocation x, y, z;
};

struct EyeTrackerLayout {
  bool uses_report_ids = false;
  std::uint8_t gaze_report_id = 0;       // the Input report carrying the gaze point
  std::size_t gaze_report_size = 0;      // bytes on the wire, report ID byte included
  ValueLocation gaze_x, gaze_y;
  std::optional<ValueLocation> timestamp;
  double timestamp_tick_s = 1e-6;
  std::optional<EyeLocations> left_eye, right_eye;
  std::optional<ValueLocation> input_status;  // Configuration Status inside the gaze report
  // Feature reports (read with hid_get_feature_report).
  std::optional<ValueLocation> screen_width, screen_height;  // Configuration: Calibrated Screen W/H
  std::optional<ValueLocation> sampling_frequency, configuration_status;  // Status
  std::optional<ValueLocation> tracker_quality;                          // Capabilities
  // Every Input report ID with its wire size (to tell "another report" from "garbage").
  std::vector<std::pair<std::uint8_t, std::size_t>> input_reports;

  std::string summary() const;  // one line for logs and HID.md's "check a device"
};

class NotAnEyeTracker : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Finds the eye tracker in a parsed descriptor. Throws NotAnEyeTracker saying what is missing and
// what the descriptor describes instead (its application collections and the usages it has).
EyeTrackerLayout map_eye_tracker(const ReportDescriptor& descriptor);

struct EyePosition {
  bool valid = false;
  double x_m = 0, y_m = 0, z_m = 0;
};

struct GazeReport {
  std::optional<std::uint64_t> timestamp_ticks;  // raw counter, unsigned, layout.timestamp->bit_size bits
  bool gaze_valid = false;
  double gaze_x_m = 0, gaze_y_m = 0;  // on the screen plane from its top-left corner
  EyePosition left, right;
  std::optional<std::int64_t> status;  // Configuration Status when the Input report carries it
};

enum class DecodeResult { Gaze, OtherReport, UnknownReportId, TooShort, Empty };
const char* to_string(DecodeResult r);

class EyeTrackerDecoder {
 public:
  explicit EyeTrackerDecoder(EyeTrackerLayout layout) : layout_(std::move(layout)) {}
  const EyeTrackerLayout& layout() const { return layout_; }

  // `report` as hid_read returns it: report ID first when the descriptor uses IDs. Longer reports
  // than the descriptor declares are accepted (their tail ignored), as the kernel does; shorter
  // ones, unknown IDs and empty reads are rejected and counted.
  DecodeResult decode(std::span<const std::uint8_t> report, GazeReport& out);

  struct Counters {
    std::uint64_t gaze = 0, other = 0, unknown_id = 0, too_short = 0, empty = 0;
    std::uint64_t rejected() const { return unknown_id + too_short + empty; }
  };
  const Counters& counters() const { return counters_; }

 private:
  EyeTrackerLayout layout_;
  Counters counters_;
};

// A value from a feature report as hid_get_feature_report returns it (report ID byte first, 0 when
// the descriptor uses none); nullopt if the report is too short, has another ID or the value is
// outside its logical range.
std::optional<std::int64_t> feature_value(const ValueLocation& loc, std::span<const std::uint8_t> report);

// The screen size the tracker was calibrated for, from its Configuration feature report; nullopt
// when absent, zero or not a length.
std::optional<std::pair<double, double>> calibrated_screen_m(const EyeTrackerLayout& layout,
                                                             std::span<const std::uint8_t> configuration_report);

// A decoded report as a gaze sample on `display` (normalized to its physical size, visual angle at
// its viewing distance), timed `time_ns` on CLOCK_MONOTONIC. Invalid gaze (out of range, status
// configuring/setup/calibration needed, non-finite) gives flags 0 and confidence 0 with x/y held at `hold`.
protocol::GazeSample to_gaze_sample(const GazeReport& report, const protocol::DisplayGeometry& display,
                                    std::int64_t time_ns, protocol::Normalized hold = {0.5, 0.5});

}  // namespace fovea::trackerd::hid
