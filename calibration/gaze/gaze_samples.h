// SPDX-License-Identifier: Apache-2.0
#pragma once
// Calibration inputs from the gaze protocol's samples: the one conversion of a GAZE_SAMPLE into the
// raw point and state a calibration collects (session.h). A separate small library
// (fovea_calibration_gaze) so that fovea_calibration itself keeps depending on nothing of fovea.
#include <span>
#include <vector>

#include "fovea/calib/session.h"
#include "fovea/protocol/display_geometry.h"
#include "fovea/protocol/messages.h"

namespace fovea::calib {

enum class GazeInput {
  PupilGlint,  // the eye's pupil–glint vector (camera pixels); valid with pupil and glint found
  Screen,      // the tracker's own gaze in screen pixels of `display`; valid with the sample's gaze
};

// One sample as collection sees it: time, raw point of `input` (of the left or right eye's data for
// PupilGlint), valid (and finite), and the tracker's eye-movement state.
RawSample to_raw_sample(const protocol::GazeSample& sample, GazeInput input, bool left_eye,
                        const protocol::DisplayGeometry& display);
std::vector<RawSample> to_raw_samples(std::span<const protocol::GazeSample> samples, GazeInput input, bool left_eye,
                                      const protocol::DisplayGeometry& display);

}  // namespace fovea::calib
