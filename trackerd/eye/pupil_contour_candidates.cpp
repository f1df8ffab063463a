// SPDX-License-Identifier: Apache-2.0
// The contour integral inside a fitted candidate (issue 44; EYE.md step 6b): pupil candidates, and
// the refinement of fits whose edge points lashes scattered. After Daugman's integro-differential
// operator (Daugman 2004, "How iris recognition works", IEEE TCSVT 14(1), §2, eq. 1):
//   max over (r, x0, y0) of | G_sigma(r) * d/dr  (1 / 2 pi r) \oint_{r, x0, y0} I(x, y) ds |,
// the circle across which the mean grey level rises fastest. A pupil barely darker than a dark iris,
// under lit lashes that split its outline into short arcs, has no edge a ray can follow, yet the
// mean over its whole outline still rises across it: a lash crosses the circle at a point or two.
// Daugman leaves out the arcs where eyelids lie; here the circle is cut into eight sectors and, at
// each radius, the two that rise most are left out, whichever side the lid (or a lash bundle, or a
// glint) is on: the camera may see the eye upside down or sideways. The refinement does the same
// over ellipses near a fit (Hooke & Jeeves' pattern search on centre, axes and angle).
#include "eye/detector_stages.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace fovea::trackerd::eye::stages {

namespace {

constexpr int kSectors = 8;
constexpr int kPerSector = 6;  // samples per sector on each circle
constexpr int kDropped = 2;    // sectors left out: those that rise most (a lid's margin, a lash bundle, a glint)

// The mean of the sector rises but the kDropped highest.
double trimmed(std::array<double, kSectors>& rise) {
  std::sort(rise.begin(), rise.end());
  double kept = 0;
  for (std::size_t s = 0; s < kSectors - kDropped; ++s) kept += rise[s];
  return kept / (kSectors - kDropped);
}

constexpr double kWorkRadius = 24.0;   // px: the search area is scaled so its half-width is about this

// Integer offsets of the circle's samples, sector by sector, for every radius searched.
struct Rings {
  std::vector<int> radii;                                    // work px
  std::vector<std::array<cv::Point, kSectors * kPerSector>> offsets;  // one ring per radius
};

Rings make_rings(int rmin, int rmax) {
  Rings rings;
  for (int r = rmin; r <= rmax; ++r) {
    std::array<cv::Point, kSectors * kPerSector> ring;
    for (int i = 0; i < kSectors * kPerSector; ++i) {
      const double th = 2 * kPi * (i + 0.5) / (kSectors * kPerSector);
      ring[static_cast<std::size_t>(i)] = {static_cast<int>(std::lround(r * std::cos(th))),
                                           static_cast<int>(std::lround(r * std::sin(th)))};
    }
    rings.radii.push_back(r);
    rings.offsets.push_back(ring);
  }
  return rings;
}

// The operator at one centre: the best radius index and its trimmed rise (grey levels per work px).
struct Rise {
  double rise = -1e300;
  int radius = 0;
};

Rise best_rise(const cv::Mat& img, cv::Point c, const Rings& rings) {
  const std::size_t n = rings.radii.size();
  // Mean level per sector on every ring.
  std::vector<std::array<double, kSectors>> mean(n);
  for (std::size_t k = 0; k < n; ++k)
    for (int s = 0; s < kSectors; ++s) {
      int sum = 0;
      for (int i = 0; i < kPerSector; ++i) {
        const cv::Point p = c + rings.offsets[k][static_cast<std::size_t>(s * kPerSector + i)];
        sum += img.at<std::uint8_t>(p.y, p.x);
      }
      mean[k][static_cast<std::size_t>(s)] = static_cast<double>(sum) / kPerSector;
    }
  Rise best;
  // d/dr by central differences over two rings (G_sigma: the window is blurred already), sectors trimmed.
  for (std::size_t k = 1; k + 1 < n; ++k) {
    std::array<double, kSectors> d{};
    for (std::size_t s = 0; s < kSectors; ++s) d[s] = (mean[k + 1][s] - mean[k - 1][s]) / 2;
    const double kept = trimmed(d);
    if (kept > best.rise) best = {kept, static_cast<int>(k)};
  }
  return best;
}

// The median grey level on the circle of radius r around c (full resolution): the surround the
// pupil's level is measured against (measure_pupil_level), robust to the lid and lashes on part of it.
double ring_median(const cv::Mat& grey, const cv::Point2d& c, double r) {
  std::array<double, 32> v{};
  for (std::size_t i = 0; i < v.size(); ++i) {
    const double th = 2 * kPi * (static_cast<double>(i) + 0.5) / static_cast<double>(v.size());
    v[i] = bilinear(grey, c.x + r * std::cos(th), c.y + r * std::sin(th));
  }
  std::nth_element(v.begin(), v.begin() + 16, v.end());
  return v[16];
}

}  // namespace

std::vector<Blob> find_contour_candidates(const cv::Mat& grey, const cv::Rect& window, const cv::Point2d& around,
                                          double reach, double rmin, double rmax, std::size_t count) {
  std::vector<Blob> out;
  if (!(reach > 0) || !(rmax > rmin) || rmin <= 0) return out;
  // Work at a scale where the centres searched span about +-kWorkRadius px.
  const double scale = std::min(1.0, kWorkRadius / reach);
  cv::Mat work;
  cv::resize(grey(window), work, cv::Size(), scale, scale, cv::INTER_AREA);
  const int r0 = std::max(2, static_cast<int>(std::floor(rmin * scale)) - 1);
  const int r1 = static_cast<int>(std::ceil(rmax * scale)) + 1;
  const Rings rings = make_rings(r0, r1);
  if (rings.radii.size() < 3) return out;
  const cv::Point2d centre = (around - cv::Point2d(window.x, window.y)) * scale;
  const int half = static_cast<int>(std::ceil(reach * scale));
  struct Found {
    Rise rise;
    cv::Point at;
  };
  std::vector<Found> found;
  for (int y = static_cast<int>(centre.y) - half; y <= static_cast<int>(centre.y) + half; ++y)
    for (int x = static_cast<int>(centre.x) - half; x <= static_cast<int>(centre.x) + half; ++x) {
      // Every ring inside the window: a circle cut by the window's edge says nothing there.
      if (x - r1 - 1 < 0 || y - r1 - 1 < 0 || x + r1 + 1 >= work.cols || y + r1 + 1 >= work.rows) continue;
      const double dx = x - centre.x, dy = y - centre.y;
      if (dx * dx + dy * dy > static_cast<double>(half) * half) continue;
      const Rise r = best_rise(work, {x, y}, rings);
      if (r.rise > 0) found.push_back({r, {x, y}});
    }
  std::sort(found.begin(), found.end(), [](const Found& a, const Found& b) { return a.rise.rise > b.rise.rise; });
  // The best `count`, each at least a radius from those kept before it.
  for (const Found& f : found) {
    if (out.size() >= count) break;
    const double r = rings.radii[static_cast<std::size_t>(f.rise.radius)] / scale;
    const cv::Point2d c(window.x + (f.at.x + 0.5) / scale - 0.5, window.y + (f.at.y + 0.5) / scale - 0.5);
    const bool near_kept = std::any_of(out.begin(), out.end(), [&](const Blob& b) {
      return std::hypot(b.centre.x - c.x, b.centre.y - c.y) < std::max(b.radius, r);
    });
    if (near_kept) continue;
    Blob b;
    b.centre = c;
    b.radius = r;
    b.response = f.rise.rise * scale;
    b.surround = ring_median(grey, c, 1.3 * r);
    b.inner = ring_median(grey, c, 0.5 * r);
    b.on_contour = true;
    out.push_back(b);
  }
  return out;
}

namespace {

constexpr int kRefineSamples = 64;  // 8 per sector
constexpr int kMaxMoves = 200;      // pattern-search sweeps that moved (a few dozen in practice)

// The unit circle at the refinement's sample angles, t_i = 2 pi (i + 1/2) / kRefineSamples.
struct UnitCircle {
  std::array<double, kRefineSamples> cos{}, sin{};
  UnitCircle() {
    for (int i = 0; i < kRefineSamples; ++i) {
      const double t = 2 * kPi * (i + 0.5) / kRefineSamples;
      cos[static_cast<std::size_t>(i)] = std::cos(t);
      sin[static_cast<std::size_t>(i)] = std::sin(t);
    }
  }
};
const UnitCircle kUnit;

// The contour integral's rise across an ellipse: per sector, the mean of I(p + across n) -
// I(p - across n) over its samples (n the outward normal), the sectors that rise most left out.
double contour_rise(const cv::Mat& img, const Ellipse& e, double across) {
  const double th = e.angle_deg * kPi / 180.0;
  const double ca = std::cos(th), sa = std::sin(th);
  const double a = e.major / 2, b = e.minor / 2;
  if (!(a > 0) || !(b > 0)) return -1e300;
  std::array<double, kSectors> sector{};
  for (std::size_t i = 0; i < kRefineSamples; ++i) {
    const double ct = kUnit.cos[i], st = kUnit.sin[i];
    const double px = a * ct, py = b * st;
    double nx = b * ct, ny = a * st;  // the outward normal, in the ellipse's frame
    const double len = std::sqrt(nx * nx + ny * ny);  // a, b > 0: never 0, no overflow at pixel scale
    nx /= len;
    ny /= len;
    const cv::Point2d p(e.centre.x + px * ca - py * sa, e.centre.y + px * sa + py * ca);
    const cv::Point2d n(nx * ca - ny * sa, nx * sa + ny * ca);
    const cv::Point2d out(p.x + across * n.x, p.y + across * n.y), in(p.x - across * n.x, p.y - across * n.y);
    sector[i * kSectors / kRefineSamples] += bilinear(img, out.x, out.y) - bilinear(img, in.x, in.y);
  }
  return trimmed(sector) / (kRefineSamples / kSectors);
}

}  // namespace

Ellipse refine_on_contour(const cv::Mat& img, const Ellipse& start, double across) {
  // Pattern search over centre, axes and angle (Hooke & Jeeves 1961), kept near the start: the
  // refinement moves the outline onto the edge, it does not look for another one.
  Ellipse best = start;
  double value = contour_rise(img, best, across);
  double step = 0.5;  // px; the angle turns by 20 step / (major - minor) degrees, moving the outline ~step / 6
  const auto allowed = [&](const Ellipse& e) {
    const double dx = e.centre.x - start.centre.x, dy = e.centre.y - start.centre.y, reach = 0.25 * start.minor + 1;
    return dx * dx + dy * dy <= reach * reach &&
           e.minor >= 0.7 * start.minor && e.major <= 1.4 * start.major && e.minor >= 0.3 * e.major &&
           e.minor <= e.major && e.minor > 2;
  };
  // Each move must raise the rise; the count bounds the search on any image all the same. Once a
  // step forward along an axis raised it, the step back would return to a lower value: not tried.
  for (int moves = 0; step >= 0.06 && moves < kMaxMoves;) {
    bool moved = false;
    for (int k = 0; k < 5; ++k)
      for (const double sign : {1.0, -1.0}) {
        Ellipse e = best;
        const double d = sign * step;
        switch (k) {
          case 0: e.centre.x += d; break;
          case 1: e.centre.y += d; break;
          case 2: e.major += 2 * d; break;
          case 3: e.minor += 2 * d; break;
          default: e.angle_deg += 10 * d * 2 / std::max(1.0, e.major - e.minor); break;
        }
        if (!allowed(e)) continue;
        const double v = contour_rise(img, e, across);
        if (v > value) {
          value = v;
          best = e;
          moved = true;
          break;
        }
      }
    if (moved) ++moves;
    else step /= 2;
  }
  best.angle_deg = std::fmod(std::fmod(best.angle_deg, 180.0) + 180.0, 180.0);
  return best;
}

}  // namespace fovea::trackerd::eye::stages
