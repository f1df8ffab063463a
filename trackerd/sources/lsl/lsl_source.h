// SPDX-License-Identifier: Apache-2.0
#pragma once
// `lsl[:NAME][?x=I&y=J&units=pixels|normalized&confidence=K&min_confidence=C]`: gaze from a tracker's
// Lab Streaming Layer stream (issue 27 item 2). Most research trackers have an LSL app (Tobii Pro,
// EyeLink, Pupil Labs' relay, Gazepoint, SMI); this reads any of them:
//  - which stream: the one named NAME, or with `lsl` alone the first of type Gaze;
//  - which channels: from the stream's metadata (desc/channels, the XDF gaze meta-data conventions):
//    the first channels of type ScreenX / ScreenY (unit normalized, else pixels), Confidence,
//    Validity, and Diameter per eye (mm); where the metadata says nothing, the spec's x= / y=
//    indices and units= (a clear problem until given);
//  - time: the outlet's timestamps, through liblsl's clock synchronisation (time_correction) onto
//    this host's LSL clock, then onto CLOCK_MONOTONIC: a sample's time is when the tracker took it;
//  - validity: NaN coordinates, a Validity channel at 0 or a confidence below min_confidence make
//    the sample's gaze invalid. Where the stream has a confidence channel (its metadata's, or the
//    spec's confidence=K) and the spec gives no min_confidence, kDefaultMinConfidence applies, as
//    Pupil Labs' own tools do, and the start's log line says so; min_confidence=0 turns it off;
//  - channel formats: numbers of any width; a stream of strings (or of no declared format) cannot
//    carry coordinates and is refused, naming its format;
//  - the arrival rules of every network source (sources/arrival_guard.h): published at most 4x the
//    stream's nominal rate, a flood's samples timed by their arrival, and a timestamp after its
//    sample's arrival replaced by the arrival and counted; published times never decrease (a
//    sample timed before the last one published is dropped and counted as out of order);
//  - a lost stream (the app closed) is re-resolved by name and read again when it comes back.
// STATUS shows the stream, its host and rate, the clock offset and the dropouts.
#include <cstdint>
#include <optional>
#include <string>

#include "fovea/protocol/display_geometry.h"
#include "source_api/gaze_source.h"

namespace fovea::trackerd::lsl_source {

struct LslSpec {
  std::string name;                      // empty: the first stream of type Gaze
  std::optional<int> x, y, confidence;   // channel indices given in the spec
  std::string units;                     // for x/y given in the spec: "normalized" or "pixels"
  std::optional<double> min_confidence;  // below it a sample's gaze is invalid; none given: the default
  std::string to_string() const;         // as written: "lsl:Tobii?x=0&y=1&units=pixels"
};
// Pupil Labs' threshold for usable gaze (their Player's and LSL relay's default).
inline constexpr double kDefaultMinConfidence = 0.6;
// The threshold a stream gets: the spec's, else the default where the stream has a confidence
// channel, else none (0).
double effective_min_confidence(const LslSpec& spec, bool has_confidence_channel);
// Throws std::invalid_argument naming the spec and what is wrong.
LslSpec parse_lsl_spec(const std::string& spec);
std::string check_lsl_spec(const std::string& spec);  // empty when usable (and liblsl is built in)

// Which channel holds what, from the stream's metadata or the spec.
struct ChannelMap {
  int x = -1, y = -1;
  bool pixels = false;  // x/y in pixels (else normalized)
  int confidence = -1, validity = -1, pupil_left = -1, pupil_right = -1;
  std::string origin;   // "metadata" or "spec"
};

// Why a stream of this channel format (liblsl's channel_format_t values: 1 float32, 2 double64,
// 3 string, 4 int32, 5 int16, 6 int8, 7 int64, 0 undefined) cannot carry gaze, or empty when it can.
std::string unusable_channel_format(int format);

// Builds the source: resolves the stream (up to 5 s) for its rate, unless `rate_hz` > 0 is given,
// which also lets it start before the stream exists. Throws std::runtime_error naming the spec.
std::unique_ptr<GazeSource> make_lsl_source(const LslSpec& spec, protocol::DisplayGeometry display, double rate_hz);

}  // namespace fovea::trackerd::lsl_source
