// SPDX-License-Identifier: Apache-2.0
#pragma once
// The plain 2-D types calibration models are fitted and applied on.
namespace fovea::calib {

struct Point {
  double x = 0, y = 0;
  friend bool operator==(const Point&, const Point&) = default;
};

// One calibration sample: a raw measurement (e.g. the pupil–glint vector in eye-camera pixels) and
// where on the screen it belongs (e.g. normalised screen coordinates of the target looked at).
struct Correspondence {
  Point raw;
  Point target;
};

}  // namespace fovea::calib
