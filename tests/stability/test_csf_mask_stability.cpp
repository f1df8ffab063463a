// SPDX-License-Identifier: Apache-2.0
// Hard cases of the CSF ray mask, ring mesh and reconstruction (renderer/gi/csf_mask.h): finite
// results and no crash, or a std::invalid_argument naming the bad field.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "gi/csf_mask.h"

namespace fovea::render::gi {
namespace {

protocol::DisplayGeometry monitor_at_60cm() { return {1280, 1024, 0.376, 0.301, 0.60}; }

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

std::uint32_t two_discs(glm::vec2 p) {
  if (glm::length(p - glm::vec2(100, 80)) < 50) return 1;
  return glm::length(p - glm::vec2(250, 150)) < 70 ? 2u : 0u;
}
glm::vec3 shade(glm::vec2 p, std::uint32_t id) { return glm::vec3(p.x * 1e-3f, p.y * 1e-3f, static_cast<float>(id)); }

// Renders and checks: finite geometry, every pixel's id equals a ray through it, finite colours.
CsfReconstruction render_and_check(std::uint32_t w, std::uint32_t h, glm::vec2 gaze, const CsfSettings& settings = {}) {
  const CsfReconstruction image = render_csf(monitor_at_60cm(), w, h, gaze, settings, two_discs, shade);
  EXPECT_EQ(image.object_ids.size(), std::size_t{w} * h);
  EXPECT_EQ(image.stats.full_resolution_rays, std::uint64_t{w} * h);
  for (std::uint32_t y = 0; y < h; ++y)
    for (std::uint32_t x = 0; x < w; ++x) {
      const std::size_t i = std::size_t{y} * w + x;
      EXPECT_EQ(image.object_ids[i], two_discs({static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f}))
          << x << "," << y;
      EXPECT_TRUE(std::isfinite(image.colours[i].x) && std::isfinite(image.colours[i].y) &&
                  std::isfinite(image.colours[i].z));
      if (::testing::Test::HasFailure()) return image;
    }
  return image;
}

void expect_finite_mesh(const RingMesh& mesh) {
  EXPECT_TRUE(std::isfinite(mesh.gaze_px.x) && std::isfinite(mesh.gaze_px.y));
  EXPECT_TRUE(std::isfinite(mesh.foveal_radius_px));
  for (glm::vec2 v : mesh.vertices) ASSERT_TRUE(std::isfinite(v.x) && std::isfinite(v.y));
  for (std::uint32_t index : mesh.quads) ASSERT_LT(index, mesh.vertices.size());
}

TEST(CsfMaskStability, GazeOutsideTheScreen) {
  const auto display = monitor_at_60cm();
  for (glm::vec2 gaze : {glm::vec2(-200, 100), glm::vec2(400, -3000), glm::vec2(1e5f, 1e5f), glm::vec2(-1e30f, 5),
                         glm::vec2(320, 240), glm::vec2(0, 0), glm::vec2(320, 0)}) {
    const RingMesh mesh = ring_mesh(display, 320, 240, gaze, CsfSettings{});
    expect_finite_mesh(mesh);
    EXPECT_LT(mesh.vertices.size(), 320u * 240u) << gaze.x << "," << gaze.y;
    const CsfReconstruction image = render_and_check(320, 240, gaze);
    EXPECT_LE(image.stats.rays_cast, 2u * 320u * 240u);
  }
  // Far off the screen the sampling is coarse: far fewer rays than pixels.
  const CsfRayMask far = csf_ray_mask(display, 320, 240, {-1e30f, 5}, CsfSettings{});
  EXPECT_LT(far.rays(), far.full_resolution_rays() / 4);
}

TEST(CsfMaskStability, NonFiniteGazeMeansTheScreenCentre) {
  const auto display = monitor_at_60cm();
  const RingMesh centre = ring_mesh(display, 320, 240, {160, 120}, CsfSettings{});
  for (glm::vec2 gaze : {glm::vec2(kNan, kNan), glm::vec2(kNan, 10), glm::vec2(10, kInf), glm::vec2(-kInf, kInf)}) {
    const RingMesh mesh = ring_mesh(display, 320, 240, gaze, CsfSettings{});
    expect_finite_mesh(mesh);
    EXPECT_EQ(mesh.gaze_px, glm::vec2(160, 120));
    EXPECT_EQ(mesh.vertices.size(), centre.vertices.size());
    EXPECT_EQ(mesh.quads, centre.quads);
    render_and_check(320, 240, gaze);
  }
}

TEST(CsfMaskStability, TinyAndEmptyImages) {
  const auto display = monitor_at_60cm();
  int calls = 0;
  const auto counting = [&](glm::vec2) {
    ++calls;
    return 0u;
  };
  const CsfReconstruction empty =
      render_csf(display, 0, 0, {0, 0}, CsfSettings{}, counting, [](glm::vec2, std::uint32_t) { return glm::vec3(0); });
  EXPECT_TRUE(empty.object_ids.empty());
  EXPECT_EQ(empty.stats.rays_cast, 0u);
  EXPECT_EQ(calls, 0);
  EXPECT_EQ(csf_ray_mask(display, 0, 0, {kNan, kNan}, CsfSettings{}).rays(), 0u);
  EXPECT_EQ(csf_ray_mask(display, 0, 480, {0, 0}, CsfSettings{}).mask.size(), 0u);

  const CsfReconstruction one = render_and_check(1, 1, {0.5f, 0.5f});
  EXPECT_EQ(one.stats.rays_cast, 1u);
  const CsfRayMask one_mask = csf_ray_mask(display, 1, 1, {kNan, 0}, CsfSettings{});
  EXPECT_EQ(one_mask.rays(), 1u);
  render_and_check(1, 1, {-50, 400});
  render_and_check(1, 300, {0, 150});
  render_and_check(300, 1, {kNan, kNan});
}

TEST(CsfMaskStability, InvalidDisplayGeometryThrowsNamingTheField) {
  const auto expect_throw_naming = [](const protocol::DisplayGeometry& display, const std::string& field) {
    try {
      (void)csf_ray_mask(display, 320, 240, {160, 120}, CsfSettings{});
      ADD_FAILURE() << "no exception for " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  auto display = monitor_at_60cm();
  display.viewing_distance_m = 0;
  expect_throw_naming(display, "viewing_distance_m");
  display = monitor_at_60cm();
  display.width_m = std::nan("");
  expect_throw_naming(display, "width_m");
  display = monitor_at_60cm();
  display.height_px = 0;
  expect_throw_naming(display, "height_px");
  display = monitor_at_60cm();
  display.height_m = -1;
  expect_throw_naming(display, "height_m");
}

TEST(CsfMaskStability, QualityZeroIsCoarsestAndInvalidQualityThrows) {
  const auto display = monitor_at_60cm();
  CsfSettings settings;
  settings.quality = 0;
  const RingMesh coarse = ring_mesh(display, 320, 240, {160, 120}, settings);
  expect_finite_mesh(coarse);
  EXPECT_EQ(coarse.foveal_radius_px, 0.0f);
  for (std::size_t k = 1; k < coarse.ring_count(); ++k)
    EXPECT_NEAR(coarse.ring_radii_px[k] - coarse.ring_radii_px[k - 1], settings.max_ring_spacing_px, 1e-3);
  const CsfReconstruction image = render_and_check(320, 240, {160, 120}, settings);
  EXPECT_LT(image.stats.rays_cast, 320u * 240u);

  for (double quality : {-1.0, -1e-9, std::nan(""), std::numeric_limits<double>::infinity()}) {
    settings.quality = quality;
    try {
      (void)ring_mesh(display, 320, 240, {160, 120}, settings);
      ADD_FAILURE() << "no exception for quality " << quality;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("quality"), std::string::npos) << e.what();
    }
  }
  // Very high quality: every pixel needs a ray; still finite, no mesh.
  settings.quality = 1e6;
  const RingMesh dense = ring_mesh(display, 320, 240, {160, 120}, settings);
  EXPECT_EQ(dense.quad_count(), 0u);
  EXPECT_EQ(csf_ray_mask(display, 320, 240, {160, 120}, settings).rays(), 320u * 240u);
}

TEST(CsfMaskStability, InvalidSettingsThrowNamingTheField) {
  const auto display = monitor_at_60cm();
  const auto expect_field = [&](CsfSettings settings, const std::string& field) {
    EXPECT_NE(validate(settings).find(field), std::string::npos) << validate(settings);
    EXPECT_THROW((void)ring_mesh(display, 64, 64, {32, 32}, settings), std::invalid_argument);
  };
  CsfSettings s;
  EXPECT_TRUE(validate(s).empty());
  s.ct0 = 1.5;
  expect_field(s, "ct0");
  s = {};
  s.alpha = 0;
  expect_field(s, "alpha");
  s = {};
  s.e2_deg = std::nan("");
  expect_field(s, "e2_deg");
  s = {};
  s.min_ring_spacing_px = 0.5;
  expect_field(s, "min_ring_spacing_px");
  s = {};
  s.max_ring_spacing_px = 0.9;
  expect_field(s, "max_ring_spacing_px");
}

}  // namespace
}  // namespace fovea::render::gi
