// SPDX-License-Identifier: Apache-2.0
#include "sources/hid/eye_tracker.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include "sources/hid/usage_tables.h"

namespace fovea::trackerd::hid {

namespace {

std::string hex(std::uint32_t v, int digits) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%0*X", digits, v);
  return buf;
}

ValueLocation locate(const Field& f, std::uint32_t index, std::uint32_t elements = 1) {
  ValueLocation v;
  v.type = f.type;
  v.report_id = f.report_id;
  v.bit_offset = f.bit_offset + index * f.bit_size;  // < kMaxReportBits: cannot overflow
  v.bit_size = f.bit_size * elements;
  v.is_signed = f.is_signed() && elements == 1;
  v.logical_min = f.logical_min;
  v.logical_max = f.logical_max;
  v.physical_min = f.physical_min;
  v.physical_max = f.physical_max;
  v.unit = f.unit;
  v.unit_exponent = f.unit_exponent;
  v.descriptor_offset = f.offset;
  return v;
}

bool inside(const ReportDescriptor& d, const Field& f, int app) {
  for (int c : d.collection_path(f.collection)) {
    if (c == app) return true;
  }
  return false;
}

// The first Variable field element with `usage` in reports of `type` (and `id` if given) inside the
// application collection `app`, and (if `within` is nonzero) inside a collection with that usage.
std::optional<ValueLocation> find_value(const ReportDescriptor& d, int app, ReportType type,
                                        std::optional<std::uint8_t> id, Usage usage, Usage within = 0) {
  for (const auto& r : d.reports) {
    if (r.type != type || (id && r.id != *id)) continue;
    for (const auto& f : r.fields) {
      if (!f.is_variable()) continue;  // Constant+Variable with a usage is a static value
      const auto index = f.index_of(usage);
      if (!index || !inside(d, f, app)) continue;
      if (within != 0 && !d.path_contains(f.collection, within)) continue;
      return locate(f, *index);
    }
  }
  return std::nullopt;
}

// Every distinct usage a descriptor's data fields carry (first 24), for "what it has instead".
std::string usages_present(const ReportDescriptor& d) {
  std::set<Usage> seen;
  std::string out;
  std::size_t listed = 0;
  for (const auto& r : d.reports) {
    for (const auto& f : r.fields) {
      for (const auto& u : f.usages) {
        for (Usage x : {u.min, u.max}) {
          if (!seen.insert(x).second) continue;
          if (listed++ < 24) out += (out.empty() ? "" : ", ") + describe_usage(x);
        }
      }
    }
  }
  if (listed > 24) out += ", and " + std::to_string(listed - 24) + " more";
  return out.empty() ? "no usages" : out;
}

bool is_length_unit(std::uint32_t unit) {
  const std::uint32_t system = unit & 0xFu;
  return (unit & ~0xFFu) == 0 && ((unit >> 4) & 0xFu) == 1 && (system == 1 || system == 3);
}

bool is_time_unit(std::uint32_t unit) {
  const std::uint32_t system = unit & 0xFu;
  return (unit & ~0xF00Fu) == 0 && ((unit >> 12) & 0xFu) == 1 && system >= 1 && system <= 4;
}

void require_length(const ValueLocation& v, const char* what) {
  if (v.unit != 0 && !is_length_unit(v.unit)) {
    throw NotAnEyeTracker(std::string(what) + " (descriptor byte " + std::to_string(v.descriptor_offset) +
                          ") has unit " + hex(v.unit, 4) + ", which is not a length");
  }
}

std::string describe(const ValueLocation& v) {
  return "bits " + std::to_string(v.bit_offset) + ".." + std::to_string(v.bit_offset + v.bit_size - 1) +
         (v.is_signed ? " signed" : "");
}

std::span<const std::uint8_t> feature_data(const ValueLocation& loc, std::span<const std::uint8_t> report) {
  // hid_get_feature_report always returns the report ID byte first (0 without IDs).
  if (report.empty() || report[0] != loc.report_id) return {};
  return report.subspan(1);
}

// The index of the Eye Tracker application collection (page 0x12, usage 0x01); NotAnEyeTracker
// naming what the descriptor describes instead when it has none.
int find_eye_tracker_application(const ReportDescriptor& d) {
  int app = -1;
  for (std::size_t i = 0; i < d.collections.size(); ++i) {
    const auto& c = d.collections[i];
    if (c.kind == static_cast<std::uint8_t>(CollectionKind::Application) && c.usage == eht::EyeTracker) {
      app = static_cast<int>(i);
      break;
    }
  }
  if (app < 0) {
    std::string apps;
    for (Usage u : d.application_usages()) apps += (apps.empty() ? "" : ", ") + describe_usage(u);
    throw NotAnEyeTracker(
        "the report descriptor has no Eye Tracker application collection (usage page 0x12 \"Eye and Head "
        "Trackers\", usage 0x01); it describes " +
        (apps.empty() ? std::string("no application collection") : apps) + " with " + usages_present(d));
  }
  return app;
}

// The gaze report: the first Input report with both gaze point coordinates, which must be lengths.
void find_gaze_point(const ReportDescriptor& d, int app, EyeTrackerLayout& out) {
  bool found = false;
  for (const auto& r : d.reports) {
    if (r.type != ReportType::Input) continue;
    auto x = find_value(d, app, ReportType::Input, r.id, eht::PositionX, eht::GazePoint);
    auto y = find_value(d, app, ReportType::Input, r.id, eht::PositionY, eht::GazePoint);
    if (!x || !y) continue;
    out.gaze_report_id = r.id;
    out.gaze_report_size = r.wire_size(d.uses_report_ids);
    out.gaze_x = *x;
    out.gaze_y = *y;
    found = true;
    break;
  }
  if (!found) {
    throw NotAnEyeTracker("the Eye Tracker collection (descriptor byte " +
                          std::to_string(d.collections[static_cast<std::size_t>(app)].offset) +
                          ") has no Gaze Point (0x12:0x24) with Position X and Y (0x21, 0x22) in an Input report; "
                          "it has " + usages_present(d));
  }
  require_length(out.gaze_x, "Gaze Point X");
  require_length(out.gaze_y, "Gaze Point Y");
}

// The sensor timestamp in the gaze report `id`: join the elements that repeat its usage (up to 64
// bits), with its tick, which must be a time.
void find_sensor_timestamp(const ReportDescriptor& d, int app, std::uint8_t id, EyeTrackerLayout& out) {
  for (const auto& r : d.reports) {
    if (r.type != ReportType::Input || r.id != id || out.timestamp) continue;
    for (const auto& f : r.fields) {
      if (!f.is_variable()) continue;  // Constant+Variable with a usage is a static value
      const auto index = f.index_of(eht::SensorTimestamp);
      if (!index || !inside(d, f, app)) continue;
      std::uint32_t n = 1;
      while (*index + n < f.count && (n + 1) * f.bit_size <= 64 && f.usage_of(*index + n) == eht::SensorTimestamp) ++n;
      out.timestamp = locate(f, *index, n);
      out.timestamp->is_signed = false;  // a counter
      break;
    }
  }
  if (out.timestamp) {
    const auto tick = tick_seconds(*out.timestamp);
    if (!tick || !(*tick > 0) || !std::isfinite(*tick)) {
      throw NotAnEyeTracker("Sensor Timestamp (descriptor byte " + std::to_string(out.timestamp->descriptor_offset) +
                            ") has unit " + hex(out.timestamp->unit, 4) + ", which is not a time");
    }
    out.timestamp_tick_s = *tick;
  }
}

// One eye's position (X, Y and Z inside the collection `which`) in the gaze report `id`; all three
// must be lengths.
std::optional<EyeLocations> find_eye(const ReportDescriptor& d, int app, std::uint8_t id, Usage which,
                                     const char* name) {
  auto x = find_value(d, app, ReportType::Input, id, eht::PositionX, which);
  auto y = find_value(d, app, ReportType::Input, id, eht::PositionY, which);
  auto z = find_value(d, app, ReportType::Input, id, eht::PositionZ, which);
  if (!x || !y || !z) return std::nullopt;
  require_length(*x, name);
  require_length(*y, name);
  require_length(*z, name);
  return EyeLocations{*x, *y, *z};
}

// The calibrated screen size from the Feature reports: both in one report and lengths, or neither.
void find_calibrated_screen(const ReportDescriptor& d, int app, EyeTrackerLayout& out) {
  out.screen_width = find_value(d, app, ReportType::Feature, std::nullopt, eht::CalibratedScreenWidth);
  out.screen_height = find_value(d, app, ReportType::Feature, std::nullopt, eht::CalibratedScreenHeight);
  if (out.screen_width && out.screen_height &&
      (out.screen_width->report_id != out.screen_height->report_id ||
       (out.screen_width->unit != 0 && !is_length_unit(out.screen_width->unit)) ||
       (out.screen_height->unit != 0 && !is_length_unit(out.screen_height->unit)))) {
    out.screen_width.reset();  // not usable; the configured display geometry applies
    out.screen_height.reset();
  }
  if (!out.screen_width || !out.screen_height) {
    out.screen_width.reset();
    out.screen_height.reset();
  }
}

}  // namespace

std::optional<std::int64_t> ValueLocation::raw(std::span<const std::uint8_t> data) const {
  const auto bits = extract_bits(data, bit_offset, bit_size);
  if (!bits) return std::nullopt;
  return is_signed ? sign_extend(*bits, bit_size) : static_cast<std::int64_t>(*bits);
}

std::optional<double> length_m(const ValueLocation& loc, std::int64_t raw) {
  double physical = static_cast<double>(raw);
  if ((loc.physical_min != 0 || loc.physical_max != 0) && loc.logical_max != loc.logical_min) {
    // HID 1.11 §6.2.2.7: physical = pmin + (logical - lmin) * (pmax - pmin) / (lmax - lmin).
    physical = static_cast<double>(loc.physical_min) +
               (static_cast<double>(raw) - static_cast<double>(loc.logical_min)) *
                   (static_cast<double>(loc.physical_max) - static_cast<double>(loc.physical_min)) /
                   (static_cast<double>(loc.logical_max) - static_cast<double>(loc.logical_min));
  }
  if (loc.unit == 0) return physical * 1e-6;  // micrometres, the page's convention
  if (!is_length_unit(loc.unit)) return std::nullopt;
  const double base = (loc.unit & 0xFu) == 1 ? 0.01 : 0.0254;  // centimetre or inch
  return physical * base * std::pow(10.0, loc.unit_exponent);
}

std::optional<double> tick_seconds(const ValueLocation& loc) {
  if (loc.unit == 0) return 1e-6;  // microseconds, the page's convention
  if (!is_time_unit(loc.unit)) return std::nullopt;
  return std::pow(10.0, loc.unit_exponent);
}

std::string EyeTrackerLayout::summary() const {
  std::string s = "gaze point in Input report " + std::to_string(gaze_report_id) + " (" +
                  std::to_string(gaze_report_size) + " bytes; x " + describe(gaze_x) + ", y " + describe(gaze_y) + ")";
  if (timestamp) {
    char tick[32];
    std::snprintf(tick, sizeof tick, "%g", timestamp_tick_s);
    s += ", " + std::to_string(timestamp->bit_size) + "-bit timestamp (" + tick + " s ticks)";
  } else {
    s += ", no timestamp (host receive time used)";
  }
  if (left_eye) s += ", left eye";
  if (right_eye) s += ", right eye";
  if (input_status) s += ", status in the Input report";
  if (screen_width && screen_height) s += ", screen size in Feature report " + std::to_string(screen_width->report_id);
  if (sampling_frequency) s += ", sampling frequency in Feature report " + std::to_string(sampling_frequency->report_id);
  return s;
}

EyeTrackerLayout map_eye_tracker(const ReportDescriptor& d) {
  const int app = find_eye_tracker_application(d);

  EyeTrackerLayout out;
  out.uses_report_ids = d.uses_report_ids;
  for (const auto& r : d.reports) {
    if (r.type == ReportType::Input) out.input_reports.emplace_back(r.id, r.wire_size(d.uses_report_ids));
  }

  find_gaze_point(d, app, out);
  const std::uint8_t id = out.gaze_report_id;
  find_sensor_timestamp(d, app, id, out);
  out.left_eye = find_eye(d, app, id, eht::LeftEyePosition, "Left Eye Position");
  out.right_eye = find_eye(d, app, id, eht::RightEyePosition, "Right Eye Position");
  out.input_status = find_value(d, app, ReportType::Input, id, eht::ConfigurationStatus);

  find_calibrated_screen(d, app, out);
  out.sampling_frequency = find_value(d, app, ReportType::Feature, std::nullopt, eht::SamplingFrequency);
  out.configuration_status = find_value(d, app, ReportType::Feature, std::nullopt, eht::ConfigurationStatus);
  out.tracker_quality = find_value(d, app, ReportType::Feature, std::nullopt, eht::TrackerQuality);
  return out;
}

const char* to_string(DecodeResult r) {
  switch (r) {
    case DecodeResult::Gaze: return "gaze";
    case DecodeResult::OtherReport: return "other report";
    case DecodeResult::UnknownReportId: return "unknown report ID";
    case DecodeResult::TooShort: return "too short";
    case DecodeResult::Empty: return "empty";
  }
  return "?";
}

DecodeResult EyeTrackerDecoder::decode(std::span<const std::uint8_t> report, GazeReport& out) {
  out = GazeReport{};
  if (report.empty()) {
    ++counters_.empty;
    return DecodeResult::Empty;
  }
  const std::uint8_t id = layout_.uses_report_ids ? report[0] : 0;
  if (id != layout_.gaze_report_id) {
    const bool known = std::any_of(layout_.input_reports.begin(), layout_.input_reports.end(),
                                   [&](const auto& r) { return r.first == id; });
    if (known) {
      ++counters_.other;
      return DecodeResult::OtherReport;
    }
    ++counters_.unknown_id;
    return DecodeResult::UnknownReportId;
  }
  if (report.size() < layout_.gaze_report_size) {
    ++counters_.too_short;
    return DecodeResult::TooShort;
  }
  const auto data = layout_.uses_report_ids ? report.subspan(1) : report;

  if (layout_.timestamp) {
    if (const auto t = layout_.timestamp->raw(data)) out.timestamp_ticks = static_cast<std::uint64_t>(*t);
  }
  const auto length = [&](const ValueLocation& loc, double& metres) {
    const auto raw = loc.raw(data);
    if (!raw || !loc.in_logical_range(*raw)) return false;  // out of range: HID's "no data"
    const auto m = length_m(loc, *raw);
    if (!m || !std::isfinite(*m)) return false;
    metres = *m;
    return true;
  };
  out.gaze_valid = length(layout_.gaze_x, out.gaze_x_m) && length(layout_.gaze_y, out.gaze_y_m);
  const auto eye = [&](const std::optional<EyeLocations>& loc, EyePosition& e) {
    if (!loc) return;
    e.valid = length(loc->x, e.x_m) && length(loc->y, e.y_m) && length(loc->z, e.z_m);
    // An eye the tracker does not see is reported at the origin (no eye can be on the screen plane).
    if (e.valid && e.x_m == 0 && e.y_m == 0 && e.z_m == 0) e.valid = false;
  };
  eye(layout_.left_eye, out.left);
  eye(layout_.right_eye, out.right);
  if (layout_.input_status) {
    if (const auto s = layout_.input_status->raw(data)) out.status = *s;
  }
  ++counters_.gaze;
  return DecodeResult::Gaze;
}

std::optional<std::int64_t> feature_value(const ValueLocation& loc, std::span<const std::uint8_t> report) {
  const auto data = feature_data(loc, report);
  const auto raw = loc.raw(data);
  if (!raw || !loc.in_logical_range(*raw)) return std::nullopt;
  return raw;
}

std::optional<std::pair<double, double>> calibrated_screen_m(const EyeTrackerLayout& layout,
                                                             std::span<const std::uint8_t> configuration_report) {
  if (!layout.screen_width || !layout.screen_height) return std::nullopt;
  const auto w = feature_value(*layout.screen_width, configuration_report);
  const auto h = feature_value(*layout.screen_height, configuration_report);
  if (!w || !h) return std::nullopt;
  const auto wm = length_m(*layout.screen_width, *w);
  const auto hm = length_m(*layout.screen_height, *h);
  // Plausible screens only: 1 cm to 20 m.
  const auto plausible = [](const std::optional<double>& m) { return m && std::isfinite(*m) && *m >= 0.01 && *m <= 20; };
  if (!plausible(wm) || !plausible(hm)) return std::nullopt;
  return std::make_pair(*wm, *hm);
}

protocol::GazeSample to_gaze_sample(const GazeReport& report, const protocol::DisplayGeometry& display,
                                    std::int64_t time_ns, protocol::Normalized hold) {
  protocol::GazeSample s;
  s.tracker_time_ns = time_ns;
  bool valid = report.gaze_valid && display.width_m > 0 && display.height_m > 0;
  // A tracker that says it is configuring or needs setup or calibration: its gaze is not usable.
  // (0, "reserved", is what reference drivers send before they know; it does not invalidate.)
  if (report.status && *report.status >= eht::StatusConfiguring && *report.status <= eht::StatusUserCalibrationNeeded) {
    valid = false;
  }
  protocol::Normalized n = hold;
  if (valid) {
    n = {report.gaze_x_m / display.width_m, report.gaze_y_m / display.height_m};
    // Off-screen gaze is real (looking past the edge) but a wild value is not: keep within a
    // screen's size beyond each edge.
    if (!std::isfinite(n.x) || !std::isfinite(n.y) || n.x < -1 || n.x > 2 || n.y < -1 || n.y > 2) {
      valid = false;
      n = hold;
    }
  }
  const auto deg = protocol::normalized_to_degrees(display, n);
  s.x = static_cast<float>(n.x);
  s.y = static_cast<float>(n.y);
  s.x_deg = std::isfinite(deg.x) ? static_cast<float>(deg.x) : 0.0f;
  s.y_deg = std::isfinite(deg.y) ? static_cast<float>(deg.y) : 0.0f;
  s.flags = valid ? protocol::kGazeValid : 0;
  s.confidence = valid ? 1.0f : 0.0f;  // the page has no per-sample confidence
  // HID trackers report 3-D eye positions, not eye-camera pupil coordinates: only the flag carries.
  s.left.flags = report.left.valid ? protocol::kEyePupilValid : 0;
  s.right.flags = report.right.valid ? protocol::kEyePupilValid : 0;
  return s;
}

}  // namespace fovea::trackerd::hid
