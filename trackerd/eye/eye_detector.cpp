// SPDX-License-Identifier: Apache-2.0
#include "eye/eye_detector.h"
#include "source_api/grey8.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

namespace fovea::trackerd::eye {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Internally points use OpenCV's pixel convention (pixel centres at integer coordinates); results
// are shifted by half a pixel into Ellipse's convention (pixel i covers [i, i+1)).
constexpr double kToPublic = 0.5;

// Logistic model of P(centre error <= 1 px): bias, support, outline, residual px, aspect, contrast/100.
constexpr std::size_t kCandidates = 8;  // pupil candidates fitted per search
constexpr double kClearPupil = 0.9;     // a fit this confident ends the search

constexpr std::array<double, 6> kConfidenceModel{-21.6006, 15.4716, 4.0722, -12.6362, 18.2015, 2.4973};

double clamp01(double v) { return std::isfinite(v) ? std::clamp(v, 0.0, 1.0) : 0.0; }

bool finite(const cv::Point2d& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

// A general conic a x^2 + b xy + c y^2 + d x + e y + f = 0 in coordinates relative to `origin`,
// scaled by 1/`scale` (keeps the 5x5 solves well conditioned).
struct Conic {
  double a = 0, b = 0, c = 0, d = 0, e = 0, f = -1;
  cv::Point2d origin;
  double scale = 1;

  double value(const cv::Point2d& p) const {
    const double x = (p.x - origin.x) / scale, y = (p.y - origin.y) / scale;
    return a * x * x + b * x * y + c * y * y + d * x + e * y + f;
  }
  // First-order (Sampson) distance to the curve, in pixels.
  double distance(const cv::Point2d& p) const {
    const double x = (p.x - origin.x) / scale, y = (p.y - origin.y) / scale;
    const double q = a * x * x + b * x * y + c * y * y + d * x + e * y + f;
    const double gx = 2 * a * x + b * y + d, gy = b * x + 2 * c * y + e;
    const double g = std::hypot(gx, gy);
    if (g < 1e-12) return 1e9;
    return std::abs(q) / g * scale;
  }
};

// Through five points (relative to origin, f = -1: the origin must be off the curve, which holds
// because the origin is the pupil's estimated centre).
std::optional<Conic> conic_through(const std::array<cv::Point2d, 5>& pts, const cv::Point2d& origin, double scale) {
  double m[5][6];
  for (int i = 0; i < 5; ++i) {
    const double x = (pts[static_cast<std::size_t>(i)].x - origin.x) / scale;
    const double y = (pts[static_cast<std::size_t>(i)].y - origin.y) / scale;
    m[i][0] = x * x; m[i][1] = x * y; m[i][2] = y * y; m[i][3] = x; m[i][4] = y; m[i][5] = 1.0;
  }
  for (int col = 0; col < 5; ++col) {  // Gaussian elimination with partial pivoting
    int pivot = col;
    for (int r = col + 1; r < 5; ++r)
      if (std::abs(m[r][col]) > std::abs(m[pivot][col])) pivot = r;
    if (std::abs(m[pivot][col]) < 1e-12) return std::nullopt;
    if (pivot != col)
      for (int k = 0; k < 6; ++k) std::swap(m[col][k], m[pivot][k]);
    for (int r = 0; r < 5; ++r) {
      if (r == col) continue;
      const double factor = m[r][col] / m[col][col];
      for (int k = col; k < 6; ++k) m[r][k] -= factor * m[col][k];
    }
  }
  Conic conic;
  conic.a = m[0][5] / m[0][0];
  conic.b = m[1][5] / m[1][1];
  conic.c = m[2][5] / m[2][2];
  conic.d = m[3][5] / m[3][3];
  conic.e = m[4][5] / m[4][4];
  conic.f = -1;
  conic.origin = origin;
  conic.scale = scale;
  return conic;
}

// Centre, axes and angle of a conic that is a real ellipse; nullopt otherwise.
std::optional<Ellipse> ellipse_of(Conic q) {
  if (q.a + q.c < 0) {  // the same curve with a positive-definite quadratic part
    q.a = -q.a; q.b = -q.b; q.c = -q.c; q.d = -q.d; q.e = -q.e; q.f = -q.f;
  }
  const double det = 4 * q.a * q.c - q.b * q.b;
  if (!(det > 1e-15)) return std::nullopt;
  const double x0 = (q.b * q.e - 2 * q.c * q.d) / det;
  const double y0 = (q.b * q.d - 2 * q.a * q.e) / det;
  const double f0 = q.a * x0 * x0 + q.b * x0 * y0 + q.c * y0 * y0 + q.d * x0 + q.e * y0 + q.f;
  // Eigenvalues of [[a, b/2], [b/2, c]].
  const double mean = (q.a + q.c) / 2, diff = std::hypot((q.a - q.c) / 2, q.b / 2);
  const double l1 = mean - diff, l2 = mean + diff;  // l1 <= l2: l1 belongs to the major axis
  if (!(l1 > 0) || !(-f0 > 0)) return std::nullopt;
  const double semi_major = std::sqrt(-f0 / l1), semi_minor = std::sqrt(-f0 / l2);
  if (!std::isfinite(semi_major) || !std::isfinite(semi_minor)) return std::nullopt;
  // The major axis is the eigenvector of l1.
  const double angle = 0.5 * std::atan2(q.b, q.a - q.c) + kPi / 2;
  const double angle_deg = std::fmod(angle * 180.0 / kPi + 360.0, 180.0);
  Ellipse e;
  e.centre = {q.origin.x + x0 * q.scale, q.origin.y + y0 * q.scale};
  e.major = 2 * semi_major * q.scale;
  e.minor = 2 * semi_minor * q.scale;
  e.angle_deg = angle_deg;
  if (e.minor > e.major) std::swap(e.minor, e.major);
  return e;
}

Ellipse from_rotated_rect(const cv::RotatedRect& r) {
  Ellipse e;
  e.centre = {static_cast<double>(r.center.x), static_cast<double>(r.center.y)};
  const double w = static_cast<double>(r.size.width), h = static_cast<double>(r.size.height);
  double angle = static_cast<double>(r.angle);
  if (w >= h) {
    e.major = w; e.minor = h;
  } else {
    e.major = h; e.minor = w; angle += 90.0;
  }
  e.angle_deg = std::fmod(std::fmod(angle, 180.0) + 180.0, 180.0);
  return e;
}

// A point on the ellipse at parameter t (internal pixel convention).
cv::Point2d ellipse_point(const Ellipse& e, double t, double scale = 1.0) {
  const double th = e.angle_deg * kPi / 180.0;
  const double ca = std::cos(th), sa = std::sin(th);
  const double x = scale * e.major / 2 * std::cos(t), y = scale * e.minor / 2 * std::sin(t);
  return {e.centre.x + x * ca - y * sa, e.centre.y + x * sa + y * ca};
}

double bilinear(const cv::Mat& img, double x, double y) {
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

// Sum over [x0, x1) x [y0, y1) from an integral image (CV_32S or CV_64F handled as 64F).
double box_sum(const cv::Mat& integral, int x0, int y0, int x1, int y1) {
  return integral.at<double>(y1, x1) - integral.at<double>(y0, x1) - integral.at<double>(y1, x0) +
         integral.at<double>(y0, x0);
}

struct Blob {
  cv::Point2d centre;  // full-resolution internal pixel coordinates
  double radius = 0;   // full-resolution pixels
  double response = 0; // surround mean minus inner mean, grey levels
  double inner = 0, surround = 0;
};

// The best `count` non-overlapping candidates offered so far (greedy non-maximum suppression): a
// candidate overlapping a kept one replaces it only when it scores higher.
struct TopBlobs {
  std::size_t count = 0;
  std::vector<Blob> top;
  std::vector<double> top_score;

  void offer(const Blob& b, double score) {
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

  std::vector<Blob> best_first() const {
    std::vector<std::size_t> order(top.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return top_score[a] > top_score[b]; });
    std::vector<Blob> sorted;
    for (std::size_t i : order) sorted.push_back(top[i]);
    return sorted;
  }
};

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
      for (int x = inner; x + inner < small.cols; x += step) {
        const double inner_sum = box_sum(integral, x - inner, y - inner, x + inner + 1, y + inner + 1);
        const int ox0 = std::max(0, x - outer), oy0 = std::max(0, y - outer);
        const int ox1 = std::min(small.cols, x + outer + 1), oy1 = std::min(small.rows, y + outer + 1);
        const double outer_area = static_cast<double>((ox1 - ox0) * (oy1 - oy0));
        if (outer_area <= inner_area * 1.5) continue;  // no surround left (at the border of a tiny image)
        const double outer_sum = box_sum(integral, ox0, oy0, ox1, oy1);
        const double inner_mean = inner_sum / inner_area;
        const double ring_mean = (outer_sum - inner_sum) / (outer_area - inner_area);
        const double response = ring_mean - inner_mean;
        if (response < 8) continue;
        // Contrast alone prefers the iris (a larger dark disc with a brighter surround); the pupil
        // is also the darkest disc, so its inner level counts against a candidate.
        const double score = response - inner_mean;
        if (top.top.size() == count && score <= *std::min_element(top.top_score.begin(), top.top_score.end())) continue;
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

// A percentile of the pixels in `roi` (8-bit).
double percentile(const cv::Mat& img, double fraction) {
  std::array<int, 256> hist{};
  for (int y = 0; y < img.rows; ++y) {
    const std::uint8_t* row = img.ptr<std::uint8_t>(y);
    for (int x = 0; x < img.cols; ++x) ++hist[row[x]];
  }
  const double total = static_cast<double>(img.total());
  double seen = 0;
  for (int v = 0; v < 256; ++v) {
    seen += hist[static_cast<std::size_t>(v)];
    if (seen >= fraction * total) return v;
  }
  return 255;
}

struct GlintCandidates {
  std::vector<Glint> glints;  // internal pixel convention
  cv::Mat mask;               // glint pixels (dilated), same size as the searched window, 8U
  cv::Rect window;
};

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
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(bright, labels, stats, centroids, 8, CV_32S);
  const double max_radius = std::max(2.0, 0.04 * image_size);
  const double max_area = kPi * max_radius * max_radius;
  for (int i = 1; i < n; ++i) {
    const int area = stats.at<int>(i, cv::CC_STAT_AREA);
    const int bw = stats.at<int>(i, cv::CC_STAT_WIDTH), bh = stats.at<int>(i, cv::CC_STAT_HEIGHT);
    // Single saturated pixels are sensor noise on bright skin; a glint covers a few pixels.
    if (area < (image_size >= 160 ? 3 : 2) || area > max_area || bw > 2 * max_radius + 2 || bh > 2 * max_radius + 2) continue;
    if (std::max(bw, bh) > 3 * std::min(bw, bh) + 2) continue;  // streaks (glasses edges, lashes) are not glints
    // Intensity-weighted centroid over the component's box, above the threshold.
    const int bx = stats.at<int>(i, cv::CC_STAT_LEFT), by = stats.at<int>(i, cv::CC_STAT_TOP);
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
    cv::Mat component = (labels(cv::Rect(bx, by, bw, bh)) == i);
    out.mask(cv::Rect(bx, by, bw, bh)).setTo(255, component);
  }
  if (!out.glints.empty()) {
    const int grow = std::max(1, static_cast<int>(std::lround(image_size / 160.0)));
    cv::dilate(out.mask, out.mask, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * grow + 1, 2 * grow + 1)));
  }
  return out;
}

bool in_glint(const GlintCandidates& g, double x, double y) {
  if (g.glints.empty()) return false;
  const int ix = static_cast<int>(std::lround(x)) - g.window.x, iy = static_cast<int>(std::lround(y)) - g.window.y;
  if (ix < 0 || iy < 0 || ix >= g.mask.cols || iy >= g.mask.rows) return false;
  return g.mask.at<std::uint8_t>(iy, ix) != 0;
}

struct EdgePoint {
  cv::Point2d p;
  double contrast = 0;
};

// Starburst (Li et al. 2005 §2.3): from a point inside the pupil, walk rays outwards to the first
// dark-to-bright transition; the edge is where the profile crosses halfway between the pupil level
// and the level just outside, interpolated between samples (sub-pixel).
std::vector<EdgePoint> ray_edges(const cv::Mat& smooth, const cv::Rect& valid, const GlintCandidates& glints,
                                 const cv::Point2d& from, double pupil_level, double min_step, double max_length, int rays) {
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
    int n = 0;
    for (; n <= steps; ++n) {
      const double x = from.x + n * ds * dx, y = from.y + n * ds * dy;
      if (x < x_lo || y < y_lo || x > x_hi || y > y_hi) break;
      profile[static_cast<std::size_t>(n)] = bilinear(smooth, x, y);
      glinty[static_cast<std::size_t>(n)] = in_glint(glints, x, y) ? 1 : 0;
    }
    // The first sharp dark-to-bright step: a rise of min_step within 3 px. A soft veil (a
    // spectacle reflection, uneven light) rises over many pixels and is walked through.
    constexpr int half_span = 3;  // samples: +-1.5 px
    const auto step_at = [&](int i) {
      return profile[static_cast<std::size_t>(i + half_span)] - profile[static_cast<std::size_t>(i - half_span)];
    };
    int cross = -1;
    for (int i = half_span; i + half_span < n; ++i) {
      if (glinty[static_cast<std::size_t>(i)] || glinty[static_cast<std::size_t>(i + half_span)]) continue;
      if (step_at(i) > min_step && profile[static_cast<std::size_t>(i - half_span)] < pupil_level + 2 * min_step + 40) {
        cross = i;
        break;
      }
    }
    if (cross < 0) continue;
    for (int i = cross + 1; i + half_span < n && i <= cross + 2 * half_span; ++i)  // the steepest point nearby
      if (step_at(i) > step_at(cross)) cross = i;
    bool contaminated = false;  // a glint straddling the edge moves it: drop the ray
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
// ellipse fit, so RANSAC does not trade arc points for a flattened ellipse through the lid.
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
    std::vector<char> drop(edges.size(), 0);
    for (std::size_t i : best) drop[i] = 1;
    std::vector<EdgePoint> kept;
    for (std::size_t i = 0; i < edges.size(); ++i)
      if (!drop[i]) kept.push_back(edges[i]);
    edges.swap(kept);
  }
}

std::optional<Ellipse> fit_direct(const std::vector<cv::Point2d>& pts) {
  if (pts.size() < 5) return std::nullopt;
  std::vector<cv::Point2f> f;
  f.reserve(pts.size());
  for (const auto& p : pts) f.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
  try {
    const cv::RotatedRect r = cv::fitEllipseDirect(f);
    Ellipse e = from_rotated_rect(r);
    if (!finite(e.centre) || !std::isfinite(e.major) || !std::isfinite(e.minor) || e.minor <= 0) return std::nullopt;
    return e;
  } catch (const cv::Exception&) {
    return std::nullopt;
  }
}

// The ellipse's implicit form, to measure point distances.
Conic conic_of(const Ellipse& e) {
  const double th = e.angle_deg * kPi / 180.0;
  const double ca = std::cos(th), sa = std::sin(th);
  const double A = e.major / 2, B = e.minor / 2;
  Conic q;
  q.origin = e.centre;
  q.scale = std::max(1.0, A);
  const double a2 = (A / q.scale) * (A / q.scale), b2 = (B / q.scale) * (B / q.scale);
  q.a = ca * ca / a2 + sa * sa / b2;
  q.b = 2 * ca * sa * (1 / a2 - 1 / b2);
  q.c = sa * sa / a2 + ca * ca / b2;
  q.d = 0; q.e = 0; q.f = -1;
  return q;
}

struct FitResult {
  Ellipse ellipse;
  std::vector<std::size_t> inliers;
  double rms = 0;
};

// The sizes and places a pupil ellipse may have: radius within [rmin, rmax] (with slack for
// foreshortening) and centre near where the search started.
struct PupilBounds {
  cv::Point2d origin;
  double rmin = 0, rmax = 0;

  bool plausible(const Ellipse& e) const {
    return e.major / 2 <= rmax * 1.6 && e.major / 2 >= rmin && e.minor / 2 >= rmin * 0.6 && e.minor / e.major > 0.2 &&
           std::hypot(e.centre.x - origin.x, e.centre.y - origin.y) < rmax * 1.5;
  }
};

// Świrski 2012 §3.3 (Fischler & Bolles 1981): conics through random five-point samples, scored by
// the MSAC cost; returns the inliers of the cheapest plausible ellipse (empty when none).
std::vector<std::size_t> ransac_inliers(const std::vector<cv::Point2d>& pts, const PupilBounds& bounds,
                                        double tolerance, std::mt19937& rng) {
  const std::size_t n = pts.size();
  const cv::Point2d& origin = bounds.origin;
  std::vector<std::size_t> best_inliers;
  double scale = 0;
  for (const auto& p : pts) scale += std::hypot(p.x - origin.x, p.y - origin.y);
  scale = std::max(1.0, scale / static_cast<double>(n));
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  double best_cost = 1e300;
  const int iterations = 60;
  for (int it = 0; it < iterations; ++it) {
    std::array<std::size_t, 5> idx{};
    for (std::size_t k = 0; k < 5; ++k) {
      bool fresh = false;
      while (!fresh) {
        idx[k] = pick(rng);
        fresh = std::find(idx.begin(), idx.begin() + static_cast<std::ptrdiff_t>(k), idx[k]) == idx.begin() + static_cast<std::ptrdiff_t>(k);
      }
    }
    std::array<cv::Point2d, 5> sample;
    for (std::size_t k = 0; k < 5; ++k) sample[k] = pts[idx[k]];
    const auto conic = conic_through(sample, origin, scale);
    if (!conic) continue;
    const auto e = ellipse_of(*conic);
    if (!e || !bounds.plausible(*e)) continue;
    // MSAC cost: inliers cost their squared distance, outliers a constant.
    double cost = 0;
    std::vector<std::size_t> inliers;
    for (std::size_t i = 0; i < n; ++i) {
      const double d = conic->distance(pts[i]);
      if (d < tolerance) {
        cost += d * d;
        inliers.push_back(i);
      } else {
        cost += tolerance * tolerance;
      }
    }
    if (cost < best_cost) {
      best_cost = cost;
      best_inliers.swap(inliers);
      if (best_inliers.size() >= n * 95 / 100) break;
    }
  }
  return best_inliers;
}

// Least-squares refit on the inliers, then (after RANSAC) once more with the points it explains;
// `inliers` ends as the points the returned ellipse was fitted to.
std::optional<Ellipse> refit_on_inliers(const std::vector<cv::Point2d>& pts, FitMethod method, double tolerance,
                                        std::vector<std::size_t>& best_inliers) {
  const std::size_t n = pts.size();
  std::optional<Ellipse> e;
  for (int round = 0; round < (method == FitMethod::Ransac ? 2 : 1); ++round) {
    std::vector<cv::Point2d> in;
    in.reserve(best_inliers.size());
    for (std::size_t i : best_inliers) in.push_back(pts[i]);
    e = fit_direct(in);
    if (!e) return std::nullopt;
    if (method != FitMethod::Ransac) break;
    const Conic q = conic_of(*e);
    std::vector<std::size_t> again;
    for (std::size_t i = 0; i < n; ++i)
      if (q.distance(pts[i]) < tolerance) again.push_back(i);
    if (again.size() < 6) break;
    best_inliers.swap(again);
  }
  return e;
}

std::optional<FitResult> fit_pupil(const std::vector<EdgePoint>& edges, FitMethod method, const cv::Point2d& origin,
                                   double rmin, double rmax, std::mt19937& rng) {
  const std::size_t n = edges.size();
  if (n < 6) return std::nullopt;
  std::vector<cv::Point2d> pts(n);
  for (std::size_t i = 0; i < n; ++i) pts[i] = edges[i].p;
  const PupilBounds bounds{origin, rmin, rmax};
  const double tolerance = std::max(0.8, 0.03 * rmin * 2);
  std::vector<std::size_t> best_inliers;
  if (method == FitMethod::Ransac) {
    best_inliers = ransac_inliers(pts, bounds, tolerance, rng);
    if (best_inliers.size() < 6) return std::nullopt;
  } else {
    best_inliers.resize(n);
    std::iota(best_inliers.begin(), best_inliers.end(), std::size_t{0});
  }
  const std::optional<Ellipse> e = refit_on_inliers(pts, method, tolerance, best_inliers);
  if (!e || !bounds.plausible(*e)) return std::nullopt;
  FitResult result;
  result.ellipse = *e;
  result.inliers = best_inliers;
  const Conic q = conic_of(*e);
  double ss = 0;
  for (std::size_t i : best_inliers) ss += std::pow(q.distance(pts[i]), 2);
  result.rms = std::sqrt(ss / static_cast<double>(std::max<std::size_t>(1, best_inliers.size())));
  return result;
}

// Share of the fitted outline where the inside is clearly darker than the outside (PuRe's outline
// contrast, Santini 2018 §3.4).
double outline_contrast(const cv::Mat& smooth, const cv::Rect& valid, const Ellipse& e, double step_needed) {
  constexpr int samples = 48;
  int good = 0, seen = 0;
  for (int i = 0; i < samples; ++i) {
    const double t = 2 * kPi * i / samples;
    const cv::Point2d a = ellipse_point(e, t, 0.75), b = ellipse_point(e, t, 1.25);
    const auto inside = [&](const cv::Point2d& p) {
      return p.x >= valid.x && p.y >= valid.y && p.x <= valid.x + valid.width - 1 && p.y <= valid.y + valid.height - 1;
    };
    if (!inside(a) || !inside(b)) continue;
    ++seen;
    if (bilinear(smooth, b.x, b.y) - bilinear(smooth, a.x, a.y) > step_needed) ++good;
  }
  return seen ? static_cast<double>(good) / samples : 0.0;
}

// Share of 16 directions around the centre in which some inlier edge point lies.
double arc_coverage(const std::vector<EdgePoint>& edges, const std::vector<std::size_t>& inliers, const cv::Point2d& centre) {
  constexpr int bins = 16;
  std::array<bool, bins> hit{};
  for (std::size_t i : inliers) {
    const double a = std::atan2(edges[i].p.y - centre.y, edges[i].p.x - centre.x);
    const int b = std::clamp(static_cast<int>((a + kPi) / (2 * kPi) * bins), 0, bins - 1);
    hit[static_cast<std::size_t>(b)] = true;
  }
  return static_cast<double>(std::count(hit.begin(), hit.end(), true)) / bins;
}

double outline_inside(const cv::Rect& frame, const Ellipse& e) {
  constexpr int samples = 48;
  int inside = 0;
  for (int i = 0; i < samples; ++i) {
    const cv::Point2d p = ellipse_point(e, 2 * kPi * i / samples);
    if (p.x >= frame.x && p.y >= frame.y && p.x <= frame.x + frame.width - 1 && p.y <= frame.y + frame.height - 1) ++inside;
  }
  return static_cast<double>(inside) / samples;
}

}  // namespace

std::array<double, kConfidenceFeatures> confidence_features(const PupilEvidence& v) {
  const auto bounded = [](double x, double hi) { return std::isfinite(x) ? std::clamp(x, 0.0, hi) : hi; };
  return {1.0, bounded(v.support, 1.0), bounded(v.outline, 1.0), bounded(v.residual_px, 3.0), bounded(v.aspect, 1.0),
          bounded(v.contrast / 100.0, 2.0)};
}

// Calibrated confidence: P(centre error <= 1 px) from a logistic model of the fit's evidence
// (coefficients fitted by `bench_eye --fit-confidence` on generated frames; eye/EYE.md).
double confidence_of(const PupilEvidence& evidence) {
  const auto f = confidence_features(evidence);
  double z = 0;
  for (std::size_t i = 0; i < kConfidenceFeatures; ++i) z += kConfidenceModel[i] * f[i];
  return clamp01(1.0 / (1.0 + std::exp(-z)));
}

void DetectorSettings::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("pupil detector: " + what); };
  if (coarse_downscale != 1 && coarse_downscale != 2 && coarse_downscale != 4)
    fail("coarse_downscale " + std::to_string(coarse_downscale) + ": allowed 1, 2 or 4");
  if (rays < 8 || rays > 1024) fail("rays " + std::to_string(rays) + ": allowed 8..1024");
  if (!(min_pupil_radius > 0 && min_pupil_radius < max_pupil_radius && max_pupil_radius <= 0.5))
    fail("pupil radius range [" + std::to_string(min_pupil_radius) + ", " + std::to_string(max_pupil_radius) +
         "]: need 0 < min < max <= 0.5 (fractions of the image's smaller side)");
  if (!(blink_aspect >= 0 && blink_aspect <= 1)) fail("blink_aspect: allowed 0..1");
  if (!(min_confidence >= 0 && min_confidence <= 1)) fail("min_confidence: allowed 0..1");
  if (leds.positions_mm.size() > 8) fail("at most 8 LEDs");
}

EyeDetector::EyeDetector(DetectorSettings settings) : settings_(std::move(settings)) { settings_.validate(); }

void EyeDetector::reset() {
  last_pupil_.reset();
  last_glint_scale_ = 0;
  last_reference_.reset();
  open_aspect_ = 0;
}

namespace {

// Pairs glints with the LED layout: the glints are a reduced, upright copy of the layout, so a
// scale and translation map LED positions to glint positions (rotation is not modelled).
// Two glints fit several LED pairs exactly (each at its own scale), so among hypotheses matching as
// many glints the one whose scale is nearest the scale seen in earlier frames wins: the glint
// pattern's size changes slowly (with the eye's distance), and without that prior the reference
// point can flip between LED assignments from frame to frame, moving the pupil–glint vector by a
// whole LED spacing.
struct Pairing {
  std::vector<int> led_of;  // per glint
  cv::Point2d reference;    // image of the layout's centroid
  bool valid = false;
  double scale = 0;
  int matches = 0;
};

// The search over placements (scale s, translation t) of the layout onto the glints; keeps the best so far.
struct LayoutSearch {
  const std::vector<Glint>& glints;
  const std::vector<cv::Point2d>& leds;
  cv::Point2d layout_centroid;
  double tolerance = 0;
  double last_scale = 0;
  Pairing best;
  int best_matches = 0;
  double best_cost = 1e300;

  // Each LED takes the nearest unused glint within the tolerance; more matches win, then the lower
  // cost (residual, `extra_cost`, and the scale's distance from the last one).
  void evaluate(double s, const cv::Point2d& t, double extra_cost) {
    const std::size_t m = leds.size(), g = glints.size();
    std::vector<int> led_of(g, -1);
    int matches = 0;
    double residual = 0;
    std::vector<char> used(g, 0);
    for (std::size_t l = 0; l < m; ++l) {
      const cv::Point2d predicted = s * leds[l] + t;
      double nearest = tolerance;
      int which = -1;
      for (std::size_t j = 0; j < g; ++j) {
        if (used[j]) continue;
        const double d = std::hypot(glints[j].centre.x - predicted.x, glints[j].centre.y - predicted.y);
        if (d < nearest) { nearest = d; which = static_cast<int>(j); }
      }
      if (which >= 0) {
        used[static_cast<std::size_t>(which)] = 1;
        led_of[static_cast<std::size_t>(which)] = static_cast<int>(l);
        ++matches;
        residual += nearest;
      }
    }
    // A scale 20 % off the last one costs as much as being 1.5 tolerances off per glint.
    const double cost =
        residual + extra_cost + (last_scale > 0 ? 8 * tolerance * std::abs(std::log(s / last_scale)) : 0.0);
    if (matches > best_matches || (matches == best_matches && cost < best_cost)) {
      best_matches = matches;
      best_cost = cost;
      best.led_of = led_of;
      best.scale = s;
      best.reference = s * layout_centroid + t;
    }
  }
};

// Every ordered glint pair taken as the image of every ordered LED pair fixes a scale and translation.
void place_by_glint_pairs(LayoutSearch& search) {
  const auto& leds = search.leds;
  const auto& glints = search.glints;
  const std::size_t m = leds.size(), g = glints.size();
  for (std::size_t a = 0; a < m; ++a)
    for (std::size_t b = 0; b < m; ++b) {
      if (a == b) continue;
      const cv::Point2d dl = leds[b] - leds[a];
      const double dl2 = dl.dot(dl);
      if (dl2 <= 0) continue;
      for (std::size_t i = 0; i < g; ++i)
        for (std::size_t j = 0; j < g; ++j) {
          if (i == j) continue;
          const cv::Point2d dg = glints[j].centre - glints[i].centre;
          const double s = dg.dot(dl) / dl2;
          if (!(s > 0)) continue;
          const double cross = std::abs(dg.x * dl.y - dg.y * dl.x) / std::sqrt(dl2);
          if (cross > 0.35 * std::hypot(dg.x, dg.y) + search.tolerance) continue;  // rotated by more than ~20 deg
          search.evaluate(s, glints[i].centre - s * leds[a], 0.0);
        }
    }
}

// One glint: place the layout by the scale seen in earlier frames, trying each LED for it; every
// choice fits that glint exactly, so the one keeping the reference nearest the last frame's wins.
void place_by_last_scale(LayoutSearch& search, const std::optional<cv::Point2d>& last_reference) {
  const double last_scale = search.last_scale;
  for (std::size_t a = 0; a < search.leds.size(); ++a)
    for (std::size_t i = 0; i < search.glints.size(); ++i) {
      const cv::Point2d t = search.glints[i].centre - last_scale * search.leds[a];
      const cv::Point2d reference = last_scale * search.layout_centroid + t;
      search.evaluate(last_scale, t,
                      last_reference ? std::hypot(reference.x - last_reference->x, reference.y - last_reference->y)
                                     : 0.0);
    }
}

Pairing pair_with_layout(const std::vector<Glint>& glints, const LedLayout& layout, double tolerance,
                         double last_scale, const std::optional<cv::Point2d>& last_reference) {
  LayoutSearch search{glints, layout.positions_mm, {}, tolerance, last_scale, {}};
  Pairing& best = search.best;
  best.led_of.assign(glints.size(), -1);
  const auto& leds = layout.positions_mm;
  const std::size_t m = leds.size(), g = glints.size();
  if (m == 0 || g == 0) return best;
  cv::Point2d layout_centroid;
  for (const auto& l : leds) layout_centroid += l;
  layout_centroid *= 1.0 / static_cast<double>(m);
  search.layout_centroid = layout_centroid;
  if (m >= 2) place_by_glint_pairs(search);
  if (search.best_matches < 2 && last_scale > 0) place_by_last_scale(search, last_reference);
  if (m == 1 && g >= 1) {
    best.led_of.assign(g, -1);
    best.led_of[0] = 0;  // the caller sorted glints nearest the pupil first
    best.reference = glints[0].centre - 0.0 * leds[0];
    best.valid = true;
    return best;
  }
  best.valid = search.best_matches >= 2 || (search.best_matches == 1 && last_scale > 0);
  best.matches = search.best_matches;
  return best;
}

// What every pupil search in one frame shares: the frame, its scale, the detector's reused buffers
// and the random stream.
struct FrameSearch {
  const DetectorSettings& settings;
  const cv::Mat& grey;
  cv::Mat& smooth;         // reused: the blurred work windows
  cv::Mat& small;          // reused: the downscaled search window
  cv::Mat& integral;       // reused: its integral image
  double size = 0;         // the image's smaller side, px
  double rmin = 0, rmax = 0;  // pupil radius range, px
  cv::Rect frame;
  std::vector<EyeDetector::CandidateFit>* candidates = nullptr;  // every fitted candidate, when asked for
  std::mt19937 rng{12345};  // deterministic RANSAC: the same frame gives the same answer
};

// One search's outcome: the best pupil fit (or why there is none) and the glints of the window.
struct PupilAttempt {
  bool ok = false;
  Ellipse ellipse;
  double confidence = 0;
  PupilEvidence evidence;
  std::string why;
  GlintCandidates glints;
};

// One candidate blob's grey levels and the blurred window its edge search reads.
struct CandidateWindow {
  double pupil_level = 0;  // grey level inside the pupil
  double contrast = 0;     // surround minus pupil level
  double reach = 0;        // px: how far rays walk
  cv::Rect work;
};

// The pupil's grey level: a low percentile of the blob's inner box (robust to glints in it).
// False (with `a.why`) when the blob has no inside or no contrast.
bool measure_pupil_level(const FrameSearch& search, const Blob& blob, CandidateWindow& w, PupilAttempt& a) {
  const double r0 = blob.radius;
  const cv::Rect inner_box =
      cv::Rect(static_cast<int>(blob.centre.x - 0.7 * r0), static_cast<int>(blob.centre.y - 0.7 * r0),
               std::max(1, static_cast<int>(1.4 * r0)), std::max(1, static_cast<int>(1.4 * r0))) &
      search.frame;
  if (inner_box.area() < 1) {
    a.why = "no dark blob";
    return false;
  }
  w.pupil_level = percentile(search.grey(inner_box), 0.3);
  w.contrast = blob.surround - w.pupil_level;
  if (w.contrast < 10) {
    a.why = "no contrast around the dark blob";
    return false;
  }
  return true;
}

// Blurs only the part of the frame the edge search around this blob can reach.
void blur_work_window(FrameSearch& search, const Blob& blob, CandidateWindow& w) {
  w.reach = std::max(1.2 * search.rmax, 8.0);  // rays stop at the first edge: reaching far is cheap
  const double margin = 1.5 * w.reach + 3;  // the second Starburst round may start from a moved centre
  w.work = cv::Rect(static_cast<int>(blob.centre.x - margin), static_cast<int>(blob.centre.y - margin),
                    static_cast<int>(2 * margin) + 1, static_cast<int>(2 * margin) + 1) & search.frame;
  if (search.smooth.size() != search.grey.size()) search.smooth.create(search.grey.size(), CV_8U);
  cv::GaussianBlur(search.grey(w.work), search.smooth(w.work), cv::Size(3, 3), 0.8);
}

struct StarburstFit {
  std::optional<FitResult> fit;
  std::vector<EdgePoint> edges;  // of the last round
};

// Starburst (Li et al. 2005 §2.3): edge points around the blob, eyelid runs removed, the ellipse
// fitted; with rays, a second round from the fitted centre.
StarburstFit starburst_fit(FrameSearch& search, const Blob& blob, const GlintCandidates& glints,
                           const CandidateWindow& w) {
  const DetectorSettings& settings = search.settings;
  const cv::Mat& smooth = search.smooth;
  const double min_step = std::max(6.0, 0.3 * w.contrast);
  cv::Point2d from = blob.centre;
  StarburstFit out;
  for (int round = 0; round < 2; ++round) {
    out.edges = settings.edges == EdgeMethod::Rays
                    ? ray_edges(smooth, w.work, glints, from, w.pupil_level, min_step, w.reach, settings.rays)
                    : canny_edges(smooth, glints, from, w.contrast, std::max(3.0 * blob.radius, 8.0));
    remove_eyelid_lines(out.edges, blob.radius, search.rng);
    out.fit = fit_pupil(out.edges, settings.fit, from, search.rmin, search.rmax, search.rng);
    if (!out.fit) break;
    const cv::Point2d moved = out.fit->ellipse.centre - from;
    // Starburst iterates from the new centre: rays from near the true centre sample the outline evenly.
    if (std::hypot(moved.x, moved.y) < 0.5 || settings.edges != EdgeMethod::Rays) break;
    if (!out.fit->ellipse.centre.inside(cv::Rect2d(w.work.x, w.work.y, w.work.width - 1, w.work.height - 1))) break;
    if (bilinear(smooth, out.fit->ellipse.centre.x, out.fit->ellipse.centre.y) > w.pupil_level + min_step) break;
    from = out.fit->ellipse.centre;
  }
  return out;
}

// PuRe-style evidence (Santini 2018 §3.4) and the calibrated confidence of a fitted ellipse.
void score_fit(const FrameSearch& search, const CandidateWindow& w, const StarburstFit& sb, PupilAttempt& a) {
  const FitResult& fit = *sb.fit;
  const Ellipse& e = fit.ellipse;
  const double support = search.settings.edges == EdgeMethod::Rays
                             ? static_cast<double>(fit.inliers.size()) / search.settings.rays
                             : std::min(1.0, static_cast<double>(fit.inliers.size()) /
                                                 std::max(1.0, kPi * (e.major + e.minor) / 2));
  const double outline = outline_contrast(search.smooth, w.work, e, 0.3 * w.contrast);
  a.evidence = {support, outline, fit.rms, w.contrast, e.aspect()};
  // The calibration frames never cut the pupil at the image border; a pupil mostly outside the
  // frame is scaled down by the share of its outline that is inside.
  // Likewise an arc covering less than half the outline barely constrains the centre.
  a.confidence = confidence_of(a.evidence) * outline_inside(search.frame, e) *
                 std::min(1.0, 2.0 * arc_coverage(sb.edges, fit.inliers, e.centre));
  a.ellipse = e;
  a.ok = a.confidence >= search.settings.min_confidence;
  if (!a.ok) a.why = "pupil candidate below the confidence threshold";
}

// Fits the pupil around one candidate blob.
PupilAttempt fit_candidate(FrameSearch& search, const Blob& blob, const GlintCandidates& glints) {
  PupilAttempt a;
  CandidateWindow w;
  if (!measure_pupil_level(search, blob, w, a)) return a;
  blur_work_window(search, blob, w);
  const StarburstFit sb = starburst_fit(search, blob, glints, w);
  if (!sb.fit) {
    a.why = sb.edges.size() < 6 ? "too few edge points" : "no ellipse fits the edge points";
    return a;
  }
  score_fit(search, w, sb, a);
  return a;
}

// Candidates in the window, best blob response first; the most confident fit wins (a clear
// pupil ends the search early).
PupilAttempt search_window(FrameSearch& search, const cv::Rect& window) {
  PupilAttempt best;
  best.glints = find_glints(search.grey, window, search.size);
  const auto blobs = find_dark_blobs(search.grey, window, search.settings.coarse_downscale, search.rmin, search.rmax,
                                     kCandidates, search.small, search.integral);
  best.why = "no dark blob";
  for (const Blob& blob : blobs) {
    PupilAttempt a = fit_candidate(search, blob, best.glints);
    if (search.candidates && a.confidence > 0)
      search.candidates->push_back({Ellipse{a.ellipse.centre + cv::Point2d(kToPublic, kToPublic), a.ellipse.major,
                                            a.ellipse.minor, a.ellipse.angle_deg},
                                    a.evidence, a.confidence});
    if (a.confidence > best.confidence || (best.confidence == 0 && best.why == "no dark blob")) {
      a.glints = std::move(best.glints);
      best = std::move(a);
    }
    if (best.confidence >= kClearPupil) break;
  }
  return best;
}

// Searches near the last pupil first (`used_roi` tells whether that found it); recovery: the whole frame.
PupilAttempt find_pupil(FrameSearch& search, bool roi_tracking, const std::optional<Ellipse>& last_pupil,
                        bool& used_roi) {
  PupilAttempt found;
  if (roi_tracking && last_pupil) {
    const double half = 1.2 * last_pupil->major + 0.08 * search.size;
    const cv::Rect roi =
        cv::Rect(static_cast<int>(last_pupil->centre.x - half), static_cast<int>(last_pupil->centre.y - half),
                 static_cast<int>(2 * half), static_cast<int>(2 * half)) &
        search.frame;
    if (roi.width >= 8 && roi.height >= 8) {
      found = search_window(search, roi);
      used_roi = found.ok;
    }
  }
  if (!found.ok) found = search_window(search, search.frame);
  return found;
}

// Lee 2009 §3.5.2: minor/major below 0.7 is a blink. Lee's camera faced the eye; an eye camera
// below the eye sees an open eye looking up at about 0.7 already, so the threshold applies
// relative to this eye's recent open aspect (1 until one is known), learnt from clear open pupils.
void report_pupil(const PupilAttempt& found, double blink_aspect, double& open_aspect, EyeMeasurement& result) {
  result.pupil_found = found.ok;
  result.evidence = found.evidence;
  result.why = found.ok ? std::string() : found.why;
  if (found.ok) {
    result.pupil = found.ellipse;
    result.confidence = found.confidence;
    const double reference = open_aspect > 0 ? open_aspect : 1.0;
    result.blink = found.ellipse.aspect() < blink_aspect * reference;
    if (!result.blink && found.confidence >= kClearPupil)
      open_aspect = open_aspect > 0 ? 0.95 * open_aspect + 0.05 * found.ellipse.aspect() : found.ellipse.aspect();
  } else {
    result.blink = true;  // no pupil: the eye is closed or the pupil is hidden
  }
}

// Glints on the cornea: near the pupil (within about the iris), nearest first; at most 8.
std::vector<Glint> corneal_glints(const PupilAttempt& found, double size) {
  std::vector<Glint> glints = found.glints.glints;
  if (found.ok) {
    const double reach = std::max(3.5 * found.ellipse.major / 2, 0.12 * size);
    const cv::Point2d c = found.ellipse.centre;
    glints.erase(std::remove_if(glints.begin(), glints.end(),
                                [&](const Glint& g) { return std::hypot(g.centre.x - c.x, g.centre.y - c.y) > reach; }),
                 glints.end());
    std::sort(glints.begin(), glints.end(), [&](const Glint& a, const Glint& b) {
      return std::hypot(a.centre.x - c.x, a.centre.y - c.y) < std::hypot(b.centre.x - c.x, b.centre.y - c.y);
    });
  }
  if (glints.size() > 8) glints.resize(8);
  return glints;
}

// The glint point the pupil–glint vector is measured from.
struct GlintReference {
  cv::Point2d point;
  bool valid = false;
};

// With an LED layout: the image of the layout's centroid from the pairing (which also labels each
// glint with its LED and teaches the scale prior); without one: the glints' centroid.
GlintReference glint_reference(std::vector<Glint>& glints, const LedLayout& leds, double size, double& last_glint_scale,
                               std::optional<cv::Point2d>& last_reference) {
  GlintReference reference;
  if (!leds.positions_mm.empty() && !glints.empty()) {
    const double tolerance = std::max(1.5, 0.012 * size);
    const Pairing pairing = pair_with_layout(glints, leds, tolerance, last_glint_scale, last_reference);
    for (std::size_t i = 0; i < glints.size(); ++i) glints[i].led = pairing.led_of[i];
    if (pairing.valid) {
      reference.point = pairing.reference;
      reference.valid = true;
      last_reference = pairing.reference;
      // The scale prior learns from unambiguous pairings (three or more glints), or from two when
      // it has nothing yet or they agree with it.
      const bool learn = pairing.matches >= 3 ||
                         (pairing.matches == 2 && (last_glint_scale <= 0 ||
                                                   std::abs(std::log(pairing.scale / last_glint_scale)) < 0.2));
      if (pairing.scale > 0 && leds.positions_mm.size() >= 2 && learn) {
        last_glint_scale = last_glint_scale > 0 ? 0.8 * last_glint_scale + 0.2 * pairing.scale : pairing.scale;
      }
    }
  } else if (!glints.empty()) {
    for (const auto& g : glints) reference.point += g.centre;
    reference.point *= 1.0 / static_cast<double>(glints.size());
    reference.valid = true;
  }
  return reference;
}

// Glints and pupil move into Ellipse's pixel convention; the pupil–glint vector is a difference of
// internal positions (only for an open eye).
void report_glints(std::vector<Glint>& glints, const GlintReference& reference, const PupilAttempt& found,
                   EyeMeasurement& result) {
  for (auto& g : glints) g.centre += cv::Point2d(kToPublic, kToPublic);
  result.glints = glints;
  if (found.ok) {
    result.pupil.centre += cv::Point2d(kToPublic, kToPublic);
    if (reference.valid && !result.blink) {
      result.pupil_glint = found.ellipse.centre - reference.point;
      result.pupil_glint_valid = finite(result.pupil_glint);
    }
  }
}

bool finite_measurement(const EyeMeasurement& result) {
  return finite(result.pupil.centre) && std::isfinite(result.pupil.major) && std::isfinite(result.pupil.minor) &&
         std::isfinite(result.pupil.angle_deg) && std::isfinite(result.confidence);
}

// A measurement without a pupil (the eye counts as closed) saying why.
EyeMeasurement no_pupil(std::string why) {
  EyeMeasurement result;
  result.why = std::move(why);
  result.blink = true;
  return result;
}

}  // namespace

EyeMeasurement EyeDetector::detect(const cv::Mat& image, std::vector<CandidateFit>* candidates) {
  EyeMeasurement result;
  try {
    grey_ = to_grey8(image);
    if (grey_.empty()) return no_pupil("empty or unsupported image");
    const double size = std::min(grey_.cols, grey_.rows);
    if (size < 12)
      return no_pupil("image too small (" + std::to_string(grey_.cols) + "x" + std::to_string(grey_.rows) + ")");
    const double rmin = std::max(2.0, settings_.min_pupil_radius * size);
    const double rmax = std::max(rmin * 1.5, settings_.max_pupil_radius * size);
    const cv::Rect frame(0, 0, grey_.cols, grey_.rows);
    FrameSearch search{settings_, grey_, smooth_, small_, integral_, size, rmin, rmax, frame, candidates};

    const PupilAttempt found = find_pupil(search, settings_.roi_tracking, last_pupil_, result.used_roi);
    if (found.ok) {
      last_pupil_ = found.ellipse;
    } else {
      last_pupil_.reset();
    }
    report_pupil(found, settings_.blink_aspect, open_aspect_, result);

    std::vector<Glint> glints = corneal_glints(found, size);
    const GlintReference reference = glint_reference(glints, settings_.leds, size, last_glint_scale_, last_reference_);
    report_glints(glints, reference, found, result);
    if (!finite_measurement(result)) {
      result = no_pupil("numerical failure");
      last_pupil_.reset();
    }
  } catch (const std::exception& e) {
    result = no_pupil(std::string("detector error: ") + e.what());
    last_pupil_.reset();
  }
  return result;
}

EyeMeasurement detect_pupil_baseline(const cv::Mat& image) {
  EyeMeasurement result;
  result.blink = true;
  try {
    const cv::Mat grey = to_grey8(image);
    if (grey.empty() || std::min(grey.cols, grey.rows) < 12) {
      result.why = "image too small";
      return result;
    }
    cv::Mat blurred;
    cv::GaussianBlur(grey, blurred, cv::Size(5, 5), 0);
    double lo = 0, hi = 0;
    cv::minMaxLoc(blurred, &lo, &hi);
    const double median = percentile(blurred, 0.5);
    cv::Mat dark;
    cv::threshold(blurred, dark, lo + 0.3 * (median - lo), 255, cv::THRESH_BINARY_INV);
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(dark, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
    const std::vector<cv::Point>* largest = nullptr;
    double largest_area = 0;
    for (const auto& c : contours) {
      const double area = cv::contourArea(c);
      if (area > largest_area) { largest_area = area; largest = &c; }
    }
    if (!largest || largest->size() < 5 || median - lo < 10) {
      result.why = "no dark contour";
      return result;
    }
    const Ellipse e = from_rotated_rect(cv::fitEllipse(*largest));
    if (!finite(e.centre) || !(e.major > 0) || !(e.minor > 0)) {
      result.why = "ellipse fit failed";
      return result;
    }
    const double fill = largest_area / (kPi * e.major * e.minor / 4);
    result.pupil_found = true;
    result.pupil = e;
    result.pupil.centre += cv::Point2d(kToPublic, kToPublic);
    result.confidence = clamp01(fill);
    result.blink = e.aspect() < 0.7;
  } catch (const std::exception& ex) {
    result = EyeMeasurement{};
    result.blink = true;
    result.why = std::string("detector error: ") + ex.what();
  }
  return result;
}

}  // namespace fovea::trackerd::eye
