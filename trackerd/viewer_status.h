// SPDX-License-Identifier: Apache-2.0
#pragma once
// The daemon's state for local viewers: the DAEMON_STATUS text of the viewer feed (PROTOCOL.md
// §17.4), once a second while a viewer listens. What the 160-byte STATUS_REPLY has no room for: the
// source's problem and counters, the calibration with its validation, recording, LSL, eye images.
#include <cstdint>
#include <optional>
#include <string>

#include "fovea/protocol/display_geometry.h"

namespace fovea::trackerd {

struct ViewerStatus {
  std::int64_t time_ns = 0;         // when composed, daemon's CLOCK_MONOTONIC
  std::string source;               // the source's description
  std::string source_problem;       // empty while it works
  std::string source_detail;        // the source's counters ("1200 frames, ...")
  double nominal_rate_hz = 0;
  protocol::DisplayGeometry display;
  std::uint64_t samples_published = 0, events_published = 0, markers_published = 0;
  std::size_t subscribers = 0;
  std::string classifier;           // its description
  std::string calibration;          // its description ("none (the source's own gaze)", or file: model)
  std::string calibration_validation_json = "null";  // the file's "validation" object, or null
  std::string recording;            // the file being written; empty: none
  std::optional<std::string> lsl;   // the outlet's status; none: no outlet
  std::size_t viewers = 0;          // readers of the viewer feed
  std::uint64_t eye_frames_shown = 0, eye_frames_missed = 0;
};

// A JSON object, at most protocol::kMaxStatusJson bytes: free texts are cut to fit, the validation
// is left out (null) when it alone would not fit.
std::string to_json(const ViewerStatus& s);

}  // namespace fovea::trackerd
