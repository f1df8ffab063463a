// SPDX-License-Identifier: Apache-2.0
// The DOF references (renderer/dof/reference.h) against the thin-lens model: a pinhole lens gives
// the pinhole render, the plane in focus stays sharp, a small light blurs by the CoC the lens model
// predicts (in front of and behind the focal plane), distributed ray tracing and the accumulation
// equivalent agree, the error falls with the sample count, and a seed fixes the result.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include <glm/geometric.hpp>

#include "backend/embree/embree_backend.h"
#include "backend/lens_sample.h"
#include "dof/lens.h"
#include "dof/reference.h"
#include "image_moments.h"
#include "scene/geometry.h"

using namespace fovea::render;
using namespace fovea::render::dof;

namespace {

constexpr std::uint32_t kSize = 129;

Scene light_scene(float light_depth_m, float light_size_m) {
  Scene s;
  s.name = "dof-reference-test";
  s.camera.position = {0, 0, 0};
  s.camera.target = {0, 0, -1};
  s.camera.vertical_fov_deg = 30;
  s.camera.width = s.camera.height = kSize;
  s.camera.near_m = 0.05f;
  s.camera.far_m = 100;
  s.camera.lens.focal_length_m = 0.05;
  s.camera.lens.aperture_m = 0.05 / 2.0;  // f/2
  s.camera.lens.focus_distance_m = 4;
  Material light;
  light.name = "light";
  light.type = MaterialType::Emissive;
  light.emission = glm::vec3(1.0f, 0.5f, 0.25f);
  s.materials.push_back(light);
  s.background = glm::vec3(0.0f);
  Object o;
  o.name = "light";
  o.id = 1;
  o.mesh = std::make_shared<Mesh>(make_box({light_size_m, light_size_m, 0.001f}));
  o.transform.translation = {0, 0, -light_depth_m};
  s.objects.push_back(o);
  return s;
}

using Moments = fovea::test::ImageMoments;
Moments moments(const RgbImage& img) { return fovea::test::image_moments(img, kSize, 0); }

RgbImage reference(const Scene& s, ReferenceKind kind, std::uint32_t samples, std::uint64_t seed = 1,
                   double focus_m = 4, double gaussian_sigma_per_coc = 0) {
  EmbreeBackend b;
  b.set_scene(s);
  DofReference ref(b, {}, {}, s.camera.lens, focus_m, kind, seed, gaussian_sigma_per_coc);
  ref.add_samples(samples);
  return ref.image();
}

double rmse(const RgbImage& a, const RgbImage& b) {
  double e = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const glm::vec3 d = a[i] - b[i];
    e += static_cast<double>(glm::dot(d, d));
  }
  return std::sqrt(e / (3.0 * static_cast<double>(a.size())));
}

TEST(DofReference, APinholeLensGivesThePinholeRender) {
  Scene s = light_scene(2.0f, 0.1f);
  s.camera.lens.aperture_m = 0;
  EmbreeBackend b;
  b.set_scene(s);
  GBuffer g;
  b.render({}, {}, g);
  const RgbImage r = reference(s, ReferenceKind::RayTraced, 8);
  ASSERT_EQ(r.size(), g.color.size());
  for (std::size_t i = 0; i < r.size(); ++i) ASSERT_EQ(r[i], g.color[i]) << i;
}

TEST(DofReference, ThePlaneInFocusStaysSharp) {
  const Scene s = light_scene(4.0f, 0.2f);  // the light sits on the focal plane
  EmbreeBackend b;
  b.set_scene(s);
  GBuffer g;
  b.render({}, {}, g);
  const RgbImage r = reference(s, ReferenceKind::RayTraced, 64);
  double worst = 0;
  for (std::size_t i = 0; i < r.size(); ++i) worst = std::max(worst, static_cast<double>(std::fabs(r[i].r - g.color[i].r)));
  // Only pixels straddling the light's outline may differ (the box's thin rim is not on the plane).
  std::size_t differ = 0;
  for (std::size_t i = 0; i < r.size(); ++i) differ += std::fabs(r[i].r - g.color[i].r) > 1e-4f;
  EXPECT_LT(differ, 4u * 30u) << "worst " << worst;
}

// A small square light's blur spot has the variance of its (continuous) pinhole image, s^2 / 12 per
// axis for a square s px wide, plus that of a uniform disc of the CoC's diameter C (C^2 / 16): C
// measured from the reference must match the lens model; its energy is the square's area times the
// emission (the thin lens spreads the light, it does not lose it). A Gaussian aperture of sigma s per
// CoC diameter adds (s C)^2 instead of C^2 / 16.
void expect_blur_matches_model(float depth_m, ReferenceKind kind, double gaussian_sigma_per_coc = 0) {
  Scene s = light_scene(depth_m, 0.1f);
  s.camera.lens.aperture_m = 0.25;  // a big lens, so a 129 px image shows a blur of several pixels
  const double tan_half = std::tan(15.0 * 3.14159265358979323846 / 180.0);
  const double size_px = 0.1 / (2.0 * static_cast<double>(depth_m) * tan_half) * kSize;
  const Moments m = moments(reference(s, kind, 256, 1, 4, gaussian_sigma_per_coc));
  const CocModel model = coc_model(s.camera, s.display, 4.0, CocProjection::Sensor);
  const double c_model = model.coc_px(depth_m);
  const double square = size_px * size_px / 12.0;
  const double per_var = gaussian_sigma_per_coc > 0 ? 1.0 / (gaussian_sigma_per_coc * gaussian_sigma_per_coc) : 16.0;
  const double c_x = std::sqrt(per_var * (m.var_x - square)), c_y = std::sqrt(per_var * (m.var_y - square));
  EXPECT_NEAR(c_x, c_model, 0.05 * c_model + 0.3) << "depth " << depth_m;
  EXPECT_NEAR(c_y, c_model, 0.05 * c_model + 0.3) << "depth " << depth_m;
  EXPECT_NEAR(m.sum, size_px * size_px, 0.03 * size_px * size_px) << "depth " << depth_m;
  EXPECT_GT(c_model, 5.0);  // the test means something: a visible blur
}

TEST(DofReference, RayTracedBlurMatchesTheThinLensCocInFrontAndBehind) {
  expect_blur_matches_model(2.0f, ReferenceKind::RayTraced);
  expect_blur_matches_model(12.0f, ReferenceKind::RayTraced);
}

TEST(DofReference, AccumulationBlurMatchesTheThinLensCocInFrontAndBehind) {
  expect_blur_matches_model(2.0f, ReferenceKind::Accumulation);
  expect_blur_matches_model(12.0f, ReferenceKind::Accumulation);
}

// Lee §4.1.3's Gaussian lens: the blur's per-axis deviation is sigma x C, in front and behind, for
// both kinds. Not sigma = C / 4, whose variance equals the disc's: 0.15 and 0.35 tell the two apart
// and keep the spot inside the 129 px image at these CoCs.
TEST(DofReference, AGaussianApertureBlursByTheGaussianOfItsSigma) {
  expect_blur_matches_model(2.0f, ReferenceKind::RayTraced, 0.15);
  expect_blur_matches_model(12.0f, ReferenceKind::RayTraced, 0.35);
  expect_blur_matches_model(2.0f, ReferenceKind::Accumulation, 0.35);
}

// The Gaussian aperture's lens points: zero mean, per-axis deviation 2 sigma (units of the radius),
// finite everywhere, and unlike the disc they leave the unit circle.
TEST(DofReference, GaussianLensPointsHaveTheirDeviation) {
  constexpr std::uint32_t kN = 4096;
  for (const double sigma : {0.25, 0.5, 1.0}) {
    double sx = 0, sy = 0, sxx = 0, syy = 0;
    std::uint32_t outside = 0;
    for (std::uint32_t i = 0; i < kN; ++i) {
      const glm::vec2 p = lens_sampling::lens_point(i, lens_sampling::mix(7), sigma);
      ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y)) << i;
      sx += static_cast<double>(p.x);
      sy += static_cast<double>(p.y);
      sxx += static_cast<double>(p.x * p.x);
      syy += static_cast<double>(p.y * p.y);
      outside += glm::dot(p, p) > 1.0f;
    }
    const double want = 2.0 * sigma;
    EXPECT_NEAR(sx / kN, 0.0, 0.02 * want) << sigma;
    EXPECT_NEAR(sy / kN, 0.0, 0.02 * want) << sigma;
    EXPECT_NEAR(std::sqrt(sxx / kN), want, 0.02 * want) << sigma;
    EXPECT_NEAR(std::sqrt(syy / kN), want, 0.02 * want) << sigma;
    EXPECT_GT(outside, 0u) << sigma;
  }
  for (std::uint32_t i = 0; i < kN; ++i) {
    const glm::vec2 p = lens_sampling::lens_point(i, lens_sampling::mix(7));
    ASSERT_LE(glm::dot(p, p), 1.0f + 1e-6f) << i;
  }
}

TEST(DofReference, RayTracedAndAccumulationAgree) {
  const Scene s = light_scene(2.5f, 0.15f);
  const RgbImage a = reference(s, ReferenceKind::RayTraced, 256), b = reference(s, ReferenceKind::Accumulation, 256);
  double mean = 0;
  for (const auto& c : a) mean += static_cast<double>(c.r);
  mean /= static_cast<double>(a.size());
  EXPECT_LT(rmse(a, b), 0.1 * mean + 1e-3);
}

TEST(DofReference, ErrorFallsWithTheSampleCount) {
  const Scene s = light_scene(2.0f, 0.15f);
  const RgbImage truth = reference(s, ReferenceKind::RayTraced, 1024, 99);
  const double e16 = rmse(reference(s, ReferenceKind::RayTraced, 16), truth);
  const double e64 = rmse(reference(s, ReferenceKind::RayTraced, 64), truth);
  const double e256 = rmse(reference(s, ReferenceKind::RayTraced, 256), truth);
  EXPECT_LT(e64, e16);
  EXPECT_LT(e256, e64);
}

TEST(DofReference, ASeedFixesTheResult) {
  const Scene s = light_scene(2.0f, 0.15f);
  EXPECT_EQ(rmse(reference(s, ReferenceKind::RayTraced, 16, 7), reference(s, ReferenceKind::RayTraced, 16, 7)), 0.0);
  EXPECT_GT(rmse(reference(s, ReferenceKind::RayTraced, 16, 7), reference(s, ReferenceKind::RayTraced, 16, 8)), 0.0);
}

TEST(DofReference, RefusesABadGaussianAperture) {
  const Scene s = light_scene(2.0f, 0.1f);
  EmbreeBackend b;
  b.set_scene(s);
  for (const double bad : {-0.1, 5.0, std::nan("")}) {
    try {
      DofReference ref(b, {}, {}, s.camera.lens, 4.0, ReferenceKind::RayTraced, 1, bad);
      FAIL() << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("Gaussian aperture sigma"), std::string::npos) << e.what();
    }
  }
}

TEST(DofReference, RefusesABadFocusDistance) {
  const Scene s = light_scene(2.0f, 0.15f);
  EmbreeBackend b;
  b.set_scene(s);
  EXPECT_THROW(DofReference(b, {}, {}, s.camera.lens, 0.0, ReferenceKind::RayTraced, 1), std::invalid_argument);
  EXPECT_THROW(DofReference(b, {}, {}, s.camera.lens, std::nan(""), ReferenceKind::RayTraced, 1), std::invalid_argument);
}

}  // namespace
