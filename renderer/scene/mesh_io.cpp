// SPDX-License-Identifier: Apache-2.0
#include "scene/mesh_io.h"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <cmath>
#include <cstdint>
#include <vector>

namespace fovea::render {

namespace {

glm::mat4 to_glm(const aiMatrix4x4& m) {
  // assimp is row-major (a1..a4 is the first row); glm is column-major.
  return glm::mat4(m.a1, m.b1, m.c1, m.d1, m.a2, m.b2, m.c2, m.d2, m.a3, m.b3, m.c3, m.d3, m.a4, m.b4, m.c4, m.d4);
}

// Normals that are missing, zero or non-finite (degenerate faces) are replaced by the area-weighted
// average of the incident face normals, or +Y where even that is zero.
void repair_normals(Mesh& m) {
  if (m.normals.size() != m.positions.size()) m.normals.assign(m.positions.size(), glm::vec3(0.0f));
  std::vector<glm::vec3> acc(m.positions.size(), glm::vec3(0.0f));
  for (std::size_t i = 0; i + 2 < m.indices.size(); i += 3) {
    const glm::vec3& a = m.positions[m.indices[i]];
    const glm::vec3& b = m.positions[m.indices[i + 1]];
    const glm::vec3& c = m.positions[m.indices[i + 2]];
    const glm::vec3 n = glm::cross(b - a, c - a);  // length = twice the area
    if (!all_finite(n)) continue;
    for (std::size_t k = 0; k < 3; ++k) acc[m.indices[i + k]] += n;
  }
  for (std::size_t v = 0; v < m.normals.size(); ++v) {
    glm::vec3& n = m.normals[v];
    const float len = glm::length(n);
    if (all_finite(n) && len > 1e-12f && std::isfinite(len)) {
      n /= len;
      continue;
    }
    const float alen = glm::length(acc[v]);
    n = alen > 1e-20f && std::isfinite(alen) ? acc[v] / alen : glm::vec3(0, 1, 0);
  }
}

void append_node(const aiScene& s, const aiNode& node, const glm::mat4& parent, Mesh& out) {
  const glm::mat4 world = parent * to_glm(node.mTransformation);
  const glm::mat3 normal_matrix = glm::transpose(glm::inverse(glm::mat3(world)));
  for (unsigned k = 0; k < node.mNumMeshes; ++k) {
    const aiMesh& m = *s.mMeshes[node.mMeshes[k]];
    if ((m.mPrimitiveTypes & aiPrimitiveType_TRIANGLE) == 0) continue;
    const auto base = static_cast<std::uint32_t>(out.positions.size());
    for (unsigned v = 0; v < m.mNumVertices; ++v) {
      const aiVector3D& p = m.mVertices[v];
      out.positions.emplace_back(world * glm::vec4(p.x, p.y, p.z, 1.0f));
      if (m.mNormals != nullptr) {
        const aiVector3D& n = m.mNormals[v];
        out.normals.push_back(normal_matrix * glm::vec3(n.x, n.y, n.z));
      } else {
        out.normals.emplace_back(0.0f);  // repaired below
      }
    }
    for (unsigned f = 0; f < m.mNumFaces; ++f) {
      const aiFace& face = m.mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines left after triangulation
      for (unsigned i = 0; i < 3; ++i) out.indices.push_back(base + face.mIndices[i]);
    }
  }
  for (unsigned c = 0; c < node.mNumChildren; ++c) append_node(s, *node.mChildren[c], world, out);
}

}  // namespace

Mesh read_mesh_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw SceneError("mesh file not found: " + path.string());

  Assimp::Importer importer;
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const aiScene* s = importer.ReadFile(path.string(), aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                                          aiProcess_GenSmoothNormals | aiProcess_SortByPType |
                                                          aiProcess_ValidateDataStructure);
  if (s == nullptr || s->mRootNode == nullptr) {
    const std::string why = importer.GetErrorString();
    if (why.find("o meshes") != std::string::npos || why.find("empty") != std::string::npos) {
      throw SceneError("degenerate mesh: " + path.string() + " contains no triangles (" + why + ")");
    }
    throw SceneError("cannot read mesh " + path.string() + ": " + why);
  }
  Mesh mesh;
  append_node(*s, *s->mRootNode, glm::mat4(1.0f), mesh);
  if (mesh.indices.empty()) throw SceneError("degenerate mesh: " + path.string() + " contains no triangles");
  for (const glm::vec3& p : mesh.positions) {
    if (!all_finite(p)) throw SceneError("mesh " + path.string() + " has a non-finite vertex position");
  }
  repair_normals(mesh);
  return mesh;
}

}  // namespace fovea::render
