// SPDX-License-Identifier: Apache-2.0
// Pupil candidates: the strongest dark-centre / bright-surround box responses on an integral image
// of the (downscaled) search window, non-overlapping, best first (Świrski, Bulling & Dodgson 2012, §3.1).
#include "eye/detector_stages.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numeric>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace fovea::trackerd::eye::stages {

namespace {

// The best `count` non-overlapping candidates offered so far (greedy non-maximum suppression): a
// candidate overlapping a kept one replaces it only when it scores higher.
struct TopBlobs {
  std::size_t count = 0;
  std::vector<Blob> top;
  std::vector<double> top_score;
  double floor_ = 0;
  bool floor_valid = false;

  void offer(const Blob& b, double score) {
    floor_valid = false;
    std::size_t worst = 0;
    bool overlapped = false;
    for (std::size_t i = 0; i < top.size(); ++i) {
      if (std::hypot(top[i].centre.x - b.centre.x, top[i].centre.y - b.centre.y) < std::max(top[i].radius, b.radius)) {
        if (top_score[i] >= score) return;
        overlapped = true;
        top[i] = b;
        top_score[i] = score;
        // Drop any other candidate the new one now covers and beats.
        for (std::size_t j = top.size(); j-- > 0;) {
          if (j == i) continue;
          if (std::hypot(top[j].centre.x - b.centre.x, top[j].centre.y - b.centre.y) < std::max(top[j].radius, b.radius) &&
              top_score[j] < score) {
            top.erase(top.begin() + static_cast<std::ptrdiff_t>(j));
            top_score.erase(top_score.begin() + static_cast<std::ptrdiff_t>(j));
            if (j < i) --i;
          }
        }
        return;
      }
      if (top_score[i] < top_score[worst]) worst = i;
    }
    if (overlapped) return;
    if (top.size() < count) {
      top.push_back(b);
      top_score.push_back(score);
    } else if (score > top_score[worst]) {
      top[worst] = b;
      top_score[worst] = score;
    }
  }

  // The score a new candidate must beat to be kept (-inf while fewer than `count` are kept);
  // cached, as the scan asks for it at every position that passes the contrast test.
  double floor() {
    if (top.size() < count) return -std::numeric_limits<double>::infinity();
    if (!floor_valid) {
      floor_ = *std::min_element(top_score.begin(), top_score.end());
      floor_valid = true;
    }
    return floor_;
  }

  std::vector<Blob> best_first() const {
    std::vector<std::size_t> order(top.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return top_score[a] > top_score[b]; });
    std::vector<Blob> sorted;
    for (std::size_t i : order) sorted.push_back(top[i]);
    return sorted;
  }
};

}  // namespace

// Świrski 2012 §3.1: pupil candidates as the strongest dark-centre / bright-surround box responses
// over positions and radii. Keeps the best `count` candidates that do not overlap (greedy
// non-maximum suppression), best first: the fit decides among them.
std::vector<Blob> find_dark_blobs(const cv::Mat& grey, const cv::Rect& window, int downscale, double rmin, double rmax,
                                  std::size_t count, cv::Mat& small, cv::Mat& integral) {
  const cv::Mat region = grey(window);
  if (downscale > 1 && region.cols >= 2 * downscale && region.rows >= 2 * downscale) {
    cv::resize(region, small, cv::Size(region.cols / downscale, region.rows / downscale), 0, 0, cv::INTER_AREA);
  } else {
    small = region;
  }
  cv::integral(small, integral, CV_64F);
  const double sx = static_cast<double>(region.cols) / small.cols, sy = static_cast<double>(region.rows) / small.rows;
  const double k = (sx + sy) / 2;
  TopBlobs top;
  top.count = count;
  for (double r_full = rmin; r_full <= rmax * 1.0001; r_full *= 1.3) {
    const int inner = std::max(1, static_cast<int>(std::lround(0.8 * r_full / k)));  // half-size of the inner box
    const int outer = std::max(inner + 1, static_cast<int>(std::lround(1.8 * r_full / k)));
    if (2 * inner + 1 > small.cols || 2 * inner + 1 > small.rows) break;
    const int step = std::max(1, inner / 3);
    const double inner_area = std::pow(2.0 * inner + 1, 2);
    for (int y = inner; y + inner < small.rows; y += step) {
      // Row pointers into the integral image (the loop reads four corners of two boxes a position).
      const double* in_top = integral.ptr<double>(y - inner);
      const double* in_bottom = integral.ptr<double>(y + inner + 1);
      const int oy0 = std::max(0, y - outer), oy1 = std::min(small.rows, y + outer + 1);
      const double* out_top = integral.ptr<double>(oy0);
      const double* out_bottom = integral.ptr<double>(oy1);
      for (int x = inner; x + inner < small.cols; x += step) {
        const double inner_sum = in_bottom[x + inner + 1] - in_top[x + inner + 1] - in_bottom[x - inner] + in_top[x - inner];
        const int ox0 = std::max(0, x - outer), ox1 = std::min(small.cols, x + outer + 1);
        const double outer_area = static_cast<double>((ox1 - ox0) * (oy1 - oy0));
        if (outer_area <= inner_area * 1.5) continue;  // no surround left (at the border of a tiny image)
        const double outer_sum = out_bottom[ox1] - out_top[ox1] - out_bottom[ox0] + out_top[ox0];
        const double inner_mean = inner_sum / inner_area;
        const double ring_mean = (outer_sum - inner_sum) / (outer_area - inner_area);
        const double response = ring_mean - inner_mean;
        if (response < 8) continue;
        // Contrast alone prefers the iris (a larger dark disc with a brighter surround); the pupil
        // is also the darkest disc, so its inner level counts against a candidate.
        const double score = response - inner_mean;
        if (score <= top.floor()) continue;
        Blob b;
        b.centre = {window.x + (x + 0.5) * sx - 0.5, window.y + (y + 0.5) * sy - 0.5};
        b.radius = r_full;
        b.response = response;
        b.inner = inner_mean;
        b.surround = ring_mean;
        top.offer(b, score);
      }
    }
  }
  return top.best_first();
}

}  // namespace fovea::trackerd::eye::stages
