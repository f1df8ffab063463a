// SPDX-License-Identifier: Apache-2.0
// The G-buffer resampled to the attention pass's map (Lee 2009 §3.1.1, eq. 3.1): the map's boxes
// in the source, the box and nearest reads of the source rows, HLS and the hue vector, and the
// row loop that writes level 0 of the planes, split over the cores.
#include "attention/gbuffer_resample.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fovea::render::attention::detail {

namespace {

// (cos, sin) of the hue angle h6 * 60 deg, h6 in [0, 6): a table of 1536 steps with linear
// interpolation (error < 3e-6, far below the 8-bit colour it stands for), instead of two libm
// calls per map pixel.
glm::vec2 hue_direction(float h6) {
  constexpr int kSteps = 1536;
  static const std::vector<glm::vec2> table = [] {
    std::vector<glm::vec2> t(kSteps + 1);
    for (int i = 0; i <= kSteps; ++i) {
      const double a = 2.0 * std::numbers::pi * i / kSteps;
      t[static_cast<std::size_t>(i)] = {static_cast<float>(std::cos(a)), static_cast<float>(std::sin(a))};
    }
    return t;
  }();
  const float s = (h6 > 0 ? std::min(h6, 6.0f) : 0.0f) * (kSteps / 6.0f);  // NaN: 0 (never a NaN cast)
  const auto i = std::min(static_cast<std::size_t>(s), static_cast<std::size_t>(kSteps - 1));
  const float f = s - static_cast<float>(i);
  return table[i] + f * (table[i + 1] - table[i]);
}

float finite_or(float v, float fallback) { return std::isfinite(v) ? v : fallback; }

}  // namespace

Source read_source(const GBuffer& g, const Camera& camera) {
  // A G-buffer with missing planes is read as black, at the far plane and without objects.
  const std::size_t W = g.width, H = g.height;
  const bool has_image = W > 0 && H > 0;
  const bool has_color = has_image && g.color.size() >= W * H;
  const bool has_depth = has_image && g.depth.size() >= W * H;
  const bool has_ids = has_image && g.object_id.size() >= W * H;
  const double z_near = camera.near_m, z_far = camera.far_m;
  const double z_range = (std::isfinite(z_far - z_near) && z_far > z_near) ? z_far - z_near : 1.0;
  const float fnear = static_cast<float>(std::isfinite(z_near) ? z_near : 0.0);
  const float ffar = static_cast<float>(std::isfinite(z_far) ? z_far : static_cast<double>(fnear) + 1.0);
  return Source{g, W, H, has_image, has_color, has_depth, has_ids, z_range, fnear, ffar};
}

// Resample the G-buffer to n x n.
// Colour and depth: box filter (the mean of the source pixels whose centres fall in the map
// pixel; when the map is finer than the image, or with Resample::Nearest, the one source pixel
// under the map pixel's centre).
// Ids and the per-object depth: nearest (the source pixel under the map pixel's centre): ids must
// not be averaged. The map is square like the paper's (64^2 .. 512^2); the image's aspect is not kept.
// HDR colour is clamped to [0, 1] per source pixel before filtering: HLS is a display-colour model
// (the paper reads an 8-bit render target), and a lamp's radiance of 8 must not dwarf the rest.
ResampleGrid resample_grid(const Source& src, int n, Resample resample) {
  const auto un = static_cast<std::size_t>(n);
  const std::size_t W = src.W, H = src.H;
  ResampleGrid grid(un);
  for (std::size_t k = 0; k < un; ++k) {
    if (!src.has_image) break;
    const auto range = [&](std::size_t size, std::vector<int>& a, std::vector<int>& b, std::vector<int>& near_i) {
      const auto s = static_cast<double>(size);
      const auto kk = static_cast<double>(k);
      int lo = static_cast<int>(std::ceil(kk * s / n - 0.5));
      int hi = static_cast<int>(std::ceil((kk + 1) * s / n - 0.5));  // centres in [k, k+1) * s / n
      const int centre = std::clamp(static_cast<int>(std::floor((kk + 0.5) * s / n)), 0, static_cast<int>(size) - 1);
      lo = std::clamp(lo, 0, static_cast<int>(size));
      hi = std::clamp(hi, 0, static_cast<int>(size));
      if (hi <= lo || resample == Resample::Nearest) {
        lo = centre;
        hi = centre + 1;
      }
      a[k] = lo;
      b[k] = hi;
      near_i[k] = centre;
    };
    range(W, grid.cx0, grid.cx1, grid.nx);
    range(H, grid.cy0, grid.cy1, grid.ny);
  }
  return grid;
}

namespace {

// Box: the source rows of map row y summed per source column (straight loops over whole rows;
// comparisons written as `v > 0 ? v : 0` map NaN to the fallback without a branch).
void accumulate_box_rows(const Source& src, const ResampleGrid& grid, std::size_t y, std::vector<float>& col_rgb,
                         std::vector<float>& col_z) {
  const GBuffer& g = src.g;
  const std::size_t W = src.W;
  const bool has_color = src.has_color, has_depth = src.has_depth, has_ids = src.has_ids;
  const float fnear = src.fnear, ffar = src.ffar;
  const float depth_fallback = ffar;
  const std::vector<int>&cy0 = grid.cy0, &cy1 = grid.cy1;
  std::fill(col_rgb.begin(), col_rgb.end(), 0.0f);
  std::fill(col_z.begin(), col_z.end(), 0.0f);
  float* __restrict crgb = col_rgb.data();
  float* __restrict cz = col_z.data();
  for (int sy = cy0[y]; sy < cy1[y]; ++sy) {
    const std::size_t row = static_cast<std::size_t>(sy) * W;
    if (has_color) {
      const float* __restrict c = &g.color[row].x;
#pragma omp simd
      for (std::size_t i = 0; i < 3 * W; ++i) {
        const float v = c[i] > 0.0f ? c[i] : 0.0f;  // NaN: 0
        crgb[i] += v < 1.0f ? v : 1.0f;
      }
    }
    // Background pixels (id 0) sit at the far plane whatever the depth plane says; NaN and +Inf: far.
    if (has_depth) {
      const float* __restrict dp = g.depth.data() + row;
      if (has_ids) {
        const std::uint32_t* __restrict ip = g.object_id.data() + row;
#pragma omp simd
        for (std::size_t sx = 0; sx < W; ++sx) {
          float d = dp[sx] < ffar ? dp[sx] : ffar;
          d = d > fnear ? d : fnear;
          cz[sx] += ip[sx] != 0 ? d : depth_fallback;
        }
      } else {
#pragma omp simd
        for (std::size_t sx = 0; sx < W; ++sx) {
          const float d = dp[sx] < ffar ? dp[sx] : ffar;
          cz[sx] += d > fnear ? d : fnear;
        }
      }
    } else {
      for (std::size_t sx = 0; sx < W; ++sx) cz[sx] += depth_fallback;
    }
  }
}

// Nearest: the one source pixel under each map pixel's centre, read directly (no pass over whole
// source rows), into the same per-column layout with one column per map pixel.
void read_nearest_row(const Source& src, const ResampleGrid& grid, std::size_t un, std::size_t y,
                      std::vector<float>& col_rgb, std::vector<float>& col_z) {
  const GBuffer& g = src.g;
  const std::size_t W = src.W;
  const bool has_color = src.has_color, has_depth = src.has_depth, has_ids = src.has_ids;
  const float fnear = src.fnear, ffar = src.ffar;
  const float depth_fallback = ffar;
  const std::vector<int>&nx = grid.nx, &ny = grid.ny;
  const std::size_t row = static_cast<std::size_t>(ny[y]) * W;
  for (std::size_t x = 0; x < un; ++x) {
    const std::size_t i = row + static_cast<std::size_t>(nx[x]);
    for (glm::length_t c = 0; c < 3; ++c) {
      const float v = has_color ? g.color[i][c] : 0.0f;
      const float v0 = v > 0.0f ? v : 0.0f;  // NaN: 0
      col_rgb[3 * x + static_cast<std::size_t>(c)] = v0 < 1.0f ? v0 : 1.0f;
    }
    float d = depth_fallback;
    if (has_depth && (!has_ids || g.object_id[i] != 0)) {
      d = g.depth[i] < ffar ? g.depth[i] : ffar;
      d = d > fnear ? d : fnear;
    }
    col_z[x] = d;
  }
}

// One map pixel's lightness and hue vector.
struct Hls {
  float l, hue_a, hue_b;
};

// HLS (Lee 2009 §3.1.1): L = (max + min) / 2, S = chroma / (1 - |2L - 1|), H the hexcone angle.
// Hue is an angle, so |B_h^i - B_h^{i+j}| of eq. 3.4 is taken between hue vectors
// (S cos H, S sin H): the chord between two hues on the colour wheel, scaled by saturation.
// Grey pixels have S = 0, the zero vector: no hue, no NaN, and no contrast against any grey.
Hls hls(float r, float gg, float b) {
  const float mx = std::max({r, gg, b}), mn = std::min({r, gg, b});
  const float l = 0.5f * (mx + mn), chroma = mx - mn;
  float ha = 0, hb = 0;
  if (chroma > 1e-6f) {
    const float sat = std::clamp(chroma / std::max(1e-6f, 1.0f - std::fabs(2.0f * l - 1.0f)), 0.0f, 1.0f);
    float h6 = 0;  // hue in sixths of a turn
    if (mx == r) {
      h6 = (gg - b) / chroma;  // in [-1, 1]
      if (h6 < 0) h6 += 6.0f;
    } else if (mx == gg) {
      h6 = (b - r) / chroma + 2.0f;
    } else {
      h6 = (r - gg) / chroma + 4.0f;
    }
    const glm::vec2 dir = hue_direction(h6);
    ha = sat * dir.x;
    hb = sat * dir.y;
  }
  return Hls{l, ha, hb};
}

// Where the resampling writes: level 0 of the L, hue and depth planes, the map's ids (nearest) and
// the per-pixel depth the per-object median is taken of (nearest).
struct ResampleTarget {
  float* lum0;
  float* hue_a0;
  float* hue_b0;
  float* depth0;
  std::vector<std::uint32_t>& ids;
  std::vector<float>& map_depth;
};

// Map rows [y_begin, y_end): per map row the source columns (box or nearest), then the columns of
// each map pixel's box summed, then HLS and eq. 3.1. `col_rgb` and `col_z` are this range's own
// scratch rows.
void resample_rows(const Source& src, const ResampleGrid& grid, std::size_t un, bool nearest, const ResampleTarget& out,
                   std::size_t y_begin, std::size_t y_end) {
  const GBuffer& g = src.g;
  const std::size_t W = src.W;
  const bool has_image = src.has_image, has_depth = src.has_depth, has_ids = src.has_ids;
  const float fnear = src.fnear, ffar = src.ffar;
  const float fz_near = fnear, fz_inv_range = static_cast<float>(1.0 / src.z_range);
  const std::vector<int>&cx0 = grid.cx0, &cx1 = grid.cx1, &cy0 = grid.cy0, &cy1 = grid.cy1;
  const std::vector<int>&nx = grid.nx, &ny = grid.ny;
  float* __restrict lum0 = out.lum0;
  float* __restrict hue_a0 = out.hue_a0;
  float* __restrict hue_b0 = out.hue_b0;
  float* __restrict depth0 = out.depth0;
  std::vector<std::uint32_t>& ids = out.ids;
  std::vector<float>& map_depth = out.map_depth;
  std::vector<float> col_rgb(nearest ? un * 3 : W * 3), col_z(nearest ? un : W);
  for (std::size_t y = y_begin; y < y_end && has_image; ++y) {
    if (nearest) {
      read_nearest_row(src, grid, un, y, col_rgb, col_z);
    } else {
      accumulate_box_rows(src, grid, y, col_rgb, col_z);
    }
    const float* __restrict crgb = col_rgb.data();
    const float* __restrict cz = col_z.data();
    const int rows_in = nearest ? 1 : cy1[y] - cy0[y];
    for (std::size_t x = 0; x < un; ++x) {
      float r = 0, gg = 0, b = 0, z = 0;
      const int c0 = nearest ? static_cast<int>(x) : cx0[x], c1 = nearest ? c0 + 1 : cx1[x];
      for (int sx = c0; sx < c1; ++sx) {
        const auto k = static_cast<std::size_t>(sx);
        r += crgb[3 * k];
        gg += crgb[3 * k + 1];
        b += crgb[3 * k + 2];
        z += cz[k];
      }
      const std::size_t m = y * un + x;
      const int count = rows_in * (c1 - c0);
      const float inv = count > 0 ? 1.0f / static_cast<float>(count) : 0.0f;
      r *= inv;
      gg *= inv;
      b *= inv;
      z = count > 0 ? z * inv : ffar;
      const Hls c = hls(r, gg, b);
      lum0[m] = c.l;
      hue_a0[m] = c.hue_a;
      hue_b0[m] = c.hue_b;
      depth0[m] = std::clamp((z - fz_near) * fz_inv_range, 0.0f, 1.0f);  // eq. 3.1
      const std::size_t ni = static_cast<std::size_t>(ny[y]) * W + static_cast<std::size_t>(nx[x]);
      if (has_ids) ids[m] = g.object_id[ni];
      if (has_depth && ids[m] != 0) map_depth[m] = std::clamp(finite_or(g.depth[ni], ffar), fnear, ffar);
    }
  }
}

}  // namespace

// The resampled G-buffer: level 0 of the planes, the map's ids and per-pixel depth. Map rows are
// independent: split over the cores (TBB), each range with its own scratch rows.
void resample_gbuffer(const Source& src, const ResampleGrid& grid, int n, Resample resample, Pyramid (&planes)[kPlanes],
                      std::vector<std::uint32_t>& ids, std::vector<float>& map_depth) {
  const auto un = static_cast<std::size_t>(n), npix = un * un;
  for (Pyramid& p : planes) {
    p[0].w = p[0].h = n;
    p[0].v.assign(npix, 0.0f);
  }
  const ResampleTarget out{planes[kPL][0].v.data(), planes[kPHa][0].v.data(), planes[kPHb][0].v.data(),
                           planes[kPDepth][0].v.data(), ids, map_depth};
  ids.assign(npix, 0);
  map_depth.assign(npix, src.ffar);  // nearest: per-object median depth
  static_assert(sizeof(glm::vec3) == 3 * sizeof(float), "the colour plane is read as packed floats");
  const bool nearest = resample == Resample::Nearest;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, un, 8), [&](const tbb::blocked_range<std::size_t>& r) {
    resample_rows(src, grid, un, nearest, out, r.begin(), r.end());
  });
}

}  // namespace fovea::render::attention::detail
