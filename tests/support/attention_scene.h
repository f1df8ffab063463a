// SPDX-License-Identifier: Apache-2.0
#pragma once
// Small scenes for the attention tests: a camera at the origin looking down -z and unit-ish boxes
// placed by the test, with their task importance.
#include <limits>
#include <memory>
#include <random>
#include <string>

#include "backend/gbuffer.h"
#include "scene/geometry.h"
#include "scene/scene.h"

namespace fovea::render::test {

inline Scene make_scene() {
  Scene s;
  s.camera.position = {0, 0, 0};
  s.camera.target = {0, 0, -1};
  s.camera.near_m = 0.1f;
  s.camera.far_m = 100.0f;
  s.materials.push_back(Material{});
  return s;
}

inline Object& add_object(Scene& s, std::uint32_t id, glm::vec3 at, float importance) {
  Object o;
  o.name = "object" + std::to_string(id);
  o.id = id;
  o.mesh = std::make_shared<Mesh>(make_box({0.5f, 0.5f, 0.5f}));
  o.transform.translation = at;
  o.task_importance = importance;
  s.objects.push_back(o);
  return s.objects.back();
}

// Paints a rectangle [x0, x1) x [y0, y1) of object `id` into a G-buffer.
inline void paint(GBuffer& g, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1,
                         std::uint32_t id, glm::vec3 colour, float depth) {
  for (std::uint32_t y = y0; y < y1; ++y) {
    for (std::uint32_t x = x0; x < x1; ++x) {
      const std::size_t i = g.index(x, y);
      g.color[i] = colour;
      g.depth[i] = depth;
      g.object_id[i] = id;
    }
  }
}

// The stability catalogue's random case: 1-40 boxes (object k has id k * id_stride + id_offset, a
// fifth of them background, some animated) and a random G-buffer of up to 200x150 whose ids include
// some the scene does not know, with about 1 % NaN / +-Inf / -1 / 1e30 / 0 in colour and depth.
struct RandomCase {
  Scene scene;
  GBuffer g;
};
inline RandomCase random_attention_case(std::mt19937& rng, std::uint32_t id_stride = 1, std::uint32_t id_offset = 0) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float specials[] = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity(), -1.0f, 1e30f, 0.0f};
  RandomCase c{make_scene(), {}};
  const auto objects = static_cast<std::uint32_t>(1 + rng() % 40);
  for (std::uint32_t k = 1; k <= objects; ++k) {
    Object& o = add_object(c.scene, k * id_stride + id_offset, {u(rng) * 20 - 10, u(rng) * 4 - 2, -u(rng) * 30},
                           u(rng) < 0.2f ? 0.0f : u(rng));
    if (u(rng) < 0.3f) {
      Animation a;
      a.loop = u(rng) < 0.5f;
      a.keys = {{0, {}, {}}, {1 + u(rng), {u(rng), u(rng), u(rng) * 5}, {0, u(rng) * 360, 0}}};
      o.animation = a;
    }
  }
  const auto w = 1 + rng() % 200, h = 1 + rng() % 150;
  GBuffer& g = c.g;
  g.resize(static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h));
  for (std::size_t i = 0; i < g.size(); ++i) {
    g.color[i] = glm::vec3(u(rng) * 3, u(rng), u(rng) * 0.5f);
    g.depth[i] = u(rng) * 120;
    g.object_id[i] = static_cast<std::uint32_t>(rng() % (objects + 3)) * id_stride + id_offset;  // some unknown ids
    if (u(rng) < 0.01f) g.color[i].y = specials[rng() % 6];
    if (u(rng) < 0.01f) g.depth[i] = specials[rng() % 6];
  }
  return c;
}

}  // namespace fovea::render::test
