// SPDX-License-Identifier: Apache-2.0
#pragma once
// Pupil Core's network API (Pupil Capture / Pupil Service), as data, without any socket: the
// source spec, and the msgpack payloads of the two topics fovea reads.
//  - "surfaces.NAME": the Surface Tracker's view of one surface, with gaze_on_surfaces, a list of
//    {norm_pos: [x, y], confidence, on_surf, timestamp, ...}: gaze in the surface's coordinates,
//    origin bottom-left and y up. A surface fitted to the screen makes that screen gaze.
//  - "gaze.": a gaze datum {norm_pos, confidence, timestamp, base_data, ...} in the scene camera's
//    image: not screen gaze (Pupil Core is head-mounted).
// Timestamps are Pupil time (seconds). A payload comes from a peer we do not trust: it is unpacked
// with limits on size and nesting and checked field by field; a message that does not hold what
// its topic promises is refused whole, with the reason.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace fovea::trackerd::pupil {

inline constexpr std::uint16_t kDefaultPort = 50020;  // Pupil Remote
// A gaze datum is under 1 KB, a surface event with a world frame's gaze some tens of KB.
inline constexpr std::size_t kMaxPayloadBytes = 256u << 10;

// "pupil:HOST[:PORT][?surface=NAME|gaze=scene&min_confidence=C]"
struct PupilSpec {
  std::string host;
  std::uint16_t port = kDefaultPort;
  std::string surface = "screen";  // the Surface Tracker surface that is the screen
  double min_confidence = 0.6;     // below it a gaze is invalid (Pupil's own tools use 0.6)
  // gaze=scene: the scene camera's gaze is the published point (normalised image coordinates, y
  // down), for a fovea calibration (input "screen") to map onto the screen; no surface is used.
  bool scene_gaze = false;
  std::string to_string() const;   // "HOST:PORT"
};
// Throws std::invalid_argument naming the spec and the form it should have.
PupilSpec parse_pupil_spec(const std::string& spec);
std::string check_pupil_spec(const std::string& spec);  // empty when it parses

// One gaze point as Pupil sends it: normalised, origin bottom-left, y up.
struct PupilGaze {
  double x = 0, y_up = 0;
  double confidence = 0;
  double timestamp = 0;   // Pupil time, s
  bool on_surface = true; // surfaces: on_surf; scene gaze: true
};

// A "surfaces.NAME" payload: every entry of gaze_on_surfaces (possibly none), or nullopt with
// `error`. The surface's name must be `surface`.
std::optional<std::vector<PupilGaze>> parse_surface_payload(std::span<const std::uint8_t> payload,
                                                            const std::string& surface, std::string& error);
// A "gaze." payload, or nullopt with `error`.
std::optional<PupilGaze> parse_gaze_payload(std::span<const std::uint8_t> payload, std::string& error);

// The port in Pupil Remote's answer to "SUB_PORT", or nullopt.
std::optional<std::uint16_t> parse_port_reply(const std::string& reply);
// Pupil time in the answer to "t", or nullopt (not a finite number).
std::optional<double> parse_time_reply(const std::string& reply);

}  // namespace fovea::trackerd::pupil
