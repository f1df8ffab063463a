// SPDX-License-Identifier: Apache-2.0
#pragma once
// fovea-trackerd in the Lab Streaming Layer (issue 27 item 1): what the daemon publishes, also as
// three LSL outlets, so LabRecorder and any LSL consumer record fovea's gaze beside EEG or motion
// capture on LSL's common clock.
//
//   "<name> gaze"    type Gaze, float32 channels (kLslGazeChannels), nominal rate = the source's,
//                    channel metadata in desc/channels after the XDF gaze meta-data conventions
//                    (github.com/sccn/xdf/wiki/Gaze-Meta-Data: label, eye, type, unit), the display
//                    geometry in desc/setup/display; invalid gaze as NaN
//   "<name> markers" type Markers, one string channel, irregular rate: the experiment's MARKER
//                    messages (`fovea-ctl mark LABEL`, the clients' markers), each label verbatim,
//                    so that LabRecorder, pyxdf and MNE users match on their own labels
//   "<name> events"  type GazeEvents, one string channel, irregular rate: the final eye-movement
//                    events, one string each in the format of lsl_event_text
//
// Timestamps are the sample's device time (the daemon's CLOCK_MONOTONIC, which trackers with their
// own clock were already mapped onto) mapped onto lsl_local_clock(), not the push time.
// liblsl is optional: without it (FOVEA_HAVE_LSL undefined) open_lsl_outlet throws a one-line
// message and lsl_available() is false.
#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "fovea/protocol/display_geometry.h"
#include "fovea/protocol/messages.h"

namespace fovea::trackerd {

bool lsl_available();
// lsl_local_clock() - CLOCK_MONOTONIC, seconds: maps the daemon's times onto LSL's clock and back.
// Only in builds with liblsl.
double lsl_clock_minus_monotonic_s();
// "liblsl 1.16.2 (...)" or why there is none, for --version-like messages and STATUS.
std::string lsl_library_info();

struct LslChannel {
  const char* label;
  const char* eye;   // left | right | both
  const char* type;  // the XDF gaze type (ScreenX, ScreenY, Diameter, Confidence) or fovea's own
  const char* unit;  // pixels | normalized | degrees | mm | none
};
inline constexpr std::array<LslChannel, 11> kLslGazeChannels{{
    {"screen_x", "both", "ScreenX", "pixels"},
    {"screen_y", "both", "ScreenY", "pixels"},
    {"screen_x_norm", "both", "ScreenX", "normalized"},
    {"screen_y_norm", "both", "ScreenY", "normalized"},
    {"gaze_x_deg", "both", "VisualAngleX", "degrees"},
    {"gaze_y_deg", "both", "VisualAngleY", "degrees"},
    {"valid", "both", "Validity", "none"},
    {"confidence", "both", "Confidence", "normalized"},
    {"class", "both", "EyeMovement", "none"},
    {"pupil_diameter_left", "left", "Diameter", "mm"},
    {"pupil_diameter_right", "right", "Diameter", "mm"},
}};

// One sample as the gaze outlet's channel values (kLslGazeChannels' order).
std::array<float, kLslGazeChannels.size()> lsl_gaze_values(const protocol::GazeSample& s,
                                                           const protocol::DisplayGeometry& display);
// The events stream's text for a final event: KIND PHASE, then key=value fields separated by one
// space, "saccade end duration_ms=42.0 amplitude_deg=5.12 peak_velocity_deg_s=310 x=0.4812
// y=0.5210" (x, y: the event's centroid, normalized screen coordinates, origin top-left; a start
// has x and y only). KIND: fixation, saccade, pursuit, blink; PHASE: start, end. The grammar is
// also in the stream's desc/format.
std::string lsl_event_text(const protocol::GazeEvent& e);
inline constexpr const char* kLslEventFormat =
    "KIND PHASE [duration_ms=D amplitude_deg=A peak_velocity_deg_s=V] x=X y=Y; KIND fixation|saccade|pursuit|"
    "blink, PHASE start|end (the bracketed fields at end only), X/Y the event's centroid in normalized screen "
    "coordinates (origin top-left); the timestamp is the event's onset (start) or end (end)";

struct LslOutletOptions {
  std::string name = "fovea";       // stream names "<name> gaze" / "<name> markers"
  std::string source_id = "fovea";  // made unique per daemon port by the caller
  double nominal_rate_hz = 0;       // 0: irregular
  protocol::DisplayGeometry display;
  std::string device;  // the source's description (desc/acquisition/model)
};

class LslOutlet {
 public:
  virtual ~LslOutlet() = default;
  // Loop thread. A sample's time is its tracker_time_ns; an event's its onset (Start) or end (End);
  // provisional events are not published (LSL consumers record; they get the final labels).
  virtual void push(const protocol::GazeSample& sample) = 0;
  virtual void push(const protocol::GazeEvent& event) = 0;
  // Any thread (the server's marker callback).
  virtual void push(const protocol::Marker& marker) = 0;
  // "gaze: 2 consumers, markers: 1 consumer, clock offset +0.000012 s"
  virtual std::string status() const = 0;
};

// Opens both outlets. Throws std::runtime_error naming what failed (or, without liblsl, saying that
// this build has no LSL support and how to get it).
std::unique_ptr<LslOutlet> open_lsl_outlet(const LslOutletOptions& options);

}  // namespace fovea::trackerd
