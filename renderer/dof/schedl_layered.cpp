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

// Three box blurs whose variances add up to sigma^2 approximate a Gaussian (Wells 1986): box
// widths wl (odd) for the first m passes and wl + 2 for the rest.
std::vector<int> box_radii(double sigma) {
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

// One box pass of radius r along rows (horizontal) with clamped edges: a running sum per row.
void box_rows(const Rgba& src, Rgba& dst, int w, int h, int r) {
  const float inv = 1.0f / static_cast<float>(2 * r + 1);
  tbb::parallel_for(tbb::blocked_range<int>(0, h, 8), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const glm::vec4* in = src.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
      glm::vec4* out = dst.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
      const auto at = [&](int x) { return in[std::clamp(x, 0, w - 1)]; };
      glm::vec4 sum(0.0f);
      for (int j = -r; j <= r; ++j) sum += at(j);
      for (int x = 0; x < w; ++x) {
        out[x] = sum * inv;
        sum += at(x + r + 1) - at(x - r);
      }
    }
  });
}

// One box pass along columns: a running sum per column, rows streamed top to bottom.
void box_columns(const Rgba& src, Rgba& dst, int w, int h, int r) {
  const float inv = 1.0f / static_cast<float>(2 * r + 1);
  tbb::parallel_for(tbb::blocked_range<int>(0, w, 64), [&](const tbb::blocked_range<int>& cols) {
    const int x0 = cols.begin(), x1 = cols.end();
    std::vector<glm::vec4> sum(static_cast<std::size_t>(x1 - x0), glm::vec4(0.0f));
    const auto row = [&](int y) {
      return src.data() + static_cast<std::size_t>(std::clamp(y, 0, h - 1)) * static_cast<std::size_t>(w);
    };
    for (int j = -r; j <= r; ++j) {
      const glm::vec4* p = row(j);
      for (int x = x0; x < x1; ++x) sum[static_cast<std::size_t>(x - x0)] += p[x];
    }
    for (int y = 0; y < h; ++y) {
      glm::vec4* out = dst.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
      const glm::vec4* add = row(y + r + 1);
      const glm::vec4* sub = row(y - r);
      for (int x = x0; x < x1; ++x) {
        const auto i = static_cast<std::size_t>(x - x0);
        out[x] = sum[i] * inv;
        sum[i] += add[x] - sub[x];
      }
    }
  });
}

// Gaussian blur of standard deviation sigma (px), in place (eq. 11 with H^_k).
void gaussian(Rgba& img, Rgba& tmp, int w, int h, double sigma) {
  if (!(sigma > 0.3)) return;
  for (const int r : box_radii(sigma)) {
    if (r <= 0) continue;
    box_rows(img, tmp, w, h, r);
    box_columns(tmp, img, w, h, r);
  }
}

// A over B for premultiplied colours.
inline glm::vec4 over(const glm::vec4& a, const glm::vec4& b) { return a + (1.0f - a.a) * b; }

}  // namespace

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
  float max_in = 0;
  for (std::size_t i = 0; i < np; ++i) {
    const glm::vec3 c = in.color[i];
    out[i] = {std::max(0.0f, finite_or_zero(c.x)), std::max(0.0f, finite_or_zero(c.y)), std::max(0.0f, finite_or_zero(c.z))};
    max_in = std::max({max_in, out[i].x, out[i].y, out[i].z});
  }
  const CocModel& coc = in.coc;
  const double k = coc.k_px();
  const auto depth_of = [](const float* d, std::size_t i) {
    const double z = d == nullptr ? kInf : static_cast<double>(d[i]);
    return std::isnan(z) ? kInf : std::max(z, 0.0);
  };
  // Depth range of the frame (every layer's finite depths).
  double zmin = kInf, zmax = 0;
  std::vector<PeeledLayer> layers_in;
  layers_in.push_back({in.color, in.depth});
  for (const PeeledLayer& p : peeled) {
    if (p.color != nullptr && p.depth != nullptr) layers_in.push_back(p);
  }
  for (const PeeledLayer& l : layers_in) {
    for (std::size_t i = 0; i < np; ++i) {
      const double z = depth_of(l.depth, i);
      if (std::isfinite(z)) {
        zmin = std::min(zmin, z);
        zmax = std::max(zmax, z);
      }
    }
  }
  double max_c = 0;
  if (std::isfinite(zmin)) max_c = std::max(coc.coc_px(zmin), coc.coc_px(zmax));
  if (coc.pinhole() || !(k >= 0) || max_c < 0.5 || !std::isfinite(coc.focus_m)) {
    if (stats != nullptr) *stats = {1, 0, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()};
    return;  // nothing blurs by half a pixel: the input
  }

  // Layer CoCs d_j = 4 sigma_j (eq. 10) at j layers from the focus layer, sigma_j from eq. 15 with
  // sigma^_j = j (eq. 14); anchors at the mean CoC of neighbouring layers (eq. 9).
  const auto layer_coc = [](int j) {
    double var = 0;
    for (int i = 1; i <= j; ++i) var += static_cast<double>(i) * i;
    return 4.0 * std::sqrt(var);
  };
  const int cap = std::max(1, s.max_layers);
  std::vector<double> front, back;  // boundaries, nearest-to-focus first
  const auto total = [&] { return 1 + static_cast<int>(front.size() + back.size()); };
  for (int j = 1; j <= cap; ++j) {
    const double c = 0.5 * (layer_coc(j - 1) + layer_coc(j));
    bool more = false;
    if (total() < cap && (front.empty() ? coc.focus_m : front.back()) > zmin) {
      front.push_back(coc.depth_near_for_coc(c));  // D1, eq. 6
      more = true;
    }
    if (total() < cap && (back.empty() ? coc.focus_m : back.back()) < zmax && c < k) {  // eq. 8: C < K
      const double zb = coc.depth_far_for_coc(c);                                         // D2, eq. 7
      if (std::isfinite(zb)) {
        back.push_back(zb);
        more = true;
      }
    }
    if (!more) break;
  }
  const int kf = static_cast<int>(front.size());
  const int K = kf + 1 + static_cast<int>(back.size());
  // z[k], k = 0..K-2: the boundary between layers k and k+1, front to back.
  std::vector<double> z(static_cast<std::size_t>(std::max(0, K - 1)));
  for (int kk = 0; kk < kf; ++kk) z[static_cast<std::size_t>(kk)] = front[static_cast<std::size_t>(kf - 1 - kk)];
  for (int kk = kf; kk < K - 1; ++kk) z[static_cast<std::size_t>(kk)] = back[static_cast<std::size_t>(kk - kf)];
  const auto anchor = [&](int kk) {
    if (kk < 0) return -kInf;
    if (kk >= K - 1) return kInf;
    return z[static_cast<std::size_t>(kk)];
  };
  // Matting (eqs. 3-4). A ramp towards an infinite anchor is a hard edge.
  const auto w_dot = [&](int kk, double d) -> float {
    const double a = anchor(kk - 2), b = anchor(kk - 1), c = anchor(kk);
    if (d >= b && d <= c) return 1.0f;
    if (d > a && d < b && std::isfinite(a) && b > a) return static_cast<float>((d - a) / (b - a));
    return 0.0f;
  };
  const auto w_full = [&](int kk, double d) -> float {
    const double c = anchor(kk), e = anchor(kk + 1);
    if (d > c && d < e && std::isfinite(e) && e > c) return static_cast<float>((e - d) / (e - c));
    return w_dot(kk, d);
  };
  // L_k (eq. 2): the visible layer matted with w_k, the peeled ones with w'_k, front to back.
  const auto build = [&](int kk, Rgba& L) {
    L.resize(np);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t i = r.begin(); i < r.end(); ++i) {
        glm::vec4 acc(0.0f);
        for (std::size_t l = 0; l < layers_in.size(); ++l) {
          const double d = depth_of(layers_in[l].depth, i);
          const float a = l == 0 ? w_full(kk, d) : w_dot(kk, d);
          if (a <= 0) continue;
          const glm::vec3 c = layers_in[l].color[i];
          const glm::vec3 col = l == 0 ? out[i]
                                       : glm::vec3(std::max(0.0f, finite_or_zero(c.x)), std::max(0.0f, finite_or_zero(c.y)),
                                                   std::max(0.0f, finite_or_zero(c.z)));
          acc = over(acc, glm::vec4(col * a, a));
        }
        L[i] = acc;
      }
    });
  };

  // Cascaded blur and composition (eqs. 12-13), sigma^_k = |k - kf| (eq. 14).
  Rgba front_acc, back_acc, layer, tmp(np);
  if (kf > 0) {
    build(0, front_acc);
    gaussian(front_acc, tmp, w, h, kf);
    for (int kk = 1; kk < kf; ++kk) {
      build(kk, layer);
      for (std::size_t i = 0; i < np; ++i) front_acc[i] = over(front_acc[i], layer[i]);
      gaussian(front_acc, tmp, w, h, kf - kk);
    }
  }
  if (kf < K - 1) {
    build(K - 1, back_acc);
    gaussian(back_acc, tmp, w, h, K - 1 - kf);
    for (int kk = K - 2; kk > kf; --kk) {
      build(kk, layer);
      for (std::size_t i = 0; i < np; ++i) back_acc[i] = over(layer[i], back_acc[i]);
      gaussian(back_acc, tmp, w, h, kk - kf);
    }
  }
  build(kf, layer);
  for (std::size_t i = 0; i < np; ++i) {
    glm::vec4 r = layer[i];
    if (!back_acc.empty()) r = over(r, back_acc[i]);
    if (!front_acc.empty()) r = over(front_acc[i], r);
    // Normalisation (§3.3.1): premultiplied colour over its alpha; no coverage keeps the input.
    if (r.a > 1e-6f && std::isfinite(r.a)) {
      const glm::vec3 c = glm::vec3(r) / r.a;
      out[i] = glm::clamp(glm::vec3(finite_or_zero(c.x), finite_or_zero(c.y), finite_or_zero(c.z)), 0.0f, max_in);
    }
  }
  if (stats != nullptr) {
    *stats = {K, kf, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()};
  }
}

}  // namespace fovea::render::dof
