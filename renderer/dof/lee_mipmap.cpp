// SPDX-License-Identifier: Apache-2.0
// Lee 2009 ch. 4 (lee_mipmap.h): LeeMipmap::run, which handles the cases without blur and runs the
// stages of lee_mipmap_detail.h: the mipmaps (lee_mipmap_levels.cpp) and the final pass
// (lee_mipmap_final_pass.cpp).
#include "dof/lee_mipmap.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "dof/lee_mipmap_detail.h"

namespace fovea::render::dof {

using namespace lee_mipmap_detail;

namespace {

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
