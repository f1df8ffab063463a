// SPDX-License-Identifier: Apache-2.0
#pragma once
// Overlays drawn on the display image: the gaze point and the gaze area, and false-colour views of
// G-buffer maps.
#include <optional>
#include <string>

#include "attention/attention.h"
#include "dof/lens.h"
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
inline double degrees_to_pixels(const protocol::DisplayGeometry& display, std::uint32_t image_width, double degrees) {
  return protocol::degrees_to_image_pixels(display, image_width, degrees);
}

// Draws a ring of 1 deg diameter at the gaze point (red when the sample is valid, grey when the
// last valid point is shown), and, if area_deg > 0, a thin ring of that diameter (the gaze area).
void draw_gaze(Image8& image, const protocol::DisplayGeometry& display, const GazeMark& gaze, double area_deg);

// draw_focus's iso-depth line takes depths within this fraction of the focal depth as on it: above
// the float depth's rounding (the G-buffer passes agree within 1e-5, tests/gl/test_gl_backend.cpp).
inline constexpr double kIsoDepthTolerance = 2e-5;

// Shows the focus pass's result: outlines the focused object's pixels (yellow when settled, cyan
// during a focus transition); for a focal depth without an object (screen centre, depth under the
// gaze point) it draws the iso-depth line where the scene crosses the focal depth instead. The image
// code has no text drawing, so `label` (FocusResult::why) is not drawn; it is taken so that callers
// need not change when text arrives. The G-buffer is sampled nearest when its size differs.
void draw_focus(Image8& image, const GBuffer& g, std::uint32_t focused_object, double focal_depth_m,
                bool in_transition, const std::string& label);

// Replaces the image with a false-colour view of a G-buffer map: depth, id, normal, motion.
// Returns false when `map` is not a G-buffer map (maps of later passes).
bool draw_gbuffer_map(Image8& image, const GBuffer& g, const std::string& map, float far_m);

// Attention overlays (Lee 2009 Fig. 3.4): replaces the image (kept at its size) with a false-colour
// view of the attention pass's maps, black (0) through blue, red and yellow to white (maximum):
//   saliency   the pixel saliency S_p (bilinear upsampling of the map; [0, 1] as is);
//   spatial    each listed object's T_s (nearest upsampling of the map's item buffer; 0.5 = white);
//   temporal   each listed object's T_t (same scale as spatial);
//   attention  each listed object's S_o after the filter (scaled by the frame's highest S_o).
// Pixels of unlisted objects (background, T_i = 0) stay black in the object maps. Returns false when
// `map` is none of these.
bool draw_attention_map(Image8& image, const attention::AttentionFrame& frame, const std::string& map);

// The DOF pass's circle of confusion (overlay.map=coc): each pixel's CoC diameter C (Lee 2009 eqs.
// 4.2-4.4) from its depth, black (in focus) through blue, red and yellow to white at the frame's
// largest C (at least 1 px); pixels in front of the focal plane get a blue tint, so the two sides of
// the plane can be told apart.
void draw_coc_map(Image8& image, const GBuffer& g, const dof::CocModel& coc);

// Marks the most attended object: a small white square (black rim) at its pixels' centroid. Draws
// nothing when no object is attended.
void draw_attention_mark(Image8& image, const attention::AttentionFrame& frame);

}  // namespace fovea::render
