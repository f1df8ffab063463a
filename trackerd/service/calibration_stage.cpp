// SPDX-License-Identifier: Apache-2.0
#include "service/calibration_stage.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "fovea/calib/model.h"
#include "fovea/protocol/bounded_file.h"

namespace fovea::trackerd::service {

namespace {

class IdentityCalibration final : public CalibrationStage {
 public:
  std::string description() const override { return "none (the source's own gaze)"; }
  std::string summary() const override { return description(); }
  void apply(GazeItem&) const override {}
};

class MappedCalibration final : public CalibrationStage {
 public:
  MappedCalibration(calib::Calibration cal, std::string file, const protocol::DisplayGeometry& display)
      : cal_(std::move(cal)), file_(std::move(file)), display_(display) {
    pupil_glint_ = cal_.input == calib::kInputPupilGlint;
  }

  std::string description() const override { return protocol::escape_for_log(file_) + ": " + cal_.describe(); }
  std::string summary() const override {
    std::string s = cal_.model->kind() + (cal_.on_top_of ? " on " + cal_.on_top_of->kind() : "") + " on " + cal_.input;
    if (const auto a = cal_.validated_accuracy_deg()) {
      char buf[32];
      std::snprintf(buf, sizeof buf, ", validated %.2f deg", *a);
      s += buf;
    }
    return s;
  }
  std::string validation_json() const override {
    return cal_.validation.is_null() ? "null" : cal_.validation.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  }

  void apply(GazeItem& item) const override {
    auto* s = std::get_if<protocol::GazeSample>(&item);
    if (s == nullptr) return;
    std::optional<calib::Point> raw;
    if (pupil_glint_) {
      raw = pupil_glint(*s);
    } else if ((s->flags & protocol::kGazeValid) != 0) {
      raw = calib::Point{static_cast<double>(s->x) * display_.width_px, static_cast<double>(s->y) * display_.height_px};
    }
    s->angular_velocity_deg_s = 0;  // recomputed by the classifier from the calibrated gaze
    if (!raw) {
      invalidate(*s);
      return;
    }
    const calib::Point px = cal_.apply(*raw);
    const double nx = px.x / display_.width_px, ny = px.y / display_.height_px;
    if (!std::isfinite(nx) || !std::isfinite(ny) || std::abs(nx) > 100 || std::abs(ny) > 100) {
      invalidate(*s);
      return;
    }
    const protocol::Degrees deg = protocol::normalized_to_degrees(display_, {nx, ny});
    s->x = static_cast<float>(nx);
    s->y = static_cast<float>(ny);
    s->x_deg = static_cast<float>(deg.x);
    s->y_deg = static_cast<float>(deg.y);
    s->flags = static_cast<std::uint8_t>(s->flags | protocol::kGazeValid);
    map_eye_gaze(s->left_gaze);
    map_eye_gaze(s->right_gaze);
  }

 private:
  std::optional<calib::Point> pupil_glint(const protocol::GazeSample& s) const {
    constexpr std::uint8_t both = protocol::kEyePupilValid | protocol::kEyeGlintValid;
    auto usable = [&](const protocol::EyeData& e) { return (e.flags & both) == both; };
    const protocol::EyeData* eye = nullptr;
    if (cal_.eye == "left") eye = usable(s.left) ? &s.left : nullptr;
    else if (cal_.eye == "right") eye = usable(s.right) ? &s.right : nullptr;
    else eye = usable(s.right) ? &s.right : usable(s.left) ? &s.left : nullptr;
    if (eye == nullptr) return std::nullopt;
    return calib::Point{eye->pupil_glint_x_px, eye->pupil_glint_y_px};
  }

  // Each eye's point of gaze through the same screen map as the combined one. A pupil-glint
  // calibration maps one eye's camera features to the screen and has nothing for the other eye's
  // tracker-made point: that eye gaze is dropped rather than published unmapped beside mapped gaze.
  void map_eye_gaze(protocol::EyeGaze& e) const {
    if (!e.valid()) return;
    if (pupil_glint_) {
      e = protocol::EyeGaze{};
      return;
    }
    const calib::Point px =
        cal_.apply({static_cast<double>(e.x) * display_.width_px, static_cast<double>(e.y) * display_.height_px});
    const double nx = px.x / display_.width_px, ny = px.y / display_.height_px;
    if (!std::isfinite(nx) || !std::isfinite(ny) || std::abs(nx) > 100 || std::abs(ny) > 100) {
      e = protocol::EyeGaze{};
      return;
    }
    const protocol::Degrees deg = protocol::normalized_to_degrees(display_, {nx, ny});
    e.x = static_cast<float>(nx);
    e.y = static_cast<float>(ny);
    e.x_deg = static_cast<float>(deg.x);
    e.y_deg = static_cast<float>(deg.y);
  }

  static void invalidate(protocol::GazeSample& s) {
    s.flags = static_cast<std::uint8_t>(s.flags & ~protocol::kGazeValid);
    s.x = s.y = s.x_deg = s.y_deg = 0;
    s.left_gaze = s.right_gaze = protocol::EyeGaze{};
  }

  calib::Calibration cal_;
  std::string file_;
  protocol::DisplayGeometry display_;
  bool pupil_glint_ = false;
};

}  // namespace

std::unique_ptr<CalibrationStage> load_calibration_stage(const std::string& file,
                                                         const protocol::DisplayGeometry& display, bool follow_symlinks) {
  if (file.empty()) return std::make_unique<IdentityCalibration>();
  // A control request names the file: read it as a hostile user's path (regular file, bounded,
  // never blocking), then parse with the same checks as calib::load_calibration.
  const std::string text = protocol::read_bounded_file(file, {.max_bytes = kMaxCalibrationFileBytes, .follow_symlinks = follow_symlinks, .what = "calibration file"});
  calib::Calibration cal = calib::parse_calibration(text, protocol::escape_for_log(file));  // names the field at fault
  if (cal.display) {
    if (cal.display->width_px != display.width_px || cal.display->height_px != display.height_px) {
      throw std::runtime_error("calibration file " + protocol::escape_for_log(file) + ": made for a " + calib::to_string(*cal.display) +
                               " screen; the daemon's display is " + protocol::to_string(display) +
                               " (calibrate again on this display)");
    }
  }
  return std::make_unique<MappedCalibration>(std::move(cal), file, display);
}

}  // namespace fovea::trackerd::service
