// SPDX-License-Identifier: Apache-2.0
// CSF-driven peripheral ray casting (renderer/gi/csf_mask.h, Murphy 2007 ch. 4-5).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "gi/csf_mask.h"

namespace fovea::render::gi {
namespace {

// A 19" 5:4 monitor (1280x1024, 376 x 301 mm) at 60 cm.
protocol::DisplayGeometry monitor_at_60cm() { return {1280, 1024, 0.376, 0.301, 0.60}; }

struct Disc {
  glm::vec2 centre;
  float radius;
  std::uint32_t id;
};

// The object a ray through px hits: the last disc containing it (later discs in front).
std::uint32_t object_in(const std::vector<Disc>& discs, glm::vec2 px) {
  std::uint32_t hit = 0;
  for (const Disc& d : discs)
    if (glm::length(px - d.centre) <= d.radius) hit = d.id;
  return hit;
}

double mask_density(const CsfRayMask& mask, std::uint32_t x0, std::uint32_t y0, std::uint32_t size) {
  std::uint64_t set = 0;
  for (std::uint32_t y = y0; y < y0 + size; ++y)
    for (std::uint32_t x = x0; x < x0 + size; ++x) set += mask.at(x, y) ? 1u : 0u;
  return static_cast<double>(set) / static_cast<double>(size * size);
}

TEST(CsfThreshold, RisesWithEccentricityAndFrequency) {
  const CsfSettings s;
  for (double f : {1.0, 5.0, 10.0, 20.0}) {
    double previous = 0;
    for (double e : {0.0, 1.0, 5.0, 10.0, 30.0}) {
      const double ct = contrast_threshold(f, e, s);
      EXPECT_GT(ct, previous) << "f " << f << " e " << e;
      previous = ct;
    }
  }
  for (double e : {0.0, 2.0, 10.0}) {
    EXPECT_LT(contrast_threshold(2.0, e, s), contrast_threshold(4.0, e, s));
    EXPECT_LT(contrast_threshold(4.0, e, s), contrast_threshold(16.0, e, s));
  }
  // At f = 0 the threshold is CT0 everywhere (eq. 4.1).
  EXPECT_DOUBLE_EQ(contrast_threshold(0.0, 25.0, s), 1.0 / 64.0);
}

TEST(CsfThreshold, CutoffFrequencyMatchesTheClosedForm) {
  const CsfSettings s;
  // Eq. 4.3 at e = 0: f_c = ln(1 / CT0) / alpha = ln 64 / 0.106 = 39.23 cycles/deg.
  EXPECT_NEAR(cutoff_frequency_cpd(0.0, s), std::log(64.0) / 0.106, 1e-12);
  EXPECT_NEAR(cutoff_frequency_cpd(0.0, s), 39.2349, 1e-3);
  for (double e : {0.0, 0.5, 2.3, 10.0, 40.0}) {
    const double fc = cutoff_frequency_cpd(e, s);
    EXPECT_NEAR(contrast_threshold(fc, e, s), 1.0, 1e-12) << e;   // CT = 1 at the cutoff
    EXPECT_NEAR(cutoff_eccentricity_deg(fc, s), e, 1e-9) << e;    // eq. 4.2 inverts eq. 4.3
  }
  // Half resolution at e = e2.
  EXPECT_NEAR(cutoff_frequency_cpd(2.3, s), 0.5 * cutoff_frequency_cpd(0.0, s), 1e-12);
}

TEST(CsfField, NyquistComesFromThePixelPitch) {
  const auto display = monitor_at_60cm();
  const CsfSamplingField field(display, 1280, 1024, {640, 512}, CsfSettings{});
  // At the screen centre one pixel subtends visual_angle_deg(pitch, d) (Jensen & Pedersen eq. 2.1).
  const double pitch_deg = protocol::visual_angle_deg(std::max(0.376 / 1280, 0.301 / 1024), 0.60);  // the taller side
  EXPECT_NEAR(field.nyquist_cpd({640, 512}), 1.0 / (2.0 * pitch_deg), 1e-3);
  // Off axis a pixel is seen obliquely and further away: smaller angle, higher Nyquist.
  EXPECT_GT(field.nyquist_cpd({10, 10}), field.nyquist_cpd({640, 512}));
  // A half-resolution image of the same screen resolves half the frequency.
  const CsfSamplingField half(display, 640, 512, {320, 256}, CsfSettings{});
  EXPECT_NEAR(half.nyquist_cpd({320, 256}), 0.5 * field.nyquist_cpd({640, 512}), 1e-2);
  EXPECT_NEAR(field.eccentricity_deg({640, 512}), 0.0, 1e-12);
  // The spacing is one pixel or less at the gaze (f_c(0) = 39 > Nyquist ~ 18) and grows outwards.
  EXPECT_LT(field.required_spacing_px({640, 512}), 1.0);
  EXPECT_GT(field.required_spacing_px({1000, 512}), field.required_spacing_px({800, 512}));
  EXPECT_GT(field.required_spacing_px({1270, 1010}), 2.0);
}

TEST(CsfMask, FullDensityAtTheGazeAndSparserOutwards) {
  const auto display = monitor_at_60cm();
  const CsfRayMask mask = csf_ray_mask(display, 1280, 1024, {640, 512}, CsfSettings{});
  ASSERT_EQ(mask.width, 1280u);
  ASSERT_EQ(mask.mask.size(), 1280u * 1024u);
  EXPECT_EQ(mask_density(mask, 620, 492, 40), 1.0);
  // Windows stepping from the gaze to the corner: the density falls.
  const double near = mask_density(mask, 800, 600, 64), mid = mask_density(mask, 1000, 760, 64),
               corner = mask_density(mask, 1200, 950, 64);
  EXPECT_LT(near, 1.0);
  EXPECT_GT(near, mid);
  EXPECT_GT(mid, corner);
  EXPECT_LT(corner, 0.15);
  EXPECT_GT(corner, 0.0);
}

TEST(CsfMask, FewerRaysThanPixelsAndMoreWithQuality) {
  const auto display = monitor_at_60cm();
  CsfSettings settings;
  std::uint64_t previous = 0;
  for (double quality : {0.25, 0.5, 1.0, 2.0}) {
    settings.quality = quality;
    const CsfRayMask mask = csf_ray_mask(display, 1280, 1024, {640, 512}, settings);
    EXPECT_EQ(mask.full_resolution_rays(), 1280u * 1024u);
    EXPECT_LT(mask.rays(), mask.full_resolution_rays()) << quality;
    EXPECT_GT(mask.rays(), previous) << quality;
    previous = mask.rays();
  }
  settings.quality = 1.0;
  EXPECT_LT(csf_ray_mask(display, 1280, 1024, {640, 512}, settings).rays(), 1280u * 1024u / 3);
}

TEST(CsfMesh, RingsGrowOutwardsAndCoverTheScreen) {
  const auto display = monitor_at_60cm();
  const RingMesh mesh = ring_mesh(display, 1280, 1024, {640, 512}, CsfSettings{});
  ASSERT_GT(mesh.ring_count(), 10u);
  EXPECT_GT(mesh.foveal_radius_px, 20.0f);
  EXPECT_FLOAT_EQ(mesh.ring_radii_px.front(), mesh.foveal_radius_px);
  for (std::size_t k = 1; k < mesh.ring_count(); ++k) {
    const float step = mesh.ring_radii_px[k] - mesh.ring_radii_px[k - 1];
    EXPECT_GE(step, 1.0f - 1e-4f);
    if (k >= 2) {
      EXPECT_GE(step, mesh.ring_radii_px[k - 1] - mesh.ring_radii_px[k - 2] - 1e-3f);  // spacing grows
    }
  }
  EXPECT_GT(mesh.ring_radii_px.back(), std::hypot(640.0f, 512.0f));
  ASSERT_EQ(mesh.quads.size() % 4, 0u);
  for (std::uint32_t index : mesh.quads) ASSERT_LT(index, mesh.vertices.size());
  for (glm::vec2 v : mesh.vertices) {
    EXPECT_FLOAT_EQ(v.x - std::floor(v.x), 0.5f);  // vertices sit on pixel centres
    EXPECT_FLOAT_EQ(v.y - std::floor(v.y), 0.5f);
  }
  // With a uniform scene every pixel is either ray cast or inside a quad: (almost) no gap rays.
  const CsfReconstruction image =
      render_csf(display, 1280, 1024, {640, 512}, CsfSettings{}, [](glm::vec2) { return 3u; },
                 [](glm::vec2, std::uint32_t) { return glm::vec3(1.0f); });
  EXPECT_LT(image.stats.gap_rays, image.stats.full_resolution_rays / 1000);
}

TEST(CsfRefinement, UniformQuadsAreNotRefined) {
  const auto display = monitor_at_60cm();
  const RingMesh mesh = ring_mesh(display, 1280, 1024, {640, 512}, CsfSettings{});
  const SilhouetteRefinement uniform = refine_silhouettes(mesh, [](glm::vec2) { return 7u; }, CsfSettings{});
  EXPECT_EQ(uniform.refined_quads, 0u);
  EXPECT_EQ(uniform.rays_cast, mesh.vertices.size());
  EXPECT_EQ(uniform.pieces.size(), mesh.quad_count());

  // With a disc and no neighbour refinement, exactly the quads whose corners disagree are refined.
  CsfSettings settings;
  settings.refine_neighbours = false;
  const std::vector<Disc> discs = {{{1000, 300}, 150, 1}};
  const auto object_at = [&](glm::vec2 p) { return object_in(discs, p); };
  const SilhouetteRefinement r = refine_silhouettes(mesh, object_at, settings);
  EXPECT_GT(r.refined_quads, 0u);
  EXPECT_EQ(r.refined_quads, r.disagreeing_quads);
  for (std::size_t q = 0; q < mesh.quad_count(); ++q) {
    const std::uint32_t a = object_at(mesh.vertices[mesh.quads[4 * q]]);
    bool agree = true;
    for (std::size_t c = 1; c < 4; ++c) agree = agree && object_at(mesh.vertices[mesh.quads[4 * q + c]]) == a;
    EXPECT_EQ(r.quad_refined[q] != 0, !agree) << q;
  }
}

// Object ids reconstructed exactly at every pixel, with fewer rays than pixels.
void expect_exact_discs(const std::vector<Disc>& discs, glm::vec2 gaze) {
  const auto display = monitor_at_60cm();
  const auto object_at = [&](glm::vec2 p) { return object_in(discs, p); };
  const auto colour_at = [](glm::vec2, std::uint32_t id) { return glm::vec3(static_cast<float>(id)); };
  const CsfReconstruction image = render_csf(display, 1280, 1024, gaze, CsfSettings{}, object_at, colour_at);
  std::uint64_t wrong = 0;
  for (std::uint32_t y = 0; y < 1024; ++y)
    for (std::uint32_t x = 0; x < 1280; ++x) {
      const std::size_t i = std::size_t{y} * 1280 + x;
      const std::uint32_t truth = object_at({static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f});
      if (image.object_ids[i] != truth) ++wrong;
      // Uniform pieces interpolate equal corner colours: the colour is the object's exactly.
      EXPECT_NEAR(image.colours[i].x, static_cast<float>(image.object_ids[i]), 1e-4f);
    }
  EXPECT_EQ(wrong, 0u);
  EXPECT_GT(image.stats.refined_quads, 0u);
  EXPECT_GT(image.stats.refinement_rays + image.stats.pixel_level_rays, 0u);
  EXPECT_LT(image.stats.rays_cast, image.stats.full_resolution_rays / 2);
}

TEST(CsfRefinement, DiscsAreReconstructedExactly) {
  expect_exact_discs({{{1000, 300}, 150, 1}}, {640, 512});
  // A disc across the foveal boundary, a small one in the far periphery, overlapping discs.
  expect_exact_discs({{{700, 540}, 120, 1}, {{150, 900}, 40, 2}, {{1100, 800}, 120, 3}, {{1180, 860}, 70, 4}},
                     {640, 512});
  expect_exact_discs({{{400, 400}, 200, 5}, {{900, 200}, 90, 6}}, {0, 0});
}

TEST(CsfReconstruction, InterpolatesLinearColourExactly) {
  // Barycentric interpolation reproduces a linear function: any pixel that is not ray cast still
  // gets the exact colour.
  const auto display = monitor_at_60cm();
  const auto colour_at = [](glm::vec2 p, std::uint32_t) { return glm::vec3(p.x / 1280.0f, p.y / 1024.0f, 0.25f); };
  const CsfReconstruction image =
      render_csf(display, 1280, 1024, {300, 700}, CsfSettings{}, [](glm::vec2) { return 1u; }, colour_at);
  double worst = 0;
  for (std::uint32_t y = 0; y < 1024; ++y)
    for (std::uint32_t x = 0; x < 1280; ++x) {
      const glm::vec3 truth = colour_at({static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f}, 1);
      const glm::vec3 got = image.colours[std::size_t{y} * 1280 + x];
      worst = std::max(worst, static_cast<double>(glm::length(got - truth)));
    }
  EXPECT_LT(worst, 1e-5);
  EXPECT_LT(image.stats.rays_cast, image.stats.full_resolution_rays / 3);
}

}  // namespace
}  // namespace fovea::render::gi
