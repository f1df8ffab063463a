// SPDX-License-Identifier: Apache-2.0
#pragma once
// Eye-camera frames as the eye pipeline reads them: 8-bit single-channel grey. Frame sources (video
// files, cameras) and the detector both convert with this, so neither reaches into the other.
#include <opencv2/core.hpp>

namespace fovea::trackerd {

// Converts any image to 8-bit single-channel grey (BGR, BGRA; otherwise the first channel; 16-bit: scaled by the frame's own
// maximum so 10/12-bit sensors in 16-bit containers keep their contrast). Empty stays empty.
cv::Mat to_grey8(const cv::Mat& image);

}  // namespace fovea::trackerd
