// SPDX-License-Identifier: Apache-2.0
#include "sources/hid/usage_tables.h"

#include <array>

namespace fovea::trackerd::hid {

namespace {

constexpr std::array kUsages = {
    // Eye and Head Trackers (0x12), HUTRR74.
    UsageInfo{eht::EyeTracker, "Eye Tracker", UsageKind::CA},
    UsageInfo{eht::HeadTracker, "Head Tracker", UsageKind::CA},
    UsageInfo{eht::TrackingData, "Tracking Data", UsageKind::CP},
    UsageInfo{eht::Capabilities, "Capabilities", UsageKind::CL},
    UsageInfo{eht::Configuration, "Configuration", UsageKind::CL},
    UsageInfo{eht::Status, "Status", UsageKind::CL},
    UsageInfo{eht::Control, "Control", UsageKind::CL},
    UsageInfo{eht::SensorTimestamp, "Sensor Timestamp", UsageKind::DV},
    UsageInfo{eht::PositionX, "Position X", UsageKind::DV},
    UsageInfo{eht::PositionY, "Position Y", UsageKind::DV},
    UsageInfo{eht::PositionZ, "Position Z", UsageKind::DV},
    UsageInfo{eht::GazePoint, "Gaze Point", UsageKind::CP},
    UsageInfo{eht::LeftEyePosition, "Left Eye Position", UsageKind::CP},
    UsageInfo{eht::RightEyePosition, "Right Eye Position", UsageKind::CP},
    UsageInfo{eht::HeadPosition, "Head Position", UsageKind::CP},
    UsageInfo{eht::HeadDirectionPoint, "Head Direction Point", UsageKind::CP},
    UsageInfo{eht::RotationAboutX, "Rotation about X axis", UsageKind::DV},
    UsageInfo{eht::RotationAboutY, "Rotation about Y axis", UsageKind::DV},
    UsageInfo{eht::RotationAboutZ, "Rotation about Z axis", UsageKind::DV},
    UsageInfo{eht::TrackerQuality, "Tracker Quality", UsageKind::SV},
    UsageInfo{eht::MinimumTrackingDistance, "Minimum Tracking Distance", UsageKind::SV},
    UsageInfo{eht::OptimumTrackingDistance, "Optimum Tracking Distance", UsageKind::SV},
    UsageInfo{eht::MaximumTrackingDistance, "Maximum Tracking Distance", UsageKind::SV},
    UsageInfo{eht::MaximumScreenPlaneWidth, "Maximum Screen Plane Width", UsageKind::SV},
    UsageInfo{eht::MaximumScreenPlaneHeight, "Maximum Screen Plane Height", UsageKind::SV},
    UsageInfo{eht::DisplayManufacturerId, "Display Manufacturer ID", UsageKind::SV},
    UsageInfo{eht::DisplayProductId, "Display Product ID", UsageKind::SV},
    UsageInfo{eht::DisplaySerialNumber, "Display Serial Number", UsageKind::SV},
    UsageInfo{eht::DisplayManufacturerDate, "Display Manufacturer Date", UsageKind::SV},
    UsageInfo{eht::CalibratedScreenWidth, "Calibrated Screen Width", UsageKind::SV},
    UsageInfo{eht::CalibratedScreenHeight, "Calibrated Screen Height", UsageKind::SV},
    UsageInfo{eht::SamplingFrequency, "Sampling Frequency", UsageKind::DV},
    UsageInfo{eht::ConfigurationStatus, "Configuration Status", UsageKind::DV},
    UsageInfo{eht::DeviceModeRequest, "Device Mode Request", UsageKind::DV},
    // Application collections met on ordinary devices (HUT: Generic Desktop 0x01, Consumer 0x0C,
    // Digitizers 0x0D, Sensors 0x20).
    UsageInfo{make_usage(0x01, 0x01), "Pointer", UsageKind::CP},
    UsageInfo{make_usage(0x01, 0x02), "Mouse", UsageKind::CA},
    UsageInfo{make_usage(0x01, 0x04), "Joystick", UsageKind::CA},
    UsageInfo{make_usage(0x01, 0x05), "Gamepad", UsageKind::CA},
    UsageInfo{make_usage(0x01, 0x06), "Keyboard", UsageKind::CA},
    UsageInfo{make_usage(0x01, 0x07), "Keypad", UsageKind::CA},
    UsageInfo{make_usage(0x01, 0x08), "Multi-axis Controller", UsageKind::CA},
    UsageInfo{make_usage(0x01, 0x80), "System Control", UsageKind::CA},
    UsageInfo{make_usage(0x0C, 0x01), "Consumer Control", UsageKind::CA},
    UsageInfo{make_usage(0x0D, 0x02), "Pen", UsageKind::CA},
    UsageInfo{make_usage(0x0D, 0x04), "Touch Screen", UsageKind::CA},
    UsageInfo{make_usage(0x0D, 0x05), "Touch Pad", UsageKind::CA},
    UsageInfo{make_usage(0x20, 0x01), "Sensor", UsageKind::CA},
};

struct PageName {
  std::uint16_t page;
  const char* name;
};

constexpr std::array kPages = {
    PageName{0x01, "Generic Desktop"}, PageName{0x02, "Simulation Controls"}, PageName{0x05, "Game Controls"},
    PageName{0x06, "Generic Device Controls"}, PageName{0x07, "Keyboard/Keypad"}, PageName{0x08, "LED"},
    PageName{0x09, "Button"}, PageName{0x0B, "Telephony"}, PageName{0x0C, "Consumer"},
    PageName{0x0D, "Digitizers"}, PageName{0x0E, "Haptics"}, PageName{0x0F, "Physical Input Device"},
    PageName{0x12, "Eye and Head Trackers"}, PageName{0x14, "Auxiliary Display"}, PageName{0x20, "Sensors"},
    PageName{0x40, "Medical Instrument"}, PageName{0x59, "Lighting and Illumination"},
    PageName{0x84, "Power"}, PageName{0x85, "Battery System"}, PageName{0x8C, "Barcode Scanner"},
    PageName{0xF1D0, "FIDO Alliance"},
};

}  // namespace

std::span<const UsageInfo> known_usages() { return kUsages; }

const char* find_usage_name(Usage u) {
  for (const auto& info : kUsages) {
    if (info.usage == u) return info.name;
  }
  return nullptr;
}

const char* find_usage_page_name(std::uint16_t page) {
  for (const auto& p : kPages) {
    if (p.page == page) return p.name;
  }
  return nullptr;
}

const char* configuration_status_name(std::int64_t status) {
  switch (status) {
    case eht::StatusReady: return "ready";
    case eht::StatusConfiguring: return "configuring";
    case eht::StatusScreenSetupNeeded: return "screen setup needed";
    case eht::StatusUserCalibrationNeeded: return "user calibration needed";
    default: return "unknown status";
  }
}

}  // namespace fovea::trackerd::hid
