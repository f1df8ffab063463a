// SPDX-License-Identifier: Apache-2.0
// Glint candidates: small, round, near-saturated blobs well above their surround, with
// intensity-weighted sub-pixel centres, and the (dilated) mask of their pixels that keeps them out
// of the pupil's edge search.
#include "eye/detector_stages.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <opencv2/imgproc.hpp>

namespace fovea::trackerd::eye::stages {

GlintCandidates find_glints(const cv::Mat& grey, const cv::Rect& window, double image_size) {
  GlintCandidates out;
  out.window = window;
  const cv::Mat region = grey(window);
  out.mask = cv::Mat::zeros(region.size(), CV_8U);
  double lo = 0, hi = 0;
  cv::minMaxLoc(region, &lo, &hi);
  const double median = percentile(region, 0.5);
  if (hi < median + 40) return out;  // nothing stands out: no glints
  const double threshold = std::max(hi - 0.3 * (hi - median), median + 35);
  cv::Mat bright;
  cv::threshold(region, bright, threshold, 255, cv::THRESH_BINARY);
  // The components lie within the box around the bright pixels, usually a small part of the window:
  // labelling only that box finds the same components at a fraction of the cost.
  const cv::Rect box = cv::boundingRect(bright);
  if (box.empty()) return out;
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(bright(box), labels, stats, centroids, 8, CV_32S);
  const double max_radius = std::max(2.0, 0.04 * image_size);
  const double max_area = kPi * max_radius * max_radius;
  for (int i = 1; i < n; ++i) {
    const int area = stats.at<int>(i, cv::CC_STAT_AREA);
    const int bw = stats.at<int>(i, cv::CC_STAT_WIDTH), bh = stats.at<int>(i, cv::CC_STAT_HEIGHT);
    // Single saturated pixels are sensor noise on bright skin; a glint covers a few pixels.
    if (area < (image_size >= 160 ? 3 : 2) || area > max_area || bw > 2 * max_radius + 2 || bh > 2 * max_radius + 2) continue;
    if (std::max(bw, bh) > 3 * std::min(bw, bh) + 2) continue;  // streaks (glasses edges, lashes) are not glints
    // Intensity-weighted centroid over the component's box, above the threshold.
    const int bx = box.x + stats.at<int>(i, cv::CC_STAT_LEFT), by = box.y + stats.at<int>(i, cv::CC_STAT_TOP);
    double sw = 0, sx = 0, sy = 0;
    for (int y = std::max(0, by - 1); y < std::min(region.rows, by + bh + 1); ++y)
      for (int x = std::max(0, bx - 1); x < std::min(region.cols, bx + bw + 1); ++x) {
        const double w = region.at<std::uint8_t>(y, x) - (threshold - 20);
        if (w <= 0) continue;
        sw += w; sx += w * x; sy += w * y;
      }
    if (sw <= 0) continue;
    // A glint is a local peak: its surround is clearly darker.
    const int ring = static_cast<int>(std::ceil(std::max(bw, bh) / 2.0)) + 2;
    const cv::Rect around = cv::Rect(bx - ring, by - ring, bw + 2 * ring, bh + 2 * ring) & cv::Rect(0, 0, region.cols, region.rows);
    const double ring_mean = (cv::sum(region(around))[0] - cv::sum(region(cv::Rect(bx, by, bw, bh)))[0]) /
                             std::max(1.0, static_cast<double>(around.area() - bw * bh));
    // A glint is a near-saturated peak well above its surround; sensor noise on the bright sclera
    // crosses the threshold too, but neither reaches the frame's brightest level nor stands 50
    // grey levels above its neighbours.
    double peak = 0;
    cv::minMaxLoc(region(cv::Rect(bx, by, bw, bh)), nullptr, &peak);
    if (ring_mean > threshold - 15 || peak < hi - 12 || peak - ring_mean < 50) continue;
    Glint g;
    g.centre = {window.x + sx / sw, window.y + sy / sw};
    g.area_px = area;
    out.glints.push_back(g);
    cv::Mat component = (labels(cv::Rect(bx - box.x, by - box.y, bw, bh)) == i);
    out.mask(cv::Rect(bx, by, bw, bh)).setTo(255, component);
  }
  // Top to bottom, then left to right: an order that does not depend on how the components were
  // labelled (the detector without a pupil reports the first 8 in this order).
  std::sort(out.glints.begin(), out.glints.end(), [](const Glint& a, const Glint& b) {
    return a.centre.y != b.centre.y ? a.centre.y < b.centre.y : a.centre.x < b.centre.x;
  });
  if (!out.glints.empty()) {
    const int grow = std::max(1, static_cast<int>(std::lround(image_size / 160.0)));
    cv::dilate(out.mask, out.mask, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * grow + 1, 2 * grow + 1)));
  }
  return out;
}

}  // namespace fovea::trackerd::eye::stages
