#pragma once
// The daemon's calibration stage: maps raw tracker gaze to calibrated screen gaze before the
// classifier and the publisher see it. The calibration map itself arrives with step 5
// (calibration/); until then the stage is the identity and a configured calibration file is only
// checked (it must be readable JSON) and named in the log.
#include <memory>
#include <string>

#include "sources/gaze_source.h"

namespace fovea::trackerd::service {

class CalibrationStage {
 public:
  virtual ~CalibrationStage() = default;
  virtual std::string description() const = 0;  // for the log and STATUS=
  // Calibrates one item in place (samples; events pass unchanged unless the map moves them).
  virtual void apply(GazeItem& item) const = 0;
};

// Loads `file` (empty: no calibration). Throws std::runtime_error naming the file when it cannot
// be read or is not JSON. Called at start and on every reload.
std::unique_ptr<CalibrationStage> load_calibration_stage(const std::string& file);

}  // namespace fovea::trackerd::service
