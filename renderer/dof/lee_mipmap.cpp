// SPDX-License-Identifier: Apache-2.0
#include "dof/lee_mipmap.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>

namespace fovea::render::dof {

namespace {

constexpr float kFarDepth = 1e30f;          // non-finite depth: the far limit, kept finite for averaging
constexpr float kTiny = 1e-18f;             // the geometric blend's floor for 0 (log2 stays finite)
constexpr float kHuge = 1e18f;              // and its ceiling: b / a stays a normal float
constexpr int kChunk = 64;                  // pixels per gather/blend batch of the final pass

// One level of the mipmaps: colour I, depth Z and DoB B (Fig. 4.10's I and ZBN). The colour is
// planar (channel ch at ch w h) so that the final pass lerps its rows straight into the planar
// rows its gathers read, with no per-row transposition.
struct Level {
  int w = 0, h = 0;
  std::vector<float> c;
  std::vector<float> z, s;
  std::size_t pixels() const { return static_cast<std::size_t>(w) * static_cast<std::size_t>(h); }
  const float* plane(std::size_t ch) const { return c.data() + ch * pixels(); }
  float* plane(std::size_t ch) { return c.data() + ch * pixels(); }
};

// The downsampling taps along one axis, 4 per destination texel. Eq. 4.1's 3x3 Gaussian G is the
// binomial [1 2 1] / 4 (the paper gives no sigma; this is the 3x3 kernel a GPU shader would use),
// and its three samples sit one source texel apart around the destination texel's centre, each read
// with bilinear filtering as the GPU's texture unit does (GL: destination texel i's centre is at
// (i + 0.5) sw / dw - 0.5 in source texels). For power-of-two sizes the centre is 2i + 0.5 and the
// taps are the familiar [1 3 3 1] / 8; for other sizes they follow the centre, so no level drifts.
// Indices are clamped to the edge (GL_CLAMP_TO_EDGE).
struct Taps {
  std::vector<int> idx;    // 4 per destination texel
  std::vector<float> w;    // 4 per destination texel, summing to 1
  void build(int sw, int dw) {
    idx.assign(static_cast<std::size_t>(dw) * 4, 0);
    w.assign(static_cast<std::size_t>(dw) * 4, 0.0f);
    for (int i = 0; i < dw; ++i) {
      const double c = (i + 0.5) * sw / dw - 0.5;
      const double base = std::floor(c - 1.0);
      const auto o = static_cast<std::size_t>(i) * 4;
      for (int t = -1; t <= 1; ++t) {
        const double g = t == 0 ? 0.5 : 0.25;
        const double pos = c + t;
        const double fl = std::floor(pos);
        const auto k = static_cast<std::size_t>(fl - base);  // 0..2
        const double f = pos - fl;
        w[o + k] += static_cast<float>(g * (1.0 - f));
        w[o + k + 1] += static_cast<float>(g * f);
      }
      for (int k = 0; k < 4; ++k) idx[o + static_cast<std::size_t>(k)] = std::clamp(static_cast<int>(base) + k, 0, sw - 1);
    }
  }
};

// Eq. 4.6 (and eq. 4.11, the same map applied to the DoN): the continuous mipmap level of a DoB.
inline float level_of(float sigma, float k_sigma) {
  const float x = k_sigma * sigma;
  return x < 0.5f ? 0.0f : 1.0f + std::log2(x);
}

// log2 and exp2 for the geometric blend of eq. 4.8, written so the blend loop vectorises (libm's
// are scalar calls without -ffast-math, and a clamp inside the loop stops GCC's if-conversion under
// -ftrapping-math). fast_log2_ratio: a, b > 0 and normal. fast_exp2: |x| <= 126. The blend's
// factors are kept in [kTiny, kHuge] (gather()), so |beta log2(b / a)| < 120.
//
// log2(b / a) with one division: a = 2^ea ma and b = 2^eb mb (ma, mb in [1, 2)), so log2(b / a) =
// eb - ea + log2(mb / ma), and log2(mb / ma) = (2 / ln 2) atanh(t) with t = (mb - ma) / (mb + ma)
// in (-1/3, 1/3) (a series to t^11, error < 2e-7). One division instead of two: log2(m) of a single
// m in [1, 2) takes the same series with t = (m - 1) / (m + 1), and b / a would be another.
inline float fast_log2_ratio(float b, float a) {
  const auto ba = std::bit_cast<std::int32_t>(a), bb = std::bit_cast<std::int32_t>(b);
  const float e = static_cast<float>(((bb >> 23) & 255) - ((ba >> 23) & 255));
  const float ma = std::bit_cast<float>((ba & 0x7fffff) | 0x3f800000);
  const float mb = std::bit_cast<float>((bb & 0x7fffff) | 0x3f800000);
  const float t = (mb - ma) / (mb + ma), t2 = t * t;
  constexpr float c1 = 2.8853900817779268f, c3 = c1 / 3, c5 = c1 / 5, c7 = c1 / 7, c9 = c1 / 9, c11 = c1 / 11;
  return e + t * (c1 + t2 * (c3 + t2 * (c5 + t2 * (c7 + t2 * (c9 + t2 * c11)))));
}
inline float fast_exp2(float x) {
  constexpr float kRound = 12582912.0f;  // 1.5 2^23: adding it rounds x to an integer in the low bits
  const float big = x + kRound;
  const float r = big - kRound;           // round(x)
  const float f = (x - r) * 0.69314718f;  // [-0.347, 0.347]
  const auto n = static_cast<std::uint32_t>(std::bit_cast<std::int32_t>(big) - 0x4B400000 + 127);
  // e^f, Taylor to degree 6 (error < 2e-7), times 2^round(x) built in the exponent bits.
  const float p =
      1.0f + f * (1.0f + f * (0.5f + f * (1.0f / 6.0f + f * (1.0f / 24.0f + f * (1.0f / 120.0f + f * (1.0f / 720.0f))))));
  return p * std::bit_cast<float>(n << 23);
}

// The final pass's blend over one batch of kChunk pixels: res[ch][i] = sum_k w_k
// A[k][ch][i]^(1 - beta_i) B[k][ch][i]^beta_i (eq. 4.8), or the linear blend: 27 exp2/log2 per
// pixel. On x86-64 (GCC) it is also compiled for x86-64-v3 (AVX2, FMA: 8 lanes instead of 4),
// picked at run time when the CPU has it, without changing the library's baseline compile flags.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define FOVEA_LEE_BLEND_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define FOVEA_LEE_BLEND_CLONES
#endif
FOVEA_LEE_BLEND_CLONES __attribute__((noinline)) void blend_chunk(const float (*A)[3][kChunk], const float (*B)[3][kChunk],
                                                   const float* beta, const float* w, std::size_t n,
                                                   bool geometric, float (*res)[kChunk]) {
  for (std::size_t ch = 0; ch < 3; ++ch) {
    float* __restrict o = res[ch];
    std::fill(o, o + n, 0.0f);
    for (std::size_t k = 0; k < 9; ++k) {
      const float wk = w[k];
      const float* __restrict a = A[k][ch];
      const float* __restrict b = B[k][ch];
      if (geometric) {
#pragma omp simd
        for (std::size_t i = 0; i < n; ++i) {
          // a^(1-beta) b^beta = a 2^(beta log2(b / a))
          o[i] += wk * a[i] * fast_exp2(beta[i] * fast_log2_ratio(b[i], a[i]));  // Lee 2009, eq. 4.8
        }
      } else {
#pragma omp simd
        for (std::size_t i = 0; i < n; ++i) o[i] += wk * (a[i] + beta[i] * (b[i] - a[i]));
      }
    }
  }
}

// Neighbourhood sample k -> (x offset class, y offset class) of the final pass (classes: -1, -d,
// 0, d, 1 texels, see FinalPass::cls).
constexpr std::array<int, 9> kcx = {2, 4, 0, 2, 2, 3, 1, 3, 1}, kcy = {2, 2, 2, 4, 0, 3, 3, 1, 1};

// One horizontal bilinear tap: texels j and j + 1 with weight f on the second. HTab's edge cases,
// where both of its texels are the same clamped one, are stored as that texel with f = 0 (exactly
// its value: x + 0 (y - x) = x for finite y), so the second texel is always the next one.
struct HTap {
  int j;
  float f;
};

// The final pass's bilinear colour reads for one batch (eq. 4.8's factors): A[k][ch][i] is sample
// k of I(l_i - 1), B[k][ch][i] of I(l_i). Every read is "texels j0 and j1 of a vertically lerped
// planar row" with j0, j1, f from HTab's tables flattened over levels. rows: the lerped rows of
// this output row, plane (level k, y class c, channel ch) at rows[((5 k + c) 3 + ch) W]; taps:
// horizontal taps of level k and x class c at [(5 k + c) W + x]. Scalar on purpose: with the
// level varying per pixel every read is a gather, and a vectorised version (AVX2 vgatherdps, or
// SSE2's emulated gathers) measured slower than this loop on the development machine.
__attribute__((noinline)) void gather_chunk(const float* rows, const HTap* taps, int W, int x0,
                                                    const int* lvl, std::size_t n, float (*A)[3][kChunk],
                                                    float (*B)[3][kChunk]) {
  for (std::size_t k = 0; k < 9; ++k) {
    const int cx = kcx[k], cy = kcy[k];
    for (int role = 0; role < 2; ++role) {  // 0: I(l - 1), 1: I(l)
      float(*D)[kChunk] = role == 0 ? A[k] : B[k];
      for (std::size_t i = 0; i < n; ++i) {
        const int lv = lvl[i] - 1 + role;
        const int t = (5 * lv + cx) * W + x0 + static_cast<int>(i);
        const HTap tp = taps[t];
        const float f = tp.f;
        // plane (lv, cy, 0) at texel j; the next two planes follow at strides of W
        const float* ro = rows + (15 * lv + 3 * cy) * W + tp.j;
        const float r0 = ro[0], g0 = ro[W], b0 = ro[2 * W];
        const float r1 = ro[1], g1 = ro[W + 1], b1 = ro[2 * W + 1];
        D[0][i] = r0 + f * (r1 - r0);
        D[1][i] = g0 + f * (g1 - g0);
        D[2][i] = b0 + f * (b1 - b0);
      }
    }
  }
}

// A colour kept where the fast log/exp are exact enough (colours beyond kHuge saturate).
inline float gather(float v) { return std::min(std::max(v, kTiny), kHuge); }

// The 3x3 neighbourhood of eq. 4.8 (Fig. 4.4): offsets in texels of the level it is read at, and
// the Gaussian weights G(q - p) of the same binomial kernel as eq. 4.1 (centre 4, edge 2, corner
// 1, over 16). Circular: the corners move onto the unit circle, (1/sqrt 2, 1/sqrt 2).
struct Neighbourhood {
  std::array<float, 9> ox{}, oy{}, w{};
  explicit Neighbourhood(bool circular) {
    const float d = circular ? 0.70710678f : 1.0f;
    const std::array<float, 9> x = {0, 1, -1, 0, 0, d, -d, d, -d};
    const std::array<float, 9> y = {0, 0, 0, 1, -1, d, d, -d, -d};
    const std::array<float, 9> g = {4, 2, 2, 2, 2, 1, 1, 1, 1};
    for (std::size_t k = 0; k < 9; ++k) {
      ox[k] = x[k];
      oy[k] = y[k];
      w[k] = g[k] / 16.0f;
    }
  }
};

// Horizontal bilinear taps of one level at the level-0 columns, for each of the 5 offset classes:
// texel coordinate X = pos(x, o) * n - 0.5, GL_CLAMP_TO_EDGE.
struct HTab {
  int n = 0;
  std::size_t w = 0;
  std::vector<int> i0, i1;  // [class * w + x]
  std::vector<float> f;
  template <class Pos>
  void build(int width, int n_src, Pos pos, const std::array<float, 5>& cls) {
    n = n_src;
    w = static_cast<std::size_t>(width);
    i0.resize(5 * w);
    i1.resize(5 * w);
    f.resize(5 * w);
    for (std::size_t c = 0; c < 5; ++c)
      for (int x = 0; x < width; ++x) {
        const float X = pos(x, cls[c]) * static_cast<float>(n_src) - 0.5f;
        const float fl = std::floor(X);
        const int j = static_cast<int>(fl);
        const std::size_t at = c * w + static_cast<std::size_t>(x);
        i0[at] = std::clamp(j, 0, n_src - 1);
        i1[at] = std::clamp(j + 1, 0, n_src - 1);
        f[at] = X - fl;
      }
  }
  float at(std::size_t c, const float* row, std::size_t x) const {
    const std::size_t k = c * w + x;
    const float a = row[i0[k]], b = row[i1[k]];
    return a + f[k] * (b - a);
  }
  glm::vec3 at3(std::size_t c, const glm::vec3* row, std::size_t x) const {
    glm::vec3 v;
    at3(c, row, x, &v.x, &v.y, &v.z);
    return v;
  }
  // The same into three floats, reading the texels as floats (no vec3 temporaries on the stack).
  void at3(std::size_t c, const glm::vec3* row, std::size_t x, float* r, float* g, float* b) const {
    const std::size_t k = c * w + x;
    const float* p = reinterpret_cast<const float*>(row) + 3 * static_cast<std::size_t>(i0[k]);
    const float* q = reinterpret_cast<const float*>(row) + 3 * static_cast<std::size_t>(i1[k]);
    const float t = f[k];
    *r = p[0] + t * (q[0] - p[0]);
    *g = p[1] + t * (q[1] - p[1]);
    *b = p[2] + t * (q[2] - p[2]);
  }
};

// Vertical bilinear taps at texel coordinate Y of an n-row level.
struct VRow {
  std::size_t r0, r1;
  float f;
};
inline VRow vrow(int n, float Y) {
  const float fl = std::floor(Y);
  const int j = static_cast<int>(fl);
  return {static_cast<std::size_t>(std::clamp(j, 0, n - 1)), static_cast<std::size_t>(std::clamp(j + 1, 0, n - 1)), Y - fl};
}
// out = row r0 + f (row r1 - row r0) of a plane with `len` floats per row.
inline void lerp_rows(const float* plane, int len, const VRow& vr, float* __restrict out) {
  const auto ul = static_cast<std::size_t>(len);
  const float* __restrict a = plane + vr.r0 * ul;
  const float* __restrict b = plane + vr.r1 * ul;
  const float f = vr.f;
#pragma omp simd
  for (std::size_t i = 0; i < ul; ++i) out[i] = a[i] + f * (b[i] - a[i]);
}

float finite_or_zero(float v) { return std::isfinite(v) ? std::max(v, 0.0f) : 0.0f; }

// What LeeMipmap keeps from frame to frame (its Scratch), declared here so the stages below can take it.
struct Buffers {
  std::vector<Level> levels;  // 0..M
  std::vector<float> don;     // N(M), eq. 4.10, at the top level only (the only level step 4 reads)
  std::vector<Taps> tx, ty;   // downsampling taps from level l-1 to l (index l)
  std::vector<float> tmp_z, tmp_s;  // horizontal pass of the separable isotropic downsampling
  std::vector<glm::vec3> row_max;   // per-row colour maxima of the input
  std::vector<float> level_map, dob_map;
  std::vector<HTab> hx;  // horizontal taps per level
  HTab hn;               // horizontal taps of the DoN magnification
  std::vector<HTap> taps;  // hx flattened over levels (gather_chunk)
};

// A pinhole: the output is the input, bit for bit (non-finite colour as 0, per dof_image.h).
static void copy_input(const DofInput& in, RgbImage& out) {
  const std::size_t np = in.pixels();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np, 16384), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      const glm::vec3 c = in.color[i];
      out[i] = {std::isfinite(c.x) ? c.x : 0.0f, std::isfinite(c.y) ? c.y : 0.0f, std::isfinite(c.z) ? c.z : 0.0f};
    }
  });
}

// Step 1 (Fig. 4.10): I(0), Z(0) and B(0) = sigma = dob_per_coc x C (C / 2 in §4.1.3). Returns the
// largest input colour per channel, the final pass's clamp.
static glm::vec3 base_level(const DofInput& in, const LeeMipmapSettings& s, Buffers& sc) {
  const int W = static_cast<int>(in.width), H = static_cast<int>(in.height);
  const std::size_t np = in.pixels();
  const auto uw = static_cast<std::size_t>(W);
  sc.levels.reserve(33);  // every level a 2^32-pixel side can have: references below stay valid
  if (sc.levels.empty()) sc.levels.resize(1);
  Level& L0 = sc.levels[0];
  L0.w = W;
  L0.h = H;
  L0.c.resize(3 * np);
  L0.z.resize(np);
  L0.s.resize(np);
  sc.row_max.resize(static_cast<std::size_t>(H));
  const CocModel coc = in.coc;
  // sigma = C / 2 (Lee §4.1.3) by default; dob_per_coc = 1/4 matches a uniform disc's variance.
  const double dob = std::isfinite(s.dob_per_coc) && s.dob_per_coc > 0 ? s.dob_per_coc : 0.5;
  tbb::parallel_for(tbb::blocked_range<int>(0, H), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y < r.end(); ++y) {
      glm::vec3 mx(0.0f);
      for (std::size_t x = 0; x < uw; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * uw + x;
        const glm::vec3 c = in.color[i];
        const glm::vec3 v{finite_or_zero(c.x), finite_or_zero(c.y), finite_or_zero(c.z)};
        // The mipmaps hold colours in [kTiny, kHuge], where the geometric blend's fast log/exp
        // work (0 reads as kTiny: the blend then stays ~0, as 0^(1-beta) does); every coarser
        // texel and bilinear sample is a convex mix of these, so stays inside too.
        L0.c[i] = gather(v.x);
        L0.c[np + i] = gather(v.y);
        L0.c[2 * np + i] = gather(v.z);
        mx = glm::max(mx, v);
        const float d = in.depth[i];
        L0.z[i] = std::isnan(d) ? kFarDepth : std::clamp(d, 0.0f, kFarDepth);
      }
      const std::size_t row = static_cast<std::size_t>(y) * uw;
      coc.scaled_coc_px(in.depth + row, uw, dob, L0.s.data() + row);
      sc.row_max[static_cast<std::size_t>(y)] = mx;
    }
  });
  glm::vec3 cmax(0.0f);
  for (const glm::vec3& m : sc.row_max) cmax = glm::max(cmax, m);
  return cmax;
}

// The levels: up to the one the largest DoB needs (§4.4 step 2). Eq. 4.8 reads levels l - 1 and l
// with l = floor(m), so m_max needs floor(m_max); at least level 1 for eq. 4.11's DoN; at most the
// top level of a GL mipmap (1 texel along the longer side), or the caller's max_level.
static int top_mipmap_level(int W, int H, float smax, float ks, int max_level) {
  const int top = static_cast<int>(std::floor(std::log2(static_cast<double>(std::max(W, H)))));
  int M = std::max(1, static_cast<int>(std::floor(level_of(smax, ks))));
  if (max_level > 0) M = std::min(M, max_level);
  M = std::min(M, top);
  return M;
}

// Step 2: Z and B of level l from level l - 1, isotropic (eq. 4.1), separable: rows first (into
// tmp_z, tmp_s), then columns.
static void downsample_depth_and_dob(const Level& src, Level& dst, const Taps& tx, const Taps& ty,
                                     std::vector<float>& tmp_z, std::vector<float>& tmp_s) {
  const auto sw = static_cast<std::size_t>(src.w), dw = static_cast<std::size_t>(dst.w);
  tmp_z.resize(static_cast<std::size_t>(src.h) * dw);
  tmp_s.resize(static_cast<std::size_t>(src.h) * dw);
  tbb::parallel_for(tbb::blocked_range<int>(0, src.h), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y < r.end(); ++y) {
      const float* zr = src.z.data() + static_cast<std::size_t>(y) * sw;
      const float* sr = src.s.data() + static_cast<std::size_t>(y) * sw;
      float* oz = tmp_z.data() + static_cast<std::size_t>(y) * dw;
      float* os = tmp_s.data() + static_cast<std::size_t>(y) * dw;
      for (std::size_t x = 0; x < dw; ++x) {
        float az = 0, as = 0;
        for (std::size_t k = 0; k < 4; ++k) {
          const auto j = static_cast<std::size_t>(tx.idx[4 * x + k]);
          az += tx.w[4 * x + k] * zr[j];
          as += tx.w[4 * x + k] * sr[j];
        }
        oz[x] = az;
        os[x] = as;
      }
    }
  });
  tbb::parallel_for(tbb::blocked_range<int>(0, dst.h), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y < r.end(); ++y) {
      const auto uy = static_cast<std::size_t>(y);
      float* oz = dst.z.data() + uy * dw;
      float* os = dst.s.data() + uy * dw;
      std::fill(oz, oz + dw, 0.0f);
      std::fill(os, os + dw, 0.0f);
      for (std::size_t k = 0; k < 4; ++k) {
        const float wk = ty.w[4 * uy + k];
        const std::size_t row = static_cast<std::size_t>(ty.idx[4 * uy + k]) * dw;
        const float* __restrict az = tmp_z.data() + row;
        const float* __restrict as = tmp_s.data() + row;
#pragma omp simd
        for (std::size_t x = 0; x < dw; ++x) {
          oz[x] += wk * az[x];
          os[x] += wk * as[x];
        }
      }
    }
  });
}

// Step 3: the colour, with the anisotropic Gaussian H of eq. 4.9 over the same taps. The centre
// p is the destination texel (its Z and DoB from step 2, level l); the neighbours q are the
// source texels (level l - 1). A sharper neighbour (sigma_q + delta < sigma_p) of a background
// centre (Z_p > Z_f) gets weight 0, so a focused object's intensity does not flow into the blurred
// background around it (Fig. 4.6b). The blurriest tap always keeps its weight (sigma_p is an
// average of the taps' DoBs), so the weights never all vanish; the isotropic fallback below only
// guards rounding.
static void downsample_colour(const Level& src, Level& dst, const Taps& tx, const Taps& ty, bool aniso, float zf,
                              float delta) {
  const auto sw = static_cast<std::size_t>(src.w), dw = static_cast<std::size_t>(dst.w);
  const std::size_t sn = src.pixels(), dn = dst.pixels();
  tbb::parallel_for(tbb::blocked_range<int>(0, dst.h), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y < r.end(); ++y) {
      const auto uy = static_cast<std::size_t>(y);
      for (std::size_t x = 0; x < dw; ++x) {
        const std::size_t p = uy * dw + x;
        const float sp = dst.s[p];
        const bool background = aniso && dst.z[p] > zf;
        glm::vec3 acc(0.0f), iso(0.0f);
        float wsum = 0;
        for (std::size_t a = 0; a < 4; ++a) {
          const std::size_t row = static_cast<std::size_t>(ty.idx[4 * uy + a]) * sw;
          const float wy = ty.w[4 * uy + a];
          for (std::size_t b = 0; b < 4; ++b) {
            const std::size_t q = row + static_cast<std::size_t>(tx.idx[4 * x + b]);
            const float g = wy * tx.w[4 * x + b];  // G(q - p), eq. 4.1
            const glm::vec3 cq{src.c[q], src.c[sn + q], src.c[2 * sn + q]};
            iso += g * cq;
            const float h = background && sp > src.s[q] + delta ? 0.0f : g;  // Lee 2009, eq. 4.9
            acc += h * cq;
            wsum += h;
          }
        }
        const glm::vec3 c = wsum > 1e-6f ? acc / wsum : iso;  // w_G = 1 / sum of the weights (eq. 4.1)
        dst.c[p] = c.x;
        dst.c[dn + p] = c.y;
        dst.c[2 * dn + p] = c.z;
      }
    }
  });
}

// Steps 2 and 3 (Fig. 4.10): levels 1..M of Z, B and I, each from the level below.
static void build_mipmaps(Buffers& sc, int M, bool aniso, float zf, float delta) {
  const int W = sc.levels[0].w, H = sc.levels[0].h;
  sc.levels.resize(static_cast<std::size_t>(M) + 1);
  sc.tx.resize(static_cast<std::size_t>(M) + 1);
  sc.ty.resize(static_cast<std::size_t>(M) + 1);
  for (int l = 1; l <= M; ++l) {
    const Level& src = sc.levels[static_cast<std::size_t>(l - 1)];
    Level& dst = sc.levels[static_cast<std::size_t>(l)];
    dst.w = std::max(1, W >> l);  // GL mipmap sizes
    dst.h = std::max(1, H >> l);
    const auto dn = static_cast<std::size_t>(dst.w) * static_cast<std::size_t>(dst.h);
    dst.c.resize(3 * dn);
    dst.z.resize(dn);
    dst.s.resize(dn);
    Taps& tx = sc.tx[static_cast<std::size_t>(l)];
    Taps& ty = sc.ty[static_cast<std::size_t>(l)];
    tx.build(src.w, dst.w);
    ty.build(src.h, dst.h);
    downsample_depth_and_dob(src, dst, tx, ty, sc.tmp_z, sc.tmp_s);
    downsample_colour(src, dst, tx, ty, aniso, zf, delta);
  }
}

// Step 2's DoN at the top level M (eq. 4.10): the largest DoB of level M - 1 among the taps q of
// texel p that are foreground (Z_q < Z_f) and nearer than p (Z_q < Z_p); 0 where there is none.
// Step 4 reads only N(M), and eq. 4.10 builds N(l) from B(l - 1) and Z, not from N(l - 1), so the
// lower levels of N are never needed and are not built.
static void depth_of_neighbours(Buffers& sc, int M, float zf) {
  const Level& top_l = sc.levels[static_cast<std::size_t>(M)];
  const Level& src = sc.levels[static_cast<std::size_t>(M - 1)];
  const Taps& tx = sc.tx[static_cast<std::size_t>(M)];
  const Taps& ty = sc.ty[static_cast<std::size_t>(M)];
  const auto sw = static_cast<std::size_t>(src.w), dw = static_cast<std::size_t>(top_l.w);
  sc.don.assign(dw * static_cast<std::size_t>(top_l.h), 0.0f);
  tbb::parallel_for(tbb::blocked_range<int>(0, top_l.h), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y < r.end(); ++y) {
      const auto uy = static_cast<std::size_t>(y);
      for (std::size_t x = 0; x < dw; ++x) {
        const float zp = top_l.z[uy * dw + x];
        float rho = 0;  // Lee 2009, eq. 4.10
        for (std::size_t a = 0; a < 4; ++a) {
          const std::size_t row = static_cast<std::size_t>(ty.idx[4 * uy + a]) * sw;
          for (std::size_t b = 0; b < 4; ++b) {
            const std::size_t q = row + static_cast<std::size_t>(tx.idx[4 * x + b]);
            if (src.z[q] < zf && src.z[q] < zp) rho = std::max(rho, src.s[q]);
          }
        }
        sc.don[uy * dw + x] = rho;
      }
    }
  });
}

// Steps 4 and 5's inputs, fixed for the whole image. Every bilinear lookup is at a position
// (u + o_x / w_k, v + o_y / h_k): for a given level and offset class its horizontal texels and
// weight depend on x only (tables, built once) and its vertical ones on y only (a lerped row per
// level and class, built per output row), as a GPU's texture unit with GL_LINEAR and
// GL_CLAMP_TO_EDGE would read them. out and sc (level_map, dob_map) are written through.
struct FinalPass {
  const DofInput& in;
  RgbImage& out;
  Buffers& sc;
  const Level& L0;
  const Level& top_l;  // level M, where the DoN is
  const Level& below;  // level M - 1, whose texels step 4's magnification steps by
  Neighbourhood nb;
  std::array<float, 5> cls;  // offset classes, texels
  int W, H, M;
  std::size_t uw, np, L;  // L = M + 1 levels
  float ks, mcap;
  bool smooth, geometric, debug;
  glm::vec3 cmax;  // largest input colour: the output's clamp
  // Planar lerped rows per task: plane (k, c, ch) at ((5 k + c) 3 + ch) W (a stride of W for
  // every level, so gather_chunk finds a plane by arithmetic alone).
  std::size_t row_off(std::size_t k, std::size_t c, std::size_t ch) const { return ((5 * k + c) * 3 + ch) * uw; }
};

// Horizontal tables: level k read at offsets of its own texels; the DoN (level M) at offsets of
// level M - 1's texels (the circular magnification of step 4, as eq. 4.8 reads one level lower).
static void horizontal_taps(Buffers& sc, const FinalPass& fp) {
  const int W = fp.W;
  const std::size_t uw = fp.uw, L = fp.L;
  const std::array<float, 5>& cls = fp.cls;
  const auto htab = [&](HTab& t, int n_src, float unit) {
    const auto pos = [&](int x, float o) {
      return ((static_cast<float>(x) + 0.5f) / static_cast<float>(W) + o / unit);
    };
    t.build(W, n_src, pos, cls);
  };
  sc.hx.resize(L);
  for (std::size_t k = 0; k < L; ++k) htab(sc.hx[k], sc.levels[k].w, static_cast<float>(sc.levels[k].w));
  if (fp.smooth) htab(sc.hn, fp.top_l.w, static_cast<float>(fp.below.w));
  // The same taps flattened over levels for gather_chunk: [(5 k + c) W + x].
  sc.taps.resize(L * 5 * uw);
  for (std::size_t k = 0; k < L; ++k) {
    const HTab& t = sc.hx[k];
    for (std::size_t e = 0; e < 5 * uw; ++e)
      sc.taps[k * 5 * uw + e] = {t.i0[e], t.i1[e] == t.i0[e] ? 0.0f : t.f[e]};  // i1 = i0 + 1 otherwise
  }
}

// The final pass's case per pixel.
enum PixelKind : std::uint8_t { kCopy, kBelowOne, kBlend };

// One task's buffers of the final pass, reused from row to row.
struct RowBuffers {
  // a[k][ch][i], b[k][ch][i]: sample k of I(l - 1) and I(l) for batch pixel i (eq. 4.8's factors).
  alignas(64) float A[9][3][kChunk];
  alignas(64) float B[9][3][kChunk];
  alignas(64) float res[3][kChunk];
  // Per pixel of the output row: the pass's case, l of eq. 4.8 (1 for the special cases, so
  // gather_chunk reads levels that exist; their values are replaced) and beta = m - l.
  std::vector<std::uint8_t> kind;
  std::vector<int> lvl;
  std::vector<float> beta;
  std::vector<float> rows;  // + 1: the last plane's texel w_k (read with f = 0)
  std::vector<std::vector<float>> vs, vn;  // DoB rows (no offset) per level, DoN rows per class
  std::vector<bool> needed;
  // don_count[j]: how many of the DoN's top-level columns < j are non-zero in any of this row's
  // five lerped DoN rows, so a pixel whose taps all read zeros skips the 9 reads of step 4.
  std::vector<int> don_count;
  explicit RowBuffers(const FinalPass& fp)
      : kind(fp.uw), lvl(fp.uw), beta(fp.uw), rows(fp.L * 15 * fp.uw + 1), vs(fp.L), vn(5), needed(fp.L),
        don_count(static_cast<std::size_t>(fp.top_l.w) + 1) {
    for (std::size_t k = 0; k < fp.L; ++k) vs[k].resize(static_cast<std::size_t>(fp.sc.levels[k].w));
    for (auto& row : vn) row.resize(static_cast<std::size_t>(fp.top_l.w));
  }
};

// B of every level at this row's v, no offset (step 4 reads sigma(n) at a level n per pixel).
static void lerp_dob_rows(const FinalPass& fp, RowBuffers& rb, float v) {
  for (std::size_t k = 0; k < fp.L; ++k) {
    const Level& lv = fp.sc.levels[k];
    lerp_rows(lv.s.data(), lv.w, vrow(lv.h, v * static_cast<float>(lv.h) - 0.5f), rb.vs[k].data());
  }
}

// N(M) at this row's v plus each offset class in level M - 1's texels, and don_count. Returns
// false where there is no foreground near this row: eq. 4.11 gives n = 0 throughout.
static bool lerp_don_rows(const FinalPass& fp, RowBuffers& rb, float v) {
  bool row_has_don = false;
  const float hb = static_cast<float>(fp.below.h), ht = static_cast<float>(fp.top_l.h);
  for (std::size_t c = 0; c < 5; ++c) {
    lerp_rows(fp.sc.don.data(), fp.top_l.w, vrow(fp.top_l.h, (v + fp.cls[c] / hb) * ht - 0.5f), rb.vn[c].data());
    for (float d : rb.vn[c]) row_has_don = row_has_don || d > 0;
  }
  if (row_has_don)
    for (std::size_t j = 0; j < rb.vn[0].size(); ++j) {
      bool nz = false;
      for (const auto& row : rb.vn) nz = nz || row[j] > 0;
      rb.don_count[j + 1] = rb.don_count[j] + (nz ? 1 : 0);
    }
  return row_has_don;
}

// Step 4: rho(M) magnified with the circular 9-point filter, then n by eq. 4.11; returns the DoB
// read at level n (sigma unchanged where n = 0).
static float foreground_smoothed_dob(const FinalPass& fp, const RowBuffers& rb, std::size_t ux, float sigma) {
  float rho = 0;
  for (std::size_t k = 0; k < 9; ++k)
    rho += fp.nb.w[k] *
           fp.sc.hn.at(static_cast<std::size_t>(kcx[k]), rb.vn[static_cast<std::size_t>(kcy[k])].data(), ux);
  const float nlev = std::min(level_of(rho, fp.ks), static_cast<float>(fp.M));  // Lee 2009, eq. 4.11
  if (nlev > 0) {
    // sigma(n): B read at the continuous level n (trilinear, as texture2DLod would).
    const auto n0 = static_cast<std::size_t>(std::min(static_cast<int>(nlev), fp.M));
    const float fn = nlev - static_cast<float>(n0);
    const float sa = fp.sc.hx[n0].at(2, rb.vs[n0].data(), ux);
    sigma = (n0 + 1 < fp.L && fn > 0) ? sa + fn * (fp.sc.hx[n0 + 1].at(2, rb.vs[n0 + 1].data(), ux) - sa) : sa;
  }
  return sigma;
}

// Steps 4 and 5's level per pixel (m of eq. 4.6, after eq. 4.11's smoothing), its case, l and beta,
// and which levels this row reads at all.
static void pixel_levels(const FinalPass& fp, RowBuffers& rb, int y, bool row_has_don) {
  std::fill(rb.needed.begin(), rb.needed.end(), false);
  for (std::size_t ux = 0; ux < fp.uw; ++ux) {
    const std::size_t p = static_cast<std::size_t>(y) * fp.uw + ux;
    float sigma = fp.L0.s[p];
    // The taps of step 4's filter lie between class -1's left texel and class +1's right one
    // (cls is ascending, the clamp monotone); if the DoN is 0 there, rho = 0 and n = 0.
    const auto don_near = [&] {
      const HTab& hn = fp.sc.hn;
      const auto d0 = static_cast<std::size_t>(hn.i0[ux]), d1 = static_cast<std::size_t>(hn.i1[4 * hn.w + ux]);
      return rb.don_count[d1 + 1] != rb.don_count[d0];
    };
    if (row_has_don && don_near()) sigma = foreground_smoothed_dob(fp, rb, ux, sigma);
    const float m = std::min(level_of(sigma, fp.ks), fp.mcap);  // Lee 2009, eq. 4.6
    if (fp.debug) {
      fp.sc.level_map[p] = m;
      fp.sc.dob_map[p] = sigma;
    }
    rb.lvl[ux] = 1;
    if (!(m > 0)) {  // no blur: the pixel itself
      rb.kind[ux] = kCopy;
      continue;
    }
    int l = static_cast<int>(m);
    float bt = m - static_cast<float>(l);
    if (l > fp.M) {
      l = fp.M;
      bt = 1;
    }
    rb.beta[ux] = bt;
    if (l == 0) {
      rb.kind[ux] = kBelowOne;
      rb.needed[0] = true;
      continue;
    }
    rb.kind[ux] = kBlend;
    rb.lvl[ux] = l;
    rb.needed[static_cast<std::size_t>(l - 1)] = true;
    rb.needed[static_cast<std::size_t>(l)] = true;
  }
}

// The vertically lerped planar rows of the levels this row reads (a row in focus reads none).
static void lerp_colour_rows(const FinalPass& fp, RowBuffers& rb, float v) {
  for (std::size_t k = 0; k < fp.L; ++k) {
    if (!rb.needed[k]) continue;
    const Level& lv = fp.sc.levels[k];
    const float hk = static_cast<float>(lv.h);
    for (std::size_t c = 0; c < 5; ++c) {
      const VRow vr = vrow(lv.h, (v + fp.cls[c] / hk) * hk - 0.5f);
      for (std::size_t ch = 0; ch < 3; ++ch) lerp_rows(lv.plane(ch), lv.w, vr, rb.rows.data() + fp.row_off(k, c, ch));
    }
  }
}

// The special cases' factors over gather_chunk's, for the batch at ux0 (p0 in the image). Copy:
// A = B = the pixel (the blend gives it back; the output is taken from the input anyway). m in
// (0, 1): there is no level -1 for eq. 4.8, so blend (eq. 4.7's form) the pixel itself with its 3x3
// circular Gaussian at level 0, which is eq. 4.8's value at m = 1; continuous with eq. 4.8 there
// and equal to the input at m = 0.
static void special_case_factors(const FinalPass& fp, RowBuffers& rb, std::size_t ux0, std::size_t p0,
                                 std::size_t un) {
  const std::uint8_t* kd = rb.kind.data() + ux0;
  for (std::size_t i = 0; i < un; ++i) {
    if (kd[i] == kBlend) continue;
    float self[3], filtered[3] = {0, 0, 0};
    for (std::size_t ch = 0; ch < 3; ++ch) self[ch] = fp.L0.c[ch * fp.np + p0 + i];
    if (kd[i] == kBelowOne) {
      for (std::size_t k = 0; k < 9; ++k) {
        const HTap tp = fp.sc.taps[static_cast<std::size_t>(kcx[k]) * fp.uw + ux0 + i];
        for (std::size_t ch = 0; ch < 3; ++ch) {
          const float* ro = rb.rows.data() + fp.row_off(0, static_cast<std::size_t>(kcy[k]), ch) +
                            static_cast<std::size_t>(tp.j);
          filtered[ch] += fp.nb.w[k] * (ro[0] + tp.f * (ro[1] - ro[0]));
        }
      }
    } else {
      std::copy(self, self + 3, filtered);
    }
    for (std::size_t k = 0; k < 9; ++k)
      for (std::size_t ch = 0; ch < 3; ++ch) {
        rb.A[k][ch][i] = self[ch];
        rb.B[k][ch][i] = filtered[ch];
      }
  }
}

// Step 5 for the batch of kChunk pixels at x0 of row y: eq. 4.8's factors, their blend, clamped.
static void shade_chunk(const FinalPass& fp, RowBuffers& rb, int y, int x0) {
  const auto ux0 = static_cast<std::size_t>(x0);
  const auto un = static_cast<std::size_t>(std::min(kChunk, fp.W - x0));
  const std::size_t p0 = static_cast<std::size_t>(y) * fp.uw + ux0;
  const std::uint8_t* kd = rb.kind.data() + ux0;
  if (std::all_of(kd, kd + un, [](std::uint8_t k) { return k == kCopy; })) {
    for (std::size_t i = 0; i < un; ++i) {
      const glm::vec3 c = fp.in.color[p0 + i];
      fp.out[p0 + i] = {finite_or_zero(c.x), finite_or_zero(c.y), finite_or_zero(c.z)};
    }
    return;
  }
  gather_chunk(rb.rows.data(), fp.sc.taps.data(), fp.W, x0, rb.lvl.data() + ux0, un, rb.A, rb.B);
  special_case_factors(fp, rb, ux0, p0, un);
  blend_chunk(rb.A, rb.B, rb.beta.data() + ux0, fp.nb.w.data(), un, fp.geometric, rb.res);
  for (std::size_t i = 0; i < un; ++i) {
    const std::size_t p = p0 + i;
    if (kd[i] == kCopy) {  // the input itself, exactly (non-finite and negative as 0)
      const glm::vec3 c = fp.in.color[p];
      fp.out[p] = {finite_or_zero(c.x), finite_or_zero(c.y), finite_or_zero(c.z)};
      continue;
    }
    // Every factor is a convex mix of input texels, so only the approximate log/exp can leave
    // [0, max input]; clamp to it (a NaN cannot arise: all factors are in [kTiny, kHuge]).
    fp.out[p] = {std::clamp(rb.res[0][i], 0.0f, fp.cmax.x), std::clamp(rb.res[1][i], 0.0f, fp.cmax.y),
                 std::clamp(rb.res[2][i], 0.0f, fp.cmax.z)};
  }
}

// Steps 4 and 5 for output row y.
static void final_pass_row(const FinalPass& fp, RowBuffers& rb, int y) {
  const float v = (static_cast<float>(y) + 0.5f) / static_cast<float>(fp.H);
  lerp_dob_rows(fp, rb, v);
  const bool row_has_don = fp.smooth && lerp_don_rows(fp, rb, v);
  pixel_levels(fp, rb, y, row_has_don);
  lerp_colour_rows(fp, rb, v);
  for (int x0 = 0; x0 < fp.W; x0 += kChunk) shade_chunk(fp, rb, y, x0);
}

// Steps 4 and 5 (§4.4) over the image, 8 rows per task.
static void final_pass(const FinalPass& fp) {
  if (fp.debug) {
    fp.sc.level_map.resize(fp.np);
    fp.sc.dob_map.resize(fp.np);
  }
  tbb::parallel_for(tbb::blocked_range<int>(0, fp.H, 8), [&](const tbb::blocked_range<int>& r) {
    RowBuffers rb(fp);
    for (int y = r.begin(); y < r.end(); ++y) final_pass_row(fp, rb, y);
  });
}

}  // namespace

struct LeeMipmap::Scratch : Buffers {};

LeeMipmap::LeeMipmap() : scratch_(std::make_unique<Scratch>()) {}
LeeMipmap::~LeeMipmap() = default;
const std::vector<float>& LeeMipmap::level_map() const { return scratch_->level_map; }
const std::vector<float>& LeeMipmap::dob_map() const { return scratch_->dob_map; }

void LeeMipmap::run(const DofInput& in, const LeeMipmapSettings& s, RgbImage& out, LeeMipmapStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  Scratch& sc = *scratch_;
  const int W = static_cast<int>(in.width), H = static_cast<int>(in.height);
  const std::size_t np = in.pixels();
  out.resize(np);
  sc.level_map.clear();
  sc.dob_map.clear();
  LeeMipmapStats st;
  const auto finish = [&] {
    st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (stats) *stats = st;
  };
  if (np == 0 || !in.color) {
    std::fill(out.begin(), out.end(), glm::vec3(0.0f));
    finish();
    return;
  }
  if (in.coc.pinhole() || !in.depth) {
    copy_input(in, out);
    finish();
    return;
  }

  const glm::vec3 cmax = base_level(in, s, sc);
  float smax = 0;
  for (float v : sc.levels[0].s) smax = std::max(smax, v);
  st.max_dob_px = smax;
  const float ks = std::isfinite(s.k_sigma) && s.k_sigma > 0 ? static_cast<float>(s.k_sigma) : 2.0f / 3.0f;
  if (!(smax > 0)) {  // everything in focus: eq. 4.6 gives m = 0 everywhere
    copy_input(in, out);
    finish();
    return;
  }
  const int M = top_mipmap_level(W, H, smax, ks, s.max_level);
  st.levels = M;
  if (M < 1) {  // a 1x1 image: every blur of one texel clamped to the edge is that texel
    copy_input(in, out);
    finish();
    return;
  }
  const CocModel& coc = in.coc;
  const float zf = std::isfinite(coc.focus_m) ? static_cast<float>(std::max(coc.focus_m, 0.0))
                                              : (coc.focus_m > 0 ? kFarDepth : 0.0f);
  const float delta = std::isfinite(s.delta) ? static_cast<float>(s.delta) : 0.0f;
  build_mipmaps(sc, M, s.anisotropic, zf, delta);
  if (s.smooth_foreground) depth_of_neighbours(sc, M, zf);
  st.mipmap_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const float dg = s.circular ? 0.70710678f : 1.0f;
  const FinalPass fp{.in = in,
                     .out = out,
                     .sc = sc,
                     .L0 = sc.levels[0],
                     .top_l = sc.levels[static_cast<std::size_t>(M)],
                     .below = sc.levels[static_cast<std::size_t>(M - 1)],
                     .nb = Neighbourhood(s.circular),
                     .cls = {-1.0f, -dg, 0.0f, dg, 1.0f},
                     .W = W,
                     .H = H,
                     .M = M,
                     .uw = static_cast<std::size_t>(W),
                     .np = np,
                     .L = static_cast<std::size_t>(M) + 1,
                     .ks = ks,
                     .mcap = static_cast<float>(M + 1),
                     .smooth = s.smooth_foreground,
                     .geometric = s.geometric,
                     .debug = record_debug_,
                     .cmax = cmax};
  horizontal_taps(sc, fp);
  final_pass(fp);
  finish();
}

void lee_mipmap(const DofInput& in, const LeeMipmapSettings& s, RgbImage& out, LeeMipmapStats* stats) {
  LeeMipmap m;
  m.run(in, s, out, stats);
}

}  // namespace fovea::render::dof
