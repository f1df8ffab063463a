// SPDX-License-Identifier: Apache-2.0
// EyeDetector: the search that runs the stages (detector_stages.h) over a frame (the ROI first, then
// the whole frame; candidates until a clear pupil), the blink rule, the glints reported with the
// pupil–glint vector, and the baseline detector.
#include "eye/eye_detector.h"
#include "source_api/grey8.h"
#include "eye/detector_stages.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <span>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

namespace fovea::trackerd::eye {

using namespace stages;  // the detector's stages (detector_stages.h)

namespace {

// Internally points use OpenCV's pixel convention (pixel centres at integer coordinates); results
// are shifted by half a pixel into Ellipse's convention (pixel i covers [i, i+1)).
constexpr double kToPublic = 0.5;

constexpr std::size_t kCandidates = 8;  // pupil candidates fitted per search
constexpr std::size_t kEdgeCandidates = 4;  // and from edges, when none of those is a clear pupil
constexpr std::size_t kContourCandidates = 2;  // and inside a winner, from the contour integral
constexpr double kScatteredEdges = 0.7;  // inside a winner, a fit fewer rays than this share support is refined
constexpr double kClearPupil = 0.9;     // a fit this confident ends the search
constexpr double kTrackedPupil = 0.5;   // inside (track_inside), so does a fit this confident where the last was
constexpr double kDiscInside = 0.1;     // a fit inside the winner this confident, and darker inside
constexpr double kDiscOutline = 0.9;    // along this share of its outline, makes the winner doubtful
constexpr double kInsideOutline = 0.6;  // a disc inside the winner replaces it when darker along this share

}  // namespace

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
  last_outer_.reset();
  last_rival_ = 0;
  last_glint_scale_ = 0;
  last_reference_.reset();
  open_aspect_ = 0;
  recent_count_ = recent_next_ = 0;
}

namespace {

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
  // Every fitted candidate (in Ellipse's pixel convention): the answer's doubts (step 6c), and the
  // caller's when asked for.
  std::vector<EyeDetector::CandidateFit>* candidates = nullptr;
  std::mt19937 rng{12345};  // deterministic RANSAC: the same frame gives the same answer
  bool inside = false;      // a search inside a fitted candidate (search_inside): it does not recurse
  const Ellipse* outer = nullptr;  // inside: the candidate searched in
  // track_inside: the pupil the last frame found inside a candidate (step 6b), which this search's
  // inside searches follow (search_window); null: none.
  const Ellipse* tracked = nullptr;
};

// One search's outcome: the best pupil fit (or why there is none) and the glints of the window.
struct PupilAttempt {
  bool ok = false;
  Ellipse ellipse;
  double confidence = 0;
  PupilEvidence evidence;
  std::string why;
  GlintCandidates glints;
  std::optional<Ellipse> outer;  // the candidate the pupil was found inside (search_inside), if it was
  bool followed = false;  // found by following the last pupil inside (follow_inside): no rivals were fitted
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
    if (blob.on_contour)
      out.edges = band_edges(smooth, w.work, glints, Ellipse{from, 2 * blob.radius, 2 * blob.radius, 0}, 0.6, 1.5,
                             std::max(4.0, 0.5 * min_step), settings.rays);
    else
      out.edges = settings.edges == EdgeMethod::Rays
                      ? ray_edges(smooth, w.work, glints, from, w.pupil_level, min_step, w.reach, settings.rays,
                                  search.inside ? std::max(6.0, search.size / 40) : 0.0)
                      : canny_edges(smooth, w.work, glints, from, w.contrast, std::max(3.0 * blob.radius, 8.0));
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
  StarburstFit sb = starburst_fit(search, blob, glints, w);
  if (!sb.fit) {
    a.why = sb.edges.size() < 6 ? "too few edge points" : "no ellipse fits the edge points";
    return a;
  }
  if (search.inside && search.settings.contour_candidates &&
      static_cast<double>(sb.fit->inliers.size()) < kScatteredEdges * search.settings.rays) {
    // Lashes and a weak outline scattered the edge points: the outline is moved onto the edge the
    // whole of it shares (the contour integral), read across a little less than the opening's
    // radius (normalise_contrast), as wide as what the opening leaves of lashes at the outline.
    // Read that wide it places the outline within about a pixel; rays whose edges agree do ten
    // times better, so a fit they support is left as it is (measured: bench/RESULTS.md, "The
    // contour integral").
    sb.fit->ellipse = refine_on_contour(search.grey, sb.fit->ellipse, std::max(2.5, search.size / 80));
  }
  score_fit(search, w, sb, a);
  return a;
}

PupilAttempt search_window(FrameSearch& search, const cv::Rect& window);

// Whether `fit` is a pupil (ok) where `last` was (track_inside): its centre within a tenth of last's
// major axis (1.5 px at least) and its major axis within 15 % of last's. Between frames of a camera
// at 60 Hz and more a fixating or pursuing eye moves less than that; after a saccade the fit is
// elsewhere.
bool follows(const Ellipse* last, const PupilAttempt& fit) {
  if (last == nullptr || !fit.ok) return false;
  const cv::Point2d d = fit.ellipse.centre - last->centre;
  return std::sqrt(d.x * d.x + d.y * d.y) <= std::max(1.5, 0.1 * last->major) &&
         fit.ellipse.major >= 0.85 * last->major && fit.ellipse.major * 0.85 <= last->major;
}

// The sensor noise's standard deviation in `img` (8-bit): the median absolute difference of
// horizontal neighbours, robust to the edges in it (1.4826 MAD / sqrt 2 for Gaussian noise).
double noise_sigma(const cv::Mat& img) {
  std::array<int, 256> hist{};
  int n = 0;
  for (int y = 0; y < img.rows; y += 2) {
    const std::uint8_t* row = img.ptr<std::uint8_t>(y);
    for (int x = 1; x < img.cols; ++x, ++n) ++hist[static_cast<std::size_t>(std::abs(row[x] - row[x - 1]))];
  }
  int seen = 0, median = 0;
  while (median < 255 && (seen += hist[static_cast<std::size_t>(median)]) < (n + 1) / 2) ++median;
  // An integer median of small differences is coarse: half a level at least.
  return 1.4826 * std::max(0.5, static_cast<double>(median)) / std::sqrt(2.0);
}

// Local contrast normalisation inside a fitted candidate (issue 44): the window blurred (sigma 1 px,
// which keeps the stretched noise down), opened (grey-level erosion, then dilation, with a disc
// wider than two or three lashes: lit lashes across a pupil go, single and in the bundles they
// gather into at the lid margin, as bright lines that the stretch would make as high as the pupil's
// own edge, while a dark disc's outline, far less curved, stays; a disc of S/120, one lash wide,
// left the bundles: dark-iris-lashes within 2 px 26/15.5/40 % by size against 55/27/43.5 %) and
// stretched so that its darkest 2 % lie at 20 and its median at 100 grey levels, at most 12x.
// `out` is the frame's size, the window's edges replicated outside it (the stages' blurs read a
// pixel beyond the window they are given). False when the window is flat once opened: median -
// darkest under 3 levels or under 4 sigma of the blurred noise (the inside of a pupil, lashes
// across it or not, where a noisy sensor's speckle would otherwise be stretched into "pupils").
bool normalise_contrast(const cv::Mat& grey, const cv::Rect& window, cv::Mat& out) {
  cv::Mat1f blurred;
  grey(window).convertTo(blurred, CV_32F);
  cv::GaussianBlur(blurred, blurred, cv::Size(0, 0), 1.0);
  const int k = 2 * std::max(1, static_cast<int>(std::min(grey.cols, grey.rows) / 60)) + 1;  // 7 px at 192, 9 at 240, 17 at 480
  cv::morphologyEx(blurred, blurred, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(k, k)));
  cv::Mat levels;
  blurred.convertTo(levels, CV_8U);
  const double lo = percentile(levels, 0.02), mid = percentile(levels, 0.5);
  constexpr double kBlurNoiseGain = 0.282;  // a Gaussian of sigma 1 px leaves 1 / (2 sqrt(pi)) of white noise
  if (mid - lo < std::max(3.0, 4 * kBlurNoiseGain * noise_sigma(grey(window)))) return false;
  const double gain = std::min(12.0, 80.0 / (mid - lo));
  cv::Mat stretched;
  blurred.convertTo(stretched, CV_8U, gain, 20 - gain * lo);
  cv::copyMakeBorder(stretched, out, window.y, grey.rows - window.y - window.height, window.x,
                     grey.cols - window.x - window.width, cv::BORDER_REPLICATE);
  return true;
}

// A dark iris is itself a dark disc in a bright surround (the sclera), and often the strongest
// candidate, while the pupil inside it is darker by only a few grey levels (issue 44: about 9 in
// desk-mounted sets). So inside a fitted candidate the search runs again on the contrast-normalised
// window, for discs up to 0.75 of its minor radius near its centre: a confident one is the pupil,
// and the candidate was the iris. Inside a real pupil the window is flat and nothing is searched.
// Returns the inner fit whatever its confidence (search_window decides), nullopt when none.
std::optional<PupilAttempt> search_inside(FrameSearch& search, const PupilAttempt& outer) {
  const Ellipse& e = outer.ellipse;
  const double r = e.minor / 2;
  const double rmax = std::min(search.rmax, 0.75 * r);
  if (rmax < search.rmin * 1.2) return std::nullopt;
  const double half = 0.85 * r;
  const cv::Rect window = cv::Rect(static_cast<int>(e.centre.x - half), static_cast<int>(e.centre.y - half),
                                   static_cast<int>(2 * half) + 1, static_cast<int>(2 * half) + 1) &
                          search.frame;
  if (window.width < 8 || window.height < 8) return std::nullopt;
  cv::Mat normalised;
  if (!normalise_contrast(search.grey, window, normalised)) return std::nullopt;
  FrameSearch inner{search.settings, normalised, search.smooth, search.small, search.integral, search.size,
                    search.rmin, rmax, window, search.candidates};
  inner.inside = true;
  inner.outer = &e;
  inner.tracked = search.tracked;
  PupilAttempt found = search_window(inner, window);
  if (found.confidence <= 0) return std::nullopt;
  const cv::Point2d off = found.ellipse.centre - e.centre;
  if (std::hypot(off.x, off.y) > 0.5 * r) return std::nullopt;
  return found;
}

// Candidates in the window, best blob response first, then (without a clear pupil yet) those from
// curved edges; the most confident fit wins (a clear pupil ends the search early); then a darker
// disc inside the winner is looked for (search_inside).
PupilAttempt search_window(FrameSearch& search, const cv::Rect& window) {
  PupilAttempt best;
  best.glints = find_glints(search.grey, window, search.size);
  const auto blobs = find_dark_blobs(search.grey, window, search.settings.coarse_downscale, search.rmin, search.rmax,
                                     kCandidates, search.small, search.integral);
  best.why = "no dark blob";
  // A clear pupil ends the search; inside a candidate, so does a confident fit where the last
  // frame's pupil was (track_inside: under lashes no fit is clear, and every candidate was fitted).
  const auto settled = [&] {
    return best.confidence >= kClearPupil ||
           (search.inside && best.confidence >= kTrackedPupil && follows(search.tracked, best));
  };
  // Fits the candidates in order; the most confident wins, until one settles the search.
  const auto fit_in_turn = [&](const std::vector<Blob>& candidates) {
    for (const Blob& blob : candidates) {
      PupilAttempt a = fit_candidate(search, blob, best.glints);
      if (search.candidates && a.confidence > 0)
        search.candidates->push_back({Ellipse{a.ellipse.centre + cv::Point2d(kToPublic, kToPublic), a.ellipse.major,
                                              a.ellipse.minor, a.ellipse.angle_deg},
                                      a.evidence, a.confidence});
      if (a.confidence > best.confidence || (best.confidence == 0 && best.why == "no dark blob")) {
        a.glints = std::move(best.glints);
        best = std::move(a);
      }
      if (settled()) return;
    }
  };
  fit_in_turn(blobs);
  if (!settled() && search.settings.edge_candidates && !search.inside)
    fit_in_turn(find_edge_candidates(search.small, window, search.rmin, search.rmax, kEdgeCandidates));
  if (!settled() && search.settings.contour_candidates && search.outer) {
    // Pupils are a fifth of the iris's size or more: smaller circles are lash gaps and noise.
    const double r = search.outer->minor / 2;
    fit_in_turn(find_contour_candidates(search.grey, window, search.outer->centre, 0.5 * r,
                                        std::max(search.rmin, 0.2 * r), search.rmax, kContourCandidates));
  }
  if (best.ok && search.settings.search_inside && !search.inside) {
    // A confident disc inside replaces the winner only when darker than its surround along most
    // of its outline, as a pupil is inside an iris: a piece of a real pupil between lit lashes is
    // surrounded by pupil along half of it or more (bench_eye's long-lashes set). A doubtful fit
    // inside that is darker all round still says the winner is an iris: no pupil rather than a
    // wrong one (the whole frame is searched next when this was the ROI). Doubtful fits inside a
    // veiled real pupil are darker along half their outline or less (the glasses set).
    std::optional<PupilAttempt> pupil = search_inside(search, best);
    if (pupil && ((pupil->ok && pupil->evidence.outline >= kInsideOutline) ||
                  (pupil->confidence >= kDiscInside && pupil->evidence.outline >= kDiscOutline))) {
      pupil->glints = std::move(best.glints);  // found on the frame itself, not the normalised window
      if (!pupil->ok) pupil->why = "a darker disc inside the best candidate (a dark iris?), but no confident pupil";
      pupil->outer = best.ellipse;
      best = std::move(*pupil);
    }
  }
  return best;
}

// track_inside: the last pupil was found inside a candidate (`last_outer`, a dark iris): the pupil is
// looked for inside such a candidate around where it was, before the ROI's candidates are fitted
// anew (under lashes the iris's fit is no better than a guess: the pupil is the steadier of the
// two). Taken when it finds a pupil there, darker than its surround along as much of its outline as
// search_window asks of a disc inside the winner.
std::optional<PupilAttempt> follow_inside(FrameSearch& search, const Ellipse& last_pupil, const Ellipse& last_outer,
                                          const cv::Rect& roi) {
  PupilAttempt outer;
  outer.ellipse = Ellipse{last_pupil.centre, last_outer.major, last_outer.minor, last_outer.angle_deg};
  std::optional<PupilAttempt> pupil = search_inside(search, outer);
  if (!pupil || pupil->evidence.outline < kInsideOutline || !follows(&last_pupil, *pupil)) return std::nullopt;
  pupil->glints = find_glints(search.grey, roi, search.size);
  pupil->outer = outer.ellipse;
  pupil->followed = true;
  return pupil;
}

// Searches near the last pupil first (`used_roi` tells whether that found it); recovery: the whole frame.
// `last_outer`: the candidate the last pupil was found inside, if it was (track_inside).
PupilAttempt find_pupil(FrameSearch& search, bool roi_tracking, const std::optional<Ellipse>& last_pupil,
                        const std::optional<Ellipse>& last_outer, bool& used_roi, cv::Rect& searched) {
  PupilAttempt found;
  if (roi_tracking && last_pupil) {
    const double half = 1.2 * last_pupil->major + 0.08 * search.size;
    const cv::Rect roi =
        cv::Rect(static_cast<int>(last_pupil->centre.x - half), static_cast<int>(last_pupil->centre.y - half),
                 static_cast<int>(2 * half), static_cast<int>(2 * half)) &
        search.frame;
    if (roi.width >= 8 && roi.height >= 8) {
      searched = roi;
      if (search.settings.track_inside && last_outer) {
        search.tracked = &*last_pupil;
        if (std::optional<PupilAttempt> pupil = follow_inside(search, *last_pupil, *last_outer, roi)) {
          used_roi = true;
          return std::move(*pupil);
        }
      }
      found = search_window(search, roi);
      search.tracked = nullptr;  // the whole frame's search follows nothing
      used_roi = found.ok;
    }
  }
  if (!found.ok) {
    found = search_window(search, search.frame);
    searched = search.frame;
  }
  return found;
}

// What else the search fitted (step 6c): the most confident fit whose centre is farther than
// max(3 px, a quarter of the winner's minor axis) from the winner's -- another place that looked like
// the pupil (a disc the winner was found inside, a dark iris around its pupil, shares its centre and
// is no rival) --, and whether a smaller disc near its centre is darker than its surround along
// kInsideOutline of its outline: too doubtful for step 6b to take, yet a sign the winner is an iris.
struct Doubts {
  double rival = 0;
  bool disc_inside = false;
};

// `fitted` holds this frame's candidates, in Ellipse's pixel convention as `winner` is.
Doubts doubts_about(std::span<const EyeDetector::CandidateFit> fitted, const Ellipse& winner) {
  const double apart = std::max(3.0, 0.25 * winner.minor);
  Doubts d;
  for (const EyeDetector::CandidateFit& f : fitted) {
    const cv::Point2d c = f.ellipse.centre;
    const double off = std::hypot(c.x - winner.centre.x, c.y - winner.centre.y);
    if (off > apart) d.rival = std::max(d.rival, f.confidence);
    else if (f.ellipse.major < 0.7 * winner.major && f.evidence.outline >= kInsideOutline) d.disc_inside = true;
  }
  return d;
}

// Lee 2009 §3.5.2: minor/major below 0.7 is a blink. Lee's camera faced the eye; an eye camera
// below the eye sees an open eye looking up at about 0.7 already, so the threshold applies
// relative to this eye's recent open aspect (1 until one is known), learnt from clear open pupils.
void report_pupil(const PupilAttempt& found, const Doubts& doubts, double blink_aspect, double& open_aspect,
                  EyeMeasurement& result) {
  result.pupil_found = found.ok;
  result.evidence = found.evidence;
  result.why = found.ok ? std::string() : found.why;
  if (found.ok) {
    result.pupil = found.ellipse;
    result.fit_confidence = found.confidence;
    result.rival_confidence = doubts.rival;
    result.disc_inside = doubts.disc_inside;
    result.confidence = answer_confidence(found.confidence, doubts.rival, doubts.disc_inside);
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
         std::isfinite(result.pupil.angle_deg) && std::isfinite(result.confidence) &&
         std::isfinite(result.fit_confidence) && std::isfinite(result.rival_confidence);
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
    std::vector<CandidateFit> own;
    std::vector<CandidateFit>& fitted = candidates ? *candidates : own;
    const std::size_t first = fitted.size();  // the caller's list may hold earlier frames' candidates
    FrameSearch search{settings_, grey_, smooth_, small_, integral_, size, rmin, rmax, frame, &fitted};

    const PupilAttempt found = find_pupil(search, settings_.roi_tracking, last_pupil_, last_outer_, result.used_roi, result.search_region);
    if (found.ok) {
      last_pupil_ = found.ellipse;
      last_outer_ = found.outer;
    } else {
      last_pupil_.reset();
      last_outer_.reset();
    }
    const Ellipse winner{found.ellipse.centre + cv::Point2d(kToPublic, kToPublic), found.ellipse.major,
                         found.ellipse.minor, found.ellipse.angle_deg};
    Doubts doubts = found.ok ? doubts_about(std::span(fitted).subspan(first), winner) : Doubts{};
    // A followed pupil was weighed against no rival around the iris (none was fitted): it keeps the
    // doubt of the search its following began with, else one doubted answer, followed, would become
    // a confident one.
    if (found.followed) {
      doubts.rival = std::max(doubts.rival, last_rival_);
    } else {
      last_rival_ = doubts.rival;
    }
    result.followed = found.followed;
    report_pupil(found, doubts, settings_.blink_aspect, open_aspect_, result);
    if (found.ok) doubt_size_jumps(result);

    std::vector<Glint> glints = corneal_glints(found, size);
    const GlintReference reference = glint_reference(glints, settings_.leds, size, last_glint_scale_, last_reference_);
    report_glints(glints, reference, found, result);
    if (!finite_measurement(result)) {
      result = no_pupil("numerical failure");
      last_pupil_.reset();
      last_outer_.reset();
    }
  } catch (const std::exception& e) {
    result = no_pupil(std::string("detector error: ") + e.what());
    last_pupil_.reset();
    last_outer_.reset();
  }
  return result;
}

// A pupil changes size slowly: its light reflex at most halves it within half a second, and the
// major axis stays the pupil's diameter however the eye turns. So an answer 1.8x larger or smaller
// than the median of this eye's last clear fits (fit confidence >= kClearPupil) is likelier the iris
// (a dark iris under the lid, fitted whole and confidently: issue 44) or a piece of the pupil, and
// its confidence is held at 0.5 at most. Clear fits enter the median whatever their answer's
// confidence, so a wrong size learnt first is outvoted by the next five clear pupils.
void EyeDetector::doubt_size_jumps(EyeMeasurement& result) {
  constexpr double kSizeJump = 1.8, kDoubtfulSize = 0.5;
  const double major = result.pupil.major;
  if (recent_count_ > 0) {
    decltype(recent_major_) held{};
    std::copy_n(recent_major_.begin(), recent_count_, held.begin());
    const auto mid = held.begin() + static_cast<std::ptrdiff_t>(recent_count_ / 2);
    std::nth_element(held.begin(), mid, held.begin() + static_cast<std::ptrdiff_t>(recent_count_));
    result.size_jump = major > kSizeJump * *mid || major * kSizeJump < *mid;
    if (result.size_jump) result.confidence = std::min(result.confidence, kDoubtfulSize);
  }
  if (result.fit_confidence >= kClearPupil && std::isfinite(major) && major > 0) {  // NaN would break the median
    recent_major_[recent_next_] = major;
    recent_next_ = (recent_next_ + 1) % recent_major_.size();
    recent_count_ = std::min(recent_count_ + 1, recent_major_.size());
  }
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
