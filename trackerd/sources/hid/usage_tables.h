// SPDX-License-Identifier: Apache-2.0
#pragma once
// HID usage tables as data: the "Eye and Head Trackers" page (0x12, HUTRR74, in the HID Usage
// Tables since 1.21) in full, plus names for the pages and application usages a user is likely to
// see on other devices (so "not an eye tracker" errors can say what a device is instead).
//
// If a value here turns out to disagree with the published tables, correct it here: the mapping
// (eye_tracker.cpp) refers to usages only through the constants below.
#include <cstdint>
#include <span>

#include "sources/hid/report_descriptor.h"

namespace fovea::trackerd::hid {

inline constexpr std::uint16_t kEyeHeadTrackerPage = 0x12;

// HUT usage types: CA application collection, CP physical collection, CL logical collection,
// DV dynamic value, SV static value, Sel selector.
enum class UsageKind : std::uint8_t { CA, CP, CL, DV, SV, Sel };

struct UsageInfo {
  Usage usage;
  const char* name;
  UsageKind kind;
};

namespace eht {  // Eye and Head Trackers page, HUTRR74
inline constexpr Usage EyeTracker = make_usage(0x12, 0x0001);             // CA
inline constexpr Usage HeadTracker = make_usage(0x12, 0x0002);            // CA
inline constexpr Usage TrackingData = make_usage(0x12, 0x0010);           // CP
inline constexpr Usage Capabilities = make_usage(0x12, 0x0011);           // CL
inline constexpr Usage Configuration = make_usage(0x12, 0x0012);          // CL
inline constexpr Usage Status = make_usage(0x12, 0x0013);                 // CL
inline constexpr Usage Control = make_usage(0x12, 0x0014);                // CL
inline constexpr Usage SensorTimestamp = make_usage(0x12, 0x0020);        // DV, microseconds
inline constexpr Usage PositionX = make_usage(0x12, 0x0021);              // DV
inline constexpr Usage PositionY = make_usage(0x12, 0x0022);              // DV
inline constexpr Usage PositionZ = make_usage(0x12, 0x0023);              // DV
inline constexpr Usage GazePoint = make_usage(0x12, 0x0024);              // CP, micrometres, screen top-left
inline constexpr Usage LeftEyePosition = make_usage(0x12, 0x0025);        // CP, micrometres
inline constexpr Usage RightEyePosition = make_usage(0x12, 0x0026);       // CP, micrometres
inline constexpr Usage HeadPosition = make_usage(0x12, 0x0027);           // CP
inline constexpr Usage HeadDirectionPoint = make_usage(0x12, 0x0028);     // CP
inline constexpr Usage RotationAboutX = make_usage(0x12, 0x0029);         // DV
inline constexpr Usage RotationAboutY = make_usage(0x12, 0x002A);         // DV
inline constexpr Usage RotationAboutZ = make_usage(0x12, 0x002B);         // DV
inline constexpr Usage TrackerQuality = make_usage(0x12, 0x0100);         // SV
inline constexpr Usage MinimumTrackingDistance = make_usage(0x12, 0x0101);  // SV, micrometres
inline constexpr Usage OptimumTrackingDistance = make_usage(0x12, 0x0102);  // SV
inline constexpr Usage MaximumTrackingDistance = make_usage(0x12, 0x0103);  // SV
inline constexpr Usage MaximumScreenPlaneWidth = make_usage(0x12, 0x0104);  // SV
inline constexpr Usage MaximumScreenPlaneHeight = make_usage(0x12, 0x0105); // SV
inline constexpr Usage DisplayManufacturerId = make_usage(0x12, 0x0200);  // SV
inline constexpr Usage DisplayProductId = make_usage(0x12, 0x0201);       // SV
inline constexpr Usage DisplaySerialNumber = make_usage(0x12, 0x0202);    // SV
inline constexpr Usage DisplayManufacturerDate = make_usage(0x12, 0x0203);  // SV
inline constexpr Usage CalibratedScreenWidth = make_usage(0x12, 0x0204);  // SV, micrometres
inline constexpr Usage CalibratedScreenHeight = make_usage(0x12, 0x0205); // SV, micrometres
inline constexpr Usage SamplingFrequency = make_usage(0x12, 0x0300);      // DV, Hz
inline constexpr Usage ConfigurationStatus = make_usage(0x12, 0x0301);    // DV, see below
inline constexpr Usage DeviceModeRequest = make_usage(0x12, 0x0400);      // DV

// Configuration Status values (as used by Microsoft's reference drivers).
inline constexpr std::int64_t StatusReady = 1;
inline constexpr std::int64_t StatusConfiguring = 2;
inline constexpr std::int64_t StatusScreenSetupNeeded = 3;
inline constexpr std::int64_t StatusUserCalibrationNeeded = 4;
}  // namespace eht

// Every named usage of page 0x12 and a few application usages of other pages.
std::span<const UsageInfo> known_usages();
const char* find_usage_name(Usage u);        // nullptr if unknown
const char* find_usage_page_name(std::uint16_t page);  // nullptr if unknown
// "ready", "configuring", "screen setup needed", "user calibration needed", "unknown status".
const char* configuration_status_name(std::int64_t status);

}  // namespace fovea::trackerd::hid
