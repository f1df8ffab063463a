// SPDX-License-Identifier: Apache-2.0
#include "scene/geometry.h"

#include <cmath>
#include <numbers>

namespace fovea::render {

namespace {
constexpr float kPi = std::numbers::pi_v<float>;

void add_quad(Mesh& m, glm::vec3 origin, glm::vec3 u, glm::vec3 v) {
  const glm::vec3 n = glm::normalize(glm::cross(u, v));
  const auto base = static_cast<std::uint32_t>(m.positions.size());
  for (const glm::vec3 p : {origin, origin + u, origin + u + v, origin + v}) {
    m.positions.push_back(p);
    m.normals.push_back(n);
  }
  for (const std::uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) m.indices.push_back(base + i);
}
}  // namespace

Mesh make_box(glm::vec3 size) {
  Mesh m;
  const glm::vec3 h = size * 0.5f;
  const glm::vec3 x{size.x, 0, 0}, y{0, size.y, 0}, z{0, 0, size.z};
  add_quad(m, {-h.x, -h.y, h.z}, x, y);    // +Z
  add_quad(m, {h.x, -h.y, -h.z}, -x, y);   // -Z
  add_quad(m, {h.x, -h.y, h.z}, -z, y);    // +X
  add_quad(m, {-h.x, -h.y, -h.z}, z, y);   // -X
  add_quad(m, {-h.x, h.y, h.z}, x, -z);    // +Y
  add_quad(m, {-h.x, -h.y, -h.z}, x, z);   // -Y
  return m;
}

Mesh make_sphere(float radius, int rings, int segments) {
  Mesh m;
  for (int r = 0; r <= rings; ++r) {
    const float theta = kPi * static_cast<float>(r) / static_cast<float>(rings);
    for (int s = 0; s <= segments; ++s) {
      const float phi = 2 * kPi * static_cast<float>(s) / static_cast<float>(segments);
      const glm::vec3 n{std::sin(theta) * std::cos(phi), std::cos(theta), -std::sin(theta) * std::sin(phi)};
      m.positions.push_back(n * radius);
      m.normals.push_back(n);
    }
  }
  const auto row = static_cast<std::uint32_t>(segments + 1);
  for (std::uint32_t r = 0; r < static_cast<std::uint32_t>(rings); ++r) {
    for (std::uint32_t s = 0; s < static_cast<std::uint32_t>(segments); ++s) {
      const std::uint32_t a = r * row + s, b = a + row;
      if (r != 0) m.indices.insert(m.indices.end(), {a, b, a + 1});
      if (r + 1 != static_cast<std::uint32_t>(rings)) m.indices.insert(m.indices.end(), {a + 1, b, b + 1});
    }
  }
  return m;
}

Mesh make_plane(glm::vec2 size) {
  Mesh m;
  add_quad(m, {-size.x / 2, 0, size.y / 2}, {size.x, 0, 0}, {0, 0, -size.y});
  return m;
}

Mesh make_cylinder(float radius, float height, int segments) {
  Mesh m;
  const float h = height / 2;
  const auto seg = static_cast<std::uint32_t>(segments);
  for (std::uint32_t s = 0; s <= seg; ++s) {  // side
    const float phi = 2 * kPi * static_cast<float>(s) / static_cast<float>(segments);
    const glm::vec3 n{std::cos(phi), 0, -std::sin(phi)};
    m.positions.push_back(n * radius + glm::vec3(0, -h, 0));
    m.normals.push_back(n);
    m.positions.push_back(n * radius + glm::vec3(0, h, 0));
    m.normals.push_back(n);
  }
  for (std::uint32_t s = 0; s < seg; ++s) {
    const std::uint32_t a = 2 * s;
    m.indices.insert(m.indices.end(), {a, a + 2, a + 1, a + 1, a + 2, a + 3});
  }
  for (const float sign : {1.0f, -1.0f}) {  // caps
    const auto centre = static_cast<std::uint32_t>(m.positions.size());
    m.positions.push_back({0, sign * h, 0});
    m.normals.push_back({0, sign, 0});
    for (std::uint32_t s = 0; s <= seg; ++s) {
      const float phi = 2 * kPi * static_cast<float>(s) / static_cast<float>(segments);
      m.positions.push_back(glm::vec3(std::cos(phi) * radius, sign * h, -std::sin(phi) * radius));
      m.normals.push_back({0, sign, 0});
    }
    for (std::uint32_t s = 0; s < seg; ++s) {
      const std::uint32_t a = centre + 1 + s;
      if (sign > 0) {
        m.indices.insert(m.indices.end(), {centre, a, a + 1});
      } else {
        m.indices.insert(m.indices.end(), {centre, a + 1, a});
      }
    }
  }
  return m;
}

}  // namespace fovea::render
