// SPDX-License-Identifier: Apache-2.0
// Lee 2009 ch. 4, steps 4 and 5 of Fig. 4.10 (§4.4): per output pixel its level (eq. 4.6, after the
// foreground smoothing of eq. 4.11) and the nonlinear interpolation of eq. 4.8 between two levels'
// 3x3 neighbourhoods, in batches of kChunk pixels: bilinear reads by tables and lerped rows, the
// fast log2/exp2 of the geometric blend, and the blend itself.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "dof/lee_mipmap_detail.h"

namespace fovea::render::dof::lee_mipmap_detail {

namespace {

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

}  // namespace

// Horizontal tables: level k read at offsets of its own texels; the DoN (level M) at offsets of
// level M - 1's texels (the circular magnification of step 4, as eq. 4.8 reads one level lower).
void horizontal_taps(Buffers& sc, const FinalPass& fp) {
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
void final_pass(const FinalPass& fp) {
  if (fp.debug) {
    fp.sc.level_map.resize(fp.np);
    fp.sc.dob_map.resize(fp.np);
  }
  tbb::parallel_for(tbb::blocked_range<int>(0, fp.H, 8), [&](const tbb::blocked_range<int>& r) {
    RowBuffers rb(fp);
    for (int y = r.begin(); y < r.end(); ++y) final_pass_row(fp, rb, y);
  });
}

}  // namespace fovea::render::dof::lee_mipmap_detail
