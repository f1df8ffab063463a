#pragma once
// Overlays drawn on the display image: the gaze point and the gaze area, and false-colour views of
// G-buffer maps.
#include <optional>
#include <string>

#include "backend/gbuffer.h"
#include "fovea/protocol/display_geometry.h"
#include "image/image.h"

namespace fovea::render {

struct GazeMark {
  double x = 0.5, y = 0.5;  // normalized screen coordinates
  bool valid = false;
};

// Visual angle to pixels on this display at this image resolution: the diameter in pixels of a
// circle subtending `degrees` at the screen centre (Jensen & Pedersen 2009, eq. 2.1-2.2).
double degrees_to_pixels(const protocol::DisplayGeometry& display, std::uint32_t image_width, double degrees);

// Draws a ring of 1 deg diameter at the gaze point (red when the sample is valid, grey when the
// last valid point is shown), and, if area_deg > 0, a thin ring of that diameter (the gaze area).
void draw_gaze(Image8& image, const protocol::DisplayGeometry& display, const GazeMark& gaze, double area_deg);

// Replaces the image with a false-colour view of a G-buffer map: depth, id, normal, motion.
// Returns false when `map` is not a G-buffer map (maps of later passes).
bool draw_gbuffer_map(Image8& image, const GBuffer& g, const std::string& map, float far_m);

}  // namespace fovea::render
