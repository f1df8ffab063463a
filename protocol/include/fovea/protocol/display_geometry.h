// SPDX-License-Identifier: Apache-2.0
#pragma once
// Display geometry: converts between normalized screen coordinates, pixels and visual angle.
#include <cstdint>
#include <string>

namespace fovea::protocol {

struct DisplayGeometry {
  std::uint32_t width_px = 1920;
  std::uint32_t height_px = 1080;
  double width_m = 0.5313;   // 24" 16:9 panel
  double height_m = 0.2989;
  double viewing_distance_m = 0.65;

  friend bool operator==(const DisplayGeometry&, const DisplayGeometry&) = default;
};

// Empty string when the geometry is usable; otherwise which field is wrong and the allowed range.
std::string validate(const DisplayGeometry& g);

// Pixels per millimetre along the diagonal. Jensen & Pedersen 2009, eq. 2.2.
double pixels_per_mm(const DisplayGeometry& g);

// The diameter in pixels of an image that fills the screen's width (`image_width` pixels across)
// of a circle subtending `degrees` at the screen centre: eq. 2.1 solved for the size, then screen
// millimetres to image pixels (Jensen & Pedersen 2009, eqs. 2.1-2.2).
double degrees_to_image_pixels(const DisplayGeometry& g, std::uint32_t image_width, double degrees);

// Visual angle subtended by an extent of `size_m` centred on the line of sight at distance d.
// Jensen & Pedersen 2009, eq. 2.1: theta = 2 atan(h / 2d).
double visual_angle_deg(double size_m, double distance_m);

struct Degrees {
  double x = 0, y = 0;
};
struct Normalized {
  double x = 0, y = 0;
};

// Normalized screen point ([0,1]^2, origin top-left, y down) to degrees of visual angle from the
// screen centre (x right, y down), for an eye facing the centre at the viewing distance. This is
// eq. 2.1 applied to the offset from the centre: theta = atan(offset / d).
Degrees normalized_to_degrees(const DisplayGeometry& g, Normalized p);
Normalized degrees_to_normalized(const DisplayGeometry& g, Degrees d);

// The angle between two gaze directions given as degrees from the screen centre (each the
// direction through that point of the screen plane), in degrees. Accurate for small angles too.
double angle_between_deg(Degrees a, Degrees b);

// "1920x1080@531.3x298.9mm,650mm" — the form used on command lines and in CSV headers
// (millimetres with up to 10 significant digits).
std::string to_string(const DisplayGeometry& g);
// Parses the form above; throws std::invalid_argument naming the bad part.
DisplayGeometry parse_display_geometry(const std::string& text);

}  // namespace fovea::protocol
