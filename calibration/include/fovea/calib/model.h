// SPDX-License-Identifier: Apache-2.0
#pragma once
// One interface over fovea's calibration models, fitting by name, and the versioned JSON
// calibration file (calibration/CALIBRATION.md describes the format).
//
//   {"format": "fovea-calibration", "version": 1,
//    "model": {"kind": "poly2" | "affine" | "homography" | "bilinear-grid", ...parameters},
//    "on_top_of": {...a model, applied first; optional},
//    "input": "screen" | "pupil-glint", "eye": "left" | "right" (optional),
//    "points_used": N, "outliers_rejected": K, "rms_residual": R, "condition": C (null for bilinear-grid),
//    "created": "2026-01-02T03:04:05Z", "display": {...}, "validation": {...} (both optional)}
#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "fovea/calib/display.h"
#include "fovea/calib/linear_maps.h"
#include "fovea/calib/point.h"

namespace fovea::calib {

class CalibrationModel {
 public:
  virtual ~CalibrationModel() = default;
  virtual Point apply(Point raw) const = 0;
  virtual std::string kind() const = 0;
  // {"kind": kind(), ...parameters}; model_from_json reads it back.
  virtual nlohmann::json to_json() const = 0;
  virtual FitStats stats() const = 0;
  virtual std::unique_ptr<CalibrationModel> clone() const = 0;
};

// "poly2", "affine", "homography", "bilinear-grid".
const std::vector<std::string>& model_kinds();

// Robust fitting: after a fit, correspondences whose residual exceeds `k` robust standard
// deviations of the residuals (median residual / 1.1774: for isotropic Gaussian noise the residual
// length is Rayleigh distributed with that median) are dropped and the model is refitted, until
// nothing more is dropped (at most `max_rounds`). Never drops below half of the correspondences or
// below what the model needs: a set that is mostly "outliers" is refitted as is. Auto: on for
// poly2 (its 12 parameters bend towards a stray target more than a 6-parameter map does), off for
// the others; bilinear-grid, whose vectors are per-target means, is never robustly refitted.
struct FitOptions {
  enum class Robust { Auto, On, Off } robust = Robust::Auto;
  double k = 3.5;
  int max_rounds = 5;
};

struct ModelFit {
  std::unique_ptr<CalibrationModel> model;
  std::size_t outliers_rejected = 0;
};

// Fits a model of that kind; std::invalid_argument for an unknown kind or what the fit refuses.
ModelFit fit_model(std::string_view kind, std::span<const Correspondence> correspondences,
                   const FitOptions& options = {});

// Reads a model object; std::invalid_argument naming `where` (e.g. "cal.json: model") and the field.
std::unique_ptr<CalibrationModel> model_from_json(const nlohmann::json& j, const std::string& where);

inline constexpr int kCalibrationFileVersion = 1;

// What the raw input of a calibration is: the tracker's own (uncalibrated or factory-calibrated)
// gaze on the screen in pixels, or an eye camera's pupil–glint vector in camera pixels.
inline constexpr const char* kInputScreen = "screen";
inline constexpr const char* kInputPupilGlint = "pupil-glint";
inline constexpr const char* kTargetPixels = "px";
inline constexpr const char* kTargetFickDegrees = "fick-deg";

struct Calibration {
  std::unique_ptr<CalibrationModel> model;
  std::unique_ptr<CalibrationModel> on_top_of;  // applied to the raw point first, when set
  std::string input = kInputScreen;              // kInputScreen or kInputPupilGlint
  std::string eye;                               // pupil-glint: "left" or "right"; "" = whichever eye has one
  std::size_t points_used = 0;
  std::size_t outliers_rejected = 0;
  double rms_residual = 0;
  double condition = 0;                          // NaN when the model has none
  std::string created;                           // ISO-8601 UTC
  std::optional<Display> display;                // the screen the targets were shown on (target px)
  // Validation on separate targets, when measured: {"targets": n, "accuracy_deg": a,
  // "accuracy_mm": m, "precision_rms_deg": p, "precision_std_deg": s, "max_deg": x, ...}.
  nlohmann::json validation;

  // What the model's output is: screen pixels, or the Fick angles of the line of sight (degrees,
  // display.h) that apply() turns into pixels with `display` (which must then be set).
  std::string target_space = kTargetPixels;

  // The screen point in pixels (NaN when the model's output has no screen point).
  Point apply(Point raw) const;
  // validation["accuracy_deg"] when present and finite.
  std::optional<double> validated_accuracy_deg() const;
  // "poly2 on pupil-glint (right eye), 9 targets/412 samples, validated 0.61 deg" (for logs, STATUS).
  std::string describe() const;
  nlohmann::json to_json() const;
};

// Fits `kind` to the correspondences; with `base`, to (target, base.apply(raw)) so that the result
// corrects the base calibration (whose model becomes on_top_of; a base that is itself on top of
// another model is refused). points_used, residual and condition are the new model's, the residual
// being that of the whole chain.
// The result's input, eye and display are the base's when a base is given, else the defaults (the
// caller sets them). With `fick_display`, the targets (pixels on that display) are converted to Fick
// angles and the model is fitted to those (target_space fick-deg, display set, residuals in
// degrees); a base must then be in pixels.
Calibration fit_calibration(std::string_view kind, std::span<const Correspondence> correspondences,
                            const Calibration* base = nullptr, const FitOptions& options = {},
                            const Display* fick_display = nullptr);

// Writes to a temporary file beside `path` and moves it into place. Refuses (std::runtime_error)
// when `path` exists, unless `overwrite`.
void save_calibration(const Calibration& calibration, const std::filesystem::path& path, bool overwrite = false);

// Reads and checks a calibration file; std::runtime_error naming the file and the field at fault. A
// version above kCalibrationFileVersion: "written by a newer fovea (version N); this build reads
// version 1".
Calibration load_calibration(const std::filesystem::path& path);
// The same checks on a file's text already read (`name` for the errors): for callers that read the
// file themselves, as the daemon does with a size limit and refusing anything but a regular file.
Calibration parse_calibration(const std::string& text, const std::string& name);

// Current time as "YYYY-MM-DDTHH:MM:SSZ".
std::string utc_now_iso8601();

}  // namespace fovea::calib
