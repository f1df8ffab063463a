// SPDX-License-Identifier: Apache-2.0
#pragma once
// The validation report of `fovea-calibrate validate --report DIR` (calibration/CALIBRATION.md):
//   report.md     title, display, the per-target table (markdown), overall summary, how the figures
//                 were computed (Jensen & Pedersen 2009, §4, Tables 4.1-4.2);
//   targets.csv   one row per target with every statistic (before_* columns when there is a
//                 "before"; empty cells for absent figures);
//   summary.json  to_json(result) plus the display and the title;
//   errors.png    the error vectors per target, as J&P Fig. 4.7: panels "before" and "after" side by
//                 side (only "after" without a before), vectors and samples magnified by a stated
//                 factor, a scale bar in degrees.
#include <filesystem>
#include <string>
#include <vector>

#include "fovea/calib/display.h"
#include "fovea/calib/validation.h"

namespace fovea::calib {

// Creates `dir` when missing. Every file is rendered first, then written through a temporary file;
// when one of the four report files already exists in `dir` nothing is written (std::runtime_error
// naming that file), and a failed write removes what this call had written.
void write_validation_report(const std::filesystem::path& dir, const ValidationResult& result,
                             const std::vector<ValidationSample>& samples, const Display& display,
                             const std::string& title);

// The figure alone, PNG-encoded (for tests and callers that place it themselves).
std::vector<unsigned char> render_error_figure_png(const ValidationResult& result,
                                                   const std::vector<ValidationSample>& samples,
                                                   const Display& display, const std::string& title);

}  // namespace fovea::calib
