// SPDX-License-Identifier: Apache-2.0
#include "dof/lee_splat.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/vec4.hpp>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace fovea::render::dof {

namespace {

// Colour components are clamped to +-kColorCap before splatting so that no sum of weighted colours
// (weights <= 1, at most a few million terms) can overflow a float; 1e6 HDR highlights pass as is.
constexpr float kColorCap = 1e30f;
// Destination rows per band (one TBB task). 4 rows x 1024 px x (3 layers x 16 B + B_v, δC_v) ~ 230 KiB:
// the band's layers stay in L2 while every point that reaches them is splatted (measured at
// 1024 x 768, mean CoC 16: 4 rows ~15 % faster than 8).
constexpr int kBandRows = 4;
// Points are bucketed by radius class k (R <= 2^k px) and source row, so that a band visits only
// the source rows that the points of each class can reach.
constexpr int kClasses = 26;
// Slack on footprint edges so that a pixel centre exactly on the rim is inside, symmetrically.
constexpr double kRim = 1e-4;
// A normalisation denominator at or below this is taken as empty (eq. 5.4's "non-zero pixels").
constexpr float kMinAlpha = 1e-20f;

// 12 Poisson-disc samples in the unit disc (the common 12-tap set of real-time DOF shaders), for the
// Laplacian test of eq. 5.1 ("12 Poisson disk samples" within the CoC).
constexpr std::array<std::array<double, 2>, 12> kPoisson = {{{-0.326212, -0.405805},
                                                            {-0.840144, -0.073580},
                                                            {-0.695914, 0.457137},
                                                            {-0.203345, 0.620716},
                                                            {0.962340, -0.194983},
                                                            {0.473434, -0.480026},
                                                            {0.519456, 0.767022},
                                                            {0.185461, -0.893124},
                                                            {0.507431, 0.064425},
                                                            {0.896420, 0.412458},
                                                            {-0.321940, -0.932615},
                                                            {-0.791559, -0.597705}}};

// Nearest integer, for sample positions (clamped to the image right after): cheaper than lround.
int round_int(double v) {
  constexpr double kBias = 1 << 24;
  return static_cast<int>(std::clamp(v, -1e7, 1e7) + kBias + 0.5) - (1 << 24);
}

// floor and ceil for footprint bounds (|v| < 1e7 after clamping): inline, where std::floor and
// std::ceil are library calls without SSE4.1, and they run per footprint row.
int floor_int(double v) {
  constexpr double kBias = 1 << 24;
  return static_cast<int>(std::clamp(v, -1e7, 1e7) + kBias) - (1 << 24);
}
int ceil_int(double v) { return -floor_int(-v); }

float sane(float v) { return std::isfinite(v) ? std::clamp(v, -kColorCap, kColorCap) : 0.0f; }
glm::vec3 sane(const glm::vec3& c) { return {sane(c.x), sane(c.y), sane(c.z)}; }
float finite_or_zero(float v) { return std::isfinite(v) ? v : 0.0f; }

// Lee 2009, eq. 5.5: LDR extrapolation of bright pixels so that they stand out once defocused.
// λ_n is clamped to [0, 1]: the paper assumes LDR input (λ <= 1); brighter (HDR) pixels get the full
// gain γ rather than an unbounded one.
glm::vec3 extrapolate_highlight(const glm::vec3& f, const LeeSplatSettings& s) {
  const double l0 = s.highlight_threshold;
  if (!(l0 < 1)) return f;
  const double lambda = 0.3 * double{f.x} + 0.59 * double{f.y} + 0.11 * double{f.z};
  if (!(lambda > l0)) return f;
  const double ln = std::clamp((lambda - l0) / (1 - l0), 0.0, 1.0);
  const double p = std::pow(ln, std::max(0.0, s.highlight_falloff));
  const double g = (1 - p) + p * (std::isfinite(s.highlight_gain) ? s.highlight_gain : 1.0);
  return sane(f * static_cast<float>(g));
}

// One splat: a point of the visible image V, of the hidden image H, or a reduced block (§5.3).
struct Point {
  float cx = 0, cy = 0;  // footprint centre in pixel coordinates (pixel centres at integers)
  float r = -1;          // footprint radius C/2, clamped to the image diagonal; < 0: no point
  float b = 0;           // signed CoC B of eq. 5.3
  float w = 0;           // eq. 5.2's k_n(C)/C^2 (times the pixels a block stands for)
  glm::vec3 c{0};
  bool hidden = false;
};

// The footprint's pixel rows and, per row, its pixel span (unclipped), for radius R about (cx, cy).
// Disc and Gaussian: the disc |q - p| <= R (eq. 5.2's support); Hexagon: the regular hexagon of
// circumradius R with vertices up and down. Both are point-symmetric about the centre, so a source
// pixel reaches q exactly when q's mirror reaches it: with equal CoCs every pixel receives unit
// total weight, which is what makes constant images stay constant before normalisation.
struct Footprint {
  Aperture ap;
  double cx, cy, r;
  int row_lo() const { return ceil_int(cy - r - kRim); }
  int row_hi() const { return floor_int(cy + r + kRim); }
  bool span(int qy, int& xa, int& xb) const {
    const double dy = std::fabs(qy - cy);
    double hw = 0;
    if (ap == Aperture::Hexagon) {
      constexpr double kSqrt3 = 1.7320508075688772;
      hw = dy <= 0.5 * r ? 0.5 * kSqrt3 * r : (r - dy) * kSqrt3;
    } else {
      hw = std::sqrt(std::max(0.0, r * r - dy * dy));
    }
    if (hw < 0) return false;
    xa = ceil_int(cx - hw - kRim);
    xb = floor_int(cx + hw + kRim);
    return xa <= xb;
  }
};

// Gaussian IDF: σ = R / 2 (the disc truncates it at 2σ). Values along x from x0 by the recurrence
// g(x+1) = g(x) ρ(x), ρ(x+1) = ρ(x) q (three exp per row of values instead of one per pixel).
double gauss_a(double r) { return r > 0 ? 2.0 / (r * r) : 0.0; }  // 1 / (2 σ^2)
void gauss_row(double x0, int n, double a, double* out) {
  double g = std::exp(-x0 * x0 * a), rho = std::exp(-(2 * x0 + 1) * a);
  const double q = std::exp(-2 * a);
  for (int i = 0; i < n; ++i) {
    out[i] = g;
    g *= rho;
    rho *= q;
  }
}

// Lee 2009, eq. 5.2: A(p, q) = k_n(C) / C^2 over the rasterised footprint, with k_n(C) chosen per
// discrete footprint so that the intensities of one point sum to one (Fig. 5.5's look-up table).
// Here the sum is taken over the exact footprint of this point (any diameter, any sub-pixel centre)
// instead of a table per integer point size: returns 1 / sum of IDF values over the footprint.
double footprint_norm(const Footprint& f, std::vector<double>& scratch) {
  const int lo = f.row_lo(), hi = f.row_hi();
  double total = 0;
  if (f.ap == Aperture::Gaussian) {
    const double a = gauss_a(f.r);
    const int x0 = ceil_int(f.cx - f.r - kRim);
    const int n = floor_int(f.cx + f.r + kRim) - x0 + 1;
    scratch.resize(static_cast<std::size_t>(n) + 1);
    gauss_row(x0 - f.cx, n, a, scratch.data() + 1);
    scratch[0] = 0;
    for (std::size_t i = 1; i < scratch.size(); ++i) scratch[i] += scratch[i - 1];  // prefix sums
    for (int qy = lo; qy <= hi; ++qy) {
      int xa = 0, xb = 0;
      if (!f.span(qy, xa, xb)) continue;
      const double dy = qy - f.cy;
      const auto ia = static_cast<std::size_t>(std::clamp(xa - x0, 0, n));
      const auto ib = static_cast<std::size_t>(std::clamp(xb - x0 + 1, 0, n));
      total += std::exp(-dy * dy * a) * (scratch[ib] - scratch[ia]);
    }
  } else {
    for (int qy = lo; qy <= hi; ++qy) {
      int xa = 0, xb = 0;
      if (f.span(qy, xa, xb)) total += xb - xa + 1;
    }
  }
  return total > 0 ? 1.0 / total : 1.0;
}

int radius_class(float r) {
  int k = 0;
  while (k + 1 < kClasses && static_cast<float>(1 << k) < r) ++k;
  return k;
}

// One footprint row of one splat onto the per-pixel layers of destination pixels [xa, xb].
// Lee 2009, eq. 5.3: l = 0 (in front) if B(p) - B_v(q) < -δ C_v(q), 2 (behind) if > δ C_v(q), else 1
// (same depth group); the splat's premultiplied colour and alpha (eq. 5.2) go to layer l only, by
// additive blending. The layers of a pixel are adjacent (r, g, b, a) quadruples, so one splat costs
// one 4-wide add at the chosen layer instead of masked adds to all three.
template <bool kVarWeight>
void splat_row(glm::vec4* __restrict acc, const float* __restrict bvq, const float* __restrict tq,
               const float* __restrict wq, int xa, int xb, float b, const glm::vec4& cw, int lmin) {
#if defined(__SSE2__)
  float* const a = &acc[0].x;
  const __m128 c = _mm_loadu_ps(&cw.x);
  for (int x = xa; x <= xb; ++x) {
    const float d = b - bvq[x], t = tq[x];
    const int l = std::max(lmin, int{d >= -t} + int{d > t});
    float* const slot = a + 4 * (3 * x + l);
    if constexpr (kVarWeight) {
      _mm_storeu_ps(slot, _mm_add_ps(_mm_loadu_ps(slot), _mm_mul_ps(c, _mm_set1_ps(wq[x]))));
    } else {
      _mm_storeu_ps(slot, _mm_add_ps(_mm_loadu_ps(slot), c));
    }
  }
#else
  for (int x = xa; x <= xb; ++x) {
    const float d = b - bvq[x], t = tq[x];
    const int l = std::max(lmin, int{d >= -t} + int{d > t});
    if constexpr (kVarWeight) {
      acc[3 * x + l] += cw * wq[x];
    } else {
      acc[3 * x + l] += cw;
    }
  }
#endif
}

// Reusable per-thread buffers (one frame's worth), so that repeated frames do not reallocate.
struct Workspace {
  std::vector<glm::vec3> col;          // sanitised (and eq. 5.5-extrapolated) source colour of V
  std::vector<float> bv, cv, tv;       // B_v, C_v, δ C_v per pixel (eq. 5.3)
  std::vector<std::uint8_t> edge;      // §5.3: depth discontinuity within the (95 %) CoC
  std::vector<std::uint8_t> hid_ok;    // §5.1.2: the hidden pixel passed the three tests
  std::vector<std::uint8_t> covered;   // §5.3: pixel splatted through its reduced block
  std::vector<Point> slots;            // 2 per pixel: V (or its block) and H
  std::vector<Point> sorted;           // slots bucketed by (radius class, source row)
  std::vector<std::uint32_t> row_count;  // kClasses x height
  std::vector<std::size_t> offset;       // kClasses x height + 1
  std::vector<glm::vec4> acc;            // per pixel L^0, L^1, L^2 as (r, g, b, alpha), premultiplied
};

void prepare_workspace(Workspace& ws, std::size_t n) {
  ws.col.resize(n);
  ws.bv.resize(n);
  ws.cv.resize(n);
  ws.tv.resize(n);
  ws.edge.assign(n, 0);
  ws.hid_ok.assign(n, 0);
  ws.covered.assign(n, 0);
}

// The identity result (non-finite colour as 0), for frames where nothing is defocused.
void copy_input_finite(const DofInput& in, RgbImage& out) {
  const std::size_t n = in.pixels();
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = {finite_or_zero(in.color[i].x), finite_or_zero(in.color[i].y), finite_or_zero(in.color[i].z)};
  }
}

// Per-frame constants derived once from the input and settings, shared by every stage.
struct Frame {
  const DofInput& in;
  const LeeSplatSettings& s;
  int w, h;
  std::size_t uw, uh;
  float delta;           // δ of eq. 5.3, sanitised
  double r_cap;          // footprint radius cap: the image diagonal
  double zf, zscale;     // focus distance and §5.1.2's depth normalisation
  bool hidden_in;        // the hidden image H is present and used
  int reduce;            // §5.3's block size r
  float min_block_coc;   // §5.3: smallest C that may be splatted through a block
  double eps, lap_thr;   // §5.1.2's tests 1 and 3

  float signed_coc(float d) const {
    return static_cast<float>(std::clamp(in.coc.signed_coc_px(double{d}), -2 * r_cap, 2 * r_cap));
  }
  double znorm(float d) const {  // non-finite or non-positive depth: far (NaN, +inf) or 0
    const double z = double{d} / zscale;
    if (std::isnan(z)) return 1e6;
    return std::clamp(z, 0.0, 1e6);
  }
  // Lee 2009, eq. 5.1: L(p) = sum_n (Z_v(n) - Z_v(p)) / N_Ω over samples within radius `rad` of p.
  double laplacian(int x, int y, double rad, bool symmetric) const {
    const double zp = znorm(in.depth[std::size_t(y) * uw + std::size_t(x)]);
    double sum = 0;
    int count = 0;
    for (const auto& smp : kPoisson) {
      for (int sgn = 1; sgn >= (symmetric ? -1 : 1); sgn -= 2) {
        const int nx = std::clamp(round_int(x + sgn * smp[0] * rad), 0, w - 1);
        const int ny = std::clamp(round_int(y + sgn * smp[1] * rad), 0, h - 1);
        sum += znorm(in.depth[std::size_t(ny) * uw + std::size_t(nx)]) - zp;
        ++count;
      }
    }
    return sum / count;
  }
};

Frame make_frame(const DofInput& in, const LeeSplatSettings& s) {
  const int w = static_cast<int>(in.width), h = static_cast<int>(in.height);
  const CocModel& coc = in.coc;
  const float delta = static_cast<float>(std::isfinite(s.delta) ? std::max(0.0, s.delta) : 0.4);
  // A footprint of radius = the image diagonal covers the whole image from any pixel; CoCs larger
  // than the image are clamped to that (their weight 1/area then no longer falls with C: every such
  // pixel becomes the same whole-image blur). B is clamped alike so that it stays a finite float.
  const double diag = std::hypot(static_cast<double>(in.width), static_cast<double>(in.height));
  const double r_cap = std::max(1.0, diag);
  // §5.1.2's "normalized scale": depth / d_f (the focus distance is unit depth). Without a finite
  // focus distance, 1 m.
  const double zf = coc.focus_m;
  const double zscale = (std::isfinite(zf) && zf > 0) ? zf : 1.0;
  const bool hidden_in = s.use_hidden && in.hidden_color && in.hidden_depth;
  const int reduce = std::clamp(s.reduce, 1, 64);
  // §5.3: CoCs under 4 px stay at full resolution (the paper's "focused regions"), and so do CoCs
  // under 2 r, so that a block's sub-block shift of its centre (<= r / 2) stays under C / 4.
  const float min_block_coc = std::max(4.0f, 2.0f * static_cast<float>(reduce));
  const double eps = std::isfinite(s.hidden_epsilon) ? s.hidden_epsilon : 0.05;
  const double lap_thr = std::isfinite(s.laplacian_threshold) ? s.laplacian_threshold : 0.01;
  return Frame{.in = in,
               .s = s,
               .w = w,
               .h = h,
               .uw = std::size_t{in.width},
               .uh = static_cast<std::size_t>(h),
               .delta = delta,
               .r_cap = r_cap,
               .zf = zf,
               .zscale = zscale,
               .hidden_in = hidden_in,
               .reduce = reduce,
               .min_block_coc = min_block_coc,
               .eps = eps,
               .lap_thr = lap_thr};
}

// Lee 2009, §5.1.2: the three depth tests for the hidden fragment at p (of signed CoC b).
bool hidden_pixel_passes(const Frame& fr, int x, int y, std::size_t i, float b) {
  const DofInput& in = fr.in;
  const float zh = in.hidden_depth[i], zv = in.depth[i];
  bool ok = std::isfinite(zh) && zh > 0;
  ok = ok && fr.znorm(zh) >= fr.znorm(zv) + fr.eps;                     // 1: not the same surface (ε)
  ok = ok && !(fr.znorm(zv) > fr.zf / fr.zscale) && std::isfinite(zv);  // 2: visible pixel not background
  ok = ok && fr.laplacian(x, y, 0.5 * std::fabs(double{b}), false) >= fr.lap_thr;  // 3: eq. 5.1
  return ok;
}

struct PixelSummary {
  float max_c = 0;              // largest |B| of any splat (visible or accepted hidden)
  std::size_t hidden_used = 0;  // hidden pixels that passed §5.1.2's tests
};

// Pass 1 (per pixel): source colour, B_v, C_v, the hidden pixel's three tests, §5.3's edge flag.
PixelSummary classify_pixels(const Frame& fr, Workspace& ws) {
  const DofInput& in = fr.in;
  const LeeSplatSettings& s = fr.s;
  const int w = fr.w, h = fr.h;
  const std::size_t uw = fr.uw;
  std::vector<float> row_max_c(static_cast<std::size_t>(h), 0.0f);
  std::vector<std::size_t> row_hidden(static_cast<std::size_t>(h), 0);
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      float cmax = 0;
      std::size_t hid = 0;
      for (int x = 0; x < w; ++x) {
        const std::size_t i = std::size_t(y) * uw + std::size_t(x);
        glm::vec3 c = sane(in.color[i]);
        if (s.ldr_highlights) c = extrapolate_highlight(c, s);
        ws.col[i] = c;
        const float b = fr.signed_coc(in.depth[i]);
        ws.bv[i] = b;
        ws.cv[i] = std::fabs(b);
        ws.tv[i] = fr.delta * std::fabs(b);
        cmax = std::max(cmax, std::fabs(b));
        if (fr.hidden_in && hidden_pixel_passes(fr, x, y, i, b)) {
          ws.hid_ok[i] = 1;
          ++hid;
          cmax = std::max(cmax, std::fabs(fr.signed_coc(in.hidden_depth[i])));
        }
        if (fr.reduce > 1 && std::fabs(b) >= fr.min_block_coc) {
          // §5.3: where depth changes within (95 % of) the CoC, splat at full resolution. Samples
          // are mirrored so that a planar depth ramp has L = 0 exactly and is not flagged.
          ws.edge[i] = std::fabs(fr.laplacian(x, y, 0.95 * 0.5 * std::fabs(double{b}), true)) >= fr.lap_thr;
        }
      }
      row_max_c[std::size_t(y)] = cmax;
      row_hidden[std::size_t(y)] = hid;
    }
  });
  PixelSummary sum;
  for (std::size_t y = 0; y < row_hidden.size(); ++y) sum.hidden_used += row_hidden[y];
  sum.max_c = *std::max_element(row_max_c.begin(), row_max_c.end());
  return sum;
}

// One splat of eq. 5.2: radius C/2 (capped at the image diagonal), weight k_n(C)/C^2 times `weight`.
Point make_point(const Frame& fr, double cx, double cy, float b, float weight, const glm::vec3& c, bool hidden,
                 std::vector<double>& scratch) {
  Point p;
  p.cx = static_cast<float>(cx);
  p.cy = static_cast<float>(cy);
  p.r = static_cast<float>(std::min(0.5 * std::fabs(double{b}), fr.r_cap));
  p.b = b;
  const Footprint f{fr.s.aperture, cx, cy, double{p.r}};
  p.w = static_cast<float>(double{weight} * footprint_norm(f, scratch));
  p.c = c;
  p.hidden = hidden;
  return p;
}

// §5.3's reduced point array: one point per r x r block that passes the tests (see build_points).
void reduced_block_points(const Frame& fr, Workspace& ws) {
  const int reduce = fr.reduce;
  const std::size_t uw = fr.uw;
  const int bw = fr.w / reduce, bh = fr.h / reduce;  // whole blocks only; the rest stays at full resolution
  const auto r2 = static_cast<float>(reduce * reduce);
  tbb::parallel_for(tbb::blocked_range<int>(0, bh), [&](const tbb::blocked_range<int>& brows) {
    std::vector<double> scratch;
    for (int by = brows.begin(); by < brows.end(); ++by) {
      for (int bx = 0; bx < bw; ++bx) {
        float cmin = std::numeric_limits<float>::max(), bmin = cmin, bmax = -cmin;
        bool ok = true;
        double bsum = 0;
        glm::dvec3 csum(0);
        for (int yy = by * reduce; ok && yy < (by + 1) * reduce; ++yy) {
          for (int xx = bx * reduce; xx < (bx + 1) * reduce; ++xx) {
            const std::size_t i = std::size_t(yy) * uw + std::size_t(xx);
            if (ws.edge[i] || ws.hid_ok[i]) {
              ok = false;
              break;
            }
            cmin = std::min(cmin, ws.cv[i]);
            bmin = std::min(bmin, ws.bv[i]);
            bmax = std::max(bmax, ws.bv[i]);
            bsum += double{ws.bv[i]};
            csum += glm::dvec3(ws.col[i]);
          }
        }
        if (!ok || cmin < fr.min_block_coc || bmax - bmin > fr.delta * cmin) continue;
        for (int yy = by * reduce; yy < (by + 1) * reduce; ++yy) {
          for (int xx = bx * reduce; xx < (bx + 1) * reduce; ++xx) {
            ws.covered[std::size_t(yy) * uw + std::size_t(xx)] = 1;
          }
        }
        const double inv = 1.0 / double{r2};
        const std::size_t i0 = std::size_t(by * reduce) * uw + std::size_t(bx * reduce);
        ws.slots[2 * i0] = make_point(fr, bx * reduce + 0.5 * (reduce - 1), by * reduce + 0.5 * (reduce - 1),
                                      static_cast<float>(bsum * inv), r2, sane(glm::vec3(csum * inv)), false, scratch);
      }
    }
  });
}

// One point per visible pixel not covered by a block, and one per accepted hidden pixel (§5.1.2).
void pixel_points(const Frame& fr, Workspace& ws) {
  const DofInput& in = fr.in;
  const LeeSplatSettings& s = fr.s;
  const int w = fr.w;
  const std::size_t uw = fr.uw;
  tbb::parallel_for(tbb::blocked_range<int>(0, fr.h), [&](const tbb::blocked_range<int>& rows) {
    std::vector<double> scratch;
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < w; ++x) {
        const std::size_t i = std::size_t(y) * uw + std::size_t(x);
        if (!ws.covered[i]) ws.slots[2 * i] = make_point(fr, x, y, ws.bv[i], 1.0f, ws.col[i], false, scratch);
        if (ws.hid_ok[i]) {
          glm::vec3 c = sane(in.hidden_color[i]);
          if (s.ldr_highlights) c = extrapolate_highlight(c, s);
          ws.slots[2 * i + 1] = make_point(fr, x, y, fr.signed_coc(in.hidden_depth[i]), 1.0f, c, true, scratch);
        }
      }
    }
  });
}

// Pass 2 (per block or pixel): the points. §5.3's reduced point array: an r x r block becomes one
// point (mean colour, mean B, weight r^2 at the block centre) when all its pixels are blurred
// (C >= max(4, 2 r), min_block_coc), lie in one depth group (B range <= δ min C, eq. 5.3's test), and
// none is at a depth edge or has a hidden pixel. Blocks are splatted onto the full-resolution
// layers, so the per-pixel layer decomposition stays exact.
void build_points(const Frame& fr, Workspace& ws) {
  ws.slots.assign(2 * fr.in.pixels(), Point{});
  if (fr.reduce > 1) reduced_block_points(fr, ws);
  pixel_points(fr, ws);
}

struct Buckets {
  std::size_t npts = 0;                            // points in all buckets
  std::array<std::size_t, kClasses> class_size{};  // points per radius class
};

// Pass 3: bucket the points by (radius class, source row), keeping row-major order inside each
// bucket, so that every destination pixel sums its splats in a fixed order (determinism).
Buckets bucket_points(const Frame& fr, Workspace& ws) {
  const int h = fr.h;
  const std::size_t uw = fr.uw, uh = fr.uh;
  ws.row_count.assign(kClasses * uh, 0);
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (std::size_t j = 2 * std::size_t(y) * uw; j < 2 * (std::size_t(y) + 1) * uw; ++j) {
        if (ws.slots[j].r >= 0) ++ws.row_count[std::size_t(radius_class(ws.slots[j].r)) * uh + std::size_t(y)];
      }
    }
  });
  ws.offset.assign(kClasses * uh + 1, 0);
  for (std::size_t k = 0; k < kClasses * uh; ++k) ws.offset[k + 1] = ws.offset[k] + ws.row_count[k];
  Buckets bk;
  bk.npts = ws.offset.back();
  ws.sorted.resize(bk.npts);
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
    std::array<std::size_t, kClasses> at{};
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (std::size_t k = 0; k < kClasses; ++k) at[k] = ws.offset[k * uh + std::size_t(y)];
      for (std::size_t j = 2 * std::size_t(y) * uw; j < 2 * (std::size_t(y) + 1) * uw; ++j) {
        if (ws.slots[j].r >= 0) ws.sorted[at[std::size_t(radius_class(ws.slots[j].r))]++] = ws.slots[j];
      }
    }
  });
  for (std::size_t k = 0; k < kClasses; ++k) bk.class_size[k] = ws.offset[(k + 1) * uh] - ws.offset[k * uh];
  return bk;
}

// One TBB task of pass 4: the destination rows [y0, y1) of its current band, the per-pixel layers
// and depth tests it splats against, and the task's scratch rows.
struct BandSplat {
  const Frame& fr;
  glm::vec4* acc;           // per pixel L^0, L^1, L^2 (Workspace::acc)
  const float* bv;          // B_v per pixel
  const float* tv;          // δ C_v per pixel
  std::vector<double> gx;   // Gaussian IDF along x of the point being splatted
  std::vector<float> wrow;  // its weights over one footprint row
  int y0 = 0, y1 = 0;
};

// One point onto the band's rows of the layers: eq. 5.2's footprint, eq. 5.3's layer (splat_row).
void splat_point(BandSplat& bd, const Point& p) {
  const LeeSplatSettings& s = bd.fr.s;
  const int w = bd.fr.w, y0 = bd.y0, y1 = bd.y1;
  const std::size_t uw = bd.fr.uw;
  std::vector<double>& gx = bd.gx;
  std::vector<float>& wrow = bd.wrow;
  const Footprint f{s.aperture, double{p.cx}, double{p.cy}, double{p.r}};
  const int qlo = std::max(y0, f.row_lo()), qhi = std::min(y1 - 1, f.row_hi());
  if (qlo > qhi) return;
  const bool gauss = s.aperture == Aperture::Gaussian;
  const double a = gauss_a(f.r);
  int gx0 = 0;
  if (gauss) {
    gx0 = std::max(0, ceil_int(f.cx - f.r - kRim));
    const int gx1 = std::min(w - 1, floor_int(f.cx + f.r + kRim));
    if (gx1 < gx0) return;
    gx.resize(static_cast<std::size_t>(gx1 - gx0 + 1));
    gauss_row(gx0 - f.cx, gx1 - gx0 + 1, a, gx.data());
  }
  // Hidden pixels never occlude (M^0 is not defined, §5.1.4): a hidden splat that would fall
  // in front of q is kept in the same-depth layer.
  const int lmin = p.hidden ? 1 : 0;
  const float b = p.b;
  const glm::vec4 cw(p.c * p.w, p.w);  // premultiplied colour and alpha of eq. 5.2
  for (int qy = qlo; qy <= qhi; ++qy) {
    int xa = 0, xb = 0;
    if (!f.span(qy, xa, xb)) continue;
    xa = std::max(xa, 0);
    xb = std::min(xb, w - 1);
    if (xa > xb) continue;
    const std::size_t o = std::size_t(qy) * uw;
    glm::vec4* const acc_row = bd.acc + 3 * o;
    if (gauss) {
      const double dy = qy - f.cy;
      const double gy = std::exp(-dy * dy * a);
      for (int x = xa; x <= xb; ++x) wrow[std::size_t(x)] = static_cast<float>(gy * gx[std::size_t(x - gx0)]);
      splat_row<true>(acc_row, bd.bv + o, bd.tv + o, wrow.data(), xa, xb, b, cw, lmin);
    } else {
      splat_row<false>(acc_row, bd.bv + o, bd.tv + o, nullptr, xa, xb, b, cw, lmin);
    }
  }
}

// Every point whose footprint can reach the band, class by class in bucket order (determinism).
void splat_band(BandSplat& bd, const Workspace& ws, const Buckets& bk) {
  const int h = bd.fr.h, y0 = bd.y0, y1 = bd.y1;
  const std::size_t uh = bd.fr.uh;
  for (std::size_t k = 0; k < kClasses; ++k) {
    if (bk.class_size[k] == 0) continue;
    const int margin = (1 << k) + bd.fr.reduce + 1;
    const int ylo = std::max(0, y0 - margin), yhi = std::min(h - 1, y1 - 1 + margin);
    const std::size_t beg = ws.offset[k * uh + std::size_t(ylo)], end = ws.offset[k * uh + std::size_t(yhi) + 1];
    for (std::size_t j = beg; j < end; ++j) splat_point(bd, ws.sorted[j]);
  }
}

// A composite divided by its alpha (1 afterwards), or empty (0) when nothing covers the pixel.
inline void unit_alpha(glm::vec3& d, float& da) {
  if (da > kMinAlpha) {
    d /= da;
    da = 1;
  } else {
    d = glm::vec3(0);
    da = 0;
  }
}

// Lee 2009, eq. 5.4: D <- L^2; D <- L^1 + (1 - L^1_a) D; D <- L^0 + (1 - L^0_a) D, with M^1, M^2
// already added into L^1, L^2 (they were splatted there). Each D is divided by its alpha
// (hyper/hypo intensities of overlapping CoCs); a layer's alpha above one (overlap) is taken
// as opaque in (1 - L_a) so that nothing behind it is subtracted. A pixel whose every layer is
// empty keeps its source colour (cannot happen: its own splat always lands on it).
void compose_layers(const glm::vec4* acc, const Workspace& ws, std::size_t o0, std::size_t o1, RgbImage& out) {
  for (std::size_t i = o0; i < o1; ++i) {
    const glm::vec4* l = acc + 3 * i;
    glm::vec3 d(l[2]);
    float da = l[2].w;
    unit_alpha(d, da);
    for (const int k : {1, 0}) {
      const float la = l[k].w;
      const float keep = 1.0f - std::min(std::max(la, 0.0f), 1.0f);
      d = glm::vec3(l[k]) + keep * d;
      da = la + keep * da;
      unit_alpha(d, da);
    }
    glm::vec3 r = da > 0 ? d : ws.col[i];
    out[i] = {finite_or_zero(r.x), finite_or_zero(r.y), finite_or_zero(r.z)};
  }
}

// Pass 4 (per band of destination rows): splat onto the per-pixel layers, then compose.
void splat_and_compose(const Frame& fr, Workspace& ws, const Buckets& bk, RgbImage& out) {
  const int h = fr.h;
  const std::size_t uw = fr.uw;
  ws.acc.resize(3 * fr.in.pixels());
  glm::vec4* const acc = ws.acc.data();
  const int bands = (h + kBandRows - 1) / kBandRows;
  tbb::parallel_for(tbb::blocked_range<int>(0, bands, 1), [&](const tbb::blocked_range<int>& br) {
    BandSplat bd{fr, acc, ws.bv.data(), ws.tv.data(), {}, std::vector<float>(uw), 0, 0};
    for (int band = br.begin(); band < br.end(); ++band) {
      bd.y0 = band * kBandRows;
      bd.y1 = std::min(h, bd.y0 + kBandRows);
      const std::size_t o0 = std::size_t(bd.y0) * uw, o1 = std::size_t(bd.y1) * uw;
      std::fill(acc + 3 * o0, acc + 3 * o1, glm::vec4(0));
      splat_band(bd, ws, bk);
      compose_layers(acc, ws, o0, o1, out);
    }
  });
}

}  // namespace

void lee_splat(const DofInput& in, const LeeSplatSettings& s, RgbImage& out, LeeSplatStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n = in.pixels();
  out.assign(n, glm::vec3(0));
  LeeSplatStats st;
  const auto finish = [&] {
    st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (stats) *stats = st;
  };
  if (n == 0 || !in.color) return finish();
  if (!in.depth) {  // no depth: nothing can be defocused
    copy_input_finite(in, out);
    return finish();
  }

  // The calling thread's buffers; the TBB workers in the stages reach them through this reference
  // (a thread_local named inside a lambda would be the worker's own, empty, instance).
  thread_local Workspace tls_workspace;
  Workspace& ws = tls_workspace;
  prepare_workspace(ws, n);
  const Frame fr = make_frame(in, s);

  const PixelSummary px = classify_pixels(fr, ws);
  st.hidden_used = px.hidden_used;
  // Every footprint is the pixel itself (C < 1 px everywhere, e.g. a pinhole): the result is the
  // input, exactly (eq. 5.4 with one unit-weight splat per pixel is the identity).
  if (px.max_c < 1.0f) {
    copy_input_finite(in, out);
    st.splats = n + st.hidden_used;
    return finish();
  }

  build_points(fr, ws);
  const Buckets bk = bucket_points(fr, ws);
  st.splats = bk.npts;
  splat_and_compose(fr, ws, bk, out);
  finish();
}

}  // namespace fovea::render::dof
