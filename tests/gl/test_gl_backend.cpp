// SPDX-License-Identifier: Apache-2.0
// The OpenGL raster G-buffer backend: analytic checks (depth, ids, normals, motion, background,
// shading against scene/shading.cpp) and agreement with the Embree ray-casting backend on the same
// scenes. Needs an X display: CTest runs it under xvfb-run (Mesa llvmpipe).
#include <epoxy/gl.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <glm/gtc/matrix_transform.hpp>
#include <iostream>
#include <memory>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "backend/backend.h"
#include "backend/embree/embree_backend.h"
#include "dof/reference.h"
#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_context.h"
#include "backend/gl/shaders.h"
#include "scene/geometry.h"
#include "scene/scene_loader.h"
#include "scene/shading.h"
#include "test_scenes.h"

namespace fovea::render {
namespace {

using testing::blinn_phong;
using testing::emissive;
using testing::lambertian;
using testing::object;

// ---------------------------------------------------------------------------------------------
// Helpers

// A camera at (0, 0, 5) looking down -Z at the origin, 320 x 240.
Scene base_scene() {
  Scene s;
  s.name = "test";
  s.camera.position = {0, 0, 5};
  s.camera.target = {0, 0, 0};
  s.camera.up = {0, 1, 0};
  s.camera.vertical_fov_deg = 45;
  s.camera.width = 320;
  s.camera.height = 240;
  s.camera.near_m = 0.05f;
  s.camera.far_m = 100;
  s.ambient = glm::vec3(0.02f);
  s.background = glm::vec3(0.25f, 0.5f, 0.75f);
  s.materials = {lambertian("matte", {0.7f, 0.5f, 0.3f}), blinn_phong("glossy", {0.4f, 0.4f, 0.5f}, glm::vec3(0.5f), 32),
                 emissive("lamp", {3.0f, 2.0f, 1.0f})};
  return s;
}

// A plane of the given size in z = z0 facing +Z (towards the base camera).
Object facing_plane(Scene& s, glm::vec2 size, float z0, std::uint32_t material = 0) {
  return object(s, "plane", std::make_shared<const Mesh>(make_plane(size)), material, {0, 0, z0}, {90, 0, 0});
}

float focal_px(const Camera& c) {
  return static_cast<float>(c.height) / 2 / std::tan(glm::radians(c.vertical_fov_deg) / 2);
}

// World position of the surface seen at pixel (x, y) with linear view depth `depth` at time t.
glm::vec3 world_at_pixel(const Camera& c, double t, std::uint32_t x, std::uint32_t y, float depth) {
  const float f = focal_px(c);
  const float vx = (static_cast<float>(x) + 0.5f - static_cast<float>(c.width) / 2) / f;
  const float vy = (static_cast<float>(c.height) / 2 - static_cast<float>(y) - 0.5f) / f;
  const glm::vec4 view_pos(vx * depth, vy * depth, -depth, 1.0f);
  return glm::vec3(glm::inverse(c.view_at(t)) * view_pos);
}

bool all_finite(const GBuffer& g) {
  for (std::size_t i = 0; i < g.size(); ++i) {
    const glm::vec3 c = g.color[i], n = g.normal[i];
    const glm::vec2 m = g.motion[i];
    if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.z) || !std::isfinite(g.depth[i]) ||
        !std::isfinite(n.x) || !std::isfinite(n.y) || !std::isfinite(n.z) || !std::isfinite(m.x) ||
        !std::isfinite(m.y)) {
      return false;
    }
  }
  return true;
}

// True if the 3x3 neighbourhood of (x, y) in `ids` holds more than one id (a silhouette edge).
bool at_edge(const std::vector<std::uint32_t>& ids, std::uint32_t w, std::uint32_t h, std::uint32_t x,
             std::uint32_t y) {
  const std::uint32_t centre = ids[std::size_t{y} * w + x];
  for (std::uint32_t yy = y == 0 ? 0 : y - 1; yy <= std::min(h - 1, y + 1); ++yy) {
    for (std::uint32_t xx = x == 0 ? 0 : x - 1; xx <= std::min(w - 1, x + 1); ++xx) {
      if (ids[std::size_t{yy} * w + xx] != centre) return true;
    }
  }
  return false;
}

// Compares every hit pixel's colour with shade_local at the world position reconstructed from the
// pixel's depth, using the G-buffer's normal. Returns the largest relative error (per channel,
// relative to max(|reference|, floor)) and counts the pixels checked.
struct ShadeCheck {
  double max_rel = 0;
  std::size_t pixels = 0;
};
ShadeCheck compare_with_shade_local(const Scene& s, const GBuffer& g, double t, float floor = 1e-4f) {
  ShadeCheck r;
  const glm::vec3 eye = s.camera.position_at(t);
  for (std::uint32_t y = 0; y < g.height; ++y) {
    for (std::uint32_t x = 0; x < g.width; ++x) {
      const std::size_t i = g.index(x, y);
      if (g.object_id[i] == 0 || at_edge(g.object_id, g.width, g.height, x, y)) continue;
      const Object* o = s.object_by_id(g.object_id[i]);
      const glm::vec3 p = world_at_pixel(s.camera, t, x, y, g.depth[i]);
      const glm::vec3 ref = shade_local(s, s.materials[o->material], p, g.normal[i], eye);
      for (int c = 0; c < 3; ++c) {
        const double err = std::abs(static_cast<double>(g.color[i][c]) - static_cast<double>(ref[c])) /
                           static_cast<double>(std::max(std::abs(ref[c]), floor));
        r.max_rel = std::max(r.max_rel, err);
      }
      ++r.pixels;
    }
  }
  return r;
}

// One GL backend (one context) for the whole test program; also proves a backend can render many
// scenes one after another.
class GlBackendTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { backend_ = std::make_unique<GlBackend>(); }
  static void TearDownTestSuite() { backend_.reset(); }
  static GBuffer render(const Scene& s, double now = 0, double previous = 0) {
    backend_->set_scene(s);
    GBuffer g;
    backend_->render(FrameTime{now, previous}, BackendSettings{}, g);
    EXPECT_EQ(g.width, s.camera.width);
    EXPECT_EQ(g.height, s.camera.height);
    EXPECT_TRUE(all_finite(g));
    return g;
  }
  static std::unique_ptr<GlBackend> backend_;
};
std::unique_ptr<GlBackend> GlBackendTest::backend_;

// ---------------------------------------------------------------------------------------------
// Basics

TEST_F(GlBackendTest, NameAndFactory) {
  EXPECT_EQ(backend_->name(), "gl");
  const auto made = make_backend(BackendKind::OpenGL);
  EXPECT_EQ(made->name(), "gl");
  // A raster G-buffer: no shadow rays or lens rays, depth peeling; the visibility buffer where the
  // context has compute shaders (GL 4.3), and it is the faster only on a GPU, not on a software rasteriser.
  const BackendCapabilities can = made->capabilities();
  EXPECT_FALSE(can.shadow_rays || can.per_pixel_lens);
  EXPECT_TRUE(can.peeling);
  const GlFeatures& f = backend_->context().features();
  EXPECT_EQ(can.visibility_buffer, f.at_least(4, 3));
  EXPECT_EQ(can.visibility_buffer_faster, f.at_least(4, 3) && !f.software);
  std::cout << "GL renderer: " << backend_->context().renderer() << " (" << backend_->context().platform_description()
            << ")\n";
}

TEST_F(GlBackendTest, EmptySceneIsBackgroundEverywhere) {
  Scene s = base_scene();
  const GBuffer g = render(s);
  for (std::size_t i = 0; i < g.size(); ++i) {
    ASSERT_EQ(g.object_id[i], 0u);
    ASSERT_EQ(g.depth[i], s.camera.far_m);
    ASSERT_EQ(g.color[i], s.background);
    ASSERT_EQ(g.normal[i], glm::vec3(0.0f));
    ASSERT_EQ(g.motion[i], glm::vec2(0.0f));
  }
}

TEST_F(GlBackendTest, FrontoParallelPlaneHasConstantExactDepth) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {2, 2}, 1.0f));  // 4 m from the camera
  const GBuffer g = render(s);
  const float f = focal_px(s.camera);
  std::size_t inside = 0, outside = 0;
  for (std::uint32_t y = 0; y < g.height; ++y) {
    for (std::uint32_t x = 0; x < g.width; ++x) {
      const std::size_t i = g.index(x, y);
      // Where the pixel centre's ray meets z = 1, in plane coordinates.
      const float px = (static_cast<float>(x) + 0.5f - 160) / f * 4, py = (120 - static_cast<float>(y) - 0.5f) / f * 4;
      const float margin = 4 / f;  // one pixel at the plane
      if (std::abs(px) < 1 - margin && std::abs(py) < 1 - margin) {
        ++inside;
        ASSERT_EQ(g.object_id[i], 1u) << x << "," << y;
        ASSERT_NEAR(g.depth[i], 4.0f, 4.0f * 1e-6f) << x << "," << y;
        ASSERT_NEAR(g.normal[i].z, 1.0f, 1e-6f);
        ASSERT_NEAR(glm::length(glm::vec2(g.normal[i])), 0.0f, 1e-6f);
        ASSERT_EQ(g.motion[i], glm::vec2(0.0f));
      } else if (std::abs(px) > 1 + margin || std::abs(py) > 1 + margin) {
        ++outside;
        ASSERT_EQ(g.object_id[i], 0u) << x << "," << y;
        ASSERT_EQ(g.depth[i], s.camera.far_m);
        ASSERT_EQ(g.color[i], s.background);
        ASSERT_EQ(g.normal[i], glm::vec3(0.0f));
      }
    }
  }
  EXPECT_GT(inside, 10000u);
  EXPECT_GT(outside, 10000u);
}

TEST_F(GlBackendTest, SphereCentreDepthAndNormal) {
  Scene s = base_scene();
  s.camera.width = 321;  // odd: a pixel centre lies exactly on the optical axis
  s.camera.height = 241;
  s.objects.push_back(object(s, "sphere", std::make_shared<const Mesh>(make_sphere(1.0f, 64, 128)), 0, {0, 0, 0}));
  const GBuffer g = render(s);
  const std::size_t c = g.index(160, 120);
  EXPECT_EQ(g.object_id[c], 1u);
  // The point (0, 0, 1) is a vertex of the tessellation: depth exactly 4.
  EXPECT_NEAR(g.depth[c], 4.0f, 4e-5f);
  EXPECT_NEAR(g.normal[c].z, 1.0f, 1e-4f);
  // Off-centre pixels: depth of the true sphere within the tessellation's sag (< 1 mm).
  const float f = focal_px(s.camera);
  for (const auto& [x, y] : {std::pair{200u, 120u}, std::pair{160u, 80u}, std::pair{130u, 150u}}) {
    const std::size_t i = g.index(x, y);
    ASSERT_EQ(g.object_id[i], 1u);
    const glm::vec3 d = glm::normalize(glm::vec3((static_cast<float>(x) - 160) / f, (120 - static_cast<float>(y)) / f, -1));
    // Ray o + t d with o = (0, 0, 5) against the unit sphere.
    const glm::vec3 o(0, 0, 5);
    const float b = glm::dot(o, d), cc = glm::dot(o, o) - 1;
    const float t = -b - std::sqrt(b * b - cc);
    EXPECT_NEAR(g.depth[i], t * -d.z, 1e-3f) << x << "," << y;
    const glm::vec3 n = glm::normalize(o + t * d);
    EXPECT_LT(glm::length(g.normal[i] - n), 1e-2f) << x << "," << y;
  }
}

TEST_F(GlBackendTest, ObjectIdsOfSeveralObjects) {
  Scene s = base_scene();
  const auto box = std::make_shared<const Mesh>(make_box(glm::vec3(0.5f)));
  const glm::vec3 centres[] = {{-1.2f, 0.6f, 0}, {0, 0.6f, 0}, {1.2f, 0.6f, 0}, {-1.2f, -0.6f, 0}, {1.2f, -0.6f, 0}};
  for (const glm::vec3& c : centres) s.objects.push_back(object(s, "box", box, 0, c));
  s.objects.back().id = 77;  // ids need not be dense
  const GBuffer g = render(s);
  const glm::mat4 vp = s.camera.projection() * s.camera.view_at(0);
  for (std::size_t k = 0; k < s.objects.size(); ++k) {
    const glm::vec4 clip = vp * glm::vec4(centres[k], 1);
    const auto x = static_cast<std::uint32_t>((clip.x / clip.w * 0.5f + 0.5f) * 320);
    const auto y = static_cast<std::uint32_t>((0.5f - clip.y / clip.w * 0.5f) * 240);
    EXPECT_EQ(g.object_id[g.index(x, y)], s.objects[k].id) << "object " << k;
    EXPECT_NEAR(g.depth[g.index(x, y)], 4.75f, 1e-5f);  // front face at z = 0.25
  }
}

TEST_F(GlBackendTest, BackFaceNormalIsFlippedTowardsTheCamera) {
  Scene s = base_scene();
  Object plane = facing_plane(s, {2, 2}, 0.0f);
  plane.transform.rotation_deg = {-90, 0, 0};  // normal now -Z: the camera sees its back
  s.objects.push_back(plane);
  s.lights.push_back(Light{LightType::Point, {0, 0, 2}, glm::vec3(50.0f)});
  const GBuffer g = render(s);
  const std::size_t c = g.index(160, 120);
  ASSERT_EQ(g.object_id[c], 1u);
  EXPECT_NEAR(g.normal[c].z, 1.0f, 1e-6f);
  // Lit from the camera's side: the flipped normal is the one that shades.
  EXPECT_GT(g.color[c].r, s.materials[0].kd.r * s.ambient.r * 2);
  EXPECT_LT(compare_with_shade_local(s, g, 0).max_rel, 1e-3);
}

TEST_F(GlBackendTest, ResolutionFollowsTheCamera) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {2, 2}, 0.0f));
  for (const auto& [w, h] : {std::pair{64u, 48u}, std::pair{200u, 100u}, std::pair{1u, 1u}, std::pair{64u, 48u}}) {
    s.camera.width = w;
    s.camera.height = h;
    const GBuffer g = render(s);
    ASSERT_EQ(g.size(), std::size_t{w} * h);
  }
}

// ---------------------------------------------------------------------------------------------
// Motion vectors

TEST_F(GlBackendTest, MotionOfAMovingObject) {
  Scene s = base_scene();
  Object plane = facing_plane(s, {3, 3}, 0.0f);
  // +0.5 m/s in x and +0.25 m/s in y.
  plane.animation = Animation{{{0.0, {0, 0, 0}, {}}, {10.0, {5.0f, 2.5f, 0}, {}}}, false};
  s.objects.push_back(plane);
  Object still = object(s, "still", std::make_shared<const Mesh>(make_box(glm::vec3(0.3f))), 0, {1.5f, 0, 1.5f});
  s.objects.push_back(still);
  const double now = 1.0, previous = 0.8;  // moved 0.1 m right, 0.05 m up
  const GBuffer g = render(s, now, previous);
  const float f = focal_px(s.camera);
  const glm::vec2 expected(0.1f * f / 5, -0.05f * f / 5);  // y down: moving up is negative
  const std::size_t c = g.index(140, 110);
  ASSERT_EQ(g.object_id[c], 1u);
  EXPECT_NEAR(g.motion[c].x, expected.x, 0.01f);
  EXPECT_NEAR(g.motion[c].y, expected.y, 0.01f);
  std::size_t plane_pixels = 0;
  for (std::uint32_t y = 0; y < g.height; ++y) {
    for (std::uint32_t x = 0; x < g.width; ++x) {
      const std::size_t i = g.index(x, y);
      if (at_edge(g.object_id, g.width, g.height, x, y)) continue;
      if (g.object_id[i] == 1) {
        ++plane_pixels;
        ASSERT_NEAR(g.motion[i].x, expected.x, 0.01f) << x << "," << y;
        ASSERT_NEAR(g.motion[i].y, expected.y, 0.01f) << x << "," << y;
      } else {
        ASSERT_EQ(g.motion[i], glm::vec2(0.0f)) << "static object or background at " << x << "," << y;
      }
    }
  }
  EXPECT_GT(plane_pixels, 5000u);
}

TEST_F(GlBackendTest, MotionOfAMovingCamera) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {20, 20}, 0.0f));
  // Camera (and target) move +1 m/s along x: a static plane at 5 m moves left on screen.
  s.camera.animation = Animation{{{0.0, {0, 0, 0}, {}}, {10.0, {10.0f, 0, 0}, {}}}, false};
  const GBuffer g = render(s, 2.0, 1.9);
  const float expected = -0.1f * focal_px(s.camera) / 5;
  for (std::size_t i = 0; i < g.size(); ++i) {
    ASSERT_EQ(g.object_id[i], 1u);
    ASSERT_NEAR(g.motion[i].x, expected, 0.01f);
    ASSERT_NEAR(g.motion[i].y, 0.0f, 0.01f);
    ASSERT_NEAR(g.depth[i], 5.0f, 5e-6f);
  }
  // Camera moving towards the plane: motion points away from the centre (expansion).
  s.camera.animation = Animation{{{0.0, {0, 0, 0}, {}}, {10.0, {0, 0, -10.0f}, {}}}, false};
  const GBuffer z = render(s, 2.0, 1.9);  // depth 3 now, 3.1 before
  for (const auto& [x, y] : {std::pair{10u, 10u}, std::pair{300u, 200u}, std::pair{40u, 220u}}) {
    const glm::vec2 from_centre(static_cast<float>(x) + 0.5f - 160, static_cast<float>(y) + 0.5f - 120);
    // A point at lateral offset r/f*3 was at r_prev = r * 3 / 3.1 pixels from the centre.
    const glm::vec2 expected_motion = from_centre * (1 - 3.0f / 3.1f);
    EXPECT_NEAR(z.motion[z.index(x, y)].x, expected_motion.x, 0.01f);
    EXPECT_NEAR(z.motion[z.index(x, y)].y, expected_motion.y, 0.01f);
    EXPECT_NEAR(z.depth[z.index(x, y)], 3.0f, 3e-5f);
  }
}

TEST_F(GlBackendTest, NoMotionOnTheFirstFrame) {
  Scene s = base_scene();
  Object plane = facing_plane(s, {3, 3}, 0.0f);
  plane.animation = Animation{{{0.0, {0, 0, 0}, {}}, {10.0, {5.0f, 2.5f, 0}, {}}}, false};
  s.objects.push_back(plane);
  const GBuffer g = render(s, 1.0, 1.0);
  for (const glm::vec2 m : g.motion) ASSERT_EQ(m, glm::vec2(0.0f));
}

// ---------------------------------------------------------------------------------------------
// Shading: the GLSL port against scene/shading.cpp

TEST_F(GlBackendTest, LambertianPointLightsMatchShadeLocal) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {3, 3}, 0.0f, 0));
  s.objects.push_back(object(s, "sphere", std::make_shared<const Mesh>(make_sphere(0.5f, 32, 64)), 0, {0.8f, 0.3f, 1}));
  s.lights.push_back(Light{LightType::Point, {1, 1, 2}, {40, 30, 20}});
  s.lights.push_back(Light{LightType::Point, {-1.5f, -0.5f, 1}, {10, 20, 30}});
  const GBuffer g = render(s);
  const ShadeCheck r = compare_with_shade_local(s, g, 0);
  std::cout << "lambertian: " << r.pixels << " pixels, max relative error " << r.max_rel << "\n";
  EXPECT_GT(r.pixels, 20000u);
  EXPECT_LT(r.max_rel, 1e-3);
}

TEST_F(GlBackendTest, BlinnPhongHighlightMatchesShadeLocal) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {3, 3}, 0.0f, 1));
  s.objects.push_back(object(s, "sphere", std::make_shared<const Mesh>(make_sphere(0.5f, 32, 64)), 1, {-0.6f, 0, 1}));
  s.lights.push_back(Light{LightType::Point, {0.3f, 0.4f, 3}, glm::vec3(40)});
  const GBuffer g = render(s);
  const ShadeCheck r = compare_with_shade_local(s, g, 0);
  std::cout << "blinn-phong: " << r.pixels << " pixels, max relative error " << r.max_rel << "\n";
  EXPECT_LT(r.max_rel, 1e-3);
}

TEST_F(GlBackendTest, SpotLightSoftEdgeMatchesShadeLocal) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {4, 4}, 0.0f, 0));
  Light spot;
  spot.type = LightType::Spot;
  spot.position = {0, 0, 2};
  spot.direction = glm::normalize(glm::vec3(0.2f, 0.1f, -1));
  spot.spot_cutoff_deg = 20;
  spot.spot_falloff_deg = 8;
  spot.power = glm::vec3(60.0f);
  s.lights.push_back(spot);
  const GBuffer g = render(s);
  // The cone must be in view: full-intensity pixels, soft-edge pixels and unlit pixels.
  std::size_t lit = 0, edge = 0, dark = 0;
  const float ambient = s.materials[0].kd.r * s.ambient.r;
  std::vector<LightSample> samples;
  light_samples(spot, samples);
  for (std::uint32_t y = 0; y < g.height; ++y) {
    for (std::uint32_t x = 0; x < g.width; ++x) {
      const std::size_t i = g.index(x, y);
      if (g.object_id[i] != 1) continue;
      const glm::vec3 p = world_at_pixel(s.camera, 0, x, y, g.depth[i]);
      const float c = glm::dot(glm::normalize(p - spot.position), samples[0].direction);
      if (c >= samples[0].cos_falloff_start) ++lit;
      else if (c > samples[0].cos_cutoff) ++edge;
      else {
        ++dark;
        ASSERT_NEAR(g.color[i].r, ambient, 1e-6f);
      }
    }
  }
  EXPECT_GT(lit, 1000u);
  EXPECT_GT(edge, 1000u);
  EXPECT_GT(dark, 1000u);
  const ShadeCheck r = compare_with_shade_local(s, g, 0);
  std::cout << "spot: lit " << lit << ", soft edge " << edge << ", dark " << dark << ", max relative error "
            << r.max_rel << "\n";
  EXPECT_LT(r.max_rel, 1e-3);
}

TEST_F(GlBackendTest, AreaLightSamplesMatchShadeLocal) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {4, 4}, 0.0f, 0));
  s.objects.push_back(object(s, "sphere", std::make_shared<const Mesh>(make_sphere(0.4f, 32, 64)), 1, {0.5f, -0.3f, 0.6f}));
  Light area;
  area.type = LightType::Area;
  area.position = {-0.5f, 0.8f, 1.2f};
  area.direction = glm::normalize(glm::vec3(0.3f, -0.5f, -1));
  area.area_size = {1.5f, 0.7f};
  area.area_samples = 5;
  area.power = glm::vec3(30, 40, 50);
  s.lights.push_back(area);
  s.lights.push_back(area);  // two area lights: 50 samples in the uniform block
  s.lights.back().position = {1.2f, -1.0f, 0.9f};
  s.lights.back().direction = glm::normalize(glm::vec3(-1, 0.6f, -0.5f));
  const GBuffer g = render(s);
  const ShadeCheck r = compare_with_shade_local(s, g, 0);
  std::cout << "area: " << r.pixels << " pixels, max relative error " << r.max_rel << "\n";
  EXPECT_GT(r.pixels, 20000u);
  EXPECT_LT(r.max_rel, 1e-3);
}

TEST_F(GlBackendTest, EmissiveIsEmissionPlusAmbient) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {2, 2}, 0.0f, 2));
  s.lights.push_back(Light{LightType::Point, {0, 0, 1}, glm::vec3(100)});  // must not add to emission
  const GBuffer g = render(s);
  const Material& m = s.materials[2];
  const glm::vec3 expected = m.emission + m.kd * s.ambient;
  const glm::vec3 c = g.color[g.index(160, 120)];
  EXPECT_NEAR(c.r, expected.r, 1e-6f);
  EXPECT_NEAR(c.g, expected.g, 1e-6f);
  EXPECT_NEAR(c.b, expected.b, 1e-6f);
}

TEST_F(GlBackendTest, MaximumLightSamplesAcceptedAndOneMoreRejected) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {3, 3}, 0.0f, 0));
  Light area;
  area.type = LightType::Area;
  area.position = {0, 0, 1.5f};
  area.direction = {0, 0, -1};
  area.area_samples = 16;  // 256 samples: exactly the limit
  area.power = glm::vec3(20);
  s.lights.push_back(area);
  const GBuffer g = render(s);
  EXPECT_LT(compare_with_shade_local(s, g, 0).max_rel, 1e-3);
  s.lights.push_back(Light{LightType::Point, {0, 0, 1}, glm::vec3(1)});  // 257
  try {
    backend_->set_scene(s);
    FAIL() << "257 light samples accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("257 light samples"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(std::to_string(gl::kMaxLightSamples)), std::string::npos) << e.what();
  }
}

TEST_F(GlBackendTest, InvalidObjectsAreRejectedWithTheirName) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {3, 3}, 0.0f, 0));
  s.objects.back().name = "broken";
  s.objects.back().material = 9;
  try {
    backend_->set_scene(s);
    FAIL() << "material index out of range accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'broken'"), std::string::npos) << e.what();
  }
  auto bad = std::make_shared<Mesh>(make_plane({1, 1}));
  bad->indices.back() = 1000;
  s.objects.back().material = 0;
  s.objects.back().mesh = bad;
  EXPECT_THROW(backend_->set_scene(s), std::invalid_argument);
  s.objects.back().mesh = nullptr;  // no mesh: nothing drawn, no error
  const GBuffer g = render(s);
  EXPECT_TRUE(std::all_of(g.object_id.begin(), g.object_id.end(), [](std::uint32_t id) { return id == 0; }));
}

// ---------------------------------------------------------------------------------------------
// Hard cases: nothing non-finite leaves the backend

TEST_F(GlBackendTest, DegenerateCasesStayFinite) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {3, 3}, 0.0f, 1));
  // Zero scale: a singular normal matrix.
  s.objects.push_back(object(s, "flat", std::make_shared<const Mesh>(make_sphere(0.5f, 8, 16)), 0, {0.5f, 0.5f, 1},
                             {0, 0, 0}, {1, 1, 0}));
  // A mesh with zero normals.
  auto zero_normals = std::make_shared<Mesh>(make_box(glm::vec3(0.4f)));
  for (glm::vec3& n : zero_normals->normals) n = glm::vec3(0.0f);
  s.objects.push_back(object(s, "no-normals", zero_normals, 0, {-0.8f, -0.5f, 1}));
  s.lights.push_back(Light{LightType::Point, {0, 0, 0}, glm::vec3(100)});  // on the surface: d = 0
  s.lights.push_back(Light{LightType::Point, {0.2f, 0.1f, 0.5f}, glm::vec3(3e38f)});  // irradiance overflows to Inf
  Light zero_spot;
  zero_spot.type = LightType::Spot;
  zero_spot.spot_cutoff_deg = 0;
  zero_spot.spot_falloff_deg = 0;
  zero_spot.position = {0, 0, 1};
  s.lights.push_back(zero_spot);
  s.materials[1].shininess = 0;
  const GBuffer g = render(s, 0.5, 0.4);
  EXPECT_TRUE(all_finite(g));
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (g.object_id[i] == 3) {
      ASSERT_NEAR(glm::length(g.normal[i]), 1.0f, 1e-4f);
    }
  }
  // Camera inside an object's previous position / geometry behind the previous camera.
  Scene b = base_scene();
  b.objects.push_back(facing_plane(b, {50, 50}, 0.0f));
  b.camera.animation = Animation{{{0.0, {0, 0, -10}, {}}, {1.0, {0, 0, 0}, {}}}, false};
  const GBuffer m = render(b, 1.0, 0.0);  // at t = 0 the camera was behind the plane
  EXPECT_TRUE(all_finite(m));
}

TEST(GlBackendCoexistence, TwoBackendsAndTheFactoryInOneProcess) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(s, {2, 2}, 0.0f));
  s.lights.push_back(Light{LightType::Point, {0, 0, 2}, glm::vec3(50)});
  auto a = std::make_unique<GlBackend>();
  auto b = make_backend(BackendKind::OpenGL);
  a->set_scene(s);
  s.camera.width = 100;
  s.camera.height = 50;
  b->set_scene(s);
  GBuffer ga, gb;
  a->render({}, {}, ga);
  b->render({}, {}, gb);
  EXPECT_EQ(ga.width, 320u);
  EXPECT_EQ(gb.width, 100u);
  a.reset();  // the other context (and GLFW) stay alive
  b->render({}, {}, gb);
  EXPECT_EQ(gb.object_id[gb.index(50, 25)], 1u);
  b.reset();
  auto c = std::make_unique<GlBackend>();  // a context again after the last one went (the display stays)
  c->set_scene(s);
  c->render({}, {}, gb);
  EXPECT_EQ(gb.object_id[gb.index(50, 25)], 1u);
}

// The GLFW window's own tests (GlWindow.*): ctest runs them under Xvfb, everything else without DISPLAY.
TEST(GlWindow, PresentDrawsRowZeroAtTheTop) {
  GlContext ctx(GlContextOptions{
      .visible = false, .platform = GlPlatform::Glfw, .title = "present", .width = 64, .height = 32, .vsync = false});
  EXPECT_TRUE(ctx.windowed());
  const glm::ivec2 fb = ctx.framebuffer_size();
  ASSERT_EQ(fb, glm::ivec2(64, 32));
  // 4 x 2 image, same aspect ratio as the window: top row red, bottom row blue (linear -> sRGB8).
  std::vector<glm::vec3> image(8, glm::vec3(0, 0, 1));
  for (int x = 0; x < 4; ++x) image[static_cast<std::size_t>(x)] = glm::vec3(1, 0, 0);
  ctx.present(image, 4, 2);
  glFinish();
  std::uint8_t top[4] = {}, bottom[4] = {};
  glReadBuffer(GL_BACK);
  glReadPixels(32, 28, 1, 1, GL_RGBA, GL_UNSIGNED_BYTE, top);    // GL rows count from the bottom
  glReadPixels(32, 3, 1, 1, GL_RGBA, GL_UNSIGNED_BYTE, bottom);
  EXPECT_EQ(top[0], 255);
  EXPECT_EQ(top[2], 0);
  EXPECT_EQ(bottom[0], 0);
  EXPECT_EQ(bottom[2], 255);
  ctx.swap_buffers();
  EXPECT_FALSE(ctx.should_close());
  EXPECT_THROW(ctx.present(std::vector<std::uint8_t>(7), 1, 2), std::invalid_argument);
}

// The viewer's path: a backend whose context shares the window's textures renders the frame on the
// GPU, and the window shows its display image without a trip through the CPU.
TEST(GlWindow, PresentTextureShowsTheFrameKeptOnTheGpu) {
  GlContext window(GlContextOptions{
      .visible = false, .platform = GlPlatform::Glfw, .title = "present", .width = 64, .height = 32, .vsync = false});
  ASSERT_EQ(window.framebuffer_size(), glm::ivec2(64, 32));
  GlBackend backend(GlPlatform::Glfw, &window);
  Scene s = base_scene();
  s.camera.width = 64;
  s.camera.height = 32;
  s.objects.push_back(facing_plane(s, {1.5f, 1.5f}, 0.0f, 2));  // the emissive lamp in the middle
  backend.set_scene(s);
  GpuFrame* gpu = backend.gpu_frame();
  ASSERT_TRUE(gpu->unavailable_reason().empty());
  GBuffer g;
  gpu->render_gbuffer({}, {}, GBufferPlanes::all(), g);
  gpu->tonemap({});
  gpu->finish();
  std::vector<std::uint8_t> rgb;
  std::uint32_t w = 0, h = 0;
  gpu->read_display(rgb, w, h);
  ASSERT_EQ(w, 64u);
  const GpuFrame::Texture d = gpu->display_texture();
  window.present_texture(d.id, d.width, d.height, d.texture_width, d.texture_height);
  glFinish();
  glReadBuffer(GL_BACK);
  for (const glm::ivec2 p : {glm::ivec2(32, 16), glm::ivec2(2, 2), glm::ivec2(60, 29)}) {
    std::uint8_t shown[4] = {};
    glReadPixels(p.x, p.y, 1, 1, GL_RGBA, GL_UNSIGNED_BYTE, shown);  // GL rows count from the bottom
    const std::size_t i = (std::size_t{h - 1 - static_cast<std::uint32_t>(p.y)} * w + static_cast<std::uint32_t>(p.x)) * 3;
    EXPECT_EQ(shown[0], rgb[i]) << p.x << "," << p.y;
    EXPECT_EQ(shown[2], rgb[i + 2]) << p.x << "," << p.y;
  }
  EXPECT_NE(rgb[(16 * 64 + 32) * 3], rgb[(2 * 64 + 2) * 3]);  // the lamp against the background
  EXPECT_THROW(window.present_texture(d.id, 65, 32, 64, 32), std::invalid_argument);
}

TEST(GlWindowDeathTest, NoDisplayGivesAClearError) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        unsetenv("DISPLAY");
        try {
          GlBackend b(GlPlatform::Glfw);
          std::exit(2);
        } catch (const std::runtime_error& e) {
          const std::string what = e.what();
          std::cerr << what << "\n";
          std::exit(what.find("no X display: run under xvfb-run or set DISPLAY") != std::string::npos ? 0 : 1);
        }
      },
      ::testing::ExitedWithCode(0), "no X display");
}

// Headless contexts need no window system: EGL, with DISPLAY unset (ctest also runs this whole
// binary, except GlWindow.*, without DISPLAY).
TEST(GlContextDeathTest, HeadlessRendersWithoutAnXDisplay) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        unsetenv("DISPLAY");
        Scene s = base_scene();
        s.objects.push_back(facing_plane(s, {2, 2}, 0.0f));
        GlBackend b;
        b.set_scene(s);
        GBuffer g;
        b.render({}, {}, g);
        const bool egl = b.context().platform_description().rfind("EGL ", 0) == 0 && !b.context().windowed();
        std::cerr << b.context().platform_description() << "\n";
        std::exit(egl && g.object_id[g.index(g.width / 2, g.height / 2)] == 1u ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "EGL");
}

TEST(GlContext, AnEglContextHasNoWindowToPresentTo) {
  GlContext ctx;
  EXPECT_FALSE(ctx.windowed());
  EXPECT_EQ(ctx.framebuffer_size(), glm::ivec2(0, 0));
  ctx.swap_buffers();  // nothing to swap: no effect
  EXPECT_FALSE(ctx.should_close());
  try {
    ctx.present(std::vector<glm::vec3>(8, glm::vec3(1)), 4, 2);
    ADD_FAILURE() << "present on an EGL context did not throw";
  } catch (const std::logic_error& e) {
    EXPECT_NE(std::string(e.what()).find("no window to present to"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------------------------
// Backend agreement: Embree ray casting vs OpenGL raster on the same scene and times.

struct Agreement {
  std::size_t pixels = 0, id_agree = 0, id_disagree_interior = 0, creases = 0, compared = 0;
  double max_depth_rel = 0, max_normal = 0, max_motion = 0, max_color_rel = 0;
  std::size_t depth_bad = 0, normal_bad = 0, motion_bad = 0, color_bad = 0;
  double id_fraction() const { return pixels == 0 ? 1.0 : static_cast<double>(id_agree) / static_cast<double>(pixels); }
  std::string summary() const {
    std::ostringstream o;
    o << "ids agree on " << id_agree << "/" << pixels << " (" << 100.0 * id_fraction() << "%), interior disagreements "
      << id_disagree_interior << "; over " << compared << " interior pixels (" << creases << " at creases: normal and colour not compared there): max depth rel " << max_depth_rel
      << " (bad " << depth_bad << "), max normal " << max_normal << " (bad " << normal_bad << "), max motion "
      << max_motion << " px (bad " << motion_bad << "), max colour rel " << max_color_rel << " (bad " << color_bad
      << ")";
    return o.str();
  }
};

// True if (x, y) sits on a crease: an edge between faces of one object whose normals differ by
// more than ~30 degrees (box and cylinder edges). There a pixel centre can lie on the shared edge
// (depth agrees to 1e-5), and the ray caster and the rasteriser's tie-breaking rules (Embree's
// watertight test vs the top-left fill rule) may pick different faces.
bool at_crease(const GBuffer& b, std::uint32_t x, std::uint32_t y) {
  const glm::vec3 centre = b.normal[b.index(x, y)];
  for (std::uint32_t yy = y == 0 ? 0 : y - 1; yy <= std::min(b.height - 1, y + 1); ++yy) {
    for (std::uint32_t xx = x == 0 ? 0 : x - 1; xx <= std::min(b.width - 1, x + 1); ++xx) {
      if (glm::length(b.normal[b.index(xx, yy)] - centre) > 0.5f) return true;
    }
  }
  return false;
}

Agreement compare_backends(const GBuffer& e, const GBuffer& g) {
  Agreement a;
  a.pixels = e.size();
  for (std::uint32_t y = 0; y < e.height; ++y) {
    for (std::uint32_t x = 0; x < e.width; ++x) {
      const std::size_t i = e.index(x, y);
      const bool edge = at_edge(e.object_id, e.width, e.height, x, y) || at_edge(g.object_id, g.width, g.height, x, y);
      if (e.object_id[i] != g.object_id[i]) {
        if (!edge) ++a.id_disagree_interior;
        continue;
      }
      ++a.id_agree;
      if (edge) continue;
      // Normals and colour are not compared at creases (see at_crease); depth and motion are.
      const bool crease = at_crease(e, x, y) || at_crease(g, x, y);
      a.creases += crease ? 1 : 0;
      ++a.compared;
      const double depth_rel = std::abs(static_cast<double>(e.depth[i]) - static_cast<double>(g.depth[i])) /
                               static_cast<double>(std::max(1e-6f, e.depth[i]));
      const auto normal = crease ? 0.0 : static_cast<double>(glm::length(e.normal[i] - g.normal[i]));
      const auto motion = static_cast<double>(glm::length(e.motion[i] - g.motion[i]));
      double color_rel = 0;
      for (int c = 0; c < 3 && !crease; ++c) {
        const double diff = std::abs(static_cast<double>(e.color[i][c]) - static_cast<double>(g.color[i][c]));
        color_rel = std::max(
            color_rel, diff / static_cast<double>(std::max({std::abs(e.color[i][c]), std::abs(g.color[i][c]), 1e-4f})));
      }
      a.max_depth_rel = std::max(a.max_depth_rel, depth_rel);
      a.max_normal = std::max(a.max_normal, normal);
      a.max_motion = std::max(a.max_motion, motion);
      a.max_color_rel = std::max(a.max_color_rel, color_rel);
      if (std::getenv("FOVEA_AGREEMENT_VERBOSE") != nullptr && (normal > 1e-2 || color_rel > 1e-2)) {
        std::cout << "  pixel " << x << "," << y << " id " << e.object_id[i] << " embree n " << e.normal[i].x << ","
                  << e.normal[i].y << "," << e.normal[i].z << " gl n " << g.normal[i].x << "," << g.normal[i].y << ","
                  << g.normal[i].z << " depth " << e.depth[i] << " / " << g.depth[i] << "\n";
      }
      a.depth_bad += depth_rel > 1e-3 ? 1 : 0;
      a.normal_bad += normal > 1e-2 ? 1 : 0;
      a.motion_bad += motion > 0.05 ? 1 : 0;
      a.color_bad += color_rel > 1e-2 ? 1 : 0;
    }
  }
  return a;
}

class BackendAgreementTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    embree_ = make_backend(BackendKind::Embree);
    gl_ = make_backend(BackendKind::OpenGL);
  }
  static void TearDownTestSuite() {
    embree_.reset();
    gl_.reset();
  }
  // Renders `s` with both backends at each (now, previous) and checks the tolerances.
  // `gl_settings`: how the raster backend draws (forward, depth pre-pass, visibility buffer).
  // `embree_settings`: how the ray tracer renders (a peeled layer: both render it). Without
  // strict_interior, ids may disagree away from edges on `interior_fraction` of the pixels.
  static void expect_agreement(const Scene& s, const std::vector<FrameTime>& times, bool strict_interior = true,
                               const BackendSettings& gl_settings = {}, const BackendSettings& embree_settings = {},
                               double interior_fraction = 1e-3) {
    embree_->set_scene(s);
    gl_->set_scene(s);
    for (const FrameTime& t : times) {
      GBuffer e, g;
      embree_->render(t, embree_settings, e);
      gl_->render(t, gl_settings, g);
      ASSERT_EQ(e.width, g.width);
      ASSERT_EQ(e.height, g.height);
      EXPECT_TRUE(all_finite(g));
      const Agreement a = compare_backends(e, g);
      std::cout << "[agreement] " << s.name << " t=" << t.now_s << " prev=" << t.previous_s << " " << e.width << "x"
                << e.height << ": " << a.summary() << "\n";
      EXPECT_GE(a.id_fraction(), 0.99) << a.summary();
      if (strict_interior) {
        EXPECT_EQ(a.id_disagree_interior, 0u) << a.summary();
      } else {
        EXPECT_LE(static_cast<double>(a.id_disagree_interior), interior_fraction * static_cast<double>(a.pixels))
            << a.summary();
      }
      EXPECT_EQ(a.depth_bad, 0u) << a.summary();
      EXPECT_EQ(a.normal_bad, 0u) << a.summary();
      EXPECT_EQ(a.motion_bad, 0u) << a.summary();
      EXPECT_EQ(a.color_bad, 0u) << a.summary();
    }
  }
  static std::unique_ptr<Backend> embree_, gl_;
};
std::unique_ptr<Backend> BackendAgreementTest::embree_;
std::unique_ptr<Backend> BackendAgreementTest::gl_;

TEST_F(BackendAgreementTest, CornellBoxWithSphere) {
  expect_agreement(testing::cornell_box(320, 240), {{0, 0}});
  expect_agreement(testing::cornell_box(257, 193), {{0, 0}});  // odd sizes
}

TEST_F(BackendAgreementTest, ManyObjectsWithAnimation) {
  const Scene s = testing::many_objects(120, 320, 240);
  expect_agreement(s, {{0.0, 0.0}, {0.5, 0.5 - 1.0 / 30}, {1.3, 1.25}, {2.6, 2.5}});
}

// Every bundled scene (renderer/scenes/*.json) that loads, at most 320 pixels wide.
TEST_F(BackendAgreementTest, BundledScenes) {
  const std::filesystem::path dir = std::filesystem::path(FOVEA_SOURCE_DIR) / "renderer" / "scenes";
  std::vector<std::filesystem::path> files;
  if (std::filesystem::is_directory(dir)) {
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
      if (entry.path().extension() == ".json") files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  std::size_t compared = 0;
  std::string skipped;
  for (const auto& file : files) {
    Scene s;
    try {
      s = load_scene(file);
    } catch (const std::exception& e) {
      skipped += "\n  " + file.filename().string() + ": does not load: " + e.what();
      continue;
    }
    if (s.camera.width > 320) {
      const double k = 320.0 / s.camera.width;
      s.camera.height = std::max(1u, static_cast<std::uint32_t>(std::lround(s.camera.height * k)));
      s.camera.width = 320;
    }
    if (s.name.empty()) s.name = file.filename().string();
    try {
      gl_->set_scene(s);
    } catch (const std::runtime_error& e) {  // e.g. more light samples than the raster backend takes
      skipped += "\n  " + file.filename().string() + ": GL backend refuses it: " + e.what();
      continue;
    }
    SCOPED_TRACE(file.string());
    expect_agreement(s, {{0.0, 0.0}, {1.0, 1.0 - 1.0 / 30}}, /*strict_interior=*/false);
    if (gl_->capabilities().visibility_buffer) {
      BackendSettings visibility;
      visibility.visibility_buffer = true;
      expect_agreement(s, {{0.0, 0.0}, {1.0, 1.0 - 1.0 / 30}}, /*strict_interior=*/false, visibility);
    }
    ++compared;
  }
  if (!skipped.empty()) std::cout << "bundled scenes not compared:" << skipped << "\n";
  if (compared == 0) GTEST_SKIP() << "no bundled scene in " << dir << " loads" << skipped;
}

// Depth peeling by object (BackendSettings::peel, backend/gl/gl_peel.h): the raster backend's layers
// behind the visible one agree with the ray tracer's (trace_peeled) within the same tolerances as the
// visible layer, on the synthetic scenes and the bundled scenes the DOF methods peel (layers 1 and 2:
// Schedl & Wimmer's M = 3; layer 1 is Lee's hidden image); and the frame's G-buffer textures are
// left as they were. Where two objects' surfaces coincide (attention.json's spinning box rests on
// the ground: its bottom face and the ground are one depth) either is the next layer: the ray tracer
// takes the one its BVH meets first, the rasteriser the one whose rounded depth is smaller, so up to
// 0.2 % of the pixels may disagree away from edges (88 of 76,800 there at layer 2).
// Both peels: the forward one (each draw shaded) and the visibility buffer's (GlPeeling::run_visibility:
// each draw writes its triangle, each layer is shaded once), where the context has compute shaders.
TEST_F(BackendAgreementTest, PeeledLayersAgreeWithTheRayTracer) {
  std::vector<bool> visibility{false};
  if (gl_->capabilities().visibility_buffer) visibility.push_back(true);
  for (const bool through_visibility : visibility) {
    for (std::uint32_t peel : {1u, 2u}) {
      SCOPED_TRACE("peel " + std::to_string(peel) + (through_visibility ? ", visibility buffer" : ", forward"));
      BackendSettings peeled;
      peeled.peel = peel;
      BackendSettings gl = peeled;
      gl.peel_visibility = through_visibility;
      expect_agreement(testing::cornell_box(320, 240), {{0, 0}}, false, gl, peeled);
      expect_agreement(testing::many_objects(120, 320, 240), {{0.0, 0.0}, {1.3, 1.25}}, false, gl, peeled);
      for (const char* name : {"attention.json", "occlusion.json"}) {
        Scene s = load_scene(std::filesystem::path(FOVEA_SOURCE_DIR) / "renderer" / "scenes" / name);
        s.camera.width = 320;
        s.camera.height = 240;
        s.name = name;
        expect_agreement(s, {{0.0, 0.0}}, false, gl, peeled, 2e-3);
      }
    }
  }
}

// The visibility buffer's peel keeps the forward peel's fragments: the same object and depth at every
// pixel of every layer, the colour and normal to float rounding (shaded from the ray's barycentrics).
TEST_F(GlBackendTest, TheVisibilityPeelKeepsTheForwardPeelsLayers) {
  if (!backend_->capabilities().visibility_buffer) GTEST_SKIP() << "no compute shaders on this context";
  backend_->set_scene(testing::many_objects(60, 160, 120));
  for (const FrameTime t : {FrameTime{0.0, 0.0}, FrameTime{1.3, 1.25}}) {
    std::vector<GBuffer> forward(2), visibility(2);
    BackendSettings f, v;
    f.peel_visibility = false;
    backend_->render_peeled_layers(t, f, forward);
    backend_->render_peeled_layers(t, v, visibility);
    for (std::size_t n = 0; n < 2; ++n) {
      SCOPED_TRACE("layer " + std::to_string(n + 1));
      EXPECT_EQ(forward[n].object_id, visibility[n].object_id);
      ASSERT_EQ(forward[n].depth.size(), visibility[n].depth.size());
      std::size_t color_off = 0;
      for (std::size_t i = 0; i < forward[n].depth.size(); ++i) {
        const float a = forward[n].depth[i], b = visibility[n].depth[i];
        if (std::isinf(a) || std::isinf(b)) {
          EXPECT_EQ(a, b) << "pixel " << i;
        } else {
          EXPECT_NEAR(a, b, 1e-4f * std::max(1.0f, a)) << "pixel " << i;
        }
        if (glm::length(forward[n].color[i] - visibility[n].color[i]) > 1e-3f * (1.0f + glm::length(forward[n].color[i])))
          ++color_off;
      }
      EXPECT_LE(color_off, forward[n].depth.size() / 1000) << color_off << " pixels' colours differ";
    }
  }
}

// Several layers in one peeling loop are the layers rendered one at a time.
TEST_F(GlBackendTest, PeeledLayersInOneLoopAreTheLayersRenderedOneByOne) {
  backend_->set_scene(testing::many_objects(40, 96, 72));
  std::vector<GBuffer> together(2);
  backend_->render_peeled_layers({}, {}, together);
  for (std::uint32_t n = 1; n <= 2; ++n) {
    BackendSettings p;
    p.peel = n;
    GBuffer alone;
    backend_->render({}, p, alone);
    EXPECT_EQ(together[n - 1].object_id, alone.object_id) << "layer " << n;
    EXPECT_EQ(together[n - 1].depth, alone.depth) << "layer " << n;
    EXPECT_EQ(together[n - 1].color, alone.color) << "layer " << n;
  }
}

// The stability catalogue's tiny targets for both peels: 1x1, 1xN and Nx1 images peel, stay finite and
// agree with each other (the compute resolve's 8x8 workgroups overhang such images on every side).
TEST_F(GlBackendTest, BothPeelsHandleTinyAndDegenerateSizes) {
  const bool visibility = backend_->capabilities().visibility_buffer;
  for (const auto& [w, h] : {std::pair{1u, 1u}, std::pair{1u, 7u}, std::pair{9u, 1u}, std::pair{3u, 2u}}) {
    SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
    backend_->set_scene(testing::many_objects(30, w, h));
    std::vector<GBuffer> forward(2), through_ids(2);
    BackendSettings f;
    f.peel_visibility = false;
    backend_->render_peeled_layers({}, f, forward);
    for (const GBuffer& g : forward) {
      EXPECT_EQ(g.width, w);
      EXPECT_EQ(g.height, h);
      EXPECT_TRUE(all_finite(g));
    }
    if (!visibility) continue;
    backend_->render_peeled_layers({}, {}, through_ids);
    for (std::size_t n = 0; n < 2; ++n) {
      EXPECT_TRUE(all_finite(through_ids[n]));
      EXPECT_EQ(forward[n].object_id, through_ids[n].object_id) << "layer " << n + 1;
    }
  }
}

// A ULOD frame renders two images aside every frame (the attention proxy at the map's size, the next
// levels at the frame's): both sizes keep their targets, so alternating reallocates nothing and the
// first image stays valid while the second is drawn.
TEST_F(GlBackendTest, RendersAsideAtTwoSizesKeepTheirTargets) {
  backend_->set_scene(testing::cornell_box(64, 48));
  BackendSettings small;
  small.width = 16;
  small.height = 12;
  const GlGBufferTextures a = backend_->render_aside({}, small);
  const GlGBufferTextures b = backend_->render_aside({}, {});
  EXPECT_NE(a.color, b.color);
  EXPECT_EQ(b.width, 64u);
  for (int frame = 0; frame < 3; ++frame) {
    EXPECT_EQ(backend_->render_aside({}, small).color, a.color) << "frame " << frame;
    EXPECT_EQ(backend_->render_aside({}, {}).color, b.color) << "frame " << frame;
  }
  // A third size takes the slot not drawn into last (the small one here); the full size stays.
  BackendSettings third;
  third.width = 32;
  third.height = 24;
  const GlGBufferTextures c = backend_->render_aside({}, third);
  EXPECT_EQ(c.width, 32u);
  EXPECT_EQ(backend_->render_aside({}, {}).color, b.color);
}

TEST_F(GlBackendTest, APeeledRenderLeavesTheFramesGBufferTextures) {
  const Scene s = testing::cornell_box(64, 48);
  backend_->set_scene(s);
  GBuffer visible, peeled, again;
  backend_->render({}, {}, visible);
  BackendSettings p;
  p.peel = 1;
  backend_->render({}, p, peeled);
  EXPECT_NE(visible.object_id, peeled.object_id);  // the sphere's wall behind it, at least
  backend_->read_back(GBufferPlanes::all(), again);  // what the GPU frame's passes would sample
  again.resize(visible.width, visible.height);
  backend_->read_back(GBufferPlanes::all(), again);
  EXPECT_EQ(again.object_id, visible.object_id);
  EXPECT_EQ(again.depth, visible.depth);
  EXPECT_THROW(backend_->render_on_gpu({}, p, GBufferPlanes::all()), std::invalid_argument);
}

// The visibility buffer's G-buffer agrees with the CPU reference (Embree) within the same
// tolerances as the forward pass's, on the synthetic scenes too (odd sizes, 120 animated objects).
TEST_F(BackendAgreementTest, VisibilityBufferAgreesWithTheRayTracer) {
  if (!gl_->capabilities().visibility_buffer) GTEST_SKIP() << "no compute shaders in this context";
  BackendSettings visibility;
  visibility.visibility_buffer = true;
  expect_agreement(testing::cornell_box(320, 240), {{0, 0}}, true, visibility);
  expect_agreement(testing::cornell_box(257, 193), {{0, 0}}, true, visibility);
  expect_agreement(testing::many_objects(120, 320, 240), {{0.0, 0.0}, {0.5, 0.5 - 1.0 / 30}, {1.3, 1.25}}, true,
                   visibility);
}

// Renders every bundled scene at 320x240 and two times (the second with objects and camera moving)
// with the forward pass's settings and with `changed` applied to them, and hands both G-buffers to
// `compare`; returns how many pairs it compared.
template <class Compare>
std::size_t for_each_bundled_pair(Backend& gl, void (*changed)(BackendSettings&), Compare compare) {
  const std::filesystem::path dir = std::filesystem::path(FOVEA_SOURCE_DIR) / "renderer" / "scenes";
  std::size_t compared = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() != ".json") continue;
    SCOPED_TRACE(entry.path().string());
    Scene s = load_scene(entry.path());
    s.camera.width = 320;
    s.camera.height = 240;
    gl.set_scene(s);
    for (const FrameTime t : {FrameTime{0.0, 0.0}, FrameTime{1.0, 1.0 - 1.0 / 30}}) {
      SCOPED_TRACE("t=" + std::to_string(t.now_s));
      GBuffer base, other;
      BackendSettings bs;
      gl.render(t, bs, base);
      changed(bs);
      gl.render(t, bs, other);
      compare(base, other);
      ++compared;
    }
  }
  return compared;
}

// The visibility buffer (BackendSettings::visibility_buffer) against the forward G-buffer pass, on
// every bundled scene at two times (objects and camera moving, so motion is not trivially 0):
// the same triangle covers each pixel (ids exact: both raster passes compute gl_Position alike), and
// the compute pass's barycentrics from the pixel ray equal the rasteriser's interpolation up to float
// rounding: depth within 1e-5 relative, normals within 5e-4, motion within 1e-3 px, colour within 1 %
// relative or 1e-4 absolute (a normal 2e-5 apart moves a grazing or sharply peaked light's share by
// ~0.5 %; 1e-4 of radiance is far below one 8-bit step after any tone map at exposure 1). Where the
// context has no compute shaders the test says so and skips.
TEST_F(BackendAgreementTest, VisibilityBufferAgreesWithTheForwardPass) {
  if (!gl_->capabilities().visibility_buffer) GTEST_SKIP() << "no compute shaders in this context";
  std::size_t covered = 0;
  const std::size_t compared = for_each_bundled_pair(
      *gl_, [](BackendSettings& bs) { bs.visibility_buffer = true; },
      [&](const GBuffer& forward, const GBuffer& visibility) {
        std::size_t ids = 0, depth = 0, normal = 0, color = 0, motion = 0;
        for (std::size_t i = 0; i < forward.depth.size(); ++i) {
          ids += forward.object_id[i] != visibility.object_id[i];
          covered += forward.object_id[i] != 0;
          depth += !(std::abs(forward.depth[i] - visibility.depth[i]) <= 1e-5f * std::abs(forward.depth[i]));
          normal += !(glm::length(forward.normal[i] - visibility.normal[i]) <= 5e-4f);
          const glm::vec3 dc = glm::abs(forward.color[i] - visibility.color[i]);
          const glm::vec3 bound = glm::max(1e-2f * glm::abs(forward.color[i]), glm::vec3(1e-4f));
          color += !(dc.x <= bound.x && dc.y <= bound.y && dc.z <= bound.z);
          motion += !(glm::length(forward.motion[i] - visibility.motion[i]) <= 1e-3f);
        }
        EXPECT_EQ(ids, 0u);
        EXPECT_EQ(depth, 0u);
        EXPECT_EQ(normal, 0u);
        EXPECT_EQ(color, 0u);
        EXPECT_EQ(motion, 0u);
      });
  EXPECT_GE(compared, 6u);
  EXPECT_GT(covered, compared * 320 * 240 / 4) << "the scenes must cover the image for this to mean anything";
}

// The depth pre-pass (BackendSettings::depth_prepass, the frame's default) shades each pixel once
// and must not change the G-buffer: every plane of every bundled scene, two times (one moving), is
// the same with and without it. Where two surfaces lie at exactly one depth the later-drawn one wins
// with the pre-pass; the bundled scenes have no such pixels, so the planes are compared exactly.
TEST_F(BackendAgreementTest, DepthPrepassLeavesTheGBufferUnchanged) {
  const std::size_t compared = for_each_bundled_pair(
      *gl_, [](BackendSettings& bs) { bs.depth_prepass = true; },
      [](const GBuffer& plain, const GBuffer& prepassed) {
        std::size_t differ = 0;
        for (std::size_t i = 0; i < plain.depth.size(); ++i) {
          differ += plain.color[i] != prepassed.color[i] || plain.depth[i] != prepassed.depth[i] ||
                    plain.object_id[i] != prepassed.object_id[i] || plain.normal[i] != prepassed.normal[i] ||
                    plain.motion[i] != prepassed.motion[i];
        }
        EXPECT_EQ(differ, 0u) << "pixels that differ";
      });
  EXPECT_GE(compared, 6u);
}

}  // namespace
}  // namespace fovea::render

namespace fovea::render {
namespace {

// The DOF references (renderer/dof/reference.h): the raster backend's accumulation-buffer views
// (one lens point per render, sheared frusta) against Embree's per-pixel distributed ray tracing of
// the same thin lens. Both estimate the same aperture integral; with 256 samples each they agree
// within 2 % relative RMSE (the rest: sampling noise and the backends' rasterization tolerance).
TEST_F(GlBackendTest, DofAccumulationAgreesWithTheRayTracedReference) {
  Scene s = testing::cornell_box(160, 120);
  s.camera.lens.focal_length_m = 0.05;
  s.camera.lens.aperture_m = 0.12;
  s.camera.lens.focus_distance_m = 5.7;  // the sphere sharp, the walls and the box blurred
  backend_->set_scene(s);
  dof::DofReference accum(*backend_, {}, {}, s.camera.lens, 5.7, dof::ReferenceKind::Accumulation, 1);
  accum.add_samples(256);
  EmbreeBackend embree;
  embree.set_scene(s);
  dof::DofReference traced(embree, {}, {}, s.camera.lens, 5.7, dof::ReferenceKind::RayTraced, 1);
  traced.add_samples(256);
  const dof::RgbImage a = accum.image(), b = traced.image();
  ASSERT_EQ(a.size(), b.size());
  double err = 0, mean = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const glm::dvec3 d = glm::dvec3(a[i]) - glm::dvec3(b[i]);
    err += glm::dot(d, d) / 3.0;
    mean += static_cast<double>(b[i].r + b[i].g + b[i].b) / 3.0;
  }
  const double rel = std::sqrt(err / static_cast<double>(a.size())) / (mean / static_cast<double>(a.size()));
  std::cout << "accumulation (GL) vs ray traced (Embree), 256 samples each: relative RMSE " << rel << "\n";
  EXPECT_LT(rel, 0.02);
  // And the blur is real: the pinhole render is much farther from both.
  GBuffer pinhole;
  embree.render({}, {}, pinhole);
  double perr = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const glm::dvec3 d = glm::dvec3(pinhole.color[i]) - glm::dvec3(b[i]);
    perr += glm::dot(d, d) / 3.0;
  }
  EXPECT_GT(std::sqrt(perr / static_cast<double>(a.size())) / (mean / static_cast<double>(a.size())), 3 * rel);
}

TEST_F(GlBackendTest, PerPixelLensSamplesAreRefusedWithTheReason) {
  Scene s = testing::cornell_box(32, 24);
  backend_->set_scene(s);
  BackendSettings bs;
  bs.lens.aperture_radius_m = 0.05;
  bs.lens.focus_m = 5;
  bs.lens.per_pixel = true;
  GBuffer g;
  try {
    backend_->render({}, bs, g);
    FAIL() << "per-pixel lens samples accepted by the raster backend";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("embree"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace fovea::render

namespace fovea::render {
namespace {

TEST_F(GlBackendTest, SmallerResolutionIsTheCameraAtThatResolutionAndColourOnlySkipsTheRest) {
  Scene s = base_scene();
  const auto box = std::make_shared<const Mesh>(make_box(glm::vec3(0.5f)));
  s.objects.push_back(object(s, "box", box, 0, {0, 0, 0}));
  s.lights.push_back(Light{LightType::Point, {0, 0, 3}, glm::vec3(50.0f)});
  backend_->set_scene(s);
  BackendSettings small_settings;  // the attention proxy's size, alternating with the full one
  small_settings.width = 80;
  small_settings.height = 60;
  GBuffer small, full;
  backend_->render({}, small_settings, small);
  backend_->render({}, BackendSettings{}, full);
  backend_->render({}, small_settings, small);
  ASSERT_EQ(small.width, 80u);
  ASSERT_EQ(small.height, 60u);
  ASSERT_EQ(full.width, s.camera.width);
  // Centre pixel: the box, at the same depth as at full size; a corner: background.
  EXPECT_EQ(small.object_id[small.index(40, 30)], 1u);
  EXPECT_NEAR(small.depth[small.index(40, 30)], full.depth[full.index(160, 120)], 1e-4f);
  EXPECT_EQ(small.object_id[small.index(0, 0)], 0u);
  s.camera.width = 80;
  s.camera.height = 60;
  const GBuffer direct = render(s);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < direct.size(); ++i) differ += direct.object_id[i] != small.object_id[i] ? 1u : 0u;
  EXPECT_EQ(differ, 0u);
  BackendSettings colour_only;
  colour_only.readback = {.color = true, .object_id = true};
  GBuffer c;
  backend_->render({}, colour_only, c);
  EXPECT_EQ(c.object_id, direct.object_id);
  EXPECT_EQ(c.color, direct.color);
  EXPECT_EQ(c.normal[c.index(40, 30)], glm::vec3(0.0f));
}

}  // namespace
}  // namespace fovea::render
