// SPDX-License-Identifier: Apache-2.0
#pragma once
// An ellipse in image pixels: the pupil as the camera sees it.
#include <opencv2/core.hpp>

namespace fovea::trackerd::eye {

struct Ellipse {
  cv::Point2d centre;      // pixels, origin at the top-left pixel's top-left corner (pixel i covers [i, i+1))
  double major = 0;        // full axis lengths in pixels (a diameter, as cv::RotatedRect::size)
  double minor = 0;        // minor <= major
  double angle_deg = 0;    // direction of the major axis from +x towards +y (image down), in [0, 180)
  double aspect() const { return major > 0 ? minor / major : 0.0; }
};

}  // namespace fovea::trackerd::eye
