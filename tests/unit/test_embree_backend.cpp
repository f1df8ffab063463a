// SPDX-License-Identifier: Apache-2.0
// The Embree G-buffer backend against closed-form answers: depth, ids, normals, motion, shading,
// shadows, background, hard cases (degenerate geometry), determinism and traversal agreement.
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "backend/embree/embree_backend.h"
#include "scene/geometry.h"
#include "scene/mesh_simplify.h"
#include "scene/shading.h"

using namespace fovea::render;

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

const EmbreeTraversal kAllTraversals[] = {EmbreeTraversal::Single, EmbreeTraversal::Packet4, EmbreeTraversal::Packet8,
                                          EmbreeTraversal::Packet16, EmbreeTraversal::Stream};
const EmbreeGeometry kAllGeometry[] = {EmbreeGeometry::Flattened, EmbreeGeometry::Instanced};

// Camera at z = 5 looking down -z at the origin; odd resolution so the centre pixel's ray is the
// view axis.
Scene base_scene(std::uint32_t w = 65, std::uint32_t h = 49) {
  Scene s;
  s.name = "test";
  s.camera.position = {0, 0, 5};
  s.camera.target = {0, 0, 0};
  s.camera.up = {0, 1, 0};
  s.camera.vertical_fov_deg = 60;
  s.camera.width = w;
  s.camera.height = h;
  s.camera.near_m = 0.05f;
  s.camera.far_m = 100;
  Material m;
  m.name = "grey";
  m.kd = glm::vec3(0.5f, 0.6f, 0.7f);
  s.materials.push_back(m);
  s.ambient = glm::vec3(0.02f);
  s.background = glm::vec3(0.1f, 0.2f, 0.3f);
  return s;
}

Object object(std::uint32_t id, Mesh mesh, Transform t = {}, std::uint32_t material = 0) {
  Object o;
  o.name = "object" + std::to_string(id);
  o.id = id;
  o.mesh = std::make_shared<Mesh>(std::move(mesh));
  o.transform = t;
  o.material = material;
  return o;
}

// A plane through `centre` facing +z (towards the default camera).
Object facing_plane(std::uint32_t id, glm::vec3 centre, glm::vec2 size = {40, 40}) {
  Transform t;
  t.translation = centre;
  t.rotation_deg = {90, 0, 0};  // +Y normal -> +Z
  return object(id, make_plane(size), t);
}

GBuffer render(const Scene& s, FrameTime time = {}, bool shadows = false, EmbreeOptions options = {}) {
  EmbreeBackend b(options);
  b.set_scene(s);
  GBuffer g;
  BackendSettings bs;
  bs.shadows = shadows;
  b.render(time, bs, g);
  return g;
}

// World-space ray direction through the centre of pixel (x, y), unprojected through the inverse of
// projection * view (independent of the backend's own camera construction).
glm::vec3 pixel_ray(const Camera& c, double t, std::uint32_t x, std::uint32_t y) {
  const glm::mat4 inv = glm::inverse(c.projection() * c.view_at(t));
  const float nx = 2.0f * (static_cast<float>(x) + 0.5f) / static_cast<float>(c.width) - 1.0f;
  const float ny = 1.0f - 2.0f * (static_cast<float>(y) + 0.5f) / static_cast<float>(c.height);
  glm::vec4 a = inv * glm::vec4(nx, ny, -1, 1), b = inv * glm::vec4(nx, ny, 1, 1);
  return glm::normalize(glm::vec3(b) / b.w - glm::vec3(a) / a.w);
}

glm::vec2 project_px(const Camera& c, double t, glm::vec3 p) {
  const glm::vec4 clip = c.projection() * c.view_at(t) * glm::vec4(p, 1);
  return {(clip.x / clip.w + 1) * 0.5f * static_cast<float>(c.width), (1 - clip.y / clip.w) * 0.5f * static_cast<float>(c.height)};
}

bool all_finite(const GBuffer& g) {
  for (std::size_t i = 0; i < g.size(); ++i) {
    const glm::vec3 c = g.color[i], n = g.normal[i];
    const glm::vec2 m = g.motion[i];
    for (float v : {c.x, c.y, c.z, n.x, n.y, n.z, m.x, m.y, g.depth[i]}) {
      if (!std::isfinite(v)) return false;
    }
  }
  return true;
}

void expect_vec3_near(glm::vec3 a, glm::vec3 b, float tol) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

}  // namespace

TEST(EmbreeBackend, NameAndFactory) {
  EXPECT_EQ(make_embree_backend()->name(), "embree");
  EXPECT_EQ(make_embree_backend(EmbreeOptions{EmbreeTraversal::Stream, EmbreeGeometry::Instanced, true})->name(), "embree");
}

// Passes ask the capabilities, not the name: Embree traces shadow rays, a lens point per pixel, and
// peels by object.
TEST(EmbreeBackend, CapabilitiesSayWhatItTraces) {
  EXPECT_EQ(EmbreeBackend().capabilities(),
            (BackendCapabilities{.shadow_rays = true, .per_pixel_lens = true, .peeling = true}));
}

TEST(EmbreeBackend, FrontoParallelPlaneHasConstantViewAxisDepth) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(7, {0, 0, 0}));
  for (EmbreeGeometry geo : kAllGeometry) {
    for (EmbreeTraversal tr : kAllTraversals) {
      SCOPED_TRACE(std::string(to_string(geo)) + "/" + to_string(tr));
      const GBuffer g = render(s, {}, false, {tr, geo, true});
      ASSERT_EQ(g.width, 65u);
      ASSERT_EQ(g.height, 49u);
      // Every pixel, corners included, is 5 m along the view axis (the ray length at a corner
      // is 5 / cos(angle off-axis), which is not what the G-buffer stores).
      for (std::uint32_t y = 0; y < g.height; ++y) {
        for (std::uint32_t x = 0; x < g.width; ++x) {
          const std::size_t i = g.index(x, y);
          ASSERT_NEAR(g.depth[i], 5.0f, 1e-4f) << x << "," << y;
          ASSERT_EQ(g.object_id[i], 7u);
          ASSERT_NEAR(g.normal[i].z, 1.0f, 1e-5f);
          ASSERT_EQ(g.motion[i], glm::vec2(0.0f));
        }
      }
      EXPECT_TRUE(all_finite(g));
    }
  }
}

TEST(EmbreeBackend, SphereDepthAtCentreIsDistanceMinusRadius) {
  Scene s = base_scene();
  Transform t;
  t.translation = {0, 0, -1};  // centre 6 m from the eye
  s.objects.push_back(object(3, make_sphere(1.5f, 64, 128), t));
  const GBuffer g = render(s);
  const std::size_t c = g.index(32, 24);
  EXPECT_EQ(g.object_id[c], 3u);
  EXPECT_NEAR(g.depth[c], 6.0f - 1.5f, 1e-4f);  // a mesh vertex lies exactly on the view axis
  expect_vec3_near(g.normal[c], {0, 0, 1}, 1e-4f);
  // Off-centre pixels on the sphere: unit normals facing the eye.
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (g.object_id[i] == 0) continue;
    EXPECT_NEAR(glm::length(g.normal[i]), 1.0f, 1e-5f);
    EXPECT_GT(g.normal[i].z, 0.0f);
  }
}

TEST(EmbreeBackend, WorldNormalsUseInverseTransposeOfNonUniformScale) {
  // A slab tilted in object space (normal (1,1,0)/sqrt2), scaled 2x in x: the world normal is
  // M^-T n ~ (1/2, 1, 0), i.e. (1,2,0)/sqrt5, not the naive M n ~ (2,1,0).
  Mesh m;
  const glm::vec3 n = glm::normalize(glm::vec3(1, 1, 0));
  m.positions = {{-1, 1, -1}, {1, -1, -1}, {1, -1, 1}, {-1, 1, 1}};
  m.normals.assign(4, n);
  m.indices = {0, 1, 2, 0, 2, 3};
  Scene s = base_scene();
  s.camera.position = {3, 3, 5};
  Transform t;
  t.scale = {2, 1, 1};
  s.objects.push_back(object(1, m, t));
  const GBuffer g = render(s);
  const std::size_t c = g.index(32, 24);
  ASSERT_EQ(g.object_id[c], 1u);
  expect_vec3_near(g.normal[c], glm::normalize(glm::vec3(1, 2, 0)), 1e-5f);

  // Back faces: seen from behind the normal is flipped to face the eye.
  s.camera.position = {-3, -3, 5};
  const GBuffer back = render(s);
  ASSERT_EQ(back.object_id[c], 1u);
  expect_vec3_near(back.normal[c], -glm::normalize(glm::vec3(1, 2, 0)), 1e-5f);
}

TEST(EmbreeBackend, RotatedPlaneNormalAndDepth) {
  Scene s = base_scene();
  Transform t;
  t.rotation_deg = {90, 30, 0};  // R = Ry(30) Rx(90): +Y -> +Z -> (sin30, 0, cos30)
  s.objects.push_back(object(2, make_plane({20, 20}), t));
  const GBuffer g = render(s);
  for (std::size_t i = 0; i < g.size(); ++i) {
    ASSERT_EQ(g.object_id[i], 2u);
    expect_vec3_near(g.normal[i], {0.5f, 0, std::sqrt(3.0f) / 2}, 1e-5f);
  }
  // The plane n.p = 0 with n = (1/2, 0, sqrt3/2) recedes towards +x. A ray (a, b, -1) per unit
  // view depth from (0, 0, 5) meets it at view depth d = 5 n_z / (n_z - a n_x).
  const float tan_x = std::tan(glm::radians(30.0f)) * 65.0f / 49.0f;
  for (const std::uint32_t x : {0u, 10u, 32u, 50u, 64u}) {
    const float a = (2.0f * (static_cast<float>(x) + 0.5f) / 65.0f - 1.0f) * tan_x;
    const float nz = std::sqrt(3.0f) / 2;
    EXPECT_NEAR(g.depth[g.index(x, 24)], 5 * nz / (nz - a * 0.5f), 1e-4f) << x;
    EXPECT_NEAR(g.depth[g.index(x, 0)], g.depth[g.index(x, 24)], 1e-4f);  // constant along y
  }
}

TEST(EmbreeBackend, ObjectMotionIsPixelDisplacement) {
  Scene s = base_scene();
  Object box = object(4, make_box({1, 1, 1}));
  Animation a;
  a.loop = false;
  a.keys = {{0.0, {0, 0, 0}, {0, 0, 0}}, {1.0, {1, 0, 0}, {0, 0, 0}}};
  box.animation = a;
  s.objects.push_back(box);
  const FrameTime time{0.5, 0.4};  // moved +0.1 m in x, front face at depth 4.5 m
  for (EmbreeGeometry geo : kAllGeometry) {
    SCOPED_TRACE(to_string(geo));
    const GBuffer g = render(s, time, false, {EmbreeTraversal::Single, geo, true});
    // Pixel (40, 24) sees the front face (z = 0.5) of the box centred at x = 0.5.
    const std::size_t i = g.index(40, 24);
    ASSERT_EQ(g.object_id[i], 4u);
    EXPECT_NEAR(g.depth[i], 4.5f, 1e-4f);
    const glm::vec3 p_now = s.camera.position + pixel_ray(s.camera, 0.5, 40, 24) * (4.5f / pixel_ray(s.camera, 0.5, 40, 24).z * -1.0f);
    const glm::vec2 expected = project_px(s.camera, 0.5, p_now) - project_px(s.camera, 0.4, p_now - glm::vec3(0.1f, 0, 0));
    // Analytic: 0.1 m at 4.5 m with a 60 degree vertical FOV over 49 rows.
    const float px_per_m = 24.5f / (4.5f * std::tan(glm::radians(30.0f)));
    EXPECT_NEAR(expected.x, 0.1f * px_per_m, 1e-3f);
    EXPECT_NEAR(g.motion[i].x, expected.x, 1e-3f);
    EXPECT_NEAR(g.motion[i].y, 0.0f, 1e-3f);
    // Background and first frame: zero motion.
    EXPECT_EQ(g.motion[g.index(0, 0)], glm::vec2(0.0f));
    const GBuffer first = render(s, {0.5, 0.5}, false, {EmbreeTraversal::Single, geo, true});
    EXPECT_EQ(first.motion[i], glm::vec2(0.0f));
  }
}

TEST(EmbreeBackend, CameraMotionIsPixelDisplacement) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(1, {0, 0, 0}));
  Animation a;
  a.loop = false;
  a.keys = {{0.0, {0, 0, 0}, {0, 0, 0}}, {1.0, {1, 0, 0}, {0, 0, 0}}};
  s.camera.animation = a;
  const GBuffer g = render(s, {0.5, 0.0});
  // The camera moved +0.5 m in x: a static point now in view moved left in the image, by
  // 0.5 m at 5 m everywhere on a fronto-parallel plane.
  const float expected = -0.5f * 24.5f / (5.0f * std::tan(glm::radians(30.0f)));
  for (std::uint32_t y = 0; y < g.height; y += 8) {
    for (std::uint32_t x = 0; x < g.width; x += 8) {
      const std::size_t i = g.index(x, y);
      ASSERT_EQ(g.object_id[i], 1u);
      EXPECT_NEAR(g.motion[i].x, expected, 2e-3f);
      EXPECT_NEAR(g.motion[i].y, 0.0f, 2e-3f);
    }
  }
  // The eye moved too: the centre pixel now looks at x = 0.5.
  const std::size_t c = g.index(32, 24);
  const glm::vec3 p = s.camera.position_at(0.5) + pixel_ray(s.camera, 0.5, 32, 24) * 5.0f;
  EXPECT_NEAR(p.x, 0.5f, 1e-5f);
  const glm::vec2 reprojected = project_px(s.camera, 0.5, p) - project_px(s.camera, 0.0, p);
  EXPECT_NEAR(g.motion[c].x, reprojected.x, 2e-3f);
}

TEST(EmbreeBackend, LambertianColourMatchesShadeLocalAndAnalyticIrradiance) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(1, {0, 0, 0}));
  Light l;
  l.type = LightType::Point;
  l.position = {0, 0, 2};  // 2 m straight above the centre hit point, along its normal
  l.power = glm::vec3(100, 50, 25);
  s.lights.push_back(l);
  for (EmbreeTraversal tr : kAllTraversals) {
    SCOPED_TRACE(to_string(tr));
    const GBuffer g = render(s, {}, false, {tr, EmbreeGeometry::Flattened, true});
    const std::size_t c = g.index(32, 24);
    // Jensen & Pedersen eq. 5.33: E = Phi / (4 pi d^2) cos(theta); L = kd E + kd ambient.
    const glm::vec3 kd = s.materials[0].kd;
    const glm::vec3 expected = kd * (l.power / (4 * kPi * 4.0f)) + kd * s.ambient;
    expect_vec3_near(g.color[c], expected, 1e-5f);
    // Elsewhere: exactly what shade_local gives at the hit point (eye + depth along the ray,
    // scaled to view-axis depth).
    for (std::uint32_t y = 0; y < g.height; y += 6) {
      for (std::uint32_t x = 0; x < g.width; x += 6) {
        const std::size_t i = g.index(x, y);
        const glm::vec3 d = pixel_ray(s.camera, 0, x, y);
        const glm::vec3 p = s.camera.position + d * (g.depth[i] / -d.z);
        const glm::vec3 ref = shade_local(s, s.materials[0], p, g.normal[i], s.camera.position);
        expect_vec3_near(g.color[i], ref, 1e-5f * std::max(1.0f, ref.x));
      }
    }
  }
}

TEST(EmbreeBackend, ShadowsLeaveOnlyAmbient) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(1, {0, 0, 0}));
  Transform t;
  t.translation = {0, 1, 1};  // midway between the centre hit point and the light, off the view axis
  s.objects.push_back(object(2, make_box({0.3f, 0.3f, 0.3f}), t));
  Light l;
  l.position = {0, 2, 2};
  l.power = glm::vec3(200);
  s.lights.push_back(l);
  const std::size_t c = base_scene().camera.width / 2 + std::size_t{base_scene().camera.width} * (base_scene().camera.height / 2);
  const glm::vec3 ambient_only = s.materials[0].kd * s.ambient;
  for (EmbreeGeometry geo : kAllGeometry) {
    SCOPED_TRACE(to_string(geo));
    const GBuffer lit = render(s, {}, false, {EmbreeTraversal::Packet8, geo, true});
    const GBuffer shadowed = render(s, {}, true, {EmbreeTraversal::Packet8, geo, true});
    ASSERT_EQ(lit.object_id[c], 1u);
    EXPECT_GT(lit.color[c].x, ambient_only.x * 10);
    expect_vec3_near(shadowed.color[c], ambient_only, 1e-7f);
    // A pixel far from the shadow is lit the same either way (no self-shadowing acne).
    const std::size_t corner = lit.index(2, 46);
    ASSERT_EQ(lit.object_id[corner], 1u);
    expect_vec3_near(shadowed.color[corner], lit.color[corner], 1e-7f);
  }
}

TEST(EmbreeBackend, EmissiveObjectsDoNotCastShadows) {
  // An emissive panel in front of its light (a Cornell box's ceiling panel) must not shadow the
  // room it lights.
  Scene s = base_scene();
  s.objects.push_back(facing_plane(1, {0, 0, 0}));
  Material e;
  e.name = "lamp";
  e.type = MaterialType::Emissive;
  e.emission = glm::vec3(5);
  s.materials.push_back(e);
  Transform t;
  t.translation = {0, 1, 1};
  s.objects.push_back(object(2, make_box({0.3f, 0.3f, 0.3f}), t, 1));
  Light l;
  l.position = {0, 2, 2};
  s.lights.push_back(l);
  for (EmbreeGeometry geo : kAllGeometry) {
    const GBuffer lit = render(s, {}, false, {EmbreeTraversal::Single, geo, true});
    const GBuffer shadowed = render(s, {}, true, {EmbreeTraversal::Single, geo, true});
    const std::size_t c = lit.index(32, 24);
    expect_vec3_near(shadowed.color[c], lit.color[c], 1e-7f);
  }
}

TEST(EmbreeBackend, BackgroundPixels) {
  Scene s = base_scene();
  Transform t;
  t.translation = {0, 0, 0};
  s.objects.push_back(object(9, make_sphere(0.5f, 16, 32), t));
  for (EmbreeTraversal tr : kAllTraversals) {
    const GBuffer g = render(s, {0.2, 0.1}, true, {tr, EmbreeGeometry::Flattened, true});
    for (const std::size_t i : {g.index(0, 0), g.index(64, 0), g.index(0, 48), g.index(64, 48)}) {
      EXPECT_EQ(g.object_id[i], 0u);
      EXPECT_EQ(g.depth[i], s.camera.far_m);
      EXPECT_EQ(g.color[i], s.background);
      EXPECT_EQ(g.normal[i], glm::vec3(0.0f));
      EXPECT_EQ(g.motion[i], glm::vec2(0.0f));
    }
    EXPECT_EQ(g.object_id[g.index(32, 24)], 9u);
  }
  // An empty scene is all background; so is a scene behind the far plane.
  Scene empty = base_scene();
  const GBuffer e = render(empty);
  for (std::size_t i = 0; i < e.size(); ++i) ASSERT_EQ(e.object_id[i], 0u);
  s.camera.far_m = 4.0f;
  const GBuffer clipped = render(s);
  EXPECT_EQ(clipped.object_id[clipped.index(32, 24)], 0u);
  EXPECT_EQ(clipped.depth[clipped.index(32, 24)], 4.0f);
}

TEST(EmbreeBackend, DegenerateGeometryNeverProducesNanOrInf) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(1, {0, 0, -2}));
  Mesh bad;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  bad.positions = {
      {-1, -1, 0}, {1, -1, 0}, {1, 1, 0},        // a good triangle
      {0, 0, 0.5f}, {0, 0, 0.5f}, {0, 0, 0.5f},  // zero area: three equal points
      {-1, 0, 0.2f}, {0, 0, 0.2f}, {1, 0, 0.2f}, // collinear
      {nan, 0, 0}, {0, inf, 0}, {0, 0, 1},       // non-finite positions
      {-2, -2, 0.1f}, {-1.9f, -2, 0.1f}, {-2, -1.9f, 0.1f},  // tiny, zero normals
  };
  bad.normals = {{0, 0, 1}, {0, 0, -1}, {0, 0, 0},  // interpolates to zero at some points
                 {0, 0, 0}, {0, 0, 0}, {0, 0, 0},  {0, 0, 0}, {0, 0, 0}, {0, 0, 0},
                 {nan, 0, 0}, {0, 0, 0}, {0, 0, 0}, {0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  bad.indices = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 0, 1, 99 /* out of range: dropped */};
  s.objects.push_back(object(2, bad));
  Object flat = object(3, make_sphere(1, 8, 16));  // scaled to nothing
  flat.transform.scale = {0, 0, 0};
  s.objects.push_back(flat);
  Object squashed = object(4, make_box({1, 1, 1}));  // zero thickness in z, animated
  squashed.transform.translation = {1.5f, 1, 0};
  squashed.transform.scale = {1, 1, 0};
  squashed.animation = Animation{{{0.0, {0, 0, 0}, {0, 0, 0}}, {1.0, {0, 0, 0}, {0, 90, 0}}}, true};
  s.objects.push_back(squashed);
  Object no_normals = object(5, make_box({0.5f, 0.5f, 0.5f}));
  std::const_pointer_cast<Mesh>(no_normals.mesh)->normals.clear();
  no_normals.transform.translation = {-1.5f, 1, 0};
  s.objects.push_back(no_normals);
  Object empty = object(6, Mesh{});
  s.objects.push_back(empty);
  Light l;
  l.position = {0, 0, 0.5f};  // on the zero-area triangle
  s.lights.push_back(l);
  Light area;
  area.type = LightType::Area;
  area.position = {0, 2, 1};
  area.direction = {0, 0, 0};  // no direction: shading falls back to straight down
  s.lights.push_back(area);
  for (EmbreeGeometry geo : kAllGeometry) {
    for (EmbreeTraversal tr : kAllTraversals) {
      SCOPED_TRACE(std::string(to_string(geo)) + "/" + to_string(tr));
      for (const FrameTime time : {FrameTime{0, 0}, FrameTime{0.3, 0.2}}) {
        const GBuffer g = render(s, time, true, {tr, geo, true});
        ASSERT_TRUE(all_finite(g));
        for (std::size_t i = 0; i < g.size(); ++i) {
          const float len = glm::length(g.normal[i]);
          if (g.object_id[i] == 0) {
            ASSERT_EQ(len, 0.0f);
          } else {
            ASSERT_NEAR(len, 1.0f, 1e-5f);
          }
        }
        EXPECT_EQ(g.object_id[g.index(32, 24)], 2u);  // the good triangle
      }
    }
  }
}

TEST(EmbreeBackend, DegenerateCameraRendersBackground) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(1, {0, 0, 0}));
  s.camera.up = {0, 0, 1};  // parallel to the view axis
  const GBuffer g = render(s);
  ASSERT_TRUE(all_finite(g));
  s.camera.up = {0, 1, 0};
  s.camera.vertical_fov_deg = 0;
  ASSERT_TRUE(all_finite(render(s)));
}

namespace {
Scene many_objects_scene() {
  Scene s = base_scene(97, 61);
  s.camera.position = {0, 4, 9};
  s.camera.target = {0, 0, 0};
  s.objects.push_back(object(1, make_plane({30, 30})));
  std::uint32_t id = 2;
  for (int i = -3; i <= 3; ++i) {
    for (int j = -3; j <= 3; ++j) {
      Transform t;
      t.translation = {1.2f * static_cast<float>(i), 0.4f, 1.2f * static_cast<float>(j)};
      t.rotation_deg = {0, 17.0f * static_cast<float>(i * j), 0};
      Object o = (i + j) % 2 == 0 ? object(id, make_sphere(0.4f, 12, 24), t) : object(id, make_box({0.6f, 0.8f, 0.6f}), t);
      if (i == j) o.animation = Animation{{{0.0, {0, 0, 0}, {0, 0, 0}}, {1.0, {0, 0.5f, 0}, {0, 90, 0}}}, true};
      s.objects.push_back(o);
      ++id;
    }
  }
  Light l;
  l.position = {2, 5, 3};
  l.power = glm::vec3(300);
  s.lights.push_back(l);
  Light area;
  area.type = LightType::Area;
  area.position = {-2, 4, 0};
  area.area_samples = 2;
  s.lights.push_back(area);
  return s;
}

std::size_t mismatches(const GBuffer& a, const GBuffer& b, float tol) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const bool same = a.object_id[i] == b.object_id[i] && std::abs(a.depth[i] - b.depth[i]) <= tol &&
                      glm::all(glm::lessThanEqual(glm::abs(a.color[i] - b.color[i]), glm::vec3(tol))) &&
                      glm::all(glm::lessThanEqual(glm::abs(a.normal[i] - b.normal[i]), glm::vec3(tol))) &&
                      glm::all(glm::lessThanEqual(glm::abs(a.motion[i] - b.motion[i]), glm::vec2(tol)));
    if (!same) ++n;
  }
  return n;
}
}  // namespace

TEST(EmbreeBackend, SingleAndMultiThreadedAreIdentical) {
  const Scene s = many_objects_scene();
  EmbreeBackend b;
  b.set_scene(s);
  GBuffer one, many, again;
  tbb::task_arena single(1);
  BackendSettings with_shadows;
  with_shadows.shadows = true;
  single.execute([&] { b.render({0.25, 0.2}, with_shadows, one); });
  b.render({0.25, 0.2}, with_shadows, many);
  b.render({0.25, 0.2}, with_shadows, again);
  EXPECT_EQ(mismatches(one, many, 0.0f), 0u);
  EXPECT_EQ(mismatches(many, again, 0.0f), 0u);
  EXPECT_EQ(one.color, many.color);
  EXPECT_EQ(one.depth, many.depth);
  EXPECT_EQ(one.motion, many.motion);
  EXPECT_GT(b.last_frame_stats().shadow_rays, 0u);
  EXPECT_EQ(b.last_frame_stats().primary_rays, std::uint64_t{97} * 61);
}

TEST(EmbreeBackend, TraversalModesAndGeometryModesAgree) {
  const Scene s = many_objects_scene();
  const FrameTime time{0.6, 0.55};
  const GBuffer ref = render(s, time, true, {EmbreeTraversal::Single, EmbreeGeometry::Flattened, true});
  EXPECT_TRUE(all_finite(ref));
  for (EmbreeGeometry geo : kAllGeometry) {
    for (EmbreeTraversal tr : kAllTraversals) {
      SCOPED_TRACE(std::string(to_string(geo)) + "/" + to_string(tr));
      const GBuffer g = render(s, time, true, {tr, geo, true});
      // Packets and instance transforms round differently; allow a few silhouette/shadow-edge
      // pixels to flip.
      EXPECT_LE(mismatches(ref, g, 1e-3f), ref.size() / 500);
    }
  }
}

TEST(EmbreeBackend, AnimatedObjectsFollowTimeAcrossFrames) {
  // Rendering the same backend at successive times must match a fresh backend at each time
  // (BVH updates of animated objects are not stale).
  const Scene s = many_objects_scene();
  for (EmbreeGeometry geo : kAllGeometry) {
    EmbreeBackend b({EmbreeTraversal::Packet8, geo, true});
    b.set_scene(s);
    for (double t : {0.0, 0.3, 0.7, 0.3}) {
      GBuffer g;
      b.render({t, t}, BackendSettings{}, g);
      const GBuffer fresh = render(s, {t, t}, false, {EmbreeTraversal::Packet8, geo, true});
      EXPECT_EQ(mismatches(g, fresh, 1e-5f), 0u) << to_string(geo) << " t=" << t;
    }
  }
}

TEST(EmbreeBackend, ShadingOffLeavesColourZeroOnObjects) {
  Scene s = base_scene();
  s.objects.push_back(facing_plane(1, {0, 0, 0}));
  const GBuffer g = render(s, {}, false, {EmbreeTraversal::Packet8, EmbreeGeometry::Flattened, false});
  EXPECT_EQ(g.color[g.index(3, 3)], glm::vec3(0.0f));
  EXPECT_EQ(g.object_id[g.index(3, 3)], 1u);
}

// The hidden layer (depth peeling by object, Lee 2009 §5.1.2): behind a sphere in front of a wall
// lies the wall (the sphere's own back faces are skipped), behind the wall nothing (background).
TEST(EmbreeBackend, HiddenLayerShowsTheNextObjectBehindTheVisibleOne) {
  for (EmbreeGeometry geometry : kAllGeometry) {
    Scene s = base_scene();
    s.objects.push_back(facing_plane(1, {0, 0, -2}));  // wall 7 m away
    Transform at;
    at.translation = {0, 0, 2};
    s.objects.push_back(object(2, make_sphere(0.5f, 24, 48), at));  // sphere 3 m away
    EmbreeOptions o;
    o.geometry = geometry;
    EmbreeBackend b(o);
    b.set_scene(s);
    GBuffer visible, hidden;
    b.render({}, {}, visible);
    BackendSettings bs;
    bs.peel = 1;
    b.render({}, bs, hidden);
    const std::size_t centre = visible.index(32, 24), corner = visible.index(1, 1);
    EXPECT_EQ(visible.object_id[centre], 2u);
    EXPECT_NEAR(visible.depth[centre], 2.5f, 1e-3f);
    EXPECT_EQ(hidden.object_id[centre], 1u);  // the wall, not the sphere's back face
    EXPECT_NEAR(hidden.depth[centre], 7.0f, 1e-3f);
    EXPECT_EQ(visible.object_id[corner], 1u);
    EXPECT_EQ(hidden.object_id[corner], 0u);  // nothing behind the wall
    EXPECT_EQ(hidden.depth[corner], s.camera.far_m);
    // Two objects deep: behind the sphere and the wall, the back plane (10 m away).
    Scene deeper = s;
    deeper.objects.push_back(facing_plane(3, {0, 0, -5}, {60, 60}));
    EmbreeBackend b3(o);
    b3.set_scene(deeper);
    GBuffer second;
    bs.peel = 2;
    b3.render({}, bs, second);
    EXPECT_EQ(second.object_id[centre], 3u);
    EXPECT_NEAR(second.depth[centre], 10.0f, 1e-3f);
    EXPECT_EQ(second.object_id[corner], 0u);  // wall then back plane: nothing two objects deep
  }
}

namespace {

// A sphere with two coarser levels (simplified through the LOD chain code scenes use).
fovea::render::Scene lod_scene(fovea::render::EmbreeGeometry) {
  using namespace fovea::render;
  Scene s;
  s.camera.position = {0, 0, 3};
  s.camera.target = {0, 0, 0};
  s.camera.width = 64;
  s.camera.height = 64;
  Material m;
  m.kd = glm::vec3(0.5f);
  s.materials.push_back(m);
  Object o;
  o.name = "ball";
  o.id = 7;
  o.mesh = std::make_shared<Mesh>(make_sphere(1.0f, 32, 64));
  for (double ratio : {0.1, 0.01}) {
    SimplifiedMesh r = simplify_mesh(join_identical_vertices(*o.mesh), ratio, SeamHandling::Keep);
    o.lods.push_back({std::make_shared<const Mesh>(std::move(r.mesh)), r.error_m});
  }
  s.objects.push_back(o);
  Light l;
  l.position = {0, 3, 3};
  s.lights.push_back(l);
  return s;
}

}  // namespace

// set_lod_levels: what intersect() sees after a render at other levels (the GI pass tracing the
// frame's geometry after ULOD's next-coarser render).
TEST(EmbreeBackend, SetLodLevelsChoosesWhatRaysHit) {
  using namespace fovea::render;
  EmbreeBackend b;
  b.set_scene(lod_scene(EmbreeGeometry::Flattened));
  const auto depth_along = [&](glm::vec3 dir) {
    SurfaceHit hit;
    EXPECT_TRUE(b.intersect({0, 0, 3}, glm::normalize(dir), 0.0f, 100.0f, RayVisibility::All, hit));
    return hit.t;
  };
  // A ray between the coarsest level's vertices: the full sphere and the coarse mesh differ there.
  const glm::vec3 dir(0.13f, 0.07f, -1.0f);
  GBuffer g;
  b.render({}, {}, g);
  const float full = depth_along(dir);
  BackendSettings coarse;
  coarse.lod_levels = {2};
  b.render({}, coarse, g);
  const float at_coarse = depth_along(dir);
  EXPECT_NE(full, at_coarse);
  b.set_lod_levels({});
  EXPECT_EQ(depth_along(dir), full);
  b.set_lod_levels({2});
  EXPECT_EQ(depth_along(dir), at_coarse);
}

// BackendSettings::lod_levels switches the drawn mesh per object, per frame, in both geometry
// modes; levels beyond the chain clamp to its coarsest; the object keeps its id.
TEST(EmbreeBackend, LevelsOfDetailSwitchPerFrame) {
  using namespace fovea::render;
  for (EmbreeGeometry geometry : {EmbreeGeometry::Flattened, EmbreeGeometry::Instanced}) {
    EmbreeOptions opt;
    opt.geometry = geometry;
    EmbreeBackend b(opt);
    b.set_scene(lod_scene(geometry));
    GBuffer full, coarse, clamped, back;
    BackendSettings bs;
    b.render({}, bs, full);
    bs.lod_levels = {2};
    b.render({}, bs, coarse);
    bs.lod_levels = {200};
    b.render({}, bs, clamped);
    bs.lod_levels = {};
    b.render({}, bs, back);
    double depth_diff = 0;
    std::size_t ids = 0;
    for (std::size_t i = 0; i < full.size(); ++i) {
      if (full.object_id[i] == 7 && coarse.object_id[i] == 7) {
        depth_diff = std::max(depth_diff, static_cast<double>(std::abs(full.depth[i] - coarse.depth[i])));
        ++ids;
      }
    }
    EXPECT_GT(ids, 500u) << to_string(geometry);
    EXPECT_GT(depth_diff, 1e-3) << to_string(geometry);  // a 40-triangle sphere is visibly faceted
    EXPECT_EQ(clamped.depth, coarse.depth) << to_string(geometry);
    EXPECT_EQ(back.depth, full.depth) << to_string(geometry);
  }
}

namespace fovea::render {
namespace {

TEST(EmbreeBackend, SmallerResolutionIsTheCameraAtThatResolution) {
  // BackendSettings::width/height (the attention proxy): the same image as a camera of that size.
  Scene s = many_objects_scene();
  s.camera.width = 96;
  s.camera.height = 64;
  EmbreeBackend full;
  full.set_scene(s);
  BackendSettings small_settings;
  small_settings.width = 33;
  small_settings.height = 22;
  GBuffer small;
  full.render({0.25, 0.2}, small_settings, small);
  ASSERT_EQ(small.width, 33u);
  ASSERT_EQ(small.height, 22u);
  s.camera.width = 33;
  s.camera.height = 22;
  EmbreeBackend direct;
  direct.set_scene(s);
  GBuffer expected;
  direct.render({0.25, 0.2}, BackendSettings{}, expected);
  EXPECT_EQ(mismatches(small, expected, 0.0f), 0u);
}

TEST(EmbreeBackend, PixelMaskTracesOnlyTilesWithMarkedPixelsAndThoseExactly) {
  const Scene s = many_objects_scene();
  EmbreeBackend b;
  b.set_scene(s);
  GBuffer all, masked;
  b.render({0.25, 0.2}, BackendSettings{}, all);
  BackendSettings m;
  m.pixel_mask.assign(all.size(), 0);
  m.pixel_mask[all.index(50, 30)] = 1;  // one pixel: its 16x16 tile is traced, the rest is background
  b.render({0.25, 0.2}, m, masked);
  EXPECT_EQ(masked.object_id[all.index(50, 30)], all.object_id[all.index(50, 30)]);
  EXPECT_EQ(masked.color[all.index(50, 30)], all.color[all.index(50, 30)]);
  std::size_t background = 0;
  for (std::size_t i = 0; i < masked.size(); ++i) background += masked.object_id[i] == 0 ? 1u : 0u;
  EXPECT_GE(background, masked.size() - 256);
  EXPECT_LT(background, masked.size());
  BackendSettings wrong_size;  // a mask of another size is ignored: everything is traced
  wrong_size.pixel_mask.assign(7, 0);
  b.render({0.25, 0.2}, wrong_size, masked);
  EXPECT_EQ(mismatches(masked, all, 0.0f), 0u);
}

}  // namespace
}  // namespace fovea::render
