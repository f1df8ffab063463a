// SPDX-License-Identifier: Apache-2.0
#pragma once
// The stages of LeeMipmap::run (Lee 2009 ch. 4, Fig. 4.10) and what they share: the mipmap levels
// and their downsampling taps, the buffers LeeMipmap keeps from frame to frame, and the final pass's
// inputs. Internal to the pass: lee_mipmap_levels.cpp builds the levels (steps 1-3),
// lee_mipmap_final_pass.cpp reads them for each output pixel (steps 4 and 5), lee_mipmap.cpp runs
// the stages.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

#include "dof/lee_mipmap.h"

namespace fovea::render::dof::lee_mipmap_detail {

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

// One horizontal bilinear tap: texels j and j + 1 with weight f on the second. HTab's edge cases,
// where both of its texels are the same clamped one, are stored as that texel with f = 0 (exactly
// its value: x + 0 (y - x) = x for finite y), so the second texel is always the next one.
struct HTap {
  int j;
  float f;
};

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

inline float finite_or_zero(float v) { return std::isfinite(v) ? std::max(v, 0.0f) : 0.0f; }

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

// Step 1: level 0 of `sc`; returns the largest input colour (lee_mipmap_levels.cpp).
glm::vec3 base_level(const DofInput& in, const LeeMipmapSettings& s, Buffers& sc);
// M, the top level the largest DoB `smax` needs (lee_mipmap_levels.cpp).
int top_mipmap_level(int W, int H, float smax, float ks, int max_level);
// Steps 2 and 3 (Fig. 4.10): levels 1..M of Z, B and I (lee_mipmap_levels.cpp).
void build_mipmaps(Buffers& sc, int M, bool aniso, float zf, float delta);
// Step 2's DoN N(M) at the top level (eq. 4.10; lee_mipmap_levels.cpp).
void depth_of_neighbours(Buffers& sc, int M, float zf);

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

// The final pass's horizontal tap tables (lee_mipmap_final_pass.cpp).
void horizontal_taps(Buffers& sc, const FinalPass& fp);
// Steps 4 and 5 (§4.4) over the image (lee_mipmap_final_pass.cpp).
void final_pass(const FinalPass& fp);

}  // namespace fovea::render::dof::lee_mipmap_detail
