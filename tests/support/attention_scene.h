#pragma once
// Small scenes for the attention tests: a camera at the origin looking down -z and unit-ish boxes
// placed by the test, with their task importance.
#include <memory>
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

}  // namespace fovea::render::test
