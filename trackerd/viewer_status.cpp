// SPDX-License-Identifier: Apache-2.0
#include "viewer_status.h"

#include <nlohmann/json.hpp>

#include "fovea/protocol/viewer_feed.h"

namespace fovea::trackerd {

namespace {

// Free text from sources and files is cut to 1024 bytes and kept valid UTF-8 (json::dump would
// throw on a broken sequence).
std::string text(const std::string& s) {
  const std::string cut = s.size() > 1024 ? s.substr(0, 1024) : s;
  return nlohmann::json(cut).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace

std::string to_json(const ViewerStatus& s) {
  nlohmann::json validation = nullptr;
  if (!s.calibration_validation_json.empty()) {
    validation = nlohmann::json::parse(s.calibration_validation_json, nullptr, false);
    if (validation.is_discarded()) validation = nullptr;
  }
  nlohmann::json j{
      {"time_ns", s.time_ns},
      {"source", nlohmann::json::parse(text(s.source))},
      {"source_problem", nlohmann::json::parse(text(s.source_problem))},
      {"source_detail", nlohmann::json::parse(text(s.source_detail))},
      {"nominal_rate_hz", s.nominal_rate_hz},
      {"display",
       {{"width_px", s.display.width_px},
        {"height_px", s.display.height_px},
        {"width_m", s.display.width_m},
        {"height_m", s.display.height_m},
        {"viewing_distance_m", s.display.viewing_distance_m}}},
      {"samples_published", s.samples_published},
      {"events_published", s.events_published},
      {"markers_published", s.markers_published},
      {"subscribers", s.subscribers},
      {"classifier", nlohmann::json::parse(text(s.classifier))},
      {"calibration", {{"description", nlohmann::json::parse(text(s.calibration))}, {"validation", validation}}},
      {"recording", nlohmann::json::parse(text(s.recording))},
      {"lsl", s.lsl ? nlohmann::json::parse(text(*s.lsl)) : nlohmann::json(nullptr)},
      {"viewers", s.viewers},
      {"eye_frames_shown", s.eye_frames_shown},
      {"eye_frames_missed", s.eye_frames_missed}};
  const auto dump = [&] { return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace); };
  std::string out = dump();
  if (out.size() > protocol::kMaxStatusJson) {
    j["calibration"]["validation"] = nullptr;
    out = dump();
  }
  return out;
}

}  // namespace fovea::trackerd
