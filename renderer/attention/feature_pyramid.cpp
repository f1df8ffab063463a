// SPDX-License-Identifier: Apache-2.0
// The attention pass's feature pyramids and eq. 3.4's centre-surround differences (Lee 2009
// §3.1.1): 2x2 box downsampling, bilinear magnification of the coarse levels, and the row loops of
// C_f for one plane and for the hue vector. feature_pyramid.h states what each one computes.
#include "attention/feature_pyramid.h"

#include <algorithm>
#include <cmath>

namespace fovea::render::attention::detail {

namespace {

// 2x2 box downsampling (what glGenerateMipmap does for power-of-two sizes). For an odd size the level
// below is ceil(n / 2) and the missing texel of the last 2x2 block repeats the edge texel.
void downsample(const Level& src, Level& dst) {
  dst.w = std::max(1, (src.w + 1) / 2);
  dst.h = std::max(1, (src.h + 1) / 2);
  const auto sw = static_cast<std::size_t>(src.w), dw = static_cast<std::size_t>(dst.w);
  dst.v.resize(dw * static_cast<std::size_t>(dst.h));
  const std::size_t pairs = sw / 2;  // whole 2x2 blocks per row
  for (int y = 0; y < dst.h; ++y) {
    const float* __restrict a = src.v.data() + static_cast<std::size_t>(std::min(2 * y, src.h - 1)) * sw;
    const float* __restrict b = src.v.data() + static_cast<std::size_t>(std::min(2 * y + 1, src.h - 1)) * sw;
    float* __restrict o = dst.v.data() + static_cast<std::size_t>(y) * dw;
#pragma omp simd
    for (std::size_t x = 0; x < pairs; ++x) o[x] = 0.25f * (a[2 * x] + a[2 * x + 1] + b[2 * x] + b[2 * x + 1]);
    if (pairs < dw) o[pairs] = 0.5f * (a[sw - 1] + b[sw - 1]);  // odd width: the edge texel twice
  }
}

}  // namespace

void build_pyramid(Pyramid& pyr) {
  for (int l = 1; l < kLevels; ++l) downsample(pyr[l - 1], pyr[l]);
}

namespace {

// Axis's taps for the n samples of level 0 over a level of m texels.
Axis axis(int n, int m) {
  Axis a;
  a.i0.resize(static_cast<std::size_t>(n));
  a.i1.resize(static_cast<std::size_t>(n));
  a.f.resize(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const double s = (k + 0.5) * m / n - 0.5;
    const double fl = std::floor(s);
    const int j = static_cast<int>(fl);
    const auto i = static_cast<std::size_t>(k);
    a.i0[i] = std::clamp(j, 0, m - 1);
    a.i1[i] = std::clamp(j + 1, 0, m - 1);
    a.f[i] = static_cast<float>(s - fl);
  }
  return a;
}

}  // namespace

void Magnified::build(const Pyramid& pyr, int n) {
  const auto un = static_cast<std::size_t>(n);
  for (int l = 1; l < kLevels; ++l) {
    const Level& lv = pyr[l];
    const Axis ax = axis(n, lv.w);
    vertical[l] = axis(n, lv.h);
    auto& hz = rows[l];
    hz.resize(static_cast<std::size_t>(lv.h) * un);
    for (int y = 0; y < lv.h; ++y) {
      const float* row = lv.v.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(lv.w);
      float* o = hz.data() + static_cast<std::size_t>(y) * un;
      for (std::size_t x = 0; x < un; ++x) {
        const float p = row[ax.i0[x]], q = row[ax.i1[x]];
        o[x] = p + ax.f[x] * (q - p);
      }
    }
  }
}

Magnified::Row Magnified::row(std::size_t y, std::size_t un) const {
  Row r{};
  for (int l = 1; l < kLevels; ++l) {
    r.a[l] = rows[l].data() + static_cast<std::size_t>(vertical[l].i0[y]) * un;
    r.b[l] = rows[l].data() + static_cast<std::size_t>(vertical[l].i1[y]) * un;
    r.f[l] = vertical[l].f[y];
  }
  return r;
}

// Eq. 3.4 for one feature: C = 1/6 sum_{i in 0..2} sum_{j in 3,4} |B^i - B^{i+j}|, every level
// sampled at the level-0 pixel (Fig. 3.3's shader: texture2D(DSM, tc0, i)), coarse levels by
// bilinear magnification (first horizontally per level, then a vertical lerp per output row, fused
// with the differences so the row loop vectorises).
void centre_surround(const Pyramid& pyr, int n, Magnified& mg, std::vector<float>& out) {
  const auto un = static_cast<std::size_t>(n);
  out.resize(un * un);
  mg.build(pyr, n);
  for (std::size_t y = 0; y < un; ++y) {
    const Magnified::Row r = mg.row(y, un);
    const float* __restrict p0 = pyr[0].v.data() + y * un;
    const float *__restrict a1 = r.a[1], *__restrict b1 = r.b[1], *__restrict a2 = r.a[2], *__restrict b2 = r.b[2];
    const float *__restrict a3 = r.a[3], *__restrict b3 = r.b[3], *__restrict a4 = r.a[4], *__restrict b4 = r.b[4];
    const float *__restrict a5 = r.a[5], *__restrict b5 = r.b[5], *__restrict a6 = r.a[6], *__restrict b6 = r.b[6];
    const float f1 = r.f[1], f2 = r.f[2], f3 = r.f[3], f4 = r.f[4], f5 = r.f[5], f6 = r.f[6];
    float* __restrict o = out.data() + y * un;
#pragma omp simd
    for (std::size_t x = 0; x < un; ++x) {
      const float v0 = p0[x];
      const float v1 = a1[x] + f1 * (b1[x] - a1[x]), v2 = a2[x] + f2 * (b2[x] - a2[x]);
      const float v3 = a3[x] + f3 * (b3[x] - a3[x]), v4 = a4[x] + f4 * (b4[x] - a4[x]);
      const float v5 = a5[x] + f5 * (b5[x] - a5[x]), v6 = a6[x] + f6 * (b6[x] - a6[x]);
      o[x] = (std::fabs(v0 - v3) + std::fabs(v0 - v4) + std::fabs(v1 - v4) + std::fabs(v1 - v5) + std::fabs(v2 - v5) +
              std::fabs(v2 - v6)) *
             (1.0f / 6.0f);
    }
  }
}

// Eq. 3.4 for the hue vector (two pyramids, its components): |B^i - B^{i+j}| is the Euclidean
// distance between the two levels' vectors.
void centre_surround_vector(const Pyramid& pu, const Pyramid& pw, int n, Magnified& mu, Magnified& mw,
                            std::vector<float>& out) {
  const auto un = static_cast<std::size_t>(n);
  out.resize(un * un);
  mu.build(pu, n);
  mw.build(pw, n);
  for (std::size_t y = 0; y < un; ++y) {
    const Magnified::Row r = mu.row(y, un), q = mw.row(y, un);
    const float *__restrict u0 = pu[0].v.data() + y * un, *__restrict w0 = pw[0].v.data() + y * un;
    const float *__restrict ua1 = r.a[1], *__restrict ub1 = r.b[1], *__restrict ua2 = r.a[2], *__restrict ub2 = r.b[2];
    const float *__restrict ua3 = r.a[3], *__restrict ub3 = r.b[3], *__restrict ua4 = r.a[4], *__restrict ub4 = r.b[4];
    const float *__restrict ua5 = r.a[5], *__restrict ub5 = r.b[5], *__restrict ua6 = r.a[6], *__restrict ub6 = r.b[6];
    const float *__restrict wa1 = q.a[1], *__restrict wb1 = q.b[1], *__restrict wa2 = q.a[2], *__restrict wb2 = q.b[2];
    const float *__restrict wa3 = q.a[3], *__restrict wb3 = q.b[3], *__restrict wa4 = q.a[4], *__restrict wb4 = q.b[4];
    const float *__restrict wa5 = q.a[5], *__restrict wb5 = q.b[5], *__restrict wa6 = q.a[6], *__restrict wb6 = q.b[6];
    const float f1 = r.f[1], f2 = r.f[2], f3 = r.f[3], f4 = r.f[4], f5 = r.f[5], f6 = r.f[6];
    float* __restrict o = out.data() + y * un;
#pragma omp simd
    for (std::size_t x = 0; x < un; ++x) {
      const float x0 = u0[x], y0 = w0[x];
      const float x1 = ua1[x] + f1 * (ub1[x] - ua1[x]), y1 = wa1[x] + f1 * (wb1[x] - wa1[x]);
      const float x2 = ua2[x] + f2 * (ub2[x] - ua2[x]), y2 = wa2[x] + f2 * (wb2[x] - wa2[x]);
      const float x3 = ua3[x] + f3 * (ub3[x] - ua3[x]), y3 = wa3[x] + f3 * (wb3[x] - wa3[x]);
      const float x4 = ua4[x] + f4 * (ub4[x] - ua4[x]), y4 = wa4[x] + f4 * (wb4[x] - wa4[x]);
      const float x5 = ua5[x] + f5 * (ub5[x] - ua5[x]), y5 = wa5[x] + f5 * (wb5[x] - wa5[x]);
      const float x6 = ua6[x] + f6 * (ub6[x] - ua6[x]), y6 = wa6[x] + f6 * (wb6[x] - wa6[x]);
      const float d03 = std::sqrt((x0 - x3) * (x0 - x3) + (y0 - y3) * (y0 - y3));
      const float d04 = std::sqrt((x0 - x4) * (x0 - x4) + (y0 - y4) * (y0 - y4));
      const float d14 = std::sqrt((x1 - x4) * (x1 - x4) + (y1 - y4) * (y1 - y4));
      const float d15 = std::sqrt((x1 - x5) * (x1 - x5) + (y1 - y5) * (y1 - y5));
      const float d25 = std::sqrt((x2 - x5) * (x2 - x5) + (y2 - y5) * (y2 - y5));
      const float d26 = std::sqrt((x2 - x6) * (x2 - x6) + (y2 - y6) * (y2 - y6));
      o[x] = (d03 + d04 + d14 + d15 + d25 + d26) * (1.0f / 6.0f);
    }
  }
}

}  // namespace fovea::render::attention::detail
