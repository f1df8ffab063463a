// SPDX-License-Identifier: Apache-2.0
// Pupil candidates from edges (issue 44), after PuRe (Santini, Fuhl & Kasneci 2018, §3.2-3.3): the
// pupil's outline is a strongly curved edge with darker inside all round, whether or not the pupil
// is the darkest thing in the frame (a spectacle reflection's veil lifts it; lashes and shadows can
// be darker). Canny edges of the downscaled search window, split into curves; a curve whose
// least-squares ellipse fits it, is pupil-sized and covers a wide enough arc, with the inside
// darker than the outside along most of the ellipse, is a candidate.
#include "eye/detector_stages.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace fovea::trackerd::eye::stages {

namespace {

// Canny's thresholds from the window's own gradients: the strong edges are the top 10 % (at least
// 20 grey levels per pixel), so a veiled, low-contrast frame still has edges.
void window_edges(const cv::Mat& img, cv::Mat& edges) {
  cv::Mat dx, dy, fx, fy, mag;
  cv::Sobel(img, dx, CV_16S, 1, 0, 3);
  cv::Sobel(img, dy, CV_16S, 0, 1, 3);
  dx.convertTo(fx, CV_32F);
  dy.convertTo(fy, CV_32F);
  cv::magnitude(fx, fy, mag);
  std::vector<float> m(mag.begin<float>(), mag.end<float>());
  const auto q = m.begin() + static_cast<std::ptrdiff_t>(0.9 * static_cast<double>(m.size()));
  std::nth_element(m.begin(), q, m.end());
  const double high = std::max(20.0, static_cast<double>(*q));
  cv::Canny(dx, dy, edges, 0.4 * high, high, true);
}

// The share of 32 directions around `e` (small-image coordinates) where the image just inside the
// outline is darker than just outside by `step`, and the mean levels inside and outside.
struct Outline {
  double darker = 0, inside = 0, outside = 0;
};
Outline outline_levels(const cv::Mat& img, const cv::RotatedRect& e, double step) {
  const double a = static_cast<double>(e.size.width) / 2, b = static_cast<double>(e.size.height) / 2;
  const double t = static_cast<double>(e.angle) * kPi / 180;
  const double cx = static_cast<double>(e.center.x), cy = static_cast<double>(e.center.y);
  const double ct = std::cos(t), st = std::sin(t);
  Outline o;
  int n = 0, dark = 0;
  for (int i = 0; i < 32; ++i) {
    const double phi = 2 * kPi * i / 32;
    const double ex = a * std::cos(phi), ey = b * std::sin(phi);
    const auto at = [&](double s) {
      return bilinear(img, cx + s * (ex * ct - ey * st), cy + s * (ex * st + ey * ct));
    };
    const double in = at(0.8), out = at(1.25);
    o.inside += in;
    o.outside += out;
    dark += out - in > step ? 1 : 0;
    ++n;
  }
  o.darker = static_cast<double>(dark) / n;
  o.inside /= n;
  o.outside /= n;
  return o;
}

// RMS distance of the curve's points from the ellipse (approximated along the radius through
// each point): a pupil's outline follows its ellipse to a pixel; a cluster of lashes or an iris
// texture's edges, to which an ellipse is fitted just as well, do not.
double curve_residual(const std::vector<cv::Point>& curve, const cv::RotatedRect& e) {
  const double a = static_cast<double>(e.size.width) / 2, b = static_cast<double>(e.size.height) / 2;
  const double t = static_cast<double>(e.angle) * kPi / 180, ct = std::cos(t), st = std::sin(t);
  double sum = 0;
  for (const cv::Point& p : curve) {
    const double dx = p.x - static_cast<double>(e.center.x), dy = p.y - static_cast<double>(e.center.y);
    const double u = (dx * ct + dy * st) / a, v = (-dx * st + dy * ct) / b;
    const double rho = std::hypot(u, v), d = (rho - 1) * std::hypot(dx, dy) / std::max(rho, 1e-9);
    sum += d * d;
  }
  return std::sqrt(sum / static_cast<double>(curve.size()));
}

}  // namespace

std::vector<Blob> find_edge_candidates(const cv::Mat& small, const cv::Rect& window, double rmin, double rmax,
                                       std::size_t count) {
  std::vector<Blob> out;
  if (small.cols < 8 || small.rows < 8) return out;
  const double sx = static_cast<double>(window.width) / small.cols, sy = static_cast<double>(window.height) / small.rows;
  const double k = (sx + sy) / 2;
  cv::Mat blurred, edges;
  cv::GaussianBlur(small, blurred, cv::Size(3, 3), 0.8);
  window_edges(blurred, edges);
  std::vector<std::vector<cv::Point>> curves;
  cv::findContours(edges, curves, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
  const double rmin_s = rmin / k, rmax_s = rmax / k;
  std::vector<std::pair<double, Blob>> scored;
  for (const auto& c : curves) {
    if (c.size() < 12 || static_cast<double>(c.size()) < 1.5 * rmin_s) continue;
    const cv::Rect box = cv::boundingRect(c);
    if (std::max(box.width, box.height) < rmin_s || std::max(box.width, box.height) > 2.2 * rmax_s) continue;
    const cv::RotatedRect e = cv::fitEllipseDirect(c);
    const double minor = static_cast<double>(std::min(e.size.width, e.size.height)) / 2;
    const double major = static_cast<double>(std::max(e.size.width, e.size.height)) / 2;
    if (!(minor >= rmin_s && major <= rmax_s && minor >= 0.3 * major)) continue;  // also NaN (degenerate curves)
    if (!std::isfinite(e.center.x) || !std::isfinite(e.center.y)) continue;
    // The curve covers a wide arc of its ellipse (a lash or a lid margin is a flat piece of one).
    if (std::max(box.width, box.height) < 1.2 * minor) continue;
    const double residual = curve_residual(c, e);
    if (residual > std::max(1.5, 0.12 * minor)) continue;
    const Outline o = outline_levels(blurred, e, 3.0);
    if (o.darker < 0.75 || o.outside - o.inside < 8) continue;
    Blob b;
    b.centre = {window.x + (static_cast<double>(e.center.x) + 0.5) * sx - 0.5,
                window.y + (static_cast<double>(e.center.y) + 0.5) * sy - 0.5};
    b.radius = minor * k;
    b.inner = o.inside;
    b.surround = o.outside;
    b.response = o.outside - o.inside;
    scored.emplace_back(o.darker * b.response / (1 + residual), b);
  }
  std::sort(scored.begin(), scored.end(), [](const auto& x, const auto& y) { return x.first > y.first; });
  for (const auto& [score, b] : scored) {
    const bool near_kept = std::any_of(out.begin(), out.end(), [&](const Blob& kept) {
      return std::hypot(kept.centre.x - b.centre.x, kept.centre.y - b.centre.y) < 0.5 * std::max(kept.radius, b.radius);
    });
    if (!near_kept) out.push_back(b);
    if (out.size() >= count) break;
  }
  return out;
}

}  // namespace fovea::trackerd::eye::stages
