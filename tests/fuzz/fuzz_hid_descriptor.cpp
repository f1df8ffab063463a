// SPDX-License-Identifier: Apache-2.0
// libFuzzer entry point for the HID report descriptor parser: whatever the bytes, the parser must
// either return layouts or throw DescriptorError, without undefined behaviour. When the bytes parse,
// reports derived from them (zeros, ones, the input itself; the right length, one byte short, one
// long) are decoded field by field and, if the descriptor is an eye tracker, through the gaze
// decoder: every value must stay in bounds and every sample must be finite.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

#include "sources/hid/eye_tracker.h"
#include "sources/hid/report_descriptor.h"
#include "source_api/tracker_clock.h"

namespace {

using namespace fovea::trackerd::hid;
using fovea::trackerd::TrackerClock;

void check(bool ok) {
  if (!ok) std::abort();
}

std::vector<std::vector<std::uint8_t>> derived_reports(const ReportLayout& r, bool ids, std::span<const std::uint8_t> seed) {
  const std::size_t size = r.wire_size(ids);
  std::vector<std::vector<std::uint8_t>> out;
  for (int pattern = 0; pattern < 3; ++pattern) {
    for (std::size_t len : {size, size > 0 ? size - 1 : 0, size + 1}) {
      std::vector<std::uint8_t> b(len);
      for (std::size_t i = 0; i < len; ++i) {
        b[i] = pattern == 0 ? 0x00 : pattern == 1 ? 0xFF : (seed.empty() ? 0x5A : seed[i % seed.size()]);
      }
      if (ids && !b.empty()) b[0] = r.id;
      out.push_back(std::move(b));
    }
  }
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  ReportDescriptor d;
  try {
    d = parse_report_descriptor(bytes);
  } catch (const DescriptorError& e) {
    check(e.offset() <= size);
    return 0;
  }

  for (const auto& r : d.reports) {
    check(r.bit_length <= kMaxReportBits);
    std::uint64_t expected_offset = 0;
    for (const auto& f : r.fields) {
      check(f.bit_size >= 1 && f.bit_size <= 32);
      check(f.bit_offset == expected_offset);
      expected_offset += static_cast<std::uint64_t>(f.bit_size) * f.count;
      check(f.collection < static_cast<int>(d.collections.size()));
      (void)d.collection_path(f.collection);
    }
    check(expected_offset == r.bit_length);
    for (const auto& report : derived_reports(r, d.uses_report_ids, bytes)) {
      const auto payload = d.uses_report_ids && !report.empty() ? std::span(report).subspan(1) : std::span(report);
      for (const auto& f : r.fields) {
        const std::uint32_t n = f.count < 64 ? f.count : 64;
        for (std::uint32_t i = 0; i < n; ++i) {
          const auto v = field_value(f, payload, i);
          if (v && !f.is_signed() && f.bit_size < 64) check(*v >= 0 && (static_cast<std::uint64_t>(*v) >> f.bit_size) == 0);
          (void)f.usage_of(i);
        }
        check(!field_value(f, payload, f.count).has_value());
      }
    }
  }
  for (const auto& u : d.application_usages()) (void)describe_usage(u);

  EyeTrackerLayout layout;
  try {
    layout = map_eye_tracker(d);
  } catch (const NotAnEyeTracker&) {
    return 0;
  }
  (void)layout.summary();
  EyeTrackerDecoder decoder(layout);
  TrackerClock clock(layout.timestamp_tick_s, layout.timestamp ? layout.timestamp->bit_size : 64);
  std::int64_t now = 1'000'000'000;
  const fovea::protocol::DisplayGeometry display;
  for (const auto& r : d.reports) {
    for (const auto& report : derived_reports(r, d.uses_report_ids, bytes)) {
      if (r.type == ReportType::Feature) {
        std::vector<std::uint8_t> with_id = report;
        if (!d.uses_report_ids) with_id.insert(with_id.begin(), 0);
        (void)calibrated_screen_m(layout, with_id);
        continue;
      }
      GazeReport g;
      if (decoder.decode(report, g) != DecodeResult::Gaze) continue;
      check(!g.gaze_valid || (std::isfinite(g.gaze_x_m) && std::isfinite(g.gaze_y_m)));
      now += 4'000'000;
      const std::int64_t t = g.timestamp_ticks ? clock.map(*g.timestamp_ticks, now) : now;
      check(t <= now);
      const auto s = to_gaze_sample(g, display, t);
      check(std::isfinite(s.x) && std::isfinite(s.y) && std::isfinite(s.x_deg) && std::isfinite(s.y_deg));
      check(s.confidence == 0.0f || s.confidence == 1.0f);
    }
  }
  return 0;
}
