// SPDX-License-Identifier: Apache-2.0
#include "scene/mesh_simplify.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace fovea::render {

// Out-of-range triangles are dropped so meshopt never reads past the vertices; identical vertices
// (duplicates a generator or exporter left) are joined so the only same-position vertices meshopt
// sees are real attribute seams.
Mesh join_identical_vertices(const Mesh& in) {
  struct Vertex {
    glm::vec3 p, n;
  };
  std::vector<Vertex> vertices(in.positions.size());
  for (std::size_t i = 0; i < in.positions.size(); ++i)
    vertices[i] = {in.positions[i], i < in.normals.size() && in.normals.size() == in.positions.size() ? in.normals[i] : glm::vec3(0, 1, 0)};
  std::vector<std::uint32_t> indices;
  const auto n = static_cast<std::uint32_t>(in.positions.size());
  for (std::size_t t = 0; t + 2 < in.indices.size(); t += 3) {
    const std::uint32_t a = in.indices[t], b = in.indices[t + 1], c = in.indices[t + 2];
    if (a < n && b < n && c < n) indices.insert(indices.end(), {a, b, c});
  }
  Mesh m;
  if (indices.empty() || vertices.empty()) return m;
  std::vector<unsigned> remap(vertices.size());
  const std::size_t unique = meshopt_generateVertexRemap(remap.data(), indices.data(), indices.size(), vertices.data(),
                                                         vertices.size(), sizeof(Vertex));
  std::vector<Vertex> joined(unique);
  meshopt_remapVertexBuffer(joined.data(), vertices.data(), vertices.size(), sizeof(Vertex), remap.data());
  m.indices.resize(indices.size());
  meshopt_remapIndexBuffer(m.indices.data(), indices.data(), indices.size(), remap.data());
  for (const Vertex& v : joined) {
    m.positions.push_back(v.p);
    m.normals.push_back(v.n);
  }
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
  const bool normals = full.normals.size() == full.positions.size();
  for (const unsigned old : out) {
    if (remap[old] == UINT32_MAX) {
      remap[old] = static_cast<std::uint32_t>(r.mesh.positions.size());
      r.mesh.positions.push_back(full.positions[old]);
      r.mesh.normals.push_back(normals ? full.normals[old] : glm::vec3(0, 1, 0));
    }
    r.mesh.indices.push_back(remap[old]);
  }
  const float scale = meshopt_simplifyScale(xyz, full.positions.size(), sizeof(glm::vec3));
  r.error_m = std::isfinite(relative * scale) ? relative * scale : 0.0f;
  return r;
}

}  // namespace fovea::render
