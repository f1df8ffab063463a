// SPDX-License-Identifier: Apache-2.0
#pragma once
// Procedurally built scenes shared by the GL backend tests and bench/bench_gl.cpp: a Cornell-box-like
// room with a sphere, and a many-objects scene with object and camera animation.
#include <cmath>
#include <memory>
#include <string>

#include "scene/geometry.h"
#include "scene/scene.h"

namespace fovea::render::testing {

inline Material lambertian(const std::string& name, glm::vec3 kd) {
  Material m;
  m.name = name;
  m.type = MaterialType::Lambertian;
  m.kd = kd;
  return m;
}

inline Material blinn_phong(const std::string& name, glm::vec3 kd, glm::vec3 ks, float shininess) {
  Material m = lambertian(name, kd);
  m.type = MaterialType::BlinnPhong;
  m.ks = ks;
  m.shininess = shininess;
  return m;
}

inline Material emissive(const std::string& name, glm::vec3 emission) {
  Material m = lambertian(name, glm::vec3(0.2f));
  m.type = MaterialType::Emissive;
  m.emission = emission;
  return m;
}

inline Object object(Scene& scene, const std::string& name, std::shared_ptr<const Mesh> mesh, std::uint32_t material,
                     glm::vec3 translation, glm::vec3 rotation_deg = glm::vec3(0.0f),
                     glm::vec3 scale = glm::vec3(1.0f)) {
  Object o;
  o.name = name;
  o.id = static_cast<std::uint32_t>(scene.objects.size() + 1);
  o.mesh = std::move(mesh);
  o.material = material;
  o.transform.translation = translation;
  o.transform.rotation_deg = rotation_deg;
  o.transform.scale = scale;
  return o;
}

// A 4 x 3 x 4 m room open towards the camera: red left wall, green right wall, white floor, ceiling
// and back wall, an emissive ceiling panel, a glossy sphere, a rotated box; a point light, an area
// light under the ceiling (4 x 4 samples) and a spot light.
inline Scene cornell_box(std::uint32_t width = 320, std::uint32_t height = 240) {
  Scene s;
  s.name = "cornell-box (procedural)";
  s.camera.position = {0, 1.5f, 6.0f};
  s.camera.target = {0, 1.4f, 0};
  s.camera.vertical_fov_deg = 45;
  s.camera.width = width;
  s.camera.height = height;
  s.camera.near_m = 0.1f;
  s.camera.far_m = 50;
  s.ambient = glm::vec3(0.03f);
  s.background = glm::vec3(0.1f, 0.15f, 0.2f);
  s.materials = {lambertian("white", glm::vec3(0.75f)), lambertian("red", {0.75f, 0.1f, 0.1f}),
                 lambertian("green", {0.1f, 0.7f, 0.15f}),
                 blinn_phong("glossy", {0.3f, 0.3f, 0.6f}, glm::vec3(0.6f), 40.0f),
                 emissive("panel", glm::vec3(6.0f, 5.5f, 5.0f)), blinn_phong("box", {0.6f, 0.55f, 0.4f}, glm::vec3(0.2f), 8.0f)};
  const auto wall = std::make_shared<const Mesh>(make_plane({4.0f, 4.0f}));
  const auto side = std::make_shared<const Mesh>(make_plane({4.0f, 3.0f}));
  const auto panel = std::make_shared<const Mesh>(make_plane({1.0f, 1.0f}));
  s.objects.push_back(object(s, "floor", wall, 0, {0, 0, 0}));
  s.objects.push_back(object(s, "ceiling", wall, 0, {0, 3, 0}, {180, 0, 0}));
  s.objects.push_back(object(s, "back", std::make_shared<const Mesh>(make_plane({4.0f, 3.0f})), 0, {0, 1.5f, -2},
                             {90, 0, 0}));
  // make_plane is in XZ with normal +Y; rotate about Z so the normal points into the room.
  s.objects.push_back(object(s, "left", side, 1, {-2, 1.5f, 0}, {0, 90, -90}));
  s.objects.push_back(object(s, "right", side, 2, {2, 1.5f, 0}, {0, 90, 90}));
  s.objects.push_back(object(s, "panel", panel, 4, {0, 2.98f, 0}, {180, 0, 0}));
  s.objects.push_back(object(s, "sphere", std::make_shared<const Mesh>(make_sphere(0.6f, 48, 96)), 3, {-0.7f, 0.6f, 0.3f}));
  s.objects.push_back(object(s, "box", std::make_shared<const Mesh>(make_box({0.8f, 1.4f, 0.8f})), 5, {0.8f, 0.7f, -0.6f},
                             {0, 25, 0}));
  Light point;
  point.type = LightType::Point;
  point.position = {0.5f, 2.5f, 1.5f};
  point.power = glm::vec3(60.0f);
  Light area;
  area.type = LightType::Area;
  area.position = {0, 2.9f, 0};
  area.direction = {0, -1, 0};
  area.area_size = {1.0f, 1.0f};
  area.area_samples = 4;
  area.power = glm::vec3(80.0f, 75.0f, 70.0f);
  Light spot;
  spot.type = LightType::Spot;
  spot.position = {-1.5f, 2.8f, 2.0f};
  spot.direction = glm::normalize(glm::vec3(0.8f, -1.0f, -1.2f));
  spot.spot_cutoff_deg = 25;
  spot.spot_falloff_deg = 8;
  spot.power = glm::vec3(120.0f, 100.0f, 60.0f);
  s.lights = {point, area, spot};
  return s;
}

// `count` objects (spheres, boxes, cylinders) on a jittered grid over a floor, a third of them
// animated (translation and rotation keys), and an animated camera.
inline Scene many_objects(int count = 120, std::uint32_t width = 320, std::uint32_t height = 240) {
  Scene s;
  s.name = "many-objects (procedural)";
  s.camera.position = {0, 4.0f, 9.0f};
  s.camera.target = {0, 0.5f, 0};
  s.camera.vertical_fov_deg = 50;
  s.camera.width = width;
  s.camera.height = height;
  s.camera.near_m = 0.1f;
  s.camera.far_m = 60;
  s.camera.animation = Animation{{{0.0, {0, 0, 0}, {}}, {2.0, {1.0f, 0.3f, -0.5f}, {}}}, true};
  s.ambient = glm::vec3(0.02f);
  s.background = glm::vec3(0.05f);
  s.materials = {lambertian("floor", glm::vec3(0.6f)), lambertian("red", {0.8f, 0.2f, 0.2f}),
                 blinn_phong("blue", {0.2f, 0.3f, 0.8f}, glm::vec3(0.5f), 30.0f),
                 blinn_phong("gold", {0.7f, 0.5f, 0.1f}, glm::vec3(0.8f, 0.7f, 0.4f), 60.0f),
                 emissive("lamp", glm::vec3(4.0f, 4.0f, 3.0f))};
  s.objects.push_back(object(s, "floor", std::make_shared<const Mesh>(make_plane({20.0f, 20.0f})), 0, {0, 0, 0}));
  const auto sphere = std::make_shared<const Mesh>(make_sphere(0.35f, 16, 32));
  const auto box = std::make_shared<const Mesh>(make_box({0.5f, 0.6f, 0.4f}));
  const auto cylinder = std::make_shared<const Mesh>(make_cylinder(0.25f, 0.8f, 24));
  const int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(count))));
  for (int i = 0; i < count; ++i) {
    const int gx = i % side, gz = i / side;
    // Deterministic jitter (no RNG: identical scenes in every run).
    const float jx = 0.3f * std::sin(1.7f * static_cast<float>(i)), jz = 0.3f * std::cos(2.3f * static_cast<float>(i));
    const glm::vec3 p{(static_cast<float>(gx) - static_cast<float>(side - 1) / 2) * 1.1f + jx, 0.45f,
                      (static_cast<float>(gz) - static_cast<float>(side - 1) / 2) * 1.1f + jz};
    const auto& mesh = i % 3 == 0 ? sphere : i % 3 == 1 ? box : cylinder;
    const auto material = static_cast<std::uint32_t>(1 + i % 4);
    Object o = object(s, "object" + std::to_string(i), mesh, material, p, {0, static_cast<float>(i * 17 % 360), 0});
    if (i % 3 == 1) {
      o.animation = Animation{{{0.0, {0, 0, 0}, {0, 0, 0}},
                               {1.0, {0.3f * std::sin(static_cast<float>(i)), 0.2f, 0.3f}, {0, 90, 10}},
                               {2.0, {0, 0, 0}, {0, 180, 0}}},
                              true};
    }
    s.objects.push_back(std::move(o));
  }
  for (int i = 0; i < 4; ++i) {
    Light l;
    l.type = LightType::Point;
    l.position = {static_cast<float>(i % 2) * 6 - 3, 3.5f, static_cast<float>(i / 2) * 6 - 3};
    l.power = glm::vec3(50.0f + 10.0f * static_cast<float>(i));
    s.lights.push_back(l);
  }
  Light spot;
  spot.type = LightType::Spot;
  spot.position = {0, 6, 2};
  spot.direction = {0, -1, -0.3f};
  spot.spot_cutoff_deg = 35;
  spot.spot_falloff_deg = 10;
  spot.power = glm::vec3(300.0f);
  s.lights.push_back(spot);
  return s;
}

}  // namespace fovea::render::testing
