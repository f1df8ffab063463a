// SPDX-License-Identifier: Apache-2.0
#pragma once
// Validation of a calibration on samples recorded while targets were shown: accuracy and precision
// per target and overall, as Jensen & Pedersen 2009, §4.1.2 and §4.2.3 (Tables 4.1 and 4.2).
//
// Definitions (angles are visual angles for an eye on the screen centre's normal, display.h):
//   accuracy_deg       mean over a target's samples of the angle between the sample and the target
//                      (J&P's accuracy: error with respect to the drawn point);
//   accuracy_mm        mean on-screen distance between sample and target, millimetres;
//   precision_rms_deg  sample-to-sample RMS: sqrt(mean of angle(s_i, s_i+1)^2) over successive
//                      usable samples (a lost sample between two usable ones is skipped, it does not
//                      break the pair); 0 for a target with a single usable sample (no pairs);
//   precision_std_deg  sqrt(mean of angle(s_i, mean sample)^2): the spread about the samples' own
//                      mean (J&P's "relative standard deviation"; divides by n, not n - 1), 0 for a
//                      single sample;
//   min_deg, max_deg   smallest and largest sample error (angle to the target);
//   mean_error_px      mean(samples) - target in pixels (J&P eq. 4.4, the error vector of Fig. 4.7).
//
// Lost samples. A measured point that is not finite (NaN: blink, pupil lost) is lost: counted in
// `lost`, used nowhere else. A target whose samples are all lost has samples == 0 and every
// statistic 0 — has_data() is false, to_json writes those statistics as null, format_table shows
// "-", and the overall figures skip it. No NaN or infinity leaves this file: measured points
// farther than kFarPx pixels from the screen centre are taken at kFarPx in the same direction (for
// the default display their angle to any on-screen point then differs from the true one by less
// than 1e-6 degree; millimetre figures are capped accordingly).
#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fovea/calib/display.h"
#include "fovea/calib/point.h"

namespace fovea::calib {

inline constexpr double kFarPx = 1e12;

struct ValidationSample {          // rows in time order within each target
  Point target_px;                 // must be finite
  Point measured_px;               // the calibration's output; not finite (NaN) = lost sample
  std::optional<Point> before_px;  // the same sample before this calibration (uncorrected tracker
                                   // output, or the base model's), when known; NaN = lost there
};

struct ErrorStats {                // one target, or the whole set
  std::size_t samples = 0, lost = 0;  // usable and lost samples
  double accuracy_deg = 0;         // mean angular error of the samples vs the target
  double accuracy_mm = 0;          // mean on-screen distance, mm
  double precision_rms_deg = 0;    // RMS of the angles between successive samples (sample-to-sample)
  double precision_std_deg = 0;    // RMS angular distance of samples from their own mean point (STD)
  double min_deg = 0, max_deg = 0; // smallest/largest sample error
  Point mean_error_px;             // mean(measured) - target, px (for the error-vector figure)
  bool has_data() const { return samples > 0; }  // false: every statistic above is absent (0)
};

struct TargetValidation {
  Point target_px;
  ErrorStats after;
  std::optional<ErrorStats> before;  // present exactly when ValidationResult::before is
};

struct ValidationResult {
  // In order of first appearance; samples are grouped by exact target position (the targets are
  // the same doubles for all rows of a target).
  std::vector<TargetValidation> targets;
  // Overall: accuracy_deg/mm, precision_rms/std and mean_error_px are the mean over the targets
  // that have data (each target weighs the same, whatever its sample count); min/max over all
  // usable samples; samples and lost summed.
  ErrorStats after;
  std::optional<ErrorStats> before;  // when every sample had before_px (it may still have no data)
};

// std::invalid_argument for: no samples, a target that is not finite, a display that fails
// check(), and no usable (finite) measured sample at all.
ValidationResult validate(std::span<const ValidationSample> samples, const Display& display);

// Plain-text table like J&P Tables 4.1/4.2: one row per target (x, y px, n, lost, accuracy deg and
// mm, precision RMS and STD deg, min and max deg), then the overall row; with `before`, a second
// group of the same columns for it. Absent figures are "-". Ends with a newline.
std::string format_table(const ValidationResult& result);

// {"targets": [{"target_px": [x, y], "after": STATS, "before": STATS | null}, ...],
//  "overall": {"after": STATS, "before": STATS | null}}
// STATS = {"samples", "lost", "accuracy_deg", "accuracy_mm", "precision_rms_deg",
//          "precision_std_deg", "min_deg", "max_deg", "mean_error_px": [x, y]}, the figures after
// "lost" being null when the stats have no data.
nlohmann::json to_json(const ErrorStats& stats);
nlohmann::json to_json(const ValidationResult& result);

}  // namespace fovea::calib
