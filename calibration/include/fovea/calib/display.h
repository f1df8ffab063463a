// SPDX-License-Identifier: Apache-2.0
#pragma once
// The screen a calibration was made for: pixels, visible size and viewing distance, and the
// conversions validation needs (screen millimetres, visual angle between two screen points).
//
// This is the calibration library's own copy of the display geometry, so that fovea_calibration
// depends on nothing else of fovea; it holds the same numbers as protocol's DisplayGeometry (which
// keeps metres and integer pixels) and reads and writes the same text form,
// "1920x1080@531.3x298.9mm,650mm".
//
// The eye is on the normal through the screen centre at distance_mm (Jensen & Pedersen 2009,
// §2 and §4.1: 650 mm, head aligned with the middle of the monitor). Pixel coordinates have their
// origin at the top-left corner of the screen, x right, y down; the centre is (width_px / 2,
// height_px / 2).
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "fovea/calib/point.h"

namespace fovea::calib {

struct Display {
  double width_px = 1920, height_px = 1080;
  double width_mm = 531.3, height_mm = 298.9;
  double distance_mm = 650;  // eye to screen, along the normal through the screen centre
  friend bool operator==(const Display&, const Display&) = default;
};

// "" when usable; otherwise which field is bad and the allowed range: every field finite and > 0,
// width_px and height_px <= 65536, the millimetre fields <= 100000.
std::string check(const Display& display);

// {"width_px":..,"height_px":..,"width_mm":..,"height_mm":..,"distance_mm":..}
nlohmann::json to_json(const Display& display);

// Reads the object above (every field required, numbers only, then check()); std::invalid_argument
// naming `where` (e.g. "cal.json: display") and the field at fault.
Display display_from_json(const nlohmann::json& j, const std::string& where);

// "1920x1080@531.3x298.9mm,650mm" (WxH@WMMxHMMmm,DISTmm; up to 10 significant digits each).
std::string to_string(const Display& display);
// Parses that form (pixels may have a fraction; surrounding blanks are not allowed), then check();
// std::invalid_argument quoting the text and saying what is wrong.
Display parse_display(std::string_view text);

// Screen-plane millimetres from the screen centre, x right, y down.
Point px_to_mm(const Display& display, Point px);

// The direction of the line of sight to a screen point as Fick angles in degrees, for an eye on
// the screen centre's normal at distance_mm: yaw (x, right positive) about the vertical axis, then
// pitch (y, down positive): yaw = atan2(x_mm, d), pitch = atan2(y_mm, hypot(x_mm, d)). The eye's
// own rotation is of this form, which is why calibration models fitted in these coordinates follow
// the pupil–glint vector better than models fitted straight to pixels. fick_deg_to_px inverts it;
// NaN for |yaw| or |pitch| >= 89.9 deg (no screen point) or non-finite input.
Point px_to_fick_deg(const Display& display, Point px);
Point fick_deg_to_px(const Display& display, Point fick_deg);

// Pixels per millimetre along x (width_px / width_mm).
double px_per_mm(const Display& display);

// Angle in degrees (0..180) between the lines of sight to two screen points given in pixels, for an
// eye on the screen centre's normal at distance_mm: the angle between the 3-D vectors
// (x_mm, y_mm, distance_mm), computed as atan2(|a x b|, a . b) with a x b = a x (b - a), so that it
// stays accurate for tiny angles, and on scaled vectors, so that it stays finite for any finite
// points (however far off the screen). NaN when a coordinate is not finite. The display is assumed
// to pass check().
double angle_between_deg(const Display& display, Point a_px, Point b_px);

}  // namespace fovea::calib
