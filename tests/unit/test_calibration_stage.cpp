// SPDX-License-Identifier: Apache-2.0
// The daemon's calibration stage (trackerd/service/calibration_stage.h): pupil-glint and screen
// input, the display check, invalid and absurd inputs, and the control message that loads it.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "fovea/calib/model.h"
#include "fovea/protocol/codec.h"
#include "service/calibration_stage.h"

namespace {

using namespace fovea;
using fovea::trackerd::GazeItem;
namespace fs = std::filesystem;

#define EXPECT_CONTAINS(haystack, needle) \
  EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << "message: " << (haystack)

fs::path temp_path(const std::string& name) {
  return fs::temp_directory_path() / ("fovea-stage-" + std::to_string(::getpid()) + "-" + name);
}

// An affine calibration raw -> px: x = 960 + 40 u, y = 540 + 30 v.
fs::path write_affine(const std::string& name, const std::string& input, const std::string& eye,
                      std::optional<calib::Display> display = calib::Display{}) {
  std::vector<calib::Correspondence> pts;
  for (double u : {-10.0, 0.0, 10.0})
    for (double v : {-8.0, 0.0, 8.0}) pts.push_back({{u, v}, {960 + 40 * u, 540 + 30 * v}});
  calib::Calibration cal = calib::fit_calibration("affine", pts);
  cal.input = input;
  cal.eye = eye;
  cal.display = display;
  cal.validation = {{"accuracy_deg", 0.42}};
  const fs::path path = temp_path(name);
  fs::remove(path);
  calib::save_calibration(cal, path);
  return path;
}

protocol::GazeSample eye_sample(float pg_x, float pg_y, std::uint8_t right_flags) {
  protocol::GazeSample s;
  s.tracker_time_ns = 1000;
  s.right.flags = right_flags;
  s.right.pupil_glint_x_px = pg_x;
  s.right.pupil_glint_y_px = pg_y;
  s.angular_velocity_deg_s = 12;
  return s;
}

TEST(CalibrationStage, PupilGlintInputComputesTheGazeFromTheVector) {
  const protocol::DisplayGeometry display;  // 1920x1080
  const fs::path file = write_affine("pg.json", calib::kInputPupilGlint, "right");
  const auto stage = trackerd::service::load_calibration_stage(file.string(), display);
  EXPECT_CONTAINS(stage->description(), "affine on pupil-glint (right eye)");
  EXPECT_CONTAINS(stage->description(), "validated 0.42 deg");

  GazeItem item = eye_sample(4, -2, protocol::kEyePupilValid | protocol::kEyeGlintValid);
  stage->apply(item);
  const auto& s = std::get<protocol::GazeSample>(item);
  EXPECT_TRUE(s.flags & protocol::kGazeValid);
  EXPECT_NEAR(s.x, (960 + 160) / 1920.0, 1e-6);
  EXPECT_NEAR(s.y, (540 - 60) / 1080.0, 1e-6);
  const auto deg = protocol::normalized_to_degrees(display, {static_cast<double>(s.x), static_cast<double>(s.y)});
  EXPECT_NEAR(s.x_deg, deg.x, 1e-4);
  EXPECT_NEAR(s.y_deg, deg.y, 1e-4);
  EXPECT_EQ(s.angular_velocity_deg_s, 0.0f);  // the classifier recomputes it

  // No glint: no gaze (and no stale coordinates).
  GazeItem lost = eye_sample(4, -2, protocol::kEyePupilValid);
  std::get<protocol::GazeSample>(lost).flags = protocol::kGazeValid;  // e.g. a factory gaze
  std::get<protocol::GazeSample>(lost).x = 0.3f;
  stage->apply(lost);
  EXPECT_FALSE(std::get<protocol::GazeSample>(lost).flags & protocol::kGazeValid);
  EXPECT_EQ(std::get<protocol::GazeSample>(lost).x, 0.0f);

  // A vector absurdly far out maps beyond 100 screens: invalid, never an overflow on the wire.
  GazeItem far = eye_sample(3e7f, 0, protocol::kEyePupilValid | protocol::kEyeGlintValid);
  stage->apply(far);
  EXPECT_FALSE(std::get<protocol::GazeSample>(far).flags & protocol::kGazeValid);

  // Events pass unchanged.
  GazeItem ev = protocol::GazeEvent{};
  stage->apply(ev);
  EXPECT_EQ(std::get<protocol::GazeEvent>(ev), protocol::GazeEvent{});
  fs::remove(file);
}

TEST(CalibrationStage, ScreenInputCorrectsTheTrackersOwnGaze) {
  const protocol::DisplayGeometry display;
  // The tracker reads 12 px too far right and 6 px too high everywhere.
  std::vector<calib::Correspondence> pts;
  for (double x : {192.0, 960.0, 1728.0})
    for (double y : {108.0, 540.0, 972.0}) pts.push_back({{x + 12, y - 6}, {x, y}});
  calib::Calibration cal = calib::fit_calibration("affine", pts);
  cal.display = calib::Display{};
  const fs::path file = temp_path("screen.json");
  fs::remove(file);
  calib::save_calibration(cal, file);
  const auto stage = trackerd::service::load_calibration_stage(file.string(), display);
  EXPECT_CONTAINS(stage->description(), "affine on screen");
  protocol::GazeSample s;
  s.flags = protocol::kGazeValid;
  s.x = static_cast<float>((500.0 + 12) / 1920);
  s.y = static_cast<float>((300.0 - 6) / 1080);
  GazeItem item = s;
  stage->apply(item);
  const auto& out = std::get<protocol::GazeSample>(item);
  EXPECT_TRUE(out.flags & protocol::kGazeValid);
  EXPECT_NEAR(out.x * 1920, 500, 1e-3);
  EXPECT_NEAR(out.y * 1080, 300, 1e-3);
  // Each eye's point goes through the same correction (a binocular tracker's, for a stereo view).
  protocol::GazeSample eyes = s;
  eyes.left_gaze = protocol::EyeGaze{protocol::kEyeGazeValid, static_cast<float>((480.0 + 12) / 1920),
                                     static_cast<float>((300.0 - 6) / 1080), 0, 0};
  GazeItem eyes_item = eyes;
  stage->apply(eyes_item);
  const auto& eyes_out = std::get<protocol::GazeSample>(eyes_item);
  ASSERT_TRUE(eyes_out.left_gaze.valid());
  EXPECT_NEAR(eyes_out.left_gaze.x * 1920, 480, 1e-3);
  EXPECT_NEAR(eyes_out.left_gaze.y * 1080, 300, 1e-3);
  const auto deg = protocol::normalized_to_degrees(display, {eyes_out.left_gaze.x, eyes_out.left_gaze.y});
  EXPECT_NEAR(eyes_out.left_gaze.x_deg, deg.x, 1e-4);
  EXPECT_FALSE(eyes_out.right_gaze.valid()) << "an eye the tracker did not see stays unseen";
  // An invalid tracker sample stays invalid.
  protocol::GazeSample invalid;
  GazeItem inv = invalid;
  stage->apply(inv);
  EXPECT_FALSE(std::get<protocol::GazeSample>(inv).flags & protocol::kGazeValid);
  fs::remove(file);
}

TEST(CalibrationStage, RefusesOtherDisplaysAndBadFilesByName) {
  const fs::path file = write_affine("disp.json", calib::kInputPupilGlint, "right");
  protocol::DisplayGeometry other;
  other.width_px = 2560;
  other.height_px = 1440;
  try {
    (void)trackerd::service::load_calibration_stage(file.string(), other);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_CONTAINS(e.what(), file.string());
    EXPECT_CONTAINS(e.what(), "made for a 1920x1080");
    EXPECT_CONTAINS(e.what(), "2560x1440");
  }
  std::ofstream(file) << "{\"format\": \"fovea-calibration\", \"version\": 7}";
  try {
    (void)trackerd::service::load_calibration_stage(file.string(), protocol::DisplayGeometry{});
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_CONTAINS(e.what(), "newer fovea (version 7)");
  }
  EXPECT_THROW((void)trackerd::service::load_calibration_stage("/nonexistent/c.json", protocol::DisplayGeometry{}),
               std::runtime_error);
  EXPECT_EQ(trackerd::service::load_calibration_stage("", protocol::DisplayGeometry{})->description(),
            "none (the source's own gaze)");
  fs::remove(file);
}

TEST(CalibrationStage, TheLoadCommandTravelsAsAControlRequest) {
  protocol::Message m{protocol::Header{}, protocol::ControlRequest{protocol::ControlCommand::LoadCalibration, {}}};
  m.header.type = protocol::MessageType::ControlRequest;
  std::get<protocol::ControlRequest>(m.payload).argument.value = "/var/lib/fovea/calibration.json";
  const auto bytes = protocol::encode(m);
  protocol::Message back;
  ASSERT_TRUE(protocol::decode(bytes, back));
  EXPECT_EQ(std::get<protocol::ControlRequest>(back.payload).command, protocol::ControlCommand::LoadCalibration);
  EXPECT_EQ(std::string(protocol::to_string(protocol::ControlCommand::LoadCalibration)), "calibration-load");
  // Command 5 does not exist: rejected as out of range.
  auto bad = bytes;
  bad[32] = 5;
  EXPECT_FALSE(protocol::decode(bad, back));
}

}  // namespace
