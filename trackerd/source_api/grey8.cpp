// SPDX-License-Identifier: Apache-2.0
#include "source_api/grey8.h"

#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

namespace fovea::trackerd {

cv::Mat to_grey8(const cv::Mat& image) {
  if (image.empty()) return {};
  cv::Mat grey;
  switch (image.channels()) {
    case 1: grey = image; break;
    case 3: cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY); break;
    case 4: cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY); break;
    default: cv::extractChannel(image, grey, 0); break;  // e.g. grey + alpha: the first channel
  }
  if (grey.depth() == CV_8U) return grey;
  cv::Mat as_double;  // float is exact for 16-bit values and is what patchNaNs accepts
  grey.convertTo(as_double, CV_32F);
  cv::patchNaNs(as_double, 0.0);
  cv::max(as_double, -std::numeric_limits<float>::max(), as_double);  // -Inf -> finite
  cv::min(as_double, std::numeric_limits<float>::max(), as_double);   // +Inf -> finite
  double lo = 0, hi = 0;
  cv::minMaxLoc(as_double, &lo, &hi);
  if (!std::isfinite(hi) || hi <= 0) hi = 1;
  lo = std::min(0.0, lo);
  cv::Mat eight;
  as_double.convertTo(eight, CV_8U, 255.0 / (hi - lo), -lo * 255.0 / (hi - lo));
  return eight;
}

}  // namespace fovea::trackerd
