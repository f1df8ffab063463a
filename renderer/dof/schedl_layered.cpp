// SPDX-License-Identifier: Apache-2.0
#include "dof/schedl_layered.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <glm/vec4.hpp>

namespace fovea::render::dof {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
using Rgba = std::vector<glm::vec4>;  // premultiplied colour and alpha

float finite_or_zero(float v) { return std::isfinite(v) ? v : 0.0f; }

}  // namespace

// Three box blurs whose variances add up to sigma^2 approximate a Gaussian (Wells 1986): box
// widths wl (odd) for the first m passes and wl + 2 for the rest.
std::vector<int> schedl_box_radii(double sigma) {
  constexpr int n = 3;
  const double ideal = std::sqrt(12.0 * sigma * sigma / n + 1.0);
  int wl = static_cast<int>(std::floor(ideal));
  if (wl % 2 == 0) --wl;
  wl = std::max(wl, 1);
  const double m_ideal = (12.0 * sigma * sigma - n * wl * wl - 4.0 * n * wl - 3.0 * n) / (-4.0 * wl - 4.0);
  const int m = static_cast<int>(std::lround(m_ideal));
  std::vector<int> r;
  for (int i = 0; i < n; ++i) r.push_back(((i < m ? wl : wl + 2) - 1) / 2);
  return r;
}

namespace {

// One box pass of radius r along rows (horizontal) with clamped edges: a running sum per row, kept
// in double: in float, HDR light that left the window left a residue of its rounding in the sum for
// the rest of the row (1e6 beside 0.5: about 1 % of the dark pixels' value, 39.7 dB against a direct
// sum; tests/gl/test_gl_schedl_layered.cpp's HDR stripe).
void box_rows(const Rgba& src, Rgba& dst, int w, int h, int r) {
  const double inv = 1.0 / static_cast<double>(2 * r + 1);
  tbb::parallel_for(tbb::blocked_range<int>(0, h, 8), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const glm::vec4* in = src.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
      glm::vec4* out = dst.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
      const auto at = [&](int x) { return glm::dvec4(in[std::clamp(x, 0, w - 1)]); };
      glm::dvec4 sum(0.0);
      for (int j = -r; j <= r; ++j) sum += at(j);
      for (int x = 0; x < w; ++x) {
        out[x] = glm::vec4(sum * inv);
        sum += at(x + r + 1) - at(x - r);
      }
    }
  });
}

// One box pass along columns: a running sum per column (in double, as box_rows), rows streamed top
// to bottom.
void box_columns(const Rgba& src, Rgba& dst, int w, int h, int r) {
  const double inv = 1.0 / static_cast<double>(2 * r + 1);
  tbb::parallel_for(tbb::blocked_range<int>(0, w, 64), [&](const tbb::blocked_range<int>& cols) {
    const int x0 = cols.begin(), x1 = cols.end();
    std::vector<glm::dvec4> sum(static_cast<std::size_t>(x1 - x0), glm::dvec4(0.0));
    const auto row = [&](int y) {
      return src.data() + static_cast<std::size_t>(std::clamp(y, 0, h - 1)) * static_cast<std::size_t>(w);
    };
    for (int j = -r; j <= r; ++j) {
      const glm::vec4* p = row(j);
      for (int x = x0; x < x1; ++x) sum[static_cast<std::size_t>(x - x0)] += glm::dvec4(p[x]);
    }
    for (int y = 0; y < h; ++y) {
      glm::vec4* out = dst.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
      const glm::vec4* add = row(y + r + 1);
      const glm::vec4* sub = row(y - r);
      for (int x = x0; x < x1; ++x) {
        const auto i = static_cast<std::size_t>(x - x0);
        out[x] = glm::vec4(sum[i] * inv);
        sum[i] += glm::dvec4(add[x]) - glm::dvec4(sub[x]);
      }
    }
  });
}

// Gaussian blur of standard deviation sigma (px), in place (eq. 11 with H^_k).
void gaussian(Rgba& img, Rgba& tmp, int w, int h, double sigma) {
  if (!(sigma > 0.3)) return;
  for (const int r : schedl_box_radii(sigma)) {
    if (r <= 0) continue;
    box_rows(img, tmp, w, h, r);
    box_columns(tmp, img, w, h, r);
  }
}

// A over B for premultiplied colours.
inline glm::vec4 over(const glm::vec4& a, const glm::vec4& b) { return a + (1.0f - a.a) * b; }

// No method lets NaN or Inf through, nor negative light: such channels read as 0.
glm::vec3 sanitized(const glm::vec3& c) {
  return glm::vec3(std::max(0.0f, finite_or_zero(c.x)), std::max(0.0f, finite_or_zero(c.y)),
                   std::max(0.0f, finite_or_zero(c.z)));
}

// NaN depth (or no depth buffer) reads as the far limit; negative depth as 0.
double depth_of(const float* d, std::size_t i) {
  const double z = d == nullptr ? kInf : static_cast<double>(d[i]);
  return std::isnan(z) ? kInf : std::max(z, 0.0);
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The sanitised visible colour into out (the result where nothing covers a pixel); returns its largest
// channel, which bounds the result.
float copy_sanitized_input(const glm::vec3* color, std::size_t np, RgbImage& out) {
  float max_in = 0;
  for (std::size_t i = 0; i < np; ++i) {
    out[i] = sanitized(color[i]);
    max_in = std::max({max_in, out[i].x, out[i].y, out[i].z});
  }
  return max_in;
}

// I_0, I_1, ... of eq. 2, front to back: the visible layer, then the peeled ones that carry colour and depth.
std::vector<PeeledLayer> input_layers(const DofInput& in, const std::vector<PeeledLayer>& peeled) {
  std::vector<PeeledLayer> layers_in;
  layers_in.push_back({in.color, in.depth});
  for (const PeeledLayer& p : peeled) {
    if (p.color != nullptr && p.depth != nullptr) layers_in.push_back(p);
  }
  return layers_in;
}

struct DepthRange {
  double zmin = kInf, zmax = 0;  // zmin stays +inf where no depth is finite
};

// Depth range of the frame (every layer's finite depths).
DepthRange frame_depth_range(const std::vector<PeeledLayer>& layers_in, std::size_t np) {
  DepthRange range;
  for (const PeeledLayer& l : layers_in) {
    for (std::size_t i = 0; i < np; ++i) {
      const double z = depth_of(l.depth, i);
      if (std::isfinite(z)) {
        range.zmin = std::min(range.zmin, z);
        range.zmax = std::max(range.zmax, z);
      }
    }
  }
  return range;
}

// True where no depth of the frame blurs by half a pixel (or the lens cannot blur at all).
bool nothing_blurs(const CocModel& coc, double k, const DepthRange& range) {
  double max_c = 0;
  if (std::isfinite(range.zmin)) max_c = std::max(coc.coc_px(range.zmin), coc.coc_px(range.zmax));
  return coc.pinhole() || !(k >= 0) || max_c < 0.5 || !std::isfinite(coc.focus_m);
}

// Layer CoC d_j = 4 sigma_j (eq. 10) at j layers from the focus layer, sigma_j from eq. 15 with
// sigma^_j = j (eq. 14).
double layer_coc(int j) {
  double var = 0;
  for (int i = 1; i <= j; ++i) var += static_cast<double>(i) * i;
  return 4.0 * std::sqrt(var);
}

using LayerAnchors = SchedlAnchors;

// z_k, front to back, from the boundaries in front of and behind the focus layer (nearest-to-focus first).
LayerAnchors anchors_front_to_back(const std::vector<double>& front, const std::vector<double>& back) {
  const int kf = static_cast<int>(front.size());
  const int K = kf + 1 + static_cast<int>(back.size());
  LayerAnchors an{std::vector<double>(static_cast<std::size_t>(std::max(0, K - 1))), kf, K};
  std::vector<double>& z = an.z;
  for (int kk = 0; kk < kf; ++kk) z[static_cast<std::size_t>(kk)] = front[static_cast<std::size_t>(kf - 1 - kk)];
  for (int kk = kf; kk < K - 1; ++kk) z[static_cast<std::size_t>(kk)] = back[static_cast<std::size_t>(kk - kf)];
  return an;
}

// Anchors at the mean CoC of neighbouring layers (eq. 9), with D1 (eq. 6) in front of the focus and D2
// (eq. 7) behind it, added until they cover the frame's depth range, at most max_layers layers in all.
LayerAnchors layer_anchors(const CocModel& coc, double k, const DepthRange& range, int max_layers) {
  const int cap = std::max(1, max_layers);
  std::vector<double> front, back;  // boundaries, nearest-to-focus first
  const auto total = [&] { return 1 + static_cast<int>(front.size() + back.size()); };
  for (int j = 1; j <= cap; ++j) {
    const double c = 0.5 * (layer_coc(j - 1) + layer_coc(j));
    bool more = false;
    if (total() < cap && (front.empty() ? coc.focus_m : front.back()) > range.zmin) {
      front.push_back(coc.depth_near_for_coc(c));  // D1, eq. 6
      more = true;
    }
    if (total() < cap && (back.empty() ? coc.focus_m : back.back()) < range.zmax && c < k) {  // eq. 8: C < K
      const double zb = coc.depth_far_for_coc(c);                                               // D2, eq. 7
      if (std::isfinite(zb)) {
        back.push_back(zb);
        more = true;
      }
    }
    if (!more) break;
  }
  return anchors_front_to_back(front, back);
}

// Matting w'_k (eq. 3): 0 -> 1 over [z_{k-2}, z_{k-1}], 1 over [z_{k-1}, z_k], 0 behind. A ramp towards an
// infinite anchor is a hard edge.
float w_dot(const LayerAnchors& an, int kk, double d) {
  const double a = an.anchor(kk - 2), b = an.anchor(kk - 1), c = an.anchor(kk);
  if (d >= b && d <= c) return 1.0f;
  if (d > a && d < b && std::isfinite(a) && b > a) return static_cast<float>((d - a) / (b - a));
  return 0.0f;
}

// Matting w_k (eq. 4): w'_k, but falling 1 -> 0 over [z_k, z_{k+1}].
float w_full(const LayerAnchors& an, int kk, double d) {
  const double c = an.anchor(kk), e = an.anchor(kk + 1);
  if (d > c && d < e && std::isfinite(e) && e > c) return static_cast<float>((e - d) / (e - c));
  return w_dot(an, kk, d);
}

// What every layer L_k is made of.
struct LayerStack {
  const std::vector<PeeledLayer>& layers_in;  // I_0 (visible), I_1, ... (peeled)
  const RgbImage& visible;                    // I_0's colour, sanitised
  const LayerAnchors& anchors;
  std::size_t np;
  int w, h;
};

// L_k (eq. 2): the visible layer matted with w_k, the peeled ones with w'_k, front to back.
void matted_layer(const LayerStack& st, int kk, Rgba& L) {
  L.resize(st.np);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, st.np, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      glm::vec4 acc(0.0f);
      for (std::size_t l = 0; l < st.layers_in.size(); ++l) {
        const double d = depth_of(st.layers_in[l].depth, i);
        const float a = l == 0 ? w_full(st.anchors, kk, d) : w_dot(st.anchors, kk, d);
        if (a <= 0) continue;
        const glm::vec3 col = l == 0 ? st.visible[i] : sanitized(st.layers_in[l].color[i]);
        acc = over(acc, glm::vec4(col * a, a));
      }
      L[i] = acc;
    }
  });
}

// The cascade's accumulators and scratch images, reused from layer to layer.
struct CascadeBuffers {
  explicit CascadeBuffers(std::size_t np) : tmp(np) {}
  Rgba front_acc, back_acc;  // L^_{kf-1} and L^_{kf+1}; empty where there is no such layer
  Rgba layer, tmp;
};

// Cascaded blur of the front layers (eqs. 12-13): L^_k = (L^_{k-1} over L_k) * H^_k, sigma^_k = kf - k
// (eq. 14).
void blur_front_layers(const LayerStack& st, CascadeBuffers& buf) {
  const int kf = st.anchors.kf;
  if (kf <= 0) return;
  matted_layer(st, 0, buf.front_acc);
  gaussian(buf.front_acc, buf.tmp, st.w, st.h, kf);
  for (int kk = 1; kk < kf; ++kk) {
    matted_layer(st, kk, buf.layer);
    for (std::size_t i = 0; i < st.np; ++i) buf.front_acc[i] = over(buf.front_acc[i], buf.layer[i]);
    gaussian(buf.front_acc, buf.tmp, st.w, st.h, kf - kk);
  }
}

// Cascaded blur of the back layers (eqs. 12-13): L^_k = (L_k over L^_{k+1}) * H^_k, sigma^_k = k - kf
// (eq. 14).
void blur_back_layers(const LayerStack& st, CascadeBuffers& buf) {
  const int kf = st.anchors.kf, K = st.anchors.K;
  if (!(kf < K - 1)) return;
  matted_layer(st, K - 1, buf.back_acc);
  gaussian(buf.back_acc, buf.tmp, st.w, st.h, K - 1 - kf);
  for (int kk = K - 2; kk > kf; --kk) {
    matted_layer(st, kk, buf.layer);
    for (std::size_t i = 0; i < st.np; ++i) buf.back_acc[i] = over(buf.layer[i], buf.back_acc[i]);
    gaussian(buf.back_acc, buf.tmp, st.w, st.h, kk - kf);
  }
}

// I' = L^_{kf-1} over (L_kf over L^_{kf+1}) (eq. 13), with L_kf in buf.layer, into out.
void composite_and_normalise(const CascadeBuffers& buf, float max_in, RgbImage& out) {
  for (std::size_t i = 0; i < out.size(); ++i) {
    glm::vec4 r = buf.layer[i];
    if (!buf.back_acc.empty()) r = over(r, buf.back_acc[i]);
    if (!buf.front_acc.empty()) r = over(buf.front_acc[i], r);
    // Normalisation (§3.3.1): premultiplied colour over its alpha; no coverage keeps the input.
    if (r.a > 1e-6f && std::isfinite(r.a)) {
      const glm::vec3 c = glm::vec3(r) / r.a;
      out[i] = glm::clamp(glm::vec3(finite_or_zero(c.x), finite_or_zero(c.y), finite_or_zero(c.z)), 0.0f, max_in);
    }
  }
}

}  // namespace

double SchedlAnchors::anchor(int kk) const {
  if (kk < 0) return -kInf;
  if (kk >= K - 1) return kInf;
  return z[static_cast<std::size_t>(kk)];
}

std::optional<SchedlAnchors> schedl_anchors(const CocModel& coc, double zmin, double zmax, int max_layers) {
  const double k = coc.k_px();
  const DepthRange range{zmin, zmax};
  if (nothing_blurs(coc, k, range)) return std::nullopt;
  return layer_anchors(coc, k, range, max_layers);
}

void schedl_layered(const DofInput& in, const std::vector<PeeledLayer>& peeled, const SchedlSettings& s,
                    RgbImage& out, SchedlStats* stats) {
  const auto start = std::chrono::steady_clock::now();
  const std::size_t np = in.pixels();
  out.resize(np);
  if (np == 0 || in.color == nullptr) {
    std::fill(out.begin(), out.end(), glm::vec3(0.0f));
    return;
  }
  const int w = static_cast<int>(in.width), h = static_cast<int>(in.height);
  const float max_in = copy_sanitized_input(in.color, np, out);
  const std::vector<PeeledLayer> layers_in = input_layers(in, peeled);
  const DepthRange range = frame_depth_range(layers_in, np);
  const std::optional<SchedlAnchors> chosen = schedl_anchors(in.coc, range.zmin, range.zmax, s.max_layers);
  if (!chosen) {
    if (stats != nullptr) *stats = {1, 0, seconds_since(start)};
    return;  // nothing blurs by half a pixel: the input
  }
  const LayerAnchors& anchors = *chosen;
  const LayerStack stack{layers_in, out, anchors, np, w, h};
  CascadeBuffers buf(np);
  blur_front_layers(stack, buf);
  blur_back_layers(stack, buf);
  matted_layer(stack, anchors.kf, buf.layer);  // reads out (the visible colour) before the composite overwrites it
  composite_and_normalise(buf, max_in, out);
  if (stats != nullptr) *stats = {anchors.K, anchors.kf, seconds_since(start)};
}

}  // namespace fovea::render::dof
