// SPDX-License-Identifier: Apache-2.0
#pragma once
// The focus pass's view of the renderer's gaze input (gaze/gaze_input.h): kept apart from focus.h
// so the focus code itself does not depend on the gaze sources.
#include "attention/focus.h"
#include "gaze/gaze_input.h"

namespace fovea::render::attention {

// `available`: GazeInput::available() (false for --gaze none). A sample that is not valid (blink,
// lost track) or in a saccade (GazeState::in_saccade) or a blink holds the focus. With provisional
// events the sample's final label trails the eye (a blink's label outlasts the blink by the
// classifier's window): only the samples' validity and the provisional saccade count then.
inline FocusGaze focus_gaze_from(const GazeState& state, bool available) {
  FocusGaze g;
  g.available = available;
  g.valid = available && state.valid;
  g.x = state.x;
  g.y = state.y;
  g.saccade_or_blink = state.in_saccade || !state.valid ||
                       (!state.provisional && state.movement == protocol::EyeMovement::Blink);
  g.fixations = state.fixations;
  g.pursuits = state.pursuits;
  return g;
}

}  // namespace fovea::render::attention
