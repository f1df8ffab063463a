// SPDX-License-Identifier: Apache-2.0
// Lee 2009 ch. 4, steps 1-3 of Fig. 4.10: the base level I(0), Z(0), B(0) from the input, the
// number of levels the largest DoB needs, levels 1..M of depth and DoB (isotropic, eq. 4.1) and
// colour (anisotropic, eq. 4.9), and the DoN at the top level (eq. 4.10).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "dof/lee_mipmap_detail.h"

namespace fovea::render::dof::lee_mipmap_detail {

// Step 1 (Fig. 4.10): I(0), Z(0) and B(0) = sigma = dob_per_coc x C (C / 2 in §4.1.3). Returns the
// largest input colour per channel, the final pass's clamp.
glm::vec3 base_level(const DofInput& in, const LeeMipmapSettings& s, Buffers& sc) {
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
int top_mipmap_level(int W, int H, float smax, float ks, int max_level) {
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
void build_mipmaps(Buffers& sc, int M, bool aniso, float zf, float delta) {
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
void depth_of_neighbours(Buffers& sc, int M, float zf) {
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

}  // namespace fovea::render::dof::lee_mipmap_detail
