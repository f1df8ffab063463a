// SPDX-License-Identifier: Apache-2.0
#pragma once
// Where the infrared LEDs sit around the eye camera's lens. Each LED makes one corneal glint; on
// the convex cornea the glints form a small, upright, reduced copy of this layout, which is how the
// detector tells glints from other reflections and which LED each glint belongs to.
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace fovea::trackerd::eye {

struct LedLayout {
  // LED positions in millimetres relative to the camera's optical centre, in the camera's image
  // orientation (x right, y down as in the image), in the plane of the lens. Empty: unknown layout
  // (glints are then taken as found, without pairing).
  std::vector<cv::Point2d> positions_mm;

  static LedLayout preset(int count);  // 1: one LED below the lens; 2: left/right; 3: triangle; 4: square; 5: square + centre-below
  // Parses "x,y;x,y;..." (mm) or a preset count "1".."5"; throws std::invalid_argument naming the bad part.
  static LedLayout parse(const std::string& text);
  std::string to_string() const;
};

}  // namespace fovea::trackerd::eye
