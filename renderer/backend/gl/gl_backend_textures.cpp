// SPDX-License-Identifier: Apache-2.0
// GlBackend's PBR materials (gl_backend.h): the scene's textures uploaded with the mip chains
// scene/texture.h built (the same levels the Embree backend samples, so only the choice of level
// differs: screen-space derivatives here, ray cones there), one sampler object per distinct
// TextureSampler, and each MetallicRoughness material's uniforms and texture units.
#include <epoxy/gl.h>

#include <glm/gtc/type_ptr.hpp>

#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_backend_detail.h"

namespace fovea::render {

using namespace gl_backend_detail;

namespace {

GLint gl_wrap(TextureWrap w) {
  switch (w) {
    case TextureWrap::ClampToEdge: return GL_CLAMP_TO_EDGE;
    case TextureWrap::MirroredRepeat: return GL_MIRRORED_REPEAT;
    case TextureWrap::Repeat: break;
  }
  return GL_REPEAT;
}

}  // namespace

void GlBackend::upload_textures(const Scene& scene) {
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  for (const auto& image : scene.textures) {
    GLuint t = 0;
    glGenTextures(1, &t);
    scene_textures_.push_back(t);
    if (!image || image->levels.empty()) continue;
    glBindTexture(GL_TEXTURE_2D, t);
    // sRGB images are decoded to linear by the texture unit, before filtering (as sample_texture).
    const GLint format = image->srgb ? GL_SRGB8_ALPHA8 : GL_RGBA8;
    for (std::size_t k = 0; k < image->levels.size(); ++k) {
      const TextureLevel& l = image->levels[k];
      glTexImage2D(GL_TEXTURE_2D, static_cast<GLint>(k), format, static_cast<GLsizei>(l.width),
                   static_cast<GLsizei>(l.height), 0, GL_RGBA, GL_UNSIGNED_BYTE, l.rgba.data());
    }
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_BASE_LEVEL, 0);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, static_cast<GLint>(image->levels.size() - 1));
  }
  glBindTexture(GL_TEXTURE_2D, 0);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  check_gl("GlBackend::upload_textures");
}

void GlBackend::release_textures() {
  if (!scene_textures_.empty()) glDeleteTextures(static_cast<GLsizei>(scene_textures_.size()), scene_textures_.data());
  scene_textures_.clear();
  for (const auto& [sampler, id] : samplers_) glDeleteSamplers(1, &id);
  samplers_.clear();
}

unsigned GlBackend::sampler_for(const TextureSampler& s) {
  for (const auto& [sampler, id] : samplers_) {
    if (sampler == s) return id;
  }
  GLuint id = 0;
  glGenSamplers(1, &id);
  // Trilinear in both backends; the file's minFilter is not kept (scene/texture.h).
  glSamplerParameteri(id, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glSamplerParameteri(id, GL_TEXTURE_MAG_FILTER, s.mag_nearest ? GL_NEAREST : GL_LINEAR);
  glSamplerParameteri(id, GL_TEXTURE_WRAP_S, gl_wrap(s.wrap_s));
  glSamplerParameteri(id, GL_TEXTURE_WRAP_T, gl_wrap(s.wrap_t));
  samplers_.emplace_back(s, id);
  return id;
}

// The material's PBR uniforms and its textures on units kMaterialTextureUnit + slot; a non-PBR
// material only turns the PBR path off.
void GlBackend::set_material_textures(const Material& m) {
  const bool pbr = m.type == MaterialType::MetallicRoughness;
  glUniform1i(loc_pbr_.pbr, pbr ? 1 : 0);
  if (!pbr) return;
  const PbrParameters& p = m.pbr;
  glUniform4fv(loc_pbr_.base_color, 1, glm::value_ptr(p.base_color));
  glUniform2f(loc_pbr_.metallic_roughness, p.metallic, p.roughness);
  glUniform3fv(loc_pbr_.emissive, 1, glm::value_ptr(p.emissive));
  glUniform1f(loc_pbr_.normal_scale, p.normal_scale);
  glUniform1f(loc_pbr_.occlusion_strength, p.occlusion_strength);
  glUniform1i(loc_pbr_.alpha_test, p.alpha_tested() ? 1 : 0);
  glUniform1f(loc_pbr_.alpha_cutoff, p.alpha_cutoff);
  const std::optional<TextureBinding>* slots[5] = {&p.base_color_texture, &p.metallic_roughness_texture,
                                                   &p.normal_texture, &p.occlusion_texture, &p.emissive_texture};
  int present = 0, set1 = 0;
  for (int k = 0; k < 5; ++k) {
    const std::optional<TextureBinding>& b = *slots[k];
    const auto unit = static_cast<GLuint>(kMaterialTextureUnit + k);
    glActiveTexture(GL_TEXTURE0 + unit);
    if (b && b->texture < scene_textures_.size()) {
      present |= 1 << k;
      if (b->tex_coord == 1) set1 |= 1 << k;
      glBindTexture(GL_TEXTURE_2D, scene_textures_[b->texture]);
      glBindSampler(unit, sampler_for(b->sampler));
    } else {
      glBindTexture(GL_TEXTURE_2D, 0);
      glBindSampler(unit, 0);
    }
  }
  glActiveTexture(GL_TEXTURE0);
  glUniform1i(loc_pbr_.tex_present, present);
  glUniform1i(loc_pbr_.tex_set1, set1);
}

}  // namespace fovea::render
