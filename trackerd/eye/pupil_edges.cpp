// SPDX-License-Identifier: Apache-2.0
// The pupil's edge points around a candidate: Starburst rays (Li, Winfield & Parkhurst 2005, §2.3)
// or Canny edges facing away from the centre, glints masked out; then the eyelid margins' straight
// runs removed before the ellipse fit.
#include "eye/detector_stages.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace fovea::trackerd::eye::stages {

// Starburst (Li et al. 2005 §2.3): from a point inside the pupil, walk rays outwards to the first
// dark-to-bright transition; the edge is where the profile crosses halfway between the pupil level
// and the level just outside, interpolated between samples (sub-pixel). With `thin_px` > 0, a rise
// that falls back to the level before it within `thin_px` is a thin bright line -- a lash across the
// pupil, lit by the infrared LEDs -- and is walked over (issue 44).
std::vector<EdgePoint> ray_edges(const cv::Mat& smooth, const cv::Rect& valid, const GlintCandidates& glints,
                                 const cv::Point2d& from, double pupil_level, double min_step, double max_length, int rays,
                                 double thin_px) {
  std::vector<EdgePoint> edges;
  edges.reserve(static_cast<std::size_t>(rays));
  constexpr double ds = 0.5;
  const int steps = static_cast<int>(max_length / ds);
  std::vector<double> profile(static_cast<std::size_t>(steps) + 1);
  std::vector<char> glinty(static_cast<std::size_t>(steps) + 1);
  const double x_lo = valid.x, y_lo = valid.y, x_hi = valid.x + valid.width - 1, y_hi = valid.y + valid.height - 1;
  for (int r = 0; r < rays; ++r) {
    const double th = 2 * kPi * (r + 0.5) / rays;
    const double dx = std::cos(th), dy = std::sin(th);
    // The profile is sampled only as far as the search below looks: most rays stop at the pupil's
    // edge, a fraction of max_length (sampling all of it took a third of the detector's time).
    int n = 0;           // samples taken
    bool ended = false;  // the ray has left `valid` (or reached max_length) after n samples
    const auto have = [&](int k) {  // whether sample k exists, sampling up to it
      while (n <= k && !ended) {
        const double x = from.x + n * ds * dx, y = from.y + n * ds * dy;
        if (n > steps || x < x_lo || y < y_lo || x > x_hi || y > y_hi) {
          ended = true;
          break;
        }
        profile[static_cast<std::size_t>(n)] = bilinear(smooth, x, y);
        glinty[static_cast<std::size_t>(n)] = in_glint(glints, x, y) ? 1 : 0;
        ++n;
      }
      return k < n;
    };
    // The first sharp dark-to-bright step: a rise of min_step within 3 px. A soft veil (a
    // spectacle reflection, uneven light) rises over many pixels and is walked through.
    constexpr int half_span = 3;  // samples: +-1.5 px
    const auto step_at = [&](int i) {
      return profile[static_cast<std::size_t>(i + half_span)] - profile[static_cast<std::size_t>(i - half_span)];
    };
    const int thin = static_cast<int>(std::ceil(thin_px / ds));
    const auto falls_back = [&](int i) {  // within thin_px after the rise, back near the level before it
      const double before = profile[static_cast<std::size_t>(i - half_span)];
      for (int j = i + half_span + 1; j <= i + half_span + thin && have(j); ++j)
        if (profile[static_cast<std::size_t>(j)] < before + 0.5 * min_step) return true;
      return false;
    };
    int cross = -1;
    for (int i = half_span; have(i + half_span); ++i) {
      if (glinty[static_cast<std::size_t>(i)] || glinty[static_cast<std::size_t>(i + half_span)]) continue;
      if (step_at(i) > min_step && profile[static_cast<std::size_t>(i - half_span)] < pupil_level + 2 * min_step + 40) {
        if (thin > 0 && falls_back(i)) {
          i += half_span;  // over the line
          continue;
        }
        cross = i;
        break;
      }
    }
    if (cross < 0) continue;
    for (int i = cross + 1; i <= cross + 2 * half_span && have(i + half_span); ++i)  // the steepest point nearby
      if (step_at(i) > step_at(cross)) cross = i;
    bool contaminated = false;  // a glint straddling the edge moves it: drop the ray
    have(cross + 8);  // every sample the edge's levels below may read
    for (int i = std::max(0, cross - 6); i <= std::min(n - 1, cross + 6); ++i)
      if (glinty[static_cast<std::size_t>(i)]) contaminated = true;
    if (contaminated) continue;
    // Levels either side of the step, and the half-way crossing between them (sub-pixel).
    double inside = 1e9, outside = -1e9;
    for (int i = std::max(0, cross - 8); i <= cross - 2; ++i) inside = std::min(inside, profile[static_cast<std::size_t>(i)]);
    for (int i = cross + 2; i <= std::min(n - 1, cross + 8); ++i) outside = std::max(outside, profile[static_cast<std::size_t>(i)]);
    if (!(outside - inside > min_step)) continue;
    const double half = (inside + outside) / 2;
    int i = std::min(cross + half_span, n - 2);
    while (i > std::max(0, cross - 2 * half_span) && profile[static_cast<std::size_t>(i)] > half) --i;
    const double v0 = profile[static_cast<std::size_t>(i)], v1 = profile[static_cast<std::size_t>(i + 1)];
    if (!(v1 > v0) || v0 > half || v1 < half) continue;
    const double t = (i + (half - v0) / (v1 - v0)) * ds;
    edges.push_back({{from.x + t * dx, from.y + t * dy}, outside - inside});
  }
  return edges;
}

// Canny edges in the window whose gradient points away from the centre (dark inside).
std::vector<EdgePoint> canny_edges(const cv::Mat& smooth, const GlintCandidates& glints, const cv::Point2d& from,
                                   double contrast, double max_length) {
  std::vector<EdgePoint> edges;
  const cv::Rect window = cv::Rect(static_cast<int>(from.x - max_length), static_cast<int>(from.y - max_length),
                                   static_cast<int>(2 * max_length) + 1, static_cast<int>(2 * max_length) + 1) &
                          cv::Rect(0, 0, smooth.cols, smooth.rows);
  if (window.width < 3 || window.height < 3) return edges;
  cv::Mat canny, gx, gy;
  const double high = std::max(20.0, 1.2 * contrast), low = high / 2;
  cv::Canny(smooth(window), canny, low, high, 3, true);
  cv::Sobel(smooth(window), gx, CV_32F, 1, 0);
  cv::Sobel(smooth(window), gy, CV_32F, 0, 1);
  for (int y = 0; y < canny.rows; ++y)
    for (int x = 0; x < canny.cols; ++x) {
      if (!canny.at<std::uint8_t>(y, x)) continue;
      const cv::Point2d p(window.x + x, window.y + y);
      const cv::Point2d d = p - from;
      const double dist = std::hypot(d.x, d.y);
      if (dist < 1 || dist > max_length) continue;
      const double g = std::hypot(static_cast<double>(gx.at<float>(y, x)), static_cast<double>(gy.at<float>(y, x)));
      if (g <= 0) continue;
      const double along = (d.x * static_cast<double>(gx.at<float>(y, x)) + d.y * static_cast<double>(gy.at<float>(y, x))) / (dist * g);
      if (along < 0.7) continue;  // not a dark-inside edge facing the centre
      if (in_glint(glints, p.x, p.y)) continue;
      edges.push_back({p, g / 4});
    }
  if (edges.size() > 400) {  // keep the fit cheap: an even subsample
    std::vector<EdgePoint> kept;
    const double every = static_cast<double>(edges.size()) / 400.0;
    for (double i = 0; i < static_cast<double>(edges.size()); i += every) kept.push_back(edges[static_cast<std::size_t>(i)]);
    edges.swap(kept);
  }
  return edges;
}

// An eyelid crossing the pupil leaves a run of edge points along the lid margin: nearly straight
// across the pupil, where the pupil's own outline is strongly curved. Such runs (a line holding
// many points over a span the pupil's curvature cannot keep straight) are removed before the
// ellipse fit, so RANSAC does not trade arc points for a flattened ellipse through the lid. A run
// that one ellipse through all the points also follows is kept: the flat side of a pupil seen
// far off-axis (minor/major 0.3-0.5) is as straight over as long a span (issue 44).
void remove_eyelid_lines(std::vector<EdgePoint>& edges, double radius, std::mt19937& rng) {
  const double tolerance = std::max(1.2, 0.04 * radius);
  for (int lid = 0; lid < 2 && edges.size() >= 8; ++lid) {
    std::uniform_int_distribution<std::size_t> pick(0, edges.size() - 1);
    std::vector<std::size_t> best;
    for (int it = 0; it < 40; ++it) {
      const cv::Point2d a = edges[pick(rng)].p, b = edges[pick(rng)].p;
      const cv::Point2d d = b - a;
      const double len = std::hypot(d.x, d.y);
      if (len < 0.5 * radius) continue;
      const cv::Point2d u = d * (1.0 / len);
      std::vector<std::size_t> on;
      double lo = 1e300, hi = -1e300;
      for (std::size_t i = 0; i < edges.size(); ++i) {
        const cv::Point2d v = edges[i].p - a;
        if (std::abs(v.x * u.y - v.y * u.x) > tolerance) continue;
        on.push_back(i);
        const double t = v.dot(u);
        lo = std::min(lo, t);
        hi = std::max(hi, t);
      }
      if (hi - lo < 1.3 * radius) continue;
      if (on.size() > best.size()) best.swap(on);
    }
    if (best.size() < std::max<std::size_t>(6, edges.size() / 10)) return;
    if (one_ellipse_explains(edges, best, tolerance)) return;  // an off-axis pupil's flat side
    std::vector<char> drop(edges.size(), 0);
    for (std::size_t i : best) drop[i] = 1;
    std::vector<EdgePoint> kept;
    for (std::size_t i = 0; i < edges.size(); ++i)
      if (!drop[i]) kept.push_back(edges[i]);
    edges.swap(kept);
  }
}

}  // namespace fovea::trackerd::eye::stages
