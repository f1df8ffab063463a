// SPDX-License-Identifier: Apache-2.0
// SyntheticEye::render(): one frame's geometry and the instance's look shaded pixel by pixel (skin,
// sclera, iris, pupil, glints, each anti-aliased analytically), then eyelashes and spectacle
// reflections drawn over it and the camera's effects (synthetic_eye_capture.h) applied.
#include "sim/synthetic_eye.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "sim/synthetic_eye_capture.h"
#include "sim/synthetic_eye_geometry.h"
#include "sim/synthetic_eye_look.h"

namespace fovea::trackerd::eye {

using namespace synthetic;  // sim/synthetic_eye_geometry.h, sim/synthetic_eye_capture.h

namespace {

// (1 - z^2)^2 for |z| < 1, else 0: a smooth bump with compact support.
double bump(double z) {
  const double q = 1 - z * z;
  return q > 0 ? q * q : 0.0;
}

// Box-filter coverage of the pixel by the slab between the two margins (du, dl inside distances).
double opening_coverage(double du, double dl) {
  return clamp01(std::min(du + 0.5, 1.0) + std::min(dl + 0.5, 1.0) - 1.0);
}

// atan2 to about 2e-6 rad (a minimax polynomial for atan on [0, 1] and octant folding): the iris
// texture lookup needs no more, and it is several times faster than std::atan2.
double fast_atan2(double y, double x) {
  const double ax = std::abs(x), ay = std::abs(y);
  const double mx = std::max(ax, ay), mn = std::min(ax, ay);
  const double a = mx > 0 ? mn / mx : 0.0, z = a * a;
  double r = a * (0.99997726 + z * (-0.33262347 + z * (0.19354346 + z * (-0.11643287 + z * (0.05265332 + z * -0.01172120)))));
  if (ay > ax) r = kPi / 2 - r;
  if (x < 0) r = kPi - r;
  return y < 0 ? -r : r;
}

double normal_cdf(double z) { return 0.5 * std::erfc(-z / std::numbers::sqrt2); }

// A glint as a pixel-integrated Gaussian (so its centroid is unbiased for any sigma), separable.
struct GlintSplat {
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;  // [x0, x1) x [y0, y1)
  std::vector<float> gx, gy;
};

GlintSplat make_splat(cv::Point2d c, double sigma, double peak, int width, int height) {
  GlintSplat s;
  if (!(std::abs(c.x) < 1e6 && std::abs(c.y) < 1e6)) return s;  // far outside: nothing to draw
  const double reach = 4 * sigma + 1;
  s.x0 = std::max(0, static_cast<int>(std::floor(c.x - reach)));
  s.x1 = std::min(width, static_cast<int>(std::ceil(c.x + reach)));
  s.y0 = std::max(0, static_cast<int>(std::floor(c.y - reach)));
  s.y1 = std::min(height, static_cast<int>(std::ceil(c.y + reach)));
  const double norm = normal_cdf(0.5 / sigma) - normal_cdf(-0.5 / sigma);  // a centred pixel gets `peak`
  const double amp = std::sqrt(peak) / norm;
  for (int x = s.x0; x < s.x1; ++x)
    s.gx.push_back(static_cast<float>(amp * (normal_cdf((x + 1 - c.x) / sigma) - normal_cdf((x - c.x) / sigma))));
  for (int y = s.y0; y < s.y1; ++y)
    s.gy.push_back(static_cast<float>(amp * (normal_cdf((y + 1 - c.y) / sigma) - normal_cdf((y - c.y) / sigma))));
  return s;
}

// Draws a lash (a polyline of tapered thick segments) into a coverage buffer (max-composited).
void draw_stroke(cv::Mat1f& cover, const std::vector<cv::Point2d>& pts, double width, double opacity) {
  for (std::size_t i = 0; i + 1 < pts.size(); ++i) {
    const cv::Point2d a = pts[i], b = pts[i + 1];
    if (!(std::abs(a.x) < 1e6 && std::abs(a.y) < 1e6 && std::abs(b.x) < 1e6 && std::abs(b.y) < 1e6)) continue;
    const double taper0 = 1 - 0.6 * static_cast<double>(i) / static_cast<double>(pts.size() - 1);
    const double taper1 = 1 - 0.6 * static_cast<double>(i + 1) / static_cast<double>(pts.size() - 1);
    const double wmax = width * taper0;
    const double reach = wmax / 2 + 1;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min(a.x, b.x) - reach)));
    const int x1 = std::min(cover.cols, static_cast<int>(std::ceil(std::max(a.x, b.x) + reach)));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min(a.y, b.y) - reach)));
    const int y1 = std::min(cover.rows, static_cast<int>(std::ceil(std::max(a.y, b.y) + reach)));
    const cv::Point2d ab = b - a;
    const double l2 = ab.dot(ab) + 1e-300;
    const double reach2 = reach * reach;
    for (int y = y0; y < y1; ++y) {
      // The columns this row can touch: where the segment is within `reach` of the row.
      int xa = x0, xb = x1;
      if (std::abs(ab.y) > 1e-9) {
        double t0 = (y + 0.5 - reach - a.y) / ab.y, t1 = (y + 0.5 + reach - a.y) / ab.y;
        if (t0 > t1) std::swap(t0, t1);
        t0 = std::clamp(t0, 0.0, 1.0);
        t1 = std::clamp(t1, 0.0, 1.0);
        const double xs0 = a.x + ab.x * t0, xs1 = a.x + ab.x * t1;
        xa = std::max(x0, static_cast<int>(std::floor(std::min(xs0, xs1) - reach)));
        xb = std::min(x1, static_cast<int>(std::ceil(std::max(xs0, xs1) + reach)));
      }
      float* row = cover.ptr<float>(y);
      for (int x = xa; x < xb; ++x) {
        const cv::Point2d p(x + 0.5 - a.x, y + 0.5 - a.y);
        const double tt = std::clamp(p.dot(ab) / l2, 0.0, 1.0);
        const double dx = p.x - tt * ab.x, dy = p.y - tt * ab.y;
        const double d2 = dx * dx + dy * dy;
        if (d2 >= reach2) continue;
        const double dist = std::sqrt(d2);
        const double w = width * (taper0 + (taper1 - taper0) * tt);
        // Box-filtered coverage of a line of width w (thin lines: fainter, not thicker).
        const double c = std::clamp(0.5 + w / 2 - dist, 0.0, std::min(1.0, w)) * opacity;
        row[x] = std::max(row[x], static_cast<float>(c));
      }
    }
  }
}

// Glints: every reflection on the corneal cap is drawn (masked by the lids per pixel); the
// truth lists those whose centre is inside the image and the lid opening.
std::vector<GlintSplat> glint_splats(const std::vector<GlintGeom>& glints, int width, int height) {
  const double sigma = std::clamp(std::sqrt(static_cast<double>(width) * height / (320.0 * 240.0)), 0.8, 2.5);
  std::vector<GlintSplat> splats;
  for (const GlintGeom& g : glints)
    if (g.on_cap) {
      GlintSplat s = make_splat(g.image, sigma, 700.0, width, height);
      if (s.x0 < s.x1 && s.y0 < s.y1) splats.push_back(std::move(s));
    }
  return splats;
}

// Per-frame constants of the pixel loop. The frame's geometry is small and copied; the look's
// textures are pointed to.
struct Shading {
  int width = 0, height = 0;
  std::size_t w = 0, h = 0;
  Camera cam;
  Lids lids;
  Conic pc, ic;      // pupil, iris
  cv::Matx33d hinv;  // image -> pupil plane (mm)
  struct {
    double skin = 0, sclera = 0, pupil = 0, lash = 0, iris_inner = 0;  // grey levels
    const float* iris = nullptr;                                      // Look::kRho rows of Look::kTheta
    const float *wave_cx = nullptr, *wave_sx = nullptr, *wave_cy = nullptr, *wave_sy = nullptr;
    std::size_t nw = 0;  // skin waves
  } look;
  bool iris_on = false;
  double ix0 = 0, ix1 = 0, iy0 = 0, iy1 = 0;  // the iris's bounding box, 2 px wider
  double px0 = 0, px1 = 0, py0 = 0, py1 = 0;  // the pupil's
  double pupil_r = 0;                         // mm
  double flat0 = 0, flat1 = 0;                // mm past the pupil: the iris is flat, then fades into its texture
  double rho_scale = 0, theta_scale = 0;      // pupil-plane polar coordinates -> iris texture bins
  double ox = 0, oy = 0, oz = 0, o2 = 0, rb2 = 0;  // camera -> eyeball centre in camera axes; its |.|^2; radius^2
  double lash_line_w = 0, lower_line_w = 0, crease_w = 0, socket_w = 0, shadow_w = 0;  // pixels
  double inv_half = 0;
  double band = 0, band2 = 0;  // margin features lie within this
  double crease0 = 0, crease1 = 0;
};

// What every pixel of row y shares.
struct RowShading {
  int y = 0;
  double py = 0, yn = 0, dy = 0;
  float cy[8]{}, sy[8]{};  // the skin waves' factors for this row
  std::array<const GlintSplat*, 8> active{};  // the glints that reach this row
  std::size_t n_active = 0;
  bool in_iris = false, in_pupil = false;
};

RowShading row_shading(const Shading& c, const std::vector<GlintSplat>& splats, int y) {
  RowShading r;
  r.y = y;
  r.py = y + 0.5;
  r.yn = (r.py - c.cam.cy) / c.cam.f;
  r.dy = r.py - c.lids.mid.y;
  for (std::size_t k = 0; k < c.look.nw; ++k) {
    r.cy[k] = c.look.wave_cy[k * c.h + static_cast<std::size_t>(y)];
    r.sy[k] = c.look.wave_sy[k * c.h + static_cast<std::size_t>(y)];
  }
  for (const GlintSplat& s : splats)
    if (y >= s.y0 && y < s.y1 && r.n_active < r.active.size()) r.active[r.n_active++] = &s;
  r.in_iris = c.iris_on && r.py >= c.iy0 && r.py <= c.iy1;
  r.in_pupil = c.pc.valid && r.py >= c.py0 && r.py <= c.py1;
  return r;
}

// A pixel's place in the lid frame (s, hh) and its distances inside the upper and lower margins.
struct LidDistances {
  double s, hh;
  double raw_u, raw_l;  // along n
  double du, dl;        // perpendicular to the margin within `band` of it, else raw
};

// Distances from the lid margins: vertical (along n) everywhere, made perpendicular only
// near the margins, where the coverage and the margin lines need them.
LidDistances lid_distances(const Shading& c, double dx, double dy) {
  const Lids& lids = c.lids;
  const double s = (dx * lids.t.x + dy * lids.t.y) * c.inv_half;
  const double hh = dx * lids.n.x + dy * lids.n.y;
  const double omsq = 1 - s * s;
  const double raw_u = hh - omsq * (lids.u0 + lids.u1 * s), raw_l = omsq * (lids.l0 + lids.l1 * s) - hh;
  double du = raw_u, dl = raw_l;
  const double su = Lids::slope(lids.u0, lids.u1, s) * c.inv_half, sl = Lids::slope(lids.l0, lids.l1, s) * c.inv_half;
  if (raw_u * raw_u < c.band2 * (1 + su * su)) du = raw_u / std::sqrt(1 + su * su);
  if (raw_l * raw_l < c.band2 * (1 + sl * sl)) dl = raw_l / std::sqrt(1 + sl * sl);
  return {s, hh, raw_u, raw_l, du, dl};
}

// The skin's soft waves at pixel x of the row: sum of amp cos(kx x + phi + ky y), separable per wave.
double skin_wave(const Shading& c, const RowShading& r, int x) {
  double wave = 0;
  for (std::size_t k = 0; k < c.look.nw; ++k)
    wave += static_cast<double>(c.look.wave_cx[k * c.w + static_cast<std::size_t>(x)] * r.cy[k] -
                                c.look.wave_sx[k * c.w + static_cast<std::size_t>(x)] * r.sy[k]);
  return wave;
}

// Skin: base level, soft waves, socket shading near the opening, the lash line along the
// upper margin, a fainter line along the lower margin and the upper-lid crease.
double skin_level(const Shading& c, const LidDistances& ld, double wave, double corner) {
  double skin = c.look.skin + wave;
  const double outside = std::max(-ld.raw_u, -ld.raw_l);
  if (outside > 0) {
    const double q = 1 + outside / c.socket_w;
    skin *= 1 - 0.12 / (q * q);
  }
  const double crease_d = (ld.hh - Lids::curve(c.crease0, c.crease1, ld.s)) / c.crease_w;
  if (std::abs(crease_d) < 3.5) skin *= 1 - 0.14 * c.lids.open * corner * std::exp(-crease_d * crease_d);
  if (ld.du > -c.band && ld.du < 1.5) {  // above the upper margin: the lash line
    const double xu = -ld.du;
    const double mu = xu < 0.5 * c.lash_line_w ? 1.0 : bump((xu - 0.5 * c.lash_line_w) / (0.5 * c.lash_line_w));
    skin += (c.look.lash - skin) * 0.92 * mu * corner;
  }
  if (ld.dl > -c.band && ld.dl < 1.5) {  // below the lower margin
    const double xl = -ld.dl;
    const double ml = xl < 0.3 * c.lower_line_w ? 1.0 : bump((xl - 0.3 * c.lower_line_w) / (0.7 * c.lower_line_w));
    skin += (95.0 - skin) * 0.5 * ml * corner;
  }
  return skin;
}

}  // namespace

// render()'s stages that read the instance's Look (a private type, hence members); the others are
// free functions (here and in synthetic_eye_capture.cpp). Their order in render() is the order of the image effects.
struct SyntheticEye::RenderStages {
  static Shading shading(const Frame& fr, const Look& look, const SyntheticEyeOptions& o, double ppm);
  static cv::Mat1f shade_pixels(const Shading& c, const std::vector<GlintSplat>& splats);
  static double eye_level(const Shading& c, const RowShading& r, const LidDistances& ld, int x, double px,
                          double wave);
  static double iris_level(const Shading& c, double px, double py);
  static void draw_eyelashes(cv::Mat1f& img, const Lids& lids, const Look& look, double ppm, bool lit);
  static void add_spectacle_reflections(cv::Mat1f& img, const Look& look);
};

Shading SyntheticEye::RenderStages::shading(const Frame& fr, const Look& look, const SyntheticEyeOptions& o,
                                            double ppm) {
  Shading c;
  c.width = o.width;
  c.height = o.height;
  c.w = static_cast<std::size_t>(c.width);
  c.h = static_cast<std::size_t>(c.height);
  c.cam = fr.cam;
  c.lids = fr.lids;
  c.pc = fr.pupil;
  c.ic = fr.iris;
  c.hinv = fr.hinv;
  c.look.skin = look.skin;
  c.look.sclera = look.sclera;
  c.look.pupil = look.pupil;
  c.look.lash = look.lash;
  c.look.iris_inner = look.iris_inner;
  c.look.iris = look.iris.data();
  c.look.wave_cx = look.wave_cx.data();
  c.look.wave_sx = look.wave_sx.data();
  c.look.wave_cy = look.wave_cy.data();
  c.look.wave_sy = look.wave_sy.data();
  c.look.nw = look.waves.size();

  const Conic& pc = fr.pupil;
  const Conic& ic = fr.iris;
  c.iris_on = ic.valid;
  c.ix0 = ic.c.x - ic.half_w - 2;
  c.ix1 = ic.c.x + ic.half_w + 2;
  c.iy0 = ic.c.y - ic.half_h - 2;
  c.iy1 = ic.c.y + ic.half_h + 2;
  c.px0 = pc.c.x - pc.half_w - 2;
  c.px1 = pc.c.x + pc.half_w + 2;
  c.py0 = pc.c.y - pc.half_h - 2;
  c.py1 = pc.c.y + pc.half_h + 2;
  const double iris_r = o.eye.iris_radius_mm;
  c.pupil_r = fr.pupil_r;
  // The iris is flat for a few pixels outside the pupil so the pupil edge has the same contrast
  // all round (an unbiased edge for centre measurements), then fades into its texture.
  c.flat0 = std::max(0.15, 2.5 / ppm);
  c.flat1 = c.flat0 + std::max(0.3, 3.0 / ppm);
  c.rho_scale = (Look::kRho - 1) / std::max(iris_r - c.pupil_r, 1e-6);
  c.theta_scale = Look::kTheta / (2 * kPi);
  // Sclera shading: cosine of incidence on the eyeball sphere from the ray's distance to its centre.
  const V3 oc = -fr.cam.pos;  // camera -> eyeball centre
  c.ox = oc.dot(fr.cam.right);
  c.oy = oc.dot(fr.cam.down);
  c.oz = oc.dot(fr.cam.fwd);
  c.o2 = oc.dot(oc);
  c.rb2 = o.eye.eyeball_radius_mm * o.eye.eyeball_radius_mm;
  c.lash_line_w = std::max(1.2, 0.22 * ppm);
  c.lower_line_w = std::max(0.8, 0.12 * ppm);
  c.crease_w = std::max(1.5, 0.9 * ppm);
  c.socket_w = std::max(2.0, 2.0 * ppm);
  c.shadow_w = std::max(0.8, 0.5 * ppm);
  c.inv_half = 1.0 / fr.lids.half;
  c.band = c.lash_line_w + 2.0;
  c.band2 = c.band * c.band;
  c.crease0 = fr.lids.uo0 * 1.6;
  c.crease1 = fr.lids.uo1 * 1.6;
  return c;
}

// Skin, eye and glints pixel by pixel, the eye blended over the skin by the pixel's coverage of the
// lid opening.
cv::Mat1f SyntheticEye::RenderStages::shade_pixels(const Shading& c, const std::vector<GlintSplat>& splats) {
  cv::Mat1f img(c.height, c.width);
  for (int y = 0; y < c.height; ++y) {
    float* row = img.ptr<float>(y);
    const RowShading r = row_shading(c, splats, y);
    for (int x = 0; x < c.width; ++x) {
      const double px = x + 0.5;
      const LidDistances ld = lid_distances(c, px - c.lids.mid.x, r.dy);
      const double open = opening_coverage(ld.du, ld.dl);
      const double corner = clamp01((1.06 - std::abs(ld.s)) / 0.12);  // lid-margin features fade at the corners
      const double wave = skin_wave(c, r, x);
      const double skin = skin_level(c, ld, wave, corner);
      double value = skin;
      if (open > 0) {
        const double eye = eye_level(c, r, ld, x, px, wave);
        value = skin + (eye - skin) * open;
      }
      row[x] = static_cast<float>(value);
    }
  }
  return img;
}

// The eye in the lid opening at pixel (px, r.py): the sclera shaded by the cosine of incidence, the
// iris and the pupil by their area coverage, the upper lid's shadow and the glints.
double SyntheticEye::RenderStages::eye_level(const Shading& c, const RowShading& r, const LidDistances& ld, int x,
                                             double px, double wave) {
  const double py = r.py;
  const double xn = (px - c.cam.cx) / c.cam.f;
  const double od = c.ox * xn + c.oy * r.yn + c.oz;
  const double dist2 = c.o2 - od * od / (xn * xn + r.yn * r.yn + 1);
  const double cosi = std::sqrt(std::max(0.0, 1 - dist2 / c.rb2));
  double eye = c.look.sclera * (0.6 + 0.4 * cosi) + 0.3 * wave;
  if (r.in_iris && px >= c.ix0 && px <= c.ix1) {
    const double ai = c.ic.coverage(px, py);
    if (ai > 0) {
      double ap = 0;
      if (r.in_pupil && px >= c.px0 && px <= c.px1) ap = std::min(c.pc.coverage(px, py), ai);
      double iris_v = c.look.iris_inner;
      if (ai - ap > 0) iris_v = iris_level(c, px, py);
      eye = eye * (1 - ai) + iris_v * (ai - ap) + c.look.pupil * ap;
    }
  }
  const double shadow_x = std::max(ld.raw_u, 0.0) / c.shadow_w;
  if (shadow_x < 8) eye *= 1 - 0.3 * std::exp(-shadow_x);  // the upper lid's shadow
  for (std::size_t k = 0; k < r.n_active; ++k) {
    const GlintSplat& g = *r.active[k];
    if (x >= g.x0 && x < g.x1)
      eye += static_cast<double>(g.gx[static_cast<std::size_t>(x - g.x0)] * g.gy[static_cast<std::size_t>(r.y - g.y0)]);
  }
  return eye;
}

// The iris at pixel (px, py): the pixel mapped onto the pupil plane (hinv), its polar coordinates
// looked up bilinearly in the look's iris texture, faded in from iris_inner past the flat ring.
double SyntheticEye::RenderStages::iris_level(const Shading& c, double px, double py) {
  double iris_v = c.look.iris_inner;
  const double qa = c.hinv(0, 0) * px + c.hinv(0, 1) * py + c.hinv(0, 2);
  const double qb = c.hinv(1, 0) * px + c.hinv(1, 1) * py + c.hinv(1, 2);
  const double qw = c.hinv(2, 0) * px + c.hinv(2, 1) * py + c.hinv(2, 2);
  const double a = qa / qw, b = qb / qw;
  const double rho = std::sqrt(a * a + b * b);
  const double blend = smoothstep(c.flat0, c.flat1, rho - c.pupil_r);
  if (blend > 0 && std::isfinite(rho)) {
    const double tr = std::clamp((rho - c.pupil_r) * c.rho_scale, 0.0, Look::kRho - 1.0);
    double tt = (fast_atan2(b, a) + kPi) * c.theta_scale;
    const int r0 = std::min(static_cast<int>(tr), Look::kRho - 2);
    int t0 = static_cast<int>(tt);
    const double fr_r = tr - r0, fr_t = tt - t0;
    t0 %= Look::kTheta;
    const int t1 = (t0 + 1) % Look::kTheta;
    const float* r0p = &c.look.iris[static_cast<std::size_t>(r0 * Look::kTheta)];
    const float* r1p = r0p + Look::kTheta;
    const double tex = (1 - fr_r) * ((1 - fr_t) * static_cast<double>(r0p[t0]) + fr_t * static_cast<double>(r0p[t1])) +
                       fr_r * ((1 - fr_t) * static_cast<double>(r1p[t0]) + fr_t * static_cast<double>(r1p[t1]));
    iris_v += (tex - c.look.iris_inner) * blend;
  }
  return iris_v;
}

// Eyelashes over everything (they are in front of the eye): darkening towards their level or, lit
// (`lit_lashes`), at their own level, so lighter than the pupil they cross.
void SyntheticEye::RenderStages::draw_eyelashes(cv::Mat1f& img, const Lids& lids, const Look& look, double ppm,
                                               bool lit) {
  const int width = img.cols, height = img.rows;
  cv::Mat1f cover(height, width, 0.0f);
  std::vector<cv::Point2d> pts(8);
  for (const Look::Lash& l : look.lashes) {
    const double hb = Lids::curve(lids.u0, lids.u1, l.s);
    const cv::Point2d base = lids.point(l.s, hb);
    // Direction: image "down" of the lid frame, turned towards the corners.
    const double ct = std::cos(l.tilt), st = std::sin(l.tilt);
    const cv::Point2d d0 = lids.n * ct + lids.t * st;
    const double cc = std::cos(l.tilt + l.curl), sc = std::sin(l.tilt + l.curl);
    const cv::Point2d d1 = lids.n * cc + lids.t * sc;
    const double length = l.length_mm * ppm;
    const cv::Point2d p1 = base + d0 * (0.55 * length), p2 = p1 + d1 * (0.55 * length);
    for (std::size_t i = 0; i < pts.size(); ++i) {  // quadratic Bezier
      const double t = static_cast<double>(i) / static_cast<double>(pts.size() - 1);
      pts[i] = base * ((1 - t) * (1 - t)) + p1 * (2 * t * (1 - t)) + p2 * (t * t);
    }
    draw_stroke(cover, pts, std::max(0.7, l.width_mm * ppm), l.opacity);
  }
  const float level = static_cast<float>(look.lash);
  for (int y = 0; y < height; ++y) {
    float* row = img.ptr<float>(y);
    const float* c = cover.ptr<float>(y);
    for (int x = 0; x < width; ++x)
      if (c[x] > 0) row[x] += ((lit ? level : std::min(row[x], level)) - row[x]) * c[x];
  }
}

// Spectacle reflections: soft, flat-topped, semi-transparent (screen blend).
void SyntheticEye::RenderStages::add_spectacle_reflections(cv::Mat1f& img, const Look& look) {
  const int width = img.cols, height = img.rows;
  for (const Look::Reflection& r : look.reflections) {
    const double ca = std::cos(r.angle), sa = std::sin(r.angle);
    const double reach = std::max(r.a, r.b) * 1.6 + 1;
    const int x0 = std::max(0, static_cast<int>(r.centre.x - reach));
    const int x1 = std::min(width, static_cast<int>(r.centre.x + reach) + 1);
    const int y0 = std::max(0, static_cast<int>(r.centre.y - reach));
    const int y1 = std::min(height, static_cast<int>(r.centre.y + reach) + 1);
    for (int y = y0; y < y1; ++y) {
      float* row = img.ptr<float>(y);
      for (int x = x0; x < x1; ++x) {
        const double ex = x + 0.5 - r.centre.x, ey = y + 0.5 - r.centre.y;
        const double u = (ex * ca + ey * sa) / r.a, v = (-ex * sa + ey * ca) / r.b;
        const double q2 = u * u + v * v;
        if (q2 > 2.6) continue;
        const double a = r.strength * std::exp(-q2 * q2);
        const double val = static_cast<double>(row[x]);
        row[x] = static_cast<float>(val + (255.0 - val) * a);
      }
    }
  }
}

cv::Mat SyntheticEye::render(double yaw_deg, double pitch_deg, double openness, EyeTruth* truth) {
  const Frame fr = frame(yaw_deg, pitch_deg, openness);
  const std::uint64_t noise_seed = rng_();  // one draw per frame, whatever the options
  const Look& look = *look_;
  const SyntheticEyeOptions& o = options_;
  const double ppm = std::max(fr.px_per_mm, 1e-3);

  const std::vector<GlintSplat> splats = glint_splats(fr.glints, o.width, o.height);
  cv::Mat1f img = RenderStages::shade_pixels(RenderStages::shading(fr, look, o, ppm), splats);
  if (o.eyelashes && !look.lashes.empty()) RenderStages::draw_eyelashes(img, fr.lids, look, ppm, o.lit_lashes);
  if (o.illumination_gradient > 0) apply_uneven_illumination(img, o.illumination_gradient, look.gradient_dir);
  if (o.glasses_reflection) RenderStages::add_spectacle_reflections(img, look);
  if (o.exposure != 1.0) img *= o.exposure;  // all of it is the LEDs' light
  apply_optics(img, o);
  cv::Mat out = sensor_readout(img, o.noise_sigma, noise_seed);
  if (truth) *truth = fr.truth;
  return out;
}

}  // namespace fovea::trackerd::eye
