// SPDX-License-Identifier: Apache-2.0
// Lee 2009 chapter 5 depth of field by point splatting on per-pixel layers (renderer/dof/lee_splat.h):
// pinhole exactness, energy conservation per aperture shape, partial occlusion with and without
// the hidden layer against a brute-force layered reference, no smearing of focused areas next to
// blurred ones (the layer decomposition of eq. 5.3), §5.3's reduced resolution, eq. 5.5, determinism.
#include <gtest/gtest.h>

#include <tbb/task_arena.h>

#include <cmath>
#include <random>

#include "dof/lee_splat.h"
#include "dof_test_image.h"
#include "dof_lens.h"

using namespace fovea::render::dof;

namespace {

using test::DofImage;

// A lens with K (eq. 5.3, pixels) = k_px, focused at focus_m.
CocModel lens(double k_px, double focus_m = 2.0) { return test::lens_with_k(k_px, focus_m); }

// Black at 2 m (the focus distance of lens()); the hidden layer black and empty.
DofImage blank(std::uint32_t w, std::uint32_t h) { return DofImage(w, h, glm::vec3(0), 2.0f); }

RgbImage run(const DofImage& sc, const CocModel& coc, const LeeSplatSettings& s, bool with_hidden = true,
             LeeSplatStats* st = nullptr) {
  RgbImage out;
  lee_splat(sc.input(coc, with_hidden), s, out, st);
  return out;
}

double psnr(const RgbImage& a, const RgbImage& b, double peak = 1.0) {
  double mse = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const glm::vec3 d = a[i] - b[i];
    mse += double{d.x * d.x + d.y * d.y + d.z * d.z} / 3.0;
  }
  mse /= static_cast<double>(a.size());
  return mse > 0 ? 10 * std::log10(peak * peak / mse) : 999.0;
}

glm::dvec3 total(const RgbImage& img) {
  glm::dvec3 t(0);
  for (const auto& c : img) t += glm::dvec3(c);
  return t;
}

glm::vec3 checker(std::uint32_t x, std::uint32_t y) {
  const bool odd = ((x / 3) + (y / 3)) % 2 != 0;
  return odd ? glm::vec3(0.9f, 0.8f, 0.1f) : glm::vec3(0.1f, 0.2f, 0.7f);
}

}  // namespace

TEST(LeeSplat, PinholeIsExact) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 50.0f);
  DofImage sc = blank(37, 23);
  CocModel pinhole = lens(0.0);
  pinhole.aperture_m = 0;
  for (std::size_t i = 0; i < sc.color.size(); ++i) {
    sc.color[i] = {u(rng), u(rng) * 1e4f, u(rng) * 1e-3f};
    sc.depth[i] = 0.1f + u(rng);
    sc.hidden_color[i] = glm::vec3(1e3f);
    sc.hidden_depth[i] = sc.depth[i] + 5.0f;
  }
  for (const Aperture ap : {Aperture::Disc, Aperture::Gaussian, Aperture::Hexagon}) {
    LeeSplatSettings s;
    s.aperture = ap;
    s.reduce = 2;
    const RgbImage out = run(sc, pinhole, s);
    ASSERT_EQ(out.size(), sc.color.size());
    for (std::size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], sc.color[i]) << i;
  }
  // Everything in focus with a real aperture: also exact.
  DofImage f = blank(19, 11);
  for (std::size_t i = 0; i < f.color.size(); ++i) f.color[i] = {u(rng), u(rng), u(rng)};
  const RgbImage out = run(f, lens(30.0), LeeSplatSettings{});
  for (std::size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], f.color[i]) << i;
}

TEST(LeeSplat, ConstantImageStaysConstantForAnyCoc) {
  std::mt19937 rng(11);
  const CocModel coc = lens(60.0);
  std::uniform_real_distribution<double> cd(0.0, 45.0);
  std::uniform_int_distribution<int> side(0, 1);
  DofImage sc = blank(48, 40);
  const glm::vec3 c(0.3f, 0.5f, 0.7f);
  for (std::size_t i = 0; i < sc.color.size(); ++i) {
    const double want = cd(rng);
    sc.depth[i] = static_cast<float>(side(rng) ? coc.depth_near_for_coc(want) : coc.depth_far_for_coc(want));
    sc.color[i] = c;
    sc.hidden_color[i] = c;
    sc.hidden_depth[i] = sc.depth[i] * 1.5f;
  }
  for (const Aperture ap : {Aperture::Disc, Aperture::Gaussian, Aperture::Hexagon}) {
    for (const int reduce : {1, 2, 4}) {
      LeeSplatSettings s;
      s.aperture = ap;
      s.reduce = reduce;
      const RgbImage out = run(sc, coc, s);
      for (std::size_t i = 0; i < out.size(); ++i) {
        ASSERT_NEAR(out[i].x, c.x, 1e-5) << i;
        ASSERT_NEAR(out[i].y, c.y, 1e-5) << i;
        ASSERT_NEAR(out[i].z, c.z, 1e-5) << i;
      }
    }
  }
}

TEST(LeeSplat, BrightPixelSpreadsIntoApertureShapeConservingEnergy) {
  const CocModel coc = lens(40.0);
  const double cdiam = 15.0;  // R = 7.5
  DofImage sc = blank(61, 61);
  const float d = static_cast<float>(coc.depth_far_for_coc(cdiam));
  for (auto& z : sc.depth) z = d;
  const std::uint32_t cx = 30, cy = 30;
  sc.color[sc.at(cx, cy)] = glm::vec3(1000.0f, 500.0f, 10.0f);
  const auto v = [&](const RgbImage& o, int dx, int dy) {
    return o[sc.at(static_cast<std::uint32_t>(int(cx) + dx), static_cast<std::uint32_t>(int(cy) + dy))].x;
  };
  for (const Aperture ap : {Aperture::Disc, Aperture::Gaussian, Aperture::Hexagon}) {
    LeeSplatSettings s;
    s.aperture = ap;
    const RgbImage out = run(sc, coc, s);
    const glm::dvec3 t = total(out);
    EXPECT_NEAR(t.x, 1000.0, 1e-3 * 1000.0);
    EXPECT_NEAR(t.y, 500.0, 1e-3 * 500.0);
    EXPECT_NEAR(t.z, 10.0, 1e-3 * 10.0);
    // Nothing outside the circumscribing circle of radius C/2.
    for (int dy = -30; dy <= 30; ++dy) {
      for (int dx = -30; dx <= 30; ++dx) {
        if (dx * dx + dy * dy > 7.5 * 7.5 + 1e-3) {
          ASSERT_EQ(v(out, dx, dy), 0.0f) << dx << "," << dy;
        }
      }
    }
    if (ap == Aperture::Disc) {
      // Uniform IDF over the disc: every covered pixel equal, the rim included.
      const float c0 = v(out, 0, 0);
      EXPECT_GT(c0, 0.0f);
      EXPECT_NEAR(v(out, 7, 0), c0, 1e-4f * c0);
      EXPECT_NEAR(v(out, 0, -7), c0, 1e-4f * c0);
      EXPECT_NEAR(v(out, 5, 5), c0, 1e-4f * c0);
      EXPECT_EQ(v(out, 6, 5), 0.0f);  // 61 > 56.25: outside
      EXPECT_NEAR(c0 * 177.0f, 1000.0f, 1.0f);  // 177 pixel centres within R = 7.5
    } else if (ap == Aperture::Hexagon) {
      // Pointy-top hexagon of circumradius 7.5: reaches (0, +-7) but only |x| <= 6.5 on row 0, and
      // the slanted edges cut the corner that the disc keeps.
      const float c0 = v(out, 0, 0);
      EXPECT_GT(c0, 0.0f);
      EXPECT_NEAR(v(out, 0, 7), c0, 1e-4f * c0);
      EXPECT_NEAR(v(out, 6, 0), c0, 1e-4f * c0);
      EXPECT_EQ(v(out, 7, 0), 0.0f);
      EXPECT_EQ(v(out, 3, 6), 0.0f);  // inside the disc (45 < 56.25), outside the hexagon
      EXPECT_NEAR(v(out, -3, -3), c0, 1e-4f * c0);
    } else {
      // Gaussian: peaked at the centre, falling off monotonically along a radius.
      float prev = v(out, 0, 0);
      for (int dx = 1; dx <= 7; ++dx) {
        EXPECT_LT(v(out, dx, 0), prev) << dx;
        prev = v(out, dx, 0);
      }
      EXPECT_GT(v(out, 7, 0), 0.0f);
      EXPECT_NEAR(v(out, 0, 4), v(out, 4, 0), 1e-3f * v(out, 4, 0));
    }
  }
}

namespace {

// A focused checkered background at the focus distance and a blurred foreground bar (CoC `c_fg`) in
// front of it, columns [x0, x1). The hidden layer holds the background under the bar.
struct BarScene {
  DofImage sc;
  CocModel coc = lens(40.0);
  RgbImage reference;
  std::uint32_t x0, x1;
  glm::vec3 fg{0.9f, 0.15f, 0.1f};
  BarScene(std::uint32_t w, std::uint32_t h, std::uint32_t bx0, std::uint32_t bx1, double c_fg)
      : sc(blank(w, h)), x0(bx0), x1(bx1) {
    const float zfg = static_cast<float>(coc.depth_near_for_coc(c_fg));
    for (std::uint32_t y = 0; y < h; ++y) {
      for (std::uint32_t x = 0; x < w; ++x) {
        const std::size_t i = sc.at(x, y);
        sc.depth[i] = 2.0f;
        sc.color[i] = checker(x, y);
        if (x >= x0 && x < x1) {
          sc.hidden_color[i] = sc.color[i];
          sc.hidden_depth[i] = 2.0f;
          sc.color[i] = fg;
          sc.depth[i] = zfg;
        }
      }
    }
    // Brute-force layered reference: the foreground layer's coverage alpha(q) is the sum over bar
    // pixels of a uniform disc of diameter c_fg (normalised per discrete disc); the composite is
    // alpha F + (1 - alpha) background, with the background whole and sharp.
    const double r = 0.5 * c_fg;
    const int ri = static_cast<int>(std::floor(r + 1e-4));
    int count = 0;
    for (int dy = -ri; dy <= ri; ++dy) {
      for (int dx = -ri; dx <= ri; ++dx) count += dx * dx + dy * dy <= r * r + 1e-4 ? 1 : 0;
    }
    reference.assign(sc.color.size(), glm::vec3(0));
    for (std::uint32_t y = 0; y < h; ++y) {
      for (std::uint32_t x = 0; x < w; ++x) {
        double alpha = 0;
        for (int dy = -ri; dy <= ri; ++dy) {
          for (int dx = -ri; dx <= ri; ++dx) {
            const int sx = int(x) + dx, sy = int(y) + dy;
            if (sx < int(x0) || sx >= int(x1) || sy < 0 || sy >= int(h)) continue;
            if (dx * dx + dy * dy <= r * r + 1e-4) alpha += 1.0 / count;
          }
        }
        const glm::vec3 bg = checker(x, y);
        const auto a = static_cast<float>(std::min(1.0, alpha));
        reference[sc.at(x, y)] = a * fg + (1 - a) * bg;
      }
    }
  }
};

}  // namespace

TEST(LeeSplat, HiddenLayerFillsPartialOcclusion) {
  BarScene bs(72, 40, 28, 44, 14.0);
  LeeSplatSettings s;
  LeeSplatStats with_stats, without_stats;
  const RgbImage with = run(bs.sc, bs.coc, s, true, &with_stats);
  const RgbImage without = run(bs.sc, bs.coc, s, false, &without_stats);
  // Only rows away from the top and bottom (where the bar's discs are cut by the image border).
  const auto rows = [&](const RgbImage& img) {
    RgbImage r;
    for (std::uint32_t y = 8; y < bs.sc.h - 8; ++y) {
      for (std::uint32_t x = 0; x < bs.sc.w; ++x) r.push_back(img[bs.sc.at(x, y)]);
    }
    return r;
  };
  const double p_with = psnr(rows(with), rows(bs.reference));
  const double p_without = psnr(rows(without), rows(bs.reference));
  std::printf("partial occlusion PSNR: with H %.2f dB, without H %.2f dB (hidden used %zu)\n", p_with, p_without,
              with_stats.hidden_used);
  EXPECT_GT(p_with, 35.0);
  EXPECT_GT(p_with, p_without + 3.0);
  EXPECT_EQ(without_stats.hidden_used, 0u);
  // The three tests of §5.1.2 keep only hidden pixels near the bar's edges (the bar's interior,
  // farther than its CoC radius from an edge, hides the background completely).
  EXPECT_GT(with_stats.hidden_used, 0u);
  EXPECT_LT(with_stats.hidden_used, std::size_t{16} * 40);
  // Behind the bar's middle column the foreground is opaque: the foreground colour, exactly.
  for (std::uint32_t y = 8; y < 32; ++y) {
    const glm::vec3 c = with[bs.sc.at(36, y)];
    EXPECT_NEAR(c.x, bs.fg.x, 1e-5);
    EXPECT_NEAR(c.y, bs.fg.y, 1e-5);
  }
}

TEST(LeeSplat, FocusedBackgroundNextToBlurredForegroundIsNotSmeared) {
  BarScene bs(72, 40, 28, 44, 14.0);
  const RgbImage out = run(bs.sc, bs.coc, LeeSplatSettings{}, false);
  for (std::uint32_t y = 0; y < bs.sc.h; ++y) {
    for (std::uint32_t x = 0; x < bs.sc.w; ++x) {
      if (x >= bs.x0 && x < bs.x1) continue;
      const std::size_t i = bs.sc.at(x, y);
      if (x + 8 < bs.x0 || x >= bs.x1 + 8) {
        // Beyond the foreground's reach: the focused background, exactly.
        ASSERT_EQ(out[i], bs.sc.color[i]) << x << "," << y;
      } else if (y >= 8 && y < bs.sc.h - 8) {
        // Within its reach: foreground over a sharp background (eq. 5.4), as the layered reference.
        ASSERT_NEAR(out[i].x, bs.reference[i].x, 1e-4) << x << "," << y;
        ASSERT_NEAR(out[i].z, bs.reference[i].z, 1e-4) << x << "," << y;
      }
    }
  }
}

TEST(LeeSplat, FocusedObjectDoesNotLeakIntoBlurredBackground) {
  // A sharp object in front of a blurred background: the object stays exactly sharp (its own splat
  // is opaque in layer 1, the background's arrive behind it) and its colour does not reach the
  // background beyond its own pixels (its CoC is 0).
  const CocModel coc = lens(40.0);
  DofImage sc = blank(50, 30);
  const float zbg = static_cast<float>(coc.depth_far_for_coc(20.0));
  for (std::uint32_t y = 0; y < sc.h; ++y) {
    for (std::uint32_t x = 0; x < sc.w; ++x) {
      const std::size_t i = sc.at(x, y);
      sc.depth[i] = zbg;
      sc.color[i] = glm::vec3(0.0f, 0.0f, 1.0f);
      if (x >= 20 && x < 30) {
        sc.depth[i] = 2.0f;
        sc.color[i] = glm::vec3(1.0f, 0.0f, 0.0f);
      }
    }
  }
  const RgbImage out = run(sc, coc, LeeSplatSettings{}, false);
  for (std::uint32_t y = 0; y < sc.h; ++y) {
    for (std::uint32_t x = 0; x < sc.w; ++x) {
      const std::size_t i = sc.at(x, y);
      if (x >= 20 && x < 30) {
        ASSERT_EQ(out[i], sc.color[i]) << x << "," << y;
      } else {
        ASSERT_EQ(out[i].x, 0.0f) << x << "," << y;  // no red leaks out
        ASSERT_NEAR(out[i].z, 1.0f, 1e-5) << x << "," << y;
      }
    }
  }
}

TEST(LeeSplat, ReducedResolutionStaysCloseToFull) {
  const CocModel coc = lens(60.0);
  DofImage sc = blank(96, 72);
  for (std::uint32_t y = 0; y < sc.h; ++y) {
    for (std::uint32_t x = 0; x < sc.w; ++x) {
      const std::size_t i = sc.at(x, y);
      // A slanted textured ground (CoC 0 to ~24 px) with a blurred foreground disc.
      const double c = 24.0 * y / (sc.h - 1);
      sc.depth[i] = static_cast<float>(coc.depth_far_for_coc(c));
      sc.color[i] = 0.5f * checker(x, y) + glm::vec3(0.2f * std::sin(0.3f * float(x)));
      const double dx = double(x) - 30, dy = double(y) - 30;
      if (dx * dx + dy * dy < 100) {
        sc.hidden_color[i] = sc.color[i];
        sc.hidden_depth[i] = sc.depth[i];
        sc.depth[i] = static_cast<float>(coc.depth_near_for_coc(16.0));
        sc.color[i] = glm::vec3(1.0f, 0.9f, 0.2f);
      }
    }
  }
  LeeSplatSettings full, red;
  red.reduce = 2;
  LeeSplatStats sf, sr;
  const RgbImage a = run(sc, coc, full, true, &sf);
  const RgbImage b = run(sc, coc, red, true, &sr);
  const double p = psnr(a, b);
  std::printf("reduced vs full: %.2f dB, splats %zu vs %zu\n", p, sr.splats, sf.splats);
  EXPECT_GT(p, 35.0);
  EXPECT_LT(sr.splats, sf.splats * 3 / 4);  // the point array really is reduced
}

TEST(LeeSplat, LdrHighlightsExtrapolateBrightPixelsOnly) {
  const CocModel coc = lens(40.0);
  DofImage sc = blank(41, 41);
  const float d = static_cast<float>(coc.depth_far_for_coc(9.0));
  for (auto& z : sc.depth) z = d;
  sc.color[sc.at(10, 20)] = glm::vec3(0.98f);  // bright: extrapolated (eq. 5.5)
  sc.color[sc.at(30, 20)] = glm::vec3(0.5f);   // below λ_0 = 0.8: untouched
  LeeSplatSettings off, on;
  on.ldr_highlights = true;
  const RgbImage a = run(sc, coc, off), b = run(sc, coc, on);
  double bright_a = 0, bright_b = 0, dim_a = 0, dim_b = 0;
  for (std::uint32_t y = 0; y < sc.h; ++y) {
    for (std::uint32_t x = 0; x < sc.w; ++x) {
      (x < 20 ? bright_a : dim_a) += double{a[sc.at(x, y)].x};
      (x < 20 ? bright_b : dim_b) += double{b[sc.at(x, y)].x};
    }
  }
  EXPECT_NEAR(bright_a, 0.98, 1e-4);
  const double ln = (0.98 - 0.8) / 0.2, pw = ln * ln * ln;
  EXPECT_NEAR(bright_b, 0.98 * ((1 - pw) + 2 * pw), 1e-3);
  EXPECT_NEAR(dim_a, 0.5, 1e-4);
  EXPECT_NEAR(dim_b, dim_a, 1e-6);
}

TEST(LeeSplat, DeterministicAcrossRunsAndThreadCounts) {
  const CocModel coc = lens(50.0);
  DofImage sc = blank(80, 57);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (std::size_t i = 0; i < sc.color.size(); ++i) {
    sc.color[i] = glm::vec3(float(u(rng)), float(u(rng)) * 100, float(u(rng)));
    sc.depth[i] = static_cast<float>(0.8 + 4 * u(rng));
    sc.hidden_color[i] = glm::vec3(float(u(rng)));
    sc.hidden_depth[i] = sc.depth[i] + 1.0f;
  }
  LeeSplatSettings s;
  s.aperture = Aperture::Gaussian;
  const RgbImage a = run(sc, coc, s);
  const RgbImage b = run(sc, coc, s);
  RgbImage c;
  tbb::task_arena one(1);
  one.execute([&] { c = run(sc, coc, s); });
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i], b[i]) << i;
    ASSERT_EQ(a[i], c[i]) << i;
  }
}

// Timing at the target size (run with --gtest_also_run_disabled_tests; no assertion on
// time). A textured slanted background with CoCs around the mean and foreground discs in front of
// it (with the hidden layer behind them).
#ifndef MEANS
#define MEANS 4.0, 16.0, 32.0
#endif
TEST(LeeSplat, DISABLED_Timing1024x768) {
  const CocModel coc = lens(200.0);
  for (const double mean : {MEANS}) {
    DofImage sc = blank(1024, 768);
    double csum = 0;
    for (std::uint32_t y = 0; y < sc.h; ++y) {
      for (std::uint32_t x = 0; x < sc.w; ++x) {
        const std::size_t i = sc.at(x, y);
        const double f = 0.5 + 0.45 * std::sin(0.011 * x) * std::cos(0.017 * y);  // in [0.05, 0.95]
        double c = 2.0 * mean * f;
        sc.depth[i] = static_cast<float>(coc.depth_far_for_coc(c));
        sc.color[i] = checker(x, y) + glm::vec3((x * 7 + y * 13) % 101 == 0 ? 20.0f : 0.0f);
        const double dx = double(x % 256) - 128, dy = double(y % 256) - 128;
        if (dx * dx + dy * dy < 40 * 40) {  // foreground discs
          sc.hidden_color[i] = sc.color[i];
          sc.hidden_depth[i] = sc.depth[i];
          c = 1.5 * mean;
          sc.depth[i] = static_cast<float>(coc.depth_near_for_coc(c));
          sc.color[i] = glm::vec3(1.0f, 0.5f, 0.2f);
        }
        csum += c;
      }
    }
    for (const bool hidden : {false, true}) {
      for (const int reduce : {1, 2, 4}) {
        LeeSplatSettings s;
        s.reduce = reduce;
        RgbImage out;
        LeeSplatStats st;
        lee_splat(sc.input(coc, hidden), s, out, &st);  // warm-up (allocations)
        double best = 1e9, sum = 0;
        constexpr int kRuns = 5;
        for (int r = 0; r < kRuns; ++r) {
          lee_splat(sc.input(coc, hidden), s, out, &st);
          best = std::min(best, st.seconds);
          sum += st.seconds;
        }
        std::fflush(stdout);
        std::printf("mean CoC %.1f px, hidden %d, reduce %d: %.1f ms mean, %.1f ms best (splats %zu, hidden used %zu)\n",
                    csum / double(sc.color.size()), hidden ? 1 : 0, reduce, 1e3 * sum / kRuns, 1e3 * best, st.splats,
                    st.hidden_used);
      }
    }
  }
}
