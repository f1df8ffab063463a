// SPDX-License-Identifier: Apache-2.0
#pragma once
// The daemon's calibration stage: maps raw tracker output to calibrated screen gaze before the
// classifier and the publisher see it (calibration/CALIBRATION.md describes the file).
//
//  - input "pupil-glint": the stage computes the gaze from the sample's pupil–glint vector (the
//    calibration's eye, or whichever eye has one) through the calibration map; a sample without a
//    valid pupil and glint has no valid gaze. This replaces any gaze the source computed itself
//    (the synthetic eye's factory calibration).
//  - input "screen": the stage corrects the tracker's own gaze (its screen point in pixels), as
//    Jensen & Pedersen 2009 §4.2 correct a commercial tracker's calibration.
// The mapped point becomes the normalised and angular gaze on the daemon's display; the angular
// velocity is cleared so that the classifier computes it from the calibrated gaze. A mapped point
// that is not finite or lies absurdly far outside the screen (beyond 100 screen widths) makes the
// sample invalid rather than carry an overflow onto the wire.
#include <cstddef>
#include <memory>
#include <string>

#include "fovea/protocol/display_geometry.h"
#include "source_api/gaze_source.h"

namespace fovea::trackerd::service {

class CalibrationStage {
 public:
  virtual ~CalibrationStage() = default;
  virtual std::string description() const = 0;  // for the log and STATUS= (names the file)
  virtual std::string summary() const = 0;      // short, without the file (63-byte control replies)
  // The file's "validation" object as JSON text (overall figures and, from fovea-calibrate, each
  // target's error vector: calibration/CALIBRATION.md), "null" when there is none.
  virtual std::string validation_json() const { return "null"; }
  // Calibrates one item in place (samples; events pass unchanged).
  virtual void apply(GazeItem& item) const = 0;
};

// A calibration file is a few KB; anything larger than this is refused unread.
constexpr std::size_t kMaxCalibrationFileBytes = 16u << 20;

// Loads `file` (empty: no calibration, the identity) for a daemon whose clients are told `display`.
// Throws std::runtime_error naming the file (escaped) and what is wrong: missing, not a regular file
// (a device, FIFO or directory is refused without reading or blocking), over the size limit, not a
// calibration file, from a newer fovea, or made for a screen of another pixel size than `display`.
// follow_symlinks = false: a symbolic link as the file itself is refused (a control request's path
// confined to a directory, where a link could lead out of it).
std::unique_ptr<CalibrationStage> load_calibration_stage(const std::string& file,
                                                         const protocol::DisplayGeometry& display,
                                                         bool follow_symlinks = true);

}  // namespace fovea::trackerd::service
