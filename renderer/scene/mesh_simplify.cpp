// SPDX-License-Identifier: Apache-2.0
#include "scene/mesh_simplify.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace fovea::render {

namespace {

// Which optional attributes a mesh carries (one per position) and a vertex's full record of them.
struct AttributeSet {
  bool normals, uv0, uv1, colors, tangents;
  explicit AttributeSet(const Mesh& m)
      : normals(m.normals.size() == m.positions.size()),
        uv0(m.texcoords0.size() == m.positions.size()),
        uv1(m.texcoords1.size() == m.positions.size()),
        colors(m.colors.size() == m.positions.size()),
        tangents(m.tangents.size() == m.positions.size()) {}
};

struct Vertex {
  glm::vec3 p{0.0f}, n{0, 1, 0};
  glm::vec2 uv0{0.0f}, uv1{0.0f};
  glm::vec4 color{1.0f}, tangent{0.0f};
};

Vertex vertex_of(const Mesh& m, const AttributeSet& a, std::size_t i) {
  Vertex v;
  v.p = m.positions[i];
  if (a.normals) v.n = m.normals[i];
  if (a.uv0) v.uv0 = m.texcoords0[i];
  if (a.uv1) v.uv1 = m.texcoords1[i];
  if (a.colors) v.color = m.colors[i];
  if (a.tangents) v.tangent = m.tangents[i];
  return v;
}

// Appends vertex i of `from` (with the attributes `a` says it has) to `to`.
void append_vertex(Mesh& to, const Mesh& from, const AttributeSet& a, std::size_t i) {
  to.positions.push_back(from.positions[i]);
  to.normals.push_back(a.normals ? from.normals[i] : glm::vec3(0, 1, 0));
  if (a.uv0) to.texcoords0.push_back(from.texcoords0[i]);
  if (a.uv1) to.texcoords1.push_back(from.texcoords1[i]);
  if (a.colors) to.colors.push_back(from.colors[i]);
  if (a.tangents) to.tangents.push_back(from.tangents[i]);
}

}  // namespace

// Out-of-range triangles are dropped so meshopt never reads past the vertices; identical vertices
// (duplicates a generator or exporter left: every attribute equal) are joined so the only
// same-position vertices meshopt sees are real attribute seams (normals, texture coordinates,
// colours or tangents that differ).
Mesh join_identical_vertices(const Mesh& in) {
  const AttributeSet a(in);
  std::vector<Vertex> vertices(in.positions.size());
  for (std::size_t i = 0; i < in.positions.size(); ++i) vertices[i] = vertex_of(in, a, i);
  std::vector<std::uint32_t> indices;
  const auto n = static_cast<std::uint32_t>(in.positions.size());
  for (std::size_t t = 0; t + 2 < in.indices.size(); t += 3) {
    const std::uint32_t x = in.indices[t], y = in.indices[t + 1], z = in.indices[t + 2];
    if (x < n && y < n && z < n) indices.insert(indices.end(), {x, y, z});
  }
  Mesh m;
  if (indices.empty() || vertices.empty()) return m;
  std::vector<unsigned> remap(vertices.size());
  const std::size_t unique = meshopt_generateVertexRemap(remap.data(), indices.data(), indices.size(), vertices.data(),
                                                         vertices.size(), sizeof(Vertex));
  std::vector<std::size_t> first(unique, SIZE_MAX);  // the first input vertex of each joined one
  for (std::size_t i = 0; i < remap.size(); ++i) {
    if (remap[i] != ~0u && first[remap[i]] == SIZE_MAX) first[remap[i]] = i;
  }
  m.indices.resize(indices.size());
  meshopt_remapIndexBuffer(m.indices.data(), indices.data(), indices.size(), remap.data());
  for (const std::size_t i : first) append_vertex(m, in, a, i);
  return m;
}

SimplifiedMesh simplify_mesh(const Mesh& full, double ratio, SeamHandling seams) {
  SimplifiedMesh r;
  const std::size_t count = full.indices.size();
  if (count < 3 || full.positions.empty()) return r;
  const std::size_t tris = count / 3;
  const float* xyz = &full.positions.front().x;
  const auto target_tris = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(static_cast<double>(tris) * ratio)));
  std::vector<unsigned> source(full.indices.begin(), full.indices.end());
  // Keep: meshopt classifies same-position, different-index vertices as attribute seams and only
  // collapses along a seam, both sides together. Weld: a shadow index buffer hides the seams.
  if (seams == SeamHandling::Weld) {
    meshopt_generateShadowIndexBuffer(source.data(), full.indices.data(), count, xyz, full.positions.size(),
                                      sizeof(glm::vec3), sizeof(glm::vec3));
  }
  std::vector<unsigned> out(count);
  float relative = 0;
  const std::size_t n = meshopt_simplify(out.data(), source.data(), count, xyz, full.positions.size(), sizeof(glm::vec3),
                                         target_tris * 3, 1.0f, 0, &relative);
  out.resize(n);
  std::vector<std::uint32_t> remap(full.positions.size(), UINT32_MAX);
  const AttributeSet a(full);
  for (const unsigned old : out) {
    if (remap[old] == UINT32_MAX) {
      remap[old] = static_cast<std::uint32_t>(r.mesh.positions.size());
      append_vertex(r.mesh, full, a, old);
    }
    r.mesh.indices.push_back(remap[old]);
  }
  const float scale = meshopt_simplifyScale(xyz, full.positions.size(), sizeof(glm::vec3));
  r.error_m = std::isfinite(relative * scale) ? relative * scale : 0.0f;
  return r;
}

}  // namespace fovea::render
