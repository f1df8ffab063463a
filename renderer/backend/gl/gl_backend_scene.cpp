// SPDX-License-Identifier: Apache-2.0
// GlBackend's scene on the GPU (gl_backend.h): the scene checked for what the raster backend can
// draw, its lights packed into the LightSamples uniform block, and its meshes uploaded once each
// (interleaved positions and normals) with one draw item per object and level of detail.
#include <epoxy/gl.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_backend_detail.h"
#include "backend/gl/shaders.h"

namespace fovea::render {

using namespace gl_backend_detail;

namespace {

std::string object_label(const Scene& scene, const Object& o) {
  return (scene.source.empty() ? scene.name : scene.source.string()) + ": object '" + o.name + "' (id " +
         std::to_string(o.id) + ")";
}

// Throws std::invalid_argument unless mesh (level 0 or one LOD level of o) can be drawn: one normal per
// position, whole triangles, an index count GLsizei can hold, every index a position.
void validate_drawable_mesh(const Scene& scene, const Object& o, const Mesh& m) {
  if (m.normals.size() != m.positions.size()) {
    throw std::invalid_argument(object_label(scene, o) + ": mesh has " + std::to_string(m.normals.size()) +
                                " normals for " + std::to_string(m.positions.size()) +
                                " positions (must be one per position)");
  }
  if (m.indices.size() % 3 != 0) {
    throw std::invalid_argument(object_label(scene, o) + ": mesh index count " + std::to_string(m.indices.size()) +
                                " is not a multiple of 3");
  }
  if (m.indices.size() > static_cast<std::size_t>(std::numeric_limits<GLsizei>::max())) {
    throw std::invalid_argument(object_label(scene, o) + ": mesh has too many indices for OpenGL");
  }
  for (const std::uint32_t i : m.indices) {
    if (i >= m.positions.size()) {
      throw std::invalid_argument(object_label(scene, o) + ": mesh index " + std::to_string(i) +
                                  " out of range [0, " + std::to_string(m.positions.size()) + ")");
    }
  }
}

// Throws std::invalid_argument for the first object with a mesh the raster backend cannot draw.
void validate_drawable_objects(const Scene& scene) {
  for (const Object& o : scene.objects) {
    if (!o.mesh) continue;  // nothing to draw (as in the Embree backend)
    if (o.material >= scene.materials.size()) {
      throw std::invalid_argument(object_label(scene, o) + ": material index " + std::to_string(o.material) +
                                  " out of range [0, " + std::to_string(scene.materials.size()) + ")");
    }
    for (std::size_t level = 0; level <= o.lods.size(); ++level) {
      const Mesh* level_mesh = level == 0 ? o.mesh.get() : o.lods[level - 1].mesh.get();
      if (level_mesh == nullptr) continue;
      validate_drawable_mesh(scene, o, *level_mesh);
    }
  }
}

// The scene's lights expanded to samples in the std140 layout of the LightSamples block; throws
// std::runtime_error past gl::kMaxLightSamples (the block's fixed size).
std::vector<LightSampleStd140> pack_light_samples(const Scene& scene) {
  std::vector<LightSampleStd140> packed;
  std::vector<LightSample> samples;
  for (const Light& light : scene.lights) {
    light_samples(light, samples);
    for (const LightSample& s : samples) {
      packed.push_back({{s.position.x, s.position.y, s.position.z, static_cast<float>(s.kind)},
                        {s.power.x, s.power.y, s.power.z, s.cos_cutoff},
                        {s.direction.x, s.direction.y, s.direction.z, s.cos_falloff_start}});
    }
  }
  if (packed.size() > static_cast<std::size_t>(gl::kMaxLightSamples)) {
    throw std::runtime_error((scene.source.empty() ? scene.name : scene.source.string()) + ": the lights expand to " +
                             std::to_string(packed.size()) + " light samples; the OpenGL backend supports at most " +
                             std::to_string(gl::kMaxLightSamples) +
                             " (an area light counts area_samples^2: lower area_samples or use fewer lights)");
  }
  return packed;
}

void upload_light_samples(GLuint light_ubo, const std::vector<LightSampleStd140>& packed) {
  glBindBuffer(GL_UNIFORM_BUFFER, light_ubo);
  if (!packed.empty()) {
    glBufferSubData(GL_UNIFORM_BUFFER, 0, static_cast<GLsizeiptr>(packed.size() * sizeof(LightSampleStd140)),
                    packed.data());
  }
  glBindBuffer(GL_UNIFORM_BUFFER, 0);
}

// A mesh's texture coordinates, colours and tangents as a second vertex buffer at locations 2-5
// (uv0, uv1, colour, tangent; 12 floats per vertex), into the bound VAO. Attributes the mesh lacks
// get their defaults (0, colour 1); a mesh with none of them gets no buffer: the disabled arrays
// read the generic values set per frame.
void upload_pbr_attributes(const Mesh& mesh, unsigned& extra_vbo) {
  const std::size_t n = mesh.positions.size();
  const bool uv0 = mesh.texcoords0.size() == n, uv1 = mesh.texcoords1.size() == n, colors = mesh.colors.size() == n,
             tangents = mesh.tangents.size() == n;
  if (!(uv0 || uv1 || colors || tangents) || n == 0) return;
  std::vector<float> extra(n * 12, 0.0f);
  for (std::size_t i = 0; i < n; ++i) {
    float* v = &extra[12 * i];
    if (uv0) std::memcpy(v, &mesh.texcoords0[i], 2 * sizeof(float));
    if (uv1) std::memcpy(v + 2, &mesh.texcoords1[i], 2 * sizeof(float));
    const glm::vec4 c = colors ? mesh.colors[i] : glm::vec4(1.0f);
    std::memcpy(v + 4, &c, 4 * sizeof(float));
    if (tangents) std::memcpy(v + 8, &mesh.tangents[i], 4 * sizeof(float));
  }
  glGenBuffers(1, &extra_vbo);
  glBindBuffer(GL_ARRAY_BUFFER, extra_vbo);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(extra.size() * sizeof(float)), extra.data(), GL_STATIC_DRAW);
  constexpr GLsizei kStride = 12 * sizeof(float);
  const GLint sizes[4] = {2, 2, 4, 4};
  const std::size_t offsets[4] = {0, 2, 4, 8};
  for (GLuint k = 0; k < 4; ++k) {
    glEnableVertexAttribArray(2 + k);
    glVertexAttribPointer(2 + k, sizes[k], GL_FLOAT, GL_FALSE, kStride,
                          reinterpret_cast<const void*>(static_cast<std::uintptr_t>(offsets[k] * sizeof(float))));
  }
}

}  // namespace

void GlBackend::release_meshes() {
  for (GpuMesh& m : meshes_) {
    glDeleteVertexArrays(1, &m.vao);
    glDeleteBuffers(1, &m.vbo);
    glDeleteBuffers(1, &m.ibo);
    if (m.extra_vbo != 0) glDeleteBuffers(1, &m.extra_vbo);
  }
  meshes_.clear();
  draws_.clear();
  mesh_sources_.clear();
  visibility_meshes_stale_ = true;
}

void GlBackend::set_scene(const Scene& scene) {
  // Validate everything before touching GL state, so a bad scene leaves the previous one usable.
  validate_drawable_objects(scene);
  const std::vector<LightSampleStd140> packed = pack_light_samples(scene);

  context_.make_current();
  release_meshes();
  release_textures();
  upload_draw_items(scene);
  upload_textures(scene);
  pbr_scene_ = std::any_of(scene.materials.begin(), scene.materials.end(),
                           [](const Material& m) { return m.type == MaterialType::MetallicRoughness; });
  upload_light_samples(light_ubo_, packed);
  light_sample_count_ = static_cast<int>(packed.size());
  scene_ = scene;
  check_gl("GlBackend::set_scene");
}

GlBackend::GpuMesh GlBackend::upload_interleaved_mesh(const Mesh& mesh, std::vector<float>& interleaved) {
  GpuMesh gpu;
  gpu.index_count = static_cast<std::int32_t>(mesh.indices.size());
  interleaved.resize(mesh.positions.size() * 6);
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    std::memcpy(&interleaved[6 * i], &mesh.positions[i], 3 * sizeof(float));
    std::memcpy(&interleaved[6 * i + 3], &mesh.normals[i], 3 * sizeof(float));
  }
  glGenVertexArrays(1, &gpu.vao);
  glGenBuffers(1, &gpu.vbo);
  glGenBuffers(1, &gpu.ibo);
  glBindVertexArray(gpu.vao);
  glBindBuffer(GL_ARRAY_BUFFER, gpu.vbo);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(interleaved.size() * sizeof(float)), interleaved.data(),
               GL_STATIC_DRAW);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, gpu.ibo);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(mesh.indices.size() * sizeof(std::uint32_t)),
               mesh.indices.data(), GL_STATIC_DRAW);
  constexpr GLsizei kStride = 6 * sizeof(float);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, kStride, nullptr);
  glEnableVertexAttribArray(1);
  // The classic buffer-offset idiom of glVertexAttribPointer.
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, kStride,
                        reinterpret_cast<const void*>(static_cast<std::uintptr_t>(3 * sizeof(float))));
  upload_pbr_attributes(mesh, gpu.extra_vbo);
  glBindVertexArray(0);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  return gpu;
}

void GlBackend::upload_draw_items(const Scene& scene) {
  std::unordered_map<const Mesh*, std::size_t> uploaded;  // shared meshes are uploaded once
  std::vector<float> interleaved;
  const auto upload = [&](const Mesh* mesh) -> std::size_t {
    const auto found = uploaded.find(mesh);
    if (found != uploaded.end()) return found->second;
    const GpuMesh gpu = upload_interleaved_mesh(*mesh, interleaved);
    uploaded.emplace(mesh, meshes_.size());
    meshes_.push_back(gpu);
    mesh_sources_.push_back(mesh);
    return meshes_.size() - 1;
  };
  for (const Object& o : scene.objects) {
    if (o.mesh == nullptr) {
      draws_.push_back({kNoMesh, {}});
      continue;
    }
    DrawItem item{upload(o.mesh.get()), {}};
    for (const LodLevel& l : o.lods) item.lods.push_back(l.mesh ? upload(l.mesh.get()) : item.mesh);
    draws_.push_back(std::move(item));
  }
}

}  // namespace fovea::render
