// SPDX-License-Identifier: Apache-2.0
#pragma once
// Where the viewer looks, for the renderer: a live fovea-trackerd stream, a recording replayed on
// the frame clock (deterministic headless runs), the mouse, or nothing (screen centre).
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "fovea/protocol/messages.h"

namespace fovea::render {

struct GazeState {
  double x = 0.5, y = 0.5;       // normalized screen coordinates of the last valid gaze point
  bool valid = false;            // the current sample has valid gaze (false during blinks)
  protocol::EyeMovement movement = protocol::EyeMovement::Unknown;
  double age_ms = 0;             // how old the sample is (live: now - sample time)
  std::uint64_t received = 0, lost = 0;
  double latency_p99_ms = 0;
  std::uint64_t fixations = 0;   // fixation onsets (GAZE_EVENT Fixation Start) seen so far; a change = a new fixation
  std::uint64_t pursuits = 0;    // pursuit onsets (GAZE_EVENT Pursuit Start) seen so far: the eye took up a moving thing
  // A saccade is in flight now, as best known: udp with provisional events, from them (gaze_events.h);
  // otherwise the sample's movement is Saccade.
  bool in_saccade = false;
  // The movement comes from provisional events (udp): `movement`, the sample's final label, then
  // trails the eye by the classifier's window and in_saccade says what the eye does now.
  bool provisional = false;
  // Each eye's own point of gaze (normalized, as x, y) where the source measures both eyes: udp from
  // a binocular tracker (the eye stream, PROTOCOL.md §4.18). nullopt: the stereo renderer derives
  // that eye's point from x, y and the fixation depth (FramePipeline::eye_gaze).
  struct Point { double x = 0.5, y = 0.5; };
  std::optional<Point> left_eye, right_eye;
};

class GazeInput {
 public:
  virtual ~GazeInput() = default;
  virtual std::string description() const = 0;
  virtual bool available() const { return true; }  // false only for "none"
  // Gaze for the frame at `frame_time_s` seconds since the renderer started (its frame clock).
  virtual GazeState at(double frame_time_s) = 0;
  // The mouse source takes the cursor here; others ignore it.
  virtual void set_cursor(double /*x*/, double /*y*/) {}
};

// Fixation onsets (GazeState::fixations): udp counts the stream's GAZE_EVENT Fixation Start, the
// provisional one when the daemon sends it (at landing) and the final one only when no provisional
// one came within 50 ms of it (gaze_events.h); file
// counts the recording's Fixation Start events up to the replay time (a recording without events, as
// CSV is, counts samples whose state turns to Fixation instead); mouse counts a fixation when the
// cursor has stayed within 1 deg (on the default display geometry) for 100 ms after moving; none
// never counts one. Pursuit onsets (GazeState::pursuits) likewise from the Pursuit Start events
// (final only: there are no provisional ones) or the samples whose state turns to Pursuit; mouse and
// none never count one.
// "udp://HOST:PORT", "file:REC.fgr" (or .csv), "mouse", "none". Throws std::invalid_argument for a
// bad spec and std::runtime_error when the source cannot start (unreadable recording).
std::unique_ptr<GazeInput> make_gaze_input(const std::string& spec);

}  // namespace fovea::render
