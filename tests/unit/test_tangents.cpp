// SPDX-License-Identifier: Apache-2.0
// MikkTSpace's rules for generated tangents (scene/tangents.h): one frame per group of triangles
// around a vertex, groups split at mirrored UV seams, welded duplicates, degenerate triangles.
#include <gtest/gtest.h>

#include <cmath>

#include "scene/tangents.h"

using namespace fovea::render;

namespace {

// A w x 1 strip of unit quads in the z = 0 plane (normal +z), x to the right, y up; vertex (c, r) at
// (c, r). uv_u(c) gives each column's u; v = 1 - y (glTF's v runs down the image).
Mesh strip(int columns, float (*uv_u)(int)) {
  Mesh m;
  for (int r = 0; r <= 1; ++r)
    for (int c = 0; c <= columns; ++c) {
      m.positions.push_back({static_cast<float>(c), static_cast<float>(r), 0});
      m.normals.push_back({0, 0, 1});
      m.texcoords0.push_back({uv_u(c), 1.0f - static_cast<float>(r)});
      m.colors.push_back({static_cast<float>(c), 0, 0, 1});
    }
  const auto at = [columns](int c, int r) { return static_cast<std::uint32_t>(r * (columns + 1) + c); };
  for (int c = 0; c < columns; ++c)
    m.indices.insert(m.indices.end(), {at(c, 0), at(c + 1, 0), at(c + 1, 1), at(c, 0), at(c + 1, 1), at(c, 1)});
  return m;
}

glm::vec3 corner_tangent(const Mesh& m, std::size_t corner) { return glm::vec3(m.tangents[m.indices[corner]]); }

}  // namespace

TEST(Tangents, AFlatQuadGetsUAlongXAndTheBitangentUpTheImage) {
  Mesh m = strip(1, [](int c) { return static_cast<float>(c); });
  generate_mikktspace_tangents(m, 0);
  ASSERT_EQ(m.tangents.size(), 4u);
  for (const glm::vec4& t : m.tangents) {
    EXPECT_NEAR(t.x, 1.0f, 1e-6f);
    EXPECT_NEAR(t.y, 0.0f, 1e-6f);
    // cross(n, t) * w = +y: up the image, where v decreases.
    EXPECT_EQ(t.w, 1.0f);
  }
}

TEST(Tangents, AMirroredSeamSplitsItsSharedVerticesIntoTwoFrames) {
  // u runs 0 -> 1 -> 0: the right quad is the left one mirrored, sharing the seam's vertices (u = 1).
  Mesh m = strip(2, [](int c) { return c == 1 ? 1.0f : 0.0f; });
  const std::size_t before = m.positions.size();
  generate_mikktspace_tangents(m, 0);
  // Both seam vertices split once; every attribute follows.
  ASSERT_EQ(m.positions.size(), before + 2);
  EXPECT_EQ(m.colors.size(), m.positions.size());
  EXPECT_EQ(m.texcoords0.size(), m.positions.size());
  EXPECT_EQ(m.tangents.size(), m.positions.size());
  for (std::size_t c = 0; c < m.indices.size(); ++c) {
    const bool right = c >= 6;
    const glm::vec4 t = m.tangents[m.indices[c]];
    EXPECT_NEAR(t.x, right ? -1.0f : 1.0f, 1e-6f) << "corner " << c;
    // The right side's tangent points left, and its bitangent still up the image: w = -1.
    EXPECT_EQ(t.w, right ? -1.0f : 1.0f) << "corner " << c;
  }
  // A split copy keeps its vertex's other attributes.
  for (std::size_t i = before; i < m.positions.size(); ++i) {
    EXPECT_EQ(m.positions[i].x, 1.0f);
    EXPECT_EQ(m.colors[i].r, 1.0f);
  }
}

TEST(Tangents, DuplicatesAnExporterWroteAreWeldedAndShareOneFrame) {
  // Two triangles of a bent hinge, unindexed (each corner its own vertex): at the hinge's vertices
  // the frames of both triangles are averaged as if the vertices were shared.
  Mesh m;
  const glm::vec3 n = glm::normalize(glm::vec3(0, 0.3f, 1));
  const auto add = [&](glm::vec3 p, glm::vec2 uv) {
    m.positions.push_back(p);
    m.normals.push_back(n);
    m.texcoords0.push_back(uv);
    m.indices.push_back(static_cast<std::uint32_t>(m.indices.size()));
  };
  // Triangle 1: u along +x. Triangle 2 (sharing the edge (0,0,0)-(0,1,0)): u along a direction tilted in z.
  add({0, 0, 0}, {0, 1}), add({1, 0, 0}, {1, 1}), add({0, 1, 0}, {0, 0});
  add({0, 0, 0}, {0, 1}), add({0, 1, 0}, {0, 0}), add({-1, 0, 0.6f}, {-1, 1});
  generate_mikktspace_tangents(m, 0);
  // The corners at the hinge (0,0,0): corner 0 and corner 3 get the same tangent.
  EXPECT_NEAR(glm::length(corner_tangent(m, 0) - corner_tangent(m, 3)), 0.0f, 1e-6f);
  // And it is the group's: a blend of both triangles' directions, not either one alone.
  const glm::vec3 t = corner_tangent(m, 0);
  EXPECT_NEAR(glm::length(t), 1.0f, 1e-5f);
  EXPECT_NEAR(glm::dot(t, n), 0.0f, 1e-5f);
  EXPECT_GT(t.x, 0.9f);
  EXPECT_GT(std::abs(t.z) + std::abs(t.y), 1e-3f);
  // The corner (1,0,0) belongs to triangle 1 alone: its own dP/du in the normal's plane.
  const glm::vec3 own = glm::normalize(glm::vec3(1, 0, 0) - n * glm::dot(n, glm::vec3(1, 0, 0)));
  EXPECT_NEAR(glm::length(corner_tangent(m, 1) - own), 0.0f, 1e-5f);
}

TEST(Tangents, TrianglesAreWeightedByTheirAngleAtTheVertex) {
  // A fan at the origin in z = 0: a wide triangle (90 deg there) and a thin one (atan 0.2, about
  // 11.3 deg) sharing the edge to (1, 0, 0), of one UV orientation, with dP/du along (1, 0.5) and
  // (1.5, 0.1). MikkTSpace weights each unit direction by the angle at the vertex (not by area).
  Mesh m;
  const auto add = [&](glm::vec3 p, glm::vec2 uv) {
    m.positions.push_back(p);
    m.normals.push_back({0, 0, 1});
    m.texcoords0.push_back(uv);
    return static_cast<std::uint32_t>(m.positions.size() - 1);
  };
  const std::uint32_t o = add({0, 0, 0}, {0, 0}), a = add({1, 0, 0}, {1, 0.5f}), b = add({0, -1, 0}, {0, 1});
  const std::uint32_t c = add({1, 0.2f, 0}, {0, -1});
  m.indices = {o, b, a, o, a, c};
  generate_mikktspace_tangents(m, 0);
  ASSERT_EQ(m.positions.size(), 4u);  // one group: nothing split
  const glm::vec3 wide = glm::normalize(glm::vec3(1, 0.5f, 0)), thin = glm::normalize(glm::vec3(1.5f, 0.1f, 0));
  const float pi = 3.14159265f;
  const glm::vec3 expected = glm::normalize(pi / 2 * wide + std::atan(0.2f) * thin);
  const glm::vec3 t = corner_tangent(m, 0);
  EXPECT_NEAR(glm::length(t - expected), 0.0f, 1e-5f);
  EXPECT_EQ(m.tangents[o].w, 1.0f);
}

TEST(Tangents, ADegenerateTriangleTakesItsNeighboursFrame) {
  Mesh m = strip(1, [](int c) { return static_cast<float>(c); });
  // A third triangle with no UV area, on the quad's corner vertex 0.
  m.positions.push_back({-1, 0, 0});
  m.normals.push_back({0, 0, 1});
  m.texcoords0.push_back({0, 1});
  m.colors.push_back({0, 0, 0, 1});
  m.indices.insert(m.indices.end(), {4, 0, 2});  // vertex 2 is (0, 1): all three at u = 0
  m.texcoords0[4] = m.texcoords0[0];
  generate_mikktspace_tangents(m, 0);
  for (std::size_t c = 6; c < 9; ++c) {
    const glm::vec4 t = m.tangents[m.indices[c]];
    EXPECT_NEAR(glm::length(glm::vec3(t)), 1.0f, 1e-5f) << c;
    EXPECT_TRUE(t.w == 1.0f || t.w == -1.0f);
  }
  EXPECT_NEAR(corner_tangent(m, 7).x, 1.0f, 1e-6f);  // vertex 0: the quad's frame
}

TEST(Tangents, MissingCoordinatesAreRefused) {
  Mesh m = strip(1, [](int c) { return static_cast<float>(c); });
  EXPECT_THROW(generate_mikktspace_tangents(m, 1), std::invalid_argument);
}
