#pragma once
// One interface over fovea's calibration models, fitting by name, and the versioned JSON
// calibration file (calibration/CALIBRATION.md describes the format).
//
//   {"format": "fovea-calibration", "version": 1,
//    "model": {"kind": "poly2" | "affine" | "homography" | "bilinear-grid", ...parameters},
//    "on_top_of": {...a model, applied first; optional},
//    "points_used": N, "rms_residual": R, "condition": C (null for bilinear-grid),
//    "created": "2026-01-02T03:04:05Z", "display": {...free-form; optional}}
#include <cstddef>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

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

// Fits a model of that kind; std::invalid_argument for an unknown kind or what the fit refuses.
std::unique_ptr<CalibrationModel> fit_model(std::string_view kind, std::span<const Correspondence> correspondences);

// Reads a model object; std::invalid_argument naming `where` (e.g. "cal.json: model") and the field.
std::unique_ptr<CalibrationModel> model_from_json(const nlohmann::json& j, const std::string& where);

inline constexpr int kCalibrationFileVersion = 1;

struct Calibration {
  std::unique_ptr<CalibrationModel> model;
  std::unique_ptr<CalibrationModel> on_top_of;  // applied to the raw point first, when set
  std::size_t points_used = 0;
  double rms_residual = 0;
  double condition = 0;                          // NaN when the model has none
  std::string created;                           // ISO-8601 UTC
  nlohmann::json display;                        // null when not recorded

  Point apply(Point raw) const { return model->apply(on_top_of ? on_top_of->apply(raw) : raw); }
  nlohmann::json to_json() const;
};

// Fits `kind` to the correspondences; with `base`, to (target, base.apply(raw)) so that the result
// corrects the base calibration (whose model becomes on_top_of; a base that is itself on top of
// another model is refused). points_used, residual and condition are the new model's, the residual
// being that of the whole chain.
Calibration fit_calibration(std::string_view kind, std::span<const Correspondence> correspondences,
                            const Calibration* base = nullptr);

// Writes to a temporary file beside `path` and moves it into place. Refuses (std::runtime_error)
// when `path` exists, unless `overwrite`.
void save_calibration(const Calibration& calibration, const std::filesystem::path& path, bool overwrite = false);

// Reads and checks a calibration file; std::runtime_error naming the file and the field at fault. A
// version above kCalibrationFileVersion: "written by a newer fovea (version N); this build reads
// version 1".
Calibration load_calibration(const std::filesystem::path& path);

// Current time as "YYYY-MM-DDTHH:MM:SSZ".
std::string utc_now_iso8601();

}  // namespace fovea::calib
