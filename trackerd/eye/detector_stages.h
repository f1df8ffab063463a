// SPDX-License-Identifier: Apache-2.0
#pragma once
// The pupil/glint detector's stages (eye/eye_detector.h), shared by their files and by
// eye_detector.cpp, which runs them; eye/EYE.md ("Detector") describes them in the order they run:
//   glint_candidates.cpp   bright, round, saturated blobs, and the mask that keeps them out of the edge search
//   pupil_candidates.cpp   dark centre-surround blobs on an integral image (Świrski 2012 §3.1)
//   pupil_edge_candidates.cpp  curved edges with darker inside (PuRe, Santini 2018 §3.2-3.3)
//   pupil_contour_candidates.cpp  circles the mean level rises fastest across (Daugman 2004 §2)
//   pupil_edges.cpp        edge points (Starburst rays or Canny), eyelid runs removed
//   pupil_ellipse_fit.cpp  RANSAC ellipse fit and least-squares refit (Świrski 2012 §3.3)
//   pupil_confidence.cpp   the fit's evidence and the calibrated confidence (PuRe, Santini 2018 §3.4)
//   glint_pairing.cpp      glints paired with the LED layout, and the pupil–glint reference point
// Points here use OpenCV's pixel convention (pixel centres at integer coordinates);
// eye_detector.cpp moves results into Ellipse's.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

#include "eye/eye_detector.h"

namespace fovea::trackerd::eye::stages {

inline constexpr double kPi = 3.14159265358979323846;

inline double clamp01(double v) { return std::isfinite(v) ? std::clamp(v, 0.0, 1.0) : 0.0; }

inline bool finite(const cv::Point2d& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

// sqrt(x^2 + y^2) where the squares can neither overflow nor vanish (pixel-scale values, a conic's
// coefficients in its scaled frame, whose pivots are >= 1e-12): std::hypot guards against that at
// many times the cost, and the fits call it a few hundred times a candidate.
inline double norm2(double x, double y) { return std::sqrt(x * x + y * y); }

// bilinear() where (x, y) is known to lie in [0, cols - 1) x [0, rows - 1): read through row
// pointers, without clamps.
[[gnu::always_inline]] inline double bilinear_inside(const cv::Mat& img, double x, double y) {
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double fx = x - x0, fy = y - y0;
  const std::uint8_t* r0 = img.ptr<std::uint8_t>(y0) + x0;
  const std::uint8_t* r1 = r0 + img.step[0];
  const double v00 = r0[0], v01 = r0[1], v10 = r1[0], v11 = r1[1];
  return (v00 * (1 - fx) + v01 * fx) * (1 - fy) + (v10 * (1 - fx) + v11 * fx) * fy;
}

// bilinear() on and beyond the image's last row and column (and outside it): clamped to its edge.
[[gnu::noinline]] double bilinear_clamped(const cv::Mat& img, double x, double y);

// Grey levels of an 8-bit image; clamped to its edge on and beyond its last row and column. The
// stages read thousands of samples a candidate, nearly all inside: those take the inlined path
// (out of line, the call was an eighth of the detector's time under lashes over a dark iris).
[[gnu::always_inline]] inline double bilinear(const cv::Mat& img, double x, double y) {
  if (x >= 0 && y >= 0 && x < img.cols - 1 && y < img.rows - 1) return bilinear_inside(img, x, y);
  return bilinear_clamped(img, x, y);
}

// A percentile of the pixels in `roi` (8-bit).
inline double percentile(const cv::Mat& img, double fraction) {
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

// --- glint_candidates.cpp

struct GlintCandidates {
  std::vector<Glint> glints;  // internal pixel convention
  cv::Mat mask;               // glint pixels (dilated), same size as the searched window, 8U
  cv::Rect window;
};

GlintCandidates find_glints(const cv::Mat& grey, const cv::Rect& window, double image_size);

// Whether (x, y) is a glint pixel (of the dilated mask).
inline bool in_glint(const GlintCandidates& g, double x, double y) {
  if (g.glints.empty()) return false;
  // Rounds half away from zero as std::lround does, without its call (read at every ray sample).
  const auto round = [](double v) { return static_cast<int>(v >= 0 ? v + 0.5 : v - 0.5); };
  const int ix = round(x) - g.window.x, iy = round(y) - g.window.y;
  if (ix < 0 || iy < 0 || ix >= g.mask.cols || iy >= g.mask.rows) return false;
  return g.mask.at<std::uint8_t>(iy, ix) != 0;
}

// --- pupil_candidates.cpp

struct Blob {
  cv::Point2d centre;  // full-resolution internal pixel coordinates
  double radius = 0;   // full-resolution pixels
  double response = 0; // surround mean minus inner mean, grey levels
  double inner = 0, surround = 0;
  // From the contour integral (find_contour_candidates): the radius is the outline's, and rays look
  // for the strongest rise near it rather than the first.
  bool on_contour = false;
};

// The best `count` dark blobs in `window`, best first (`small` and `integral` are reused buffers).
std::vector<Blob> find_dark_blobs(const cv::Mat& grey, const cv::Rect& window, int downscale, double rmin, double rmax,
                                  std::size_t count, cv::Mat& small, cv::Mat& integral);

// --- pupil_edge_candidates.cpp

// Up to `count` pupil candidates from curved edges with darker inside (PuRe-style, Santini 2018
// §3.2-3.3), best first, on `small`: the search window (`window`, full resolution) downscaled as
// find_dark_blobs left it. For frames where the pupil is not the darkest blob.
std::vector<Blob> find_edge_candidates(const cv::Mat& small, const cv::Rect& window, double rmin, double rmax,
                                       std::size_t count);

// --- pupil_contour_candidates.cpp

// Up to `count` pupil candidates in `window` of `grey`: the circles, centred within `reach` px of
// `around`, with radii in [rmin, rmax] px, across which the mean level rises fastest, the two sectors
// of eight that rise most left out (Daugman 2004 §2, eq. 1), best first. For a pupil barely darker
// than the iris it is inside, with lashes across it (the search inside a fitted candidate).
std::vector<Blob> find_contour_candidates(const cv::Mat& grey, const cv::Rect& window, const cv::Point2d& around,
                                          double reach, double rmin, double rmax, std::size_t count);
// The ellipse near `start` (internal pixel convention) across which the contour integral of `img`
// rises most, read `across` px either side of the outline, sectors trimmed as above: the outline of
// a fit on edge points that lashes and a weak edge scatter, moved onto the edge the whole outline shares.
Ellipse refine_on_contour(const cv::Mat& img, const Ellipse& start, double across);

// --- pupil_edges.cpp

struct EdgePoint {
  cv::Point2d p;
  double contrast = 0;
};

// Starburst rays from `from` inside the pupil to the first sharp dark-to-bright step; with
// `thin_px` > 0, not one that falls back within `thin_px` (a lash).
std::vector<EdgePoint> ray_edges(const cv::Mat& smooth, const cv::Rect& valid, const GlintCandidates& glints,
                                 const cv::Point2d& from, double pupil_level, double min_step, double max_length,
                                 int rays, double thin_px);
// Rays from the centre of `around` to the strongest dark-to-bright step between `inner` and `outer`
// times its outline's distance in each direction: the outline of a pupil whose shape is known
// roughly (a contour candidate, a fit refined on the contour integral), lashes inside it passed over.
std::vector<EdgePoint> band_edges(const cv::Mat& smooth, const cv::Rect& valid, const GlintCandidates& glints,
                                  const Ellipse& around, double inner, double outer, double min_step, int rays);
// Canny edges around `from` whose gradient points away from it (dark inside), within `valid` (the
// part of `smooth` that is blurred).
std::vector<EdgePoint> canny_edges(const cv::Mat& smooth, const cv::Rect& valid, const GlintCandidates& glints,
                                   const cv::Point2d& from, double contrast, double max_length);
// Removes up to two straight runs of edge points (the lid margins) across a pupil of `radius`.
void remove_eyelid_lines(std::vector<EdgePoint>& edges, double radius, std::mt19937& rng);

// --- pupil_ellipse_fit.cpp

struct FitResult {
  Ellipse ellipse;
  std::vector<std::size_t> inliers;
  double rms = 0;
};

// The pupil ellipse through the edge points (RANSAC, then a least-squares refit on the inliers),
// with a radius in [rmin, rmax] px near `origin`; nullopt when none is plausible.
std::optional<FitResult> fit_pupil(const std::vector<EdgePoint>& edges, FitMethod method, const cv::Point2d& origin,
                                   double rmin, double rmax, std::mt19937& rng);
Ellipse from_rotated_rect(const cv::RotatedRect& r);
// Whether the ellipse fitted (least squares) to the points outside `run` passes within `tolerance`
// px of nine in ten of them and of nine in ten of the points of `run`: a straight run that is the
// flat side of a strongly elliptical pupil, not a lid margin (a lid cuts the pupil's outline short,
// so the rest of the outline continues beyond it).
bool one_ellipse_explains(const std::vector<EdgePoint>& edges, const std::vector<std::size_t>& run, double tolerance);
// A point on the ellipse at parameter t (internal pixel convention).
cv::Point2d ellipse_point(const Ellipse& e, double t, double scale = 1.0);

// --- pupil_confidence.cpp

// Share of the fitted outline where the inside is clearly darker than the outside.
double outline_contrast(const cv::Mat& smooth, const cv::Rect& valid, const Ellipse& e, double step_needed);
// Share of 16 directions around the centre in which some inlier edge point lies.
double arc_coverage(const std::vector<EdgePoint>& edges, const std::vector<std::size_t>& inliers,
                    const cv::Point2d& centre);
// Share of the ellipse's outline inside `frame`.
double outline_inside(const cv::Rect& frame, const Ellipse& e);

// --- glint_pairing.cpp

// The glint point the pupil–glint vector is measured from.
struct GlintReference {
  cv::Point2d point;
  bool valid = false;
};

// The reference point of the glints (labelling each with its LED when there is a layout); updates
// the scale and reference priors kept between frames.
GlintReference glint_reference(std::vector<Glint>& glints, const LedLayout& leds, double size, double& last_glint_scale,
                               std::optional<cv::Point2d>& last_reference);

}  // namespace fovea::trackerd::eye::stages
