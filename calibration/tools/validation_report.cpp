// SPDX-License-Identifier: Apache-2.0
#include "validation_report.h"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <initializer_list>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <utility>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace fovea::calib {

namespace {

namespace fs = std::filesystem;

std::string num(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

std::string g10(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

// Degrees of visual angle per pixel at the screen centre (along x).
double deg_per_px_at_centre(const Display& d) {
  return angle_between_deg(d, {d.width_px / 2, d.height_px / 2}, {d.width_px / 2 + 1, d.height_px / 2});
}

// --- report.md ---

std::string md_stats_cells(const ErrorStats& s) {
  if (!s.has_data()) return " " + std::to_string(s.samples) + " | " + std::to_string(s.lost) + " | - | - | - | - | - | - |";
  return " " + std::to_string(s.samples) + " | " + std::to_string(s.lost) + " | " + num(s.accuracy_deg, 3) + " | " +
         num(s.accuracy_mm, 2) + " | " + num(s.precision_rms_deg, 3) + " | " + num(s.precision_std_deg, 3) + " | " +
         num(s.min_deg, 3) + " | " + num(s.max_deg, 3) + " |";
}

std::string summary_sentence(const ErrorStats& s, std::size_t targets_with_data) {
  if (!s.has_data()) return "no usable sample (" + std::to_string(s.lost) + " lost)";
  return "accuracy " + num(s.accuracy_deg, 3) + " deg (" + num(s.accuracy_mm, 2) + " mm), precision " +
         num(s.precision_rms_deg, 3) + " deg RMS sample-to-sample and " + num(s.precision_std_deg, 3) +
         " deg STD, sample errors " + num(s.min_deg, 3) + "-" + num(s.max_deg, 3) + " deg; mean over " +
         std::to_string(targets_with_data) + " target(s); " + std::to_string(s.samples) + " sample(s), " +
         std::to_string(s.lost) + " lost";
}

std::string render_markdown(const ValidationResult& r, const Display& d, const std::string& title) {
  const bool before = r.before.has_value();
  std::size_t after_targets = 0, before_targets = 0;
  for (const auto& t : r.targets) {
    if (t.after.has_data()) ++after_targets;
    if (t.before && t.before->has_data()) ++before_targets;
  }
  std::string md = "# " + title + "\n\n";
  md += "Display: " + g10(d.width_px) + " x " + g10(d.height_px) + " px, " + g10(d.width_mm) + " x " +
        g10(d.height_mm) + " mm, eye " + g10(d.distance_mm) + " mm from the screen centre (`" + to_string(d) +
        "`; 1 px = " + num(deg_per_px_at_centre(d) * 60, 3) + " arcmin at the centre, " +
        num(px_per_mm(d), 3) + " px/mm).\n\n";
  md += "**Overall (after):** " + summary_sentence(r.after, after_targets) + ".\n\n";
  if (before) {
    md += "**Overall (before):** " + summary_sentence(*r.before, before_targets) + ".\n\n";
    if (r.before->has_data() && r.before->accuracy_deg > 0) {
      const double gain = (1 - r.after.accuracy_deg / r.before->accuracy_deg) * 100;
      md += "Accuracy " + std::string(gain >= 0 ? "improved" : "worsened") + " by " + num(std::abs(gain), 1) +
            " % (" + num(r.before->accuracy_deg, 3) + " -> " + num(r.after.accuracy_deg, 3) + " deg).\n\n";
    }
  }
  md += "![Error vectors per target](errors.png)\n\n";
  md += "## Per target\n\nAngles in degrees of visual angle, distances in millimetres on the screen; \"-\": only lost "
        "samples.\n\n";
  const std::string cols = " n | lost | accuracy deg | accuracy mm | precision RMS deg | precision STD deg | min deg | max deg |";
  std::string head = "| target x px | target y px |", rule = "|---:|---:|";
  if (before) {
    std::string bcols = cols;
    for (const char* name : {" n |", " lost |", " accuracy deg |", " accuracy mm |", " precision RMS deg |",
                             " precision STD deg |", " min deg |", " max deg |"}) {
      const std::string from(name);
      const std::size_t at = bcols.find(from);
      bcols.replace(at, from.size(), " before" + from);
    }
    head += bcols;
    rule += "---:|---:|---:|---:|---:|---:|---:|---:|";
  }
  head += cols;
  rule += "---:|---:|---:|---:|---:|---:|---:|---:|";
  md += head + "\n" + rule + "\n";
  for (const auto& t : r.targets) {
    md += "| " + num(t.target_px.x, 1) + " | " + num(t.target_px.y, 1) + " |";
    if (before) md += md_stats_cells(t.before ? *t.before : ErrorStats{});
    md += md_stats_cells(t.after) + "\n";
  }
  md += "| **overall** | |";
  if (before) md += md_stats_cells(*r.before);
  md += md_stats_cells(r.after) + "\n\n";
  md += "## How the figures were computed\n\n";
  md += "As in Jensen & Pedersen 2009, §4 (Tables 4.1 and 4.2, Fig. 4.7), for an eye on the normal through the "
        "screen centre at the viewing distance above. For each target, *accuracy* is the mean over its samples of "
        "the visual angle between the sample and the target (their \"absolute\" deviation, about the drawn point), "
        "also given as the mean on-screen distance in millimetres; *precision* is given twice: RMS is the root mean "
        "square of the angles between successive samples (sample-to-sample), STD the root mean square angle of the "
        "samples about their own mean point (their \"relative standard deviation\"); min and max are the smallest "
        "and largest sample errors. Samples that were lost (not finite: blinks, tracking lost) are counted but not "
        "used; a target with only lost samples has no figures and is left out of the overall row. The overall "
        "accuracy and precision are the means over the targets with data, each target weighing the same; min and "
        "max are over all samples. Angles are computed between the 3-D lines of sight (atan2 of the cross and dot "
        "products), not from on-screen distances, so they stay exact off-centre. The figure shows each target's "
        "mean error vector (J&P eqs. 4.3-4.4: from the target to the mean of its samples) and the samples, both "
        "magnified about the target by the factor printed on it";
  md += before ? ", before this calibration (left) and after it (right).\n" : ".\n";
  return md;
}

// --- targets.csv ---

void csv_stats(std::string& line, const std::optional<ErrorStats>& s) {
  if (!s) {
    line += ",,,,,,,,,,";
    return;
  }
  line += "," + std::to_string(s->samples) + "," + std::to_string(s->lost);
  if (!s->has_data()) {
    line += ",,,,,,,,";
    return;
  }
  for (const double v : {s->accuracy_deg, s->accuracy_mm, s->precision_rms_deg, s->precision_std_deg, s->min_deg,
                         s->max_deg, s->mean_error_px.x, s->mean_error_px.y}) {
    line += "," + g10(v);
  }
}

std::string render_csv(const ValidationResult& r) {
  const std::string stats =
      "samples,lost,accuracy_deg,accuracy_mm,precision_rms_deg,precision_std_deg,min_deg,max_deg,mean_error_x_px,"
      "mean_error_y_px";
  std::string csv = "target_x_px,target_y_px," + stats;
  if (r.before) {
    std::string b;
    std::size_t start = 0;
    for (;;) {
      const std::size_t comma = stats.find(',', start);
      b += ",before_" + stats.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    csv += b;
  }
  csv += "\n";
  for (const auto& t : r.targets) {
    std::string line = g10(t.target_px.x) + "," + g10(t.target_px.y);
    csv_stats(line, t.after);
    if (r.before) csv_stats(line, t.before);
    csv += line + "\n";
  }
  return csv;
}

// --- errors.png ---

// The largest of `steps` times a power of ten that is at most v (v > 0).
double nice_floor(double v, std::initializer_list<double> steps = {5.0, 2.0, 1.0}) {
  const double p = std::pow(10.0, std::floor(std::log10(v)));
  for (const double m : steps) {
    if (m * p <= v * (1 + 1e-9)) return m * p;
  }
  return p;
}

std::string factor_text(double f) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%g", f);
  return buf;
}

cv::Point ipt(double x, double y) {
  // Callers keep points on the canvas; the clamp only guards the conversion.
  return {static_cast<int>(std::lround(std::clamp(x, -1e6, 1e6))), static_cast<int>(std::lround(std::clamp(y, -1e6, 1e6)))};
}

struct Palette {
  cv::Scalar arrow, dot;
};

const cv::Scalar kBlack(0, 0, 0), kGrey(120, 120, 120), kLightGrey(200, 200, 200), kScreen(250, 250, 250),
    kWhite(255, 255, 255);
const Palette kBeforePalette{cv::Scalar(40, 40, 200), cv::Scalar(160, 160, 245)};  // red
const Palette kAfterPalette{cv::Scalar(170, 90, 10), cv::Scalar(235, 200, 160)};   // blue

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale, const cv::Scalar& colour, int thickness = 1) {
  cv::putText(img, s, at, kFont, scale, colour, thickness, cv::LINE_AA);
}

int text_width(const std::string& s, double scale, int thickness = 1) {
  int baseline = 0;
  return cv::getTextSize(s, kFont, scale, thickness, &baseline).width;
}

// Clips the segment a -> b to the rectangle [x0, x1] x [y0, y1] (Liang-Barsky); false when none of
// it is inside.
bool clip(double x0, double y0, double x1, double y1, cv::Point2d& a, cv::Point2d& b) {
  double t0 = 0, t1 = 1;
  const double dx = b.x - a.x, dy = b.y - a.y;
  const std::array<std::pair<double, double>, 4> pq{{{-dx, a.x - x0}, {dx, x1 - a.x}, {-dy, a.y - y0}, {dy, y1 - a.y}}};
  for (const auto& [p, q] : pq) {
    if (p == 0) {
      if (q < 0) return false;
      continue;
    }
    const double t = q / p;
    if (p < 0) {
      t0 = std::max(t0, t);
    } else {
      t1 = std::min(t1, t);
    }
    if (t0 > t1) return false;
  }
  const cv::Point2d a0 = a;
  a = {a0.x + t0 * dx, a0.y + t0 * dy};
  b = {a0.x + t1 * dx, a0.y + t1 * dy};
  return true;
}

void draw_lost_target(cv::Mat& img, double x, double y) {
  cv::circle(img, ipt(x, y), 6, kGrey, 1, cv::LINE_AA);
  cv::line(img, ipt(x - 4, y - 4), ipt(x + 4, y + 4), kGrey, 1, cv::LINE_AA);
  cv::line(img, ipt(x - 4, y + 4), ipt(x + 4, y - 4), kGrey, 1, cv::LINE_AA);
}

struct Layout {
  double scale = 1;                 // panel px per screen px
  int screen_w = 0, screen_h = 0;   // the screen rectangle, panel px
  int margin = 45, top = 105, panel_w = 0, panel_h = 0, footer = 78;
  // Drawing reaches this far beyond the screen rectangle (panel px).
  double pad_side = 41, pad_top = 14, pad_bottom = 26;
};

// The region vectors and samples may be drawn in, in screen pixels.
struct Region {
  double x0, y0, x1, y1;
  bool contains(Point p) const { return p.x >= x0 && p.x <= x1 && p.y >= y0 && p.y <= y1; }
};
Region drawable(const Layout& L, const Display& d) {
  return {-L.pad_side / L.scale, -L.pad_top / L.scale, d.width_px + L.pad_side / L.scale,
          d.height_px + L.pad_bottom / L.scale};
}

// The largest factor f for which target + f * v stays in the region (infinity when v = 0).
double fit_factor(const Region& g, Point t, Point v) {
  double f = std::numeric_limits<double>::infinity();
  if (v.x > 0) f = std::min(f, (g.x1 - t.x) / v.x);
  if (v.x < 0) f = std::min(f, (g.x0 - t.x) / v.x);
  if (v.y > 0) f = std::min(f, (g.y1 - t.y) / v.y);
  if (v.y < 0) f = std::min(f, (g.y0 - t.y) / v.y);
  return f;
}

void draw_panel(cv::Mat& img, const Layout& L, const Display& d, int panel_x, const std::string& name, bool is_before,
                const ValidationResult& r, const std::vector<ValidationSample>& samples, double factor) {
  const Palette& pal = is_before ? kBeforePalette : kAfterPalette;
  const int sx = panel_x + L.margin, sy = L.top;
  cv::rectangle(img, {sx, sy}, {sx + L.screen_w, sy + L.screen_h}, kScreen, cv::FILLED);
  cv::rectangle(img, {sx, sy}, {sx + L.screen_w, sy + L.screen_h}, kGrey, 1, cv::LINE_AA);
  const Region region = drawable(L, d);
  const auto to_panel = [&](Point p) { return cv::Point2d(sx + p.x * L.scale, sy + p.y * L.scale); };

  // Samples, magnified about their target.
  std::size_t off_panel = 0;
  for (const auto& s : samples) {
    const std::optional<Point> m = is_before ? s.before_px : std::optional<Point>(s.measured_px);
    if (!m || !std::isfinite(m->x) || !std::isfinite(m->y)) continue;
    const Point shown{s.target_px.x + factor * (m->x - s.target_px.x), s.target_px.y + factor * (m->y - s.target_px.y)};
    if (!region.contains(shown)) {  // also false for NaN
      ++off_panel;
      continue;
    }
    const cv::Point2d p = to_panel(shown);
    cv::circle(img, ipt(p.x, p.y), 2, pal.dot, cv::FILLED, cv::LINE_AA);
  }
  // Targets and their mean error vectors (clipped at the region's edge, should one reach it).
  std::size_t clipped = 0;
  const cv::Point2d r0 = to_panel({region.x0, region.y0}), r1 = to_panel({region.x1, region.y1});
  for (const auto& t : r.targets) {
    if (!region.contains(t.target_px)) continue;
    const cv::Point2d c = to_panel(t.target_px);
    const ErrorStats& s = is_before ? *t.before : t.after;
    if (!s.has_data()) {
      draw_lost_target(img, c.x, c.y);
      continue;
    }
    cv::circle(img, ipt(c.x, c.y), 5, kBlack, 1, cv::LINE_AA);
    cv::Point2d a = c;
    cv::Point2d b(c.x + factor * s.mean_error_px.x * L.scale, c.y + factor * s.mean_error_px.y * L.scale);
    if (!std::isfinite(b.x) || !std::isfinite(b.y)) continue;
    if (!(b.x >= r0.x && b.x <= r1.x && b.y >= r0.y && b.y <= r1.y)) ++clipped;
    if (!clip(r0.x, r0.y, r1.x, r1.y, a, b)) continue;
    const double len = std::hypot(b.x - a.x, b.y - a.y);
    if (len < 1.5) continue;
    cv::arrowedLine(img, ipt(a.x, a.y), ipt(b.x, b.y), pal.arrow, 2, cv::LINE_AA, 0, std::min(0.35, 9.0 / len));
  }

  const ErrorStats& overall = is_before ? *r.before : r.after;
  const int tx = panel_x + L.margin + text_width(name, 0.8, 2) + 16;
  text(img, name, {panel_x + L.margin, 68}, 0.8, pal.arrow, 2);
  text(img,
       overall.has_data() ? "accuracy " + num(overall.accuracy_deg, 2) + " deg (" + num(overall.accuracy_mm, 1) +
                                " mm), precision " + num(overall.precision_rms_deg, 3) + " deg RMS / " +
                                num(overall.precision_std_deg, 3) + " deg STD"
                          : "no usable sample",
       {tx, 68}, 0.5, kBlack);
  std::string counts = std::to_string(r.targets.size()) + " targets, " + std::to_string(overall.samples) +
                       " samples, " + std::to_string(overall.lost) + " lost";
  if (off_panel > 0) counts += "; " + std::to_string(off_panel) + " sample(s) beyond the panel not drawn";
  if (clipped > 0) counts += "; " + std::to_string(clipped) + " vector(s) cut at the panel edge";
  text(img, counts, {tx, 88}, 0.45, kGrey);
}

Layout figure_layout(const Display& d) {
  Layout L;
  L.scale = 1000.0 / d.width_px;
  L.screen_w = 1000;
  L.screen_h = std::clamp(static_cast<int>(std::lround(d.height_px * L.scale)), 50, 4000);
  L.panel_w = L.screen_w + 2 * L.margin;
  L.panel_h = L.top + L.screen_h + 30;
  return L;
}

// One magnification for both panels: the largest mean error vector becomes `want` (screen px) long.
double magnification(const ValidationResult& r, const Layout& L, const Display& d, double want) {
  double largest = 0;
  for (const auto& t : r.targets) {
    if (t.after.has_data()) largest = std::max(largest, std::hypot(t.after.mean_error_px.x, t.after.mean_error_px.y));
    if (t.before && t.before->has_data())
      largest = std::max(largest, std::hypot(t.before->mean_error_px.x, t.before->mean_error_px.y));
  }
  double factor = 1.0;
  if (largest > 0 && std::isfinite(largest)) {
    // Smaller, if need be, so that no vector leaves the panel; but not below a quarter of that.
    const Region region = drawable(L, d);
    double fits = std::numeric_limits<double>::infinity();
    for (const auto& t : r.targets) {
      if (!region.contains(t.target_px)) continue;
      if (t.after.has_data()) fits = std::min(fits, fit_factor(region, t.target_px, t.after.mean_error_px));
      if (t.before && t.before->has_data()) fits = std::min(fits, fit_factor(region, t.target_px, t.before->mean_error_px));
    }
    const double f = std::max(std::min(want / largest, fits), want / largest / 4);
    factor = nice_floor(f, {8.0, 6.0, 5.0, 4.0, 3.0, 2.5, 2.0, 1.5, 1.0});
  }
  return factor;
}

// Scale bar: a round number of degrees (at the screen centre), magnified like the vectors, about
// as long as the largest vector. Drawn from x, which it advances past the bar; returns its label.
std::string draw_scale_bar(cv::Mat& img, const Layout& L, const Display& d, double factor, double want, int fy,
                           int& x) {
  const double px_per_deg = 1.0 / deg_per_px_at_centre(d);  // screen px per degree at the centre
  const double bar_target = want * L.scale;                 // panel px
  double bar_deg = nice_floor(std::max(bar_target / (px_per_deg * factor * L.scale), 1e-6));
  bar_deg = std::min(bar_deg, 20.0);
  const double bar_len = std::tan(bar_deg * std::numbers::pi / 180) * d.distance_mm * px_per_mm(d) * factor * L.scale;
  const int bar_px = std::clamp(static_cast<int>(std::lround(bar_len)), 2, 2000);
  cv::line(img, {x, fy}, {x + bar_px, fy}, kBlack, 2, cv::LINE_AA);
  cv::line(img, {x, fy - 6}, {x, fy + 6}, kBlack, 2, cv::LINE_AA);
  cv::line(img, {x + bar_px, fy - 6}, {x + bar_px, fy + 6}, kBlack, 2, cv::LINE_AA);
  const std::string bar_text = factor_text(bar_deg) + " deg";
  text(img, bar_text, {x + bar_px / 2 - text_width(bar_text, 0.6, 2) / 2, fy - 12}, 0.6, kBlack, 2);
  x += bar_px + 30;
  return bar_text;
}

// Legend from x on row fy, wrapped onto a second row when the image is narrow (one panel); returns
// the y of the row it ended on.
int draw_legend(cv::Mat& img, const Layout& L, bool before, int x, int fy) {
  int row_y = fy;
  const auto place = [&](int w) {
    if (x + w > img.cols - L.margin) {
      x = L.margin;
      row_y += 30;
    }
    const int at = x;
    x += w + 22;
    return at;
  };
  int at = place(16 + text_width("target", 0.5));
  cv::circle(img, {at + 5, row_y}, 5, kBlack, 1, cv::LINE_AA);
  text(img, "target", {at + 16, row_y + 5}, 0.5, kBlack);
  const std::string arrow_text = "mean error (target -> mean of samples)";
  at = place(42 + text_width(arrow_text, 0.5));
  cv::arrowedLine(img, {at, row_y}, {at + 34, row_y}, kAfterPalette.arrow, 2, cv::LINE_AA, 0, 0.3);
  if (before) cv::arrowedLine(img, {at, row_y + 10}, {at + 34, row_y + 10}, kBeforePalette.arrow, 2, cv::LINE_AA, 0, 0.3);
  text(img, arrow_text, {at + 42, row_y + 5}, 0.5, kBlack);
  at = place(12 + text_width("samples", 0.5));
  cv::circle(img, {at + 3, row_y}, 2, kAfterPalette.dot, cv::FILLED, cv::LINE_AA);
  if (before) cv::circle(img, {at + 3, row_y + 10}, 2, kBeforePalette.dot, cv::FILLED, cv::LINE_AA);
  text(img, "samples", {at + 12, row_y + 5}, 0.5, kBlack);
  at = place(18 + text_width("target with only lost samples", 0.5));
  draw_lost_target(img, at + 6, row_y);
  text(img, "target with only lost samples", {at + 18, row_y + 5}, 0.5, kGrey);
  return row_y;
}

// The notes under the legend, on two lines when one is too narrow.
void draw_notes(cv::Mat& img, const Layout& L, const Display& d, double factor, const std::string& bar_text,
                int row_y) {
  const std::string note1 = "errors and samples drawn " + factor_text(factor) + " times their size about each target; ";
  const std::string note2 = "the bar is " + bar_text + " at the screen centre, magnified alike (" + to_string(d) + ")";
  if (L.margin + text_width(note1 + note2, 0.45) <= img.cols - L.margin) {
    text(img, note1 + note2, {L.margin, row_y + 38}, 0.45, kGrey);
  } else {
    text(img, note1, {L.margin, row_y + 36}, 0.45, kGrey);
    text(img, note2, {L.margin, row_y + 56}, 0.45, kGrey);
  }
}

// Footer: magnification, scale bar, legend, notes.
void draw_footer(cv::Mat& img, const Layout& L, const Display& d, double factor, double want, bool before) {
  const int fy = L.panel_h + 20;
  int x = L.margin;
  const std::string mag = "vectors x " + factor_text(factor);
  text(img, mag, {x, fy + 6}, 0.7, kBlack, 2);
  x += text_width(mag, 0.7, 2) + 30;
  const std::string bar_text = draw_scale_bar(img, L, d, factor, want, fy, x);
  const int row_y = draw_legend(img, L, before, x, fy);
  draw_notes(img, L, d, factor, bar_text, row_y);
}

}  // namespace

std::vector<unsigned char> render_error_figure_png(const ValidationResult& r, const std::vector<ValidationSample>& samples,
                                                   const Display& d, const std::string& title) {
  const Layout L = figure_layout(d);
  const bool before = r.before.has_value();
  const int panels = before ? 2 : 1;
  cv::Mat img(L.panel_h + L.footer + (panels == 1 ? 50 : 0), panels * L.panel_w, CV_8UC3, kWhite);
  const double want = d.width_px / 8;  // the largest mean error vector's magnified length, screen px
  const double factor = magnification(r, L, d, want);

  text(img, title, {L.margin, 30}, 0.65, kBlack, 1);
  if (before) draw_panel(img, L, d, 0, "before", true, r, samples, factor);
  draw_panel(img, L, d, before ? L.panel_w : 0, "after", false, r, samples, factor);
  draw_footer(img, L, d, factor, want, before);

  std::vector<unsigned char> png;
  if (!cv::imencode(".png", img, png)) throw std::runtime_error("errors.png: PNG encoding failed");
  return png;
}

void write_validation_report(const fs::path& dir, const ValidationResult& result,
                             const std::vector<ValidationSample>& samples, const Display& display,
                             const std::string& title) {
  // Render everything first: nothing is written when any part fails.
  nlohmann::json summary = to_json(result);
  summary["title"] = title;
  summary["display"] = to_json(display);
  const std::vector<unsigned char> png = render_error_figure_png(result, samples, display, title);
  const std::vector<std::pair<std::string, std::string>> files{
      {"report.md", render_markdown(result, display, title)},
      {"targets.csv", render_csv(result)},
      {"summary.json", summary.dump(2) + "\n"},
      {"errors.png", std::string(png.begin(), png.end())}};

  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) {
    throw std::runtime_error(dir.string() + ": exists and is not a directory");
  }
  for (const auto& [name, content] : files) {
    const fs::path p = dir / name;
    if (fs::exists(fs::symlink_status(p, ec))) {
      throw std::runtime_error(p.string() + ": exists; refusing to overwrite it");
    }
  }
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error(dir.string() + ": cannot create the directory: " + ec.message());

  std::vector<fs::path> written;
  try {
    for (const auto& [name, content] : files) {
      const fs::path p = dir / name;
      const fs::path tmp = dir / (name + ".tmp-" + std::to_string(::getpid()));
      {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        out.write(content.data(), static_cast<std::streamsize>(content.size()));
        out.flush();
        if (!out) {
          std::error_code ignored;
          fs::remove(tmp, ignored);
          throw std::runtime_error(tmp.string() + ": cannot write");
        }
      }
      // A hard link never replaces an existing file (unlike rename).
      fs::create_hard_link(tmp, p, ec);
      std::error_code ignored;
      fs::remove(tmp, ignored);
      if (ec) throw std::runtime_error(p.string() + ": cannot write: " + ec.message());
      written.push_back(p);
    }
  } catch (...) {
    std::error_code ignored;
    for (const auto& p : written) fs::remove(p, ignored);
    throw;
  }
}

}  // namespace fovea::calib
