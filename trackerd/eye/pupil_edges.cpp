// SPDX-License-Identifier: Apache-2.0
// The pupil's edge points around a candidate: Starburst rays (Li, Winfield & Parkhurst 2005, §2.3)
// or Canny edges facing away from the centre, glints masked out; then the eyelid margins' straight
// runs removed before the ellipse fit.
#include "eye/detector_stages.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace fovea::trackerd::eye::stages {

// bilinear()'s path on and beyond the image's last row and column, out of line (rare).
double bilinear_clamped(const cv::Mat& img, double x, double y) {
  const int w = img.cols, h = img.rows;
  x = std::clamp(x, 0.0, static_cast<double>(w - 1));
  y = std::clamp(y, 0.0, static_cast<double>(h - 1));
  const int x0 = std::min(static_cast<int>(x), w - 2 < 0 ? 0 : w - 2);
  const int y0 = std::min(static_cast<int>(y), h - 2 < 0 ? 0 : h - 2);
  const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
  const double fx = x - x0, fy = y - y0;
  const double v00 = img.at<std::uint8_t>(y0, x0), v01 = img.at<std::uint8_t>(y0, x1);
  const double v10 = img.at<std::uint8_t>(y1, x0), v11 = img.at<std::uint8_t>(y1, x1);
  return (v00 * (1 - fx) + v01 * fx) * (1 - fy) + (v10 * (1 - fx) + v11 * fx) * fy;
}

namespace {

constexpr double kRayStepPx = 0.5;  // the profile's sample spacing along a ray
constexpr int kHalfSpan = 3;        // samples: a step is a rise within +-1.5 px

// The grey levels along one ray, sampled only as far as the search reads: most rays stop at the
// pupil's edge, a fraction of their reach (sampling all of it took a third of the detector's time).
class RayProfile {
 public:
  RayProfile(const cv::Mat& smooth, const cv::Rect& valid, const GlintCandidates& glints, int steps)
      : smooth_(smooth), glints_(glints), steps_(steps), level_(static_cast<std::size_t>(steps) + 1),
        glinty_(static_cast<std::size_t>(steps) + 1), x_lo_(valid.x), y_lo_(valid.y),
        x_hi_(valid.x + valid.width - 1), y_hi_(valid.y + valid.height - 1) {}
  void start(const cv::Point2d& from, double dx, double dy) {
    from_ = from;
    dx_ = dx;
    dy_ = dy;
    n_ = 0;
    ended_ = false;
  }
  // Whether sample k exists (the ray has not left `valid` nor its reach by then), sampling up to it.
  bool has(int k) { return k < n_ || (!ended_ && extend(k)); }
  int taken() const { return n_; }  // samples taken so far
  double at(int i) const { return level_[static_cast<std::size_t>(i)]; }
  bool glint(int i) const { return glinty_[static_cast<std::size_t>(i)] != 0; }
  double step_at(int i) const { return at(i + kHalfSpan) - at(i - kHalfSpan); }

 private:
  // Samples up to k, and a few beyond (most calls ask for one more sample: a batch keeps the loop's
  // state in registers rather than reloading it for each; the extra samples of a ray that stops
  // are a tenth of its samples or less).
  bool extend(int k) {
    constexpr int kBatch = 8;
    const int until = std::max(k, n_ + kBatch - 1);
    const double hx = kRayStepPx * dx_, hy = kRayStepPx * dy_;  // x = from + n * (step dx): exact, as (n step) dx
    const bool any_glint = !glints_.glints.empty();
    double* level = level_.data();
    char* glinty = glinty_.data();
    int n = n_;
    for (; n <= until; ++n) {
      const double x = from_.x + n * hx, y = from_.y + n * hy;
      if (n > steps_ || x < x_lo_ || y < y_lo_ || x > x_hi_ || y > y_hi_) {
        ended_ = true;
        break;
      }
      level[n] = bilinear(smooth_, x, y);
      glinty[n] = any_glint && in_glint(glints_, x, y) ? 1 : 0;
    }
    n_ = n;
    return k < n_;
  }

  const cv::Mat& smooth_;
  const GlintCandidates& glints_;
  int steps_;
  std::vector<double> level_;
  std::vector<char> glinty_;
  double x_lo_, y_lo_, x_hi_, y_hi_;
  cv::Point2d from_;
  double dx_ = 0, dy_ = 0;
  int n_ = 0;
  bool ended_ = false;
};

// The first sharp dark-to-bright step from a dark level: a rise of min_step within 3 px (a soft
// veil -- a spectacle reflection, uneven light -- rises over many pixels and is walked through),
// moved to the steepest point nearby; -1 when none. With thin > 0 samples, a rise that falls back to
// the level before it within them is a thin bright line -- a lash across the pupil, lit by the
// infrared LEDs -- and is walked over (issue 44).
int first_step(RayProfile& ray, double pupil_level, double min_step, int thin) {
  const auto falls_back = [&](int i) {
    const double before = ray.at(i - kHalfSpan);
    for (int j = i + kHalfSpan + 1; j <= i + kHalfSpan + thin && ray.has(j); ++j)
      if (ray.at(j) < before + 0.5 * min_step) return true;
    return false;
  };
  int cross = -1;
  for (int i = kHalfSpan; ray.has(i + kHalfSpan); ++i) {
    if (ray.glint(i) || ray.glint(i + kHalfSpan)) continue;
    if (ray.step_at(i) > min_step && ray.at(i - kHalfSpan) < pupil_level + 2 * min_step + 40) {
      if (thin > 0 && falls_back(i)) {
        i += kHalfSpan;  // over the line
        continue;
      }
      cross = i;
      break;
    }
  }
  if (cross < 0) return -1;
  for (int i = cross + 1; i <= cross + 2 * kHalfSpan && ray.has(i + kHalfSpan); ++i)
    if (ray.step_at(i) > ray.step_at(cross)) cross = i;
  return cross;
}

// The edge at a step: where the profile crosses half-way between the levels either side of it,
// interpolated between samples (sub-pixel), in samples from the ray's start, and the step's
// contrast; nullopt when a glint straddles it (it would move the edge) or the levels do not differ.
std::optional<std::pair<double, double>> edge_at(RayProfile& ray, int cross, double min_step) {
  ray.has(cross + 8);  // every sample read below
  const int n = ray.taken();
  for (int i = std::max(0, cross - 6); i <= std::min(n - 1, cross + 6); ++i)
    if (ray.glint(i)) return std::nullopt;
  double inside = 1e9, outside = -1e9;
  for (int i = std::max(0, cross - 8); i <= cross - 2; ++i) inside = std::min(inside, ray.at(i));
  for (int i = cross + 2; i <= std::min(n - 1, cross + 8); ++i) outside = std::max(outside, ray.at(i));
  if (!(outside - inside > min_step)) return std::nullopt;
  const double half = (inside + outside) / 2;
  int i = std::min(cross + kHalfSpan, n - 2);
  while (i > std::max(0, cross - 2 * kHalfSpan) && ray.at(i) > half) --i;
  const double v0 = ray.at(i), v1 = ray.at(i + 1);
  if (!(v1 > v0) || v0 > half || v1 < half) return std::nullopt;
  return std::make_pair(i + (half - v0) / (v1 - v0), outside - inside);
}

}  // namespace

// Starburst (Li et al. 2005 §2.3): from a point inside the pupil, walk rays outwards to the first
// dark-to-bright transition; the edge is where the profile crosses halfway between the pupil level
// and the level just outside, interpolated between samples (sub-pixel). With `thin_px` > 0, thin
// bright lines across the pupil (lit lashes) are walked over (first_step).
std::vector<EdgePoint> ray_edges(const cv::Mat& smooth, const cv::Rect& valid, const GlintCandidates& glints,
                                 const cv::Point2d& from, double pupil_level, double min_step, double max_length, int rays,
                                 double thin_px) {
  std::vector<EdgePoint> edges;
  edges.reserve(static_cast<std::size_t>(rays));
  RayProfile ray(smooth, valid, glints, static_cast<int>(max_length / kRayStepPx));
  const int thin = static_cast<int>(std::ceil(thin_px / kRayStepPx));
  for (int r = 0; r < rays; ++r) {
    const double th = 2 * kPi * (r + 0.5) / rays;
    const double dx = std::cos(th), dy = std::sin(th);
    ray.start(from, dx, dy);
    const int cross = first_step(ray, pupil_level, min_step, thin);
    if (cross < 0) continue;
    const auto edge = edge_at(ray, cross, min_step);
    if (!edge) continue;
    const double t = edge->first * kRayStepPx;
    edges.push_back({{from.x + t * dx, from.y + t * dy}, edge->second});
  }
  return edges;
}

// Each ray's strongest step within the band, when it rises by min_step: lit lashes inside the
// outline and the lid or iris beyond it rise less or lie outside the band.
std::vector<EdgePoint> band_edges(const cv::Mat& smooth, const cv::Rect& valid, const GlintCandidates& glints,
                                  const Ellipse& around, double inner, double outer, double min_step, int rays) {
  std::vector<EdgePoint> edges;
  edges.reserve(static_cast<std::size_t>(rays));
  const double a = around.major / 2, b = around.minor / 2;
  if (!(b > 0)) return edges;
  const double th0 = around.angle_deg * kPi / 180.0;
  RayProfile ray(smooth, valid, glints, static_cast<int>(outer * a / kRayStepPx) + 2 * kHalfSpan + 8);
  for (int r = 0; r < rays; ++r) {
    const double th = 2 * kPi * (r + 0.5) / rays;
    const double dx = std::cos(th), dy = std::sin(th);
    // The ellipse's distance from its centre in this direction.
    const double u = std::cos(th - th0) / a, v = std::sin(th - th0) / b;
    const double rho = 1 / std::sqrt(u * u + v * v);
    const int first = std::max(kHalfSpan, static_cast<int>(inner * rho / kRayStepPx));
    const int last = static_cast<int>(outer * rho / kRayStepPx);
    ray.start(around.centre, dx, dy);
    int cross = -1;
    for (int i = first; i <= last && ray.has(i + kHalfSpan); ++i) {
      if (ray.glint(i) || ray.glint(i + kHalfSpan)) continue;
      if (ray.step_at(i) > min_step && (cross < 0 || ray.step_at(i) > ray.step_at(cross))) cross = i;
    }
    if (cross < 0) continue;
    const auto edge = edge_at(ray, cross, min_step);
    if (!edge) continue;
    const double t = edge->first * kRayStepPx;
    edges.push_back({{around.centre.x + t * dx, around.centre.y + t * dy}, edge->second});
  }
  return edges;
}

// Canny edges in the window whose gradient points away from the centre (dark inside). Canny and
// Sobel read a pixel or two beyond the window they are given, so it keeps 2 px inside `valid`: the
// buffer beyond holds other windows' blur, or nothing yet.
std::vector<EdgePoint> canny_edges(const cv::Mat& smooth, const cv::Rect& valid, const GlintCandidates& glints,
                                   const cv::Point2d& from, double contrast, double max_length) {
  std::vector<EdgePoint> edges;
  const cv::Rect inner(valid.x + 2, valid.y + 2, std::max(0, valid.width - 4), std::max(0, valid.height - 4));
  const cv::Rect window = cv::Rect(static_cast<int>(from.x - max_length), static_cast<int>(from.y - max_length),
                                   static_cast<int>(2 * max_length) + 1, static_cast<int>(2 * max_length) + 1) &
                          inner & cv::Rect(0, 0, smooth.cols, smooth.rows);
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
    std::vector<std::size_t> best, on;
    for (int it = 0; it < 40; ++it) {
      const cv::Point2d a = edges[pick(rng)].p, b = edges[pick(rng)].p;
      const cv::Point2d d = b - a;
      const double len = norm2(d.x, d.y);
      if (len < 0.5 * radius) continue;
      const cv::Point2d u = d * (1.0 / len);
      on.clear();
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
