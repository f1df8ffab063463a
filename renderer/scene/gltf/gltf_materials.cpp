// SPDX-License-Identifier: Apache-2.0
// Samplers, textures and materials (glTF 2.0 §3.8, §3.9, KHR_materials_emissive_strength): the
// metallic-roughness material with its texture references, every factor range checked. Textures
// stay references to images; decoding them is a later step.
#include <algorithm>
#include <initializer_list>
#include <string>

#include "scene/gltf/gltf_parse.h"

namespace fovea::render::gltf::detail {

namespace {

const Range kUnit{0, 1, false, false, ""};
const Range kAny{-1e30, 1e30, false, false, ""};
const Range kNonNegative{0, 1e30, false, false, ""};

std::uint32_t gl_enum(const Parser& p, const Node& parent, std::string_view key, std::initializer_list<std::uint32_t> allowed,
                      const char* text, std::uint32_t fallback) {
  const auto n = Parser::get(parent, key);
  if (!n) return fallback;
  const auto v = static_cast<std::uint32_t>(p.integer(*n, 0, 100000));
  if (std::find(allowed.begin(), allowed.end(), v) == allowed.end()) p.fail(*n, std::string("must be ") + text);
  return v;
}

Sampler read_sampler(const Parser& p, const Node& n) {
  p.expect_object(n, "a sampler: magFilter, minFilter, wrapS, wrapT");
  Sampler s;
  s.name = p.optional_string(n, "name", "the sampler's name");
  s.mag_filter = gl_enum(p, n, "magFilter", {9728, 9729}, "9728 NEAREST or 9729 LINEAR", 0);
  s.min_filter = gl_enum(p, n, "minFilter", {9728, 9729, 9984, 9985, 9986, 9987},
                         "9728 NEAREST, 9729 LINEAR or 9984..9987 (the mipmap filters)", 0);
  const char* wrap = "33071 CLAMP_TO_EDGE, 33648 MIRRORED_REPEAT or 10497 REPEAT";
  s.wrap_s = gl_enum(p, n, "wrapS", {33071, 33648, 10497}, wrap, 10497);
  s.wrap_t = gl_enum(p, n, "wrapT", {33071, 33648, 10497}, wrap, 10497);
  return s;
}

Texture read_texture(const Parser& p, const Node& n) {
  p.expect_object(n, "a texture: sampler, source");
  Texture t;
  t.name = p.optional_string(n, "name", "the texture's name");
  t.sampler = p.optional_index(n, "sampler", p.asset.samplers.size(), "$.samplers");
  t.source = p.optional_index(n, "source", p.asset.images.size(), "$.images");
  return t;
}

// A textureInfo (§5.26): index and texCoord; `scale_key` ("scale", "strength") read into *scale.
std::optional<TextureRef> texture_ref(const Parser& p, const Node& parent, std::string_view key, const char* scale_key = nullptr,
                                      float* scale = nullptr, const Range& scale_range = kAny) {
  const auto n = p.object(parent, key, "a texture reference: index, texCoord");
  if (!n) return std::nullopt;
  TextureRef r;
  r.texture = p.index(p.require(*n, "index", "the texture's index"), p.asset.textures.size(), "$.textures");
  if (const auto tc = Parser::get(*n, "texCoord")) {
    r.tex_coord = static_cast<std::uint32_t>(p.integer(*tc, 0, 1000));
    if (r.tex_coord > 1) p.fail(*tc, "must be 0 or 1 (fovea reads TEXCOORD_0 and TEXCOORD_1)");
  }
  if (scale_key != nullptr) *scale = p.number_or(*n, scale_key, scale_range, *scale);
  return r;
}

Material read_material(const Parser& p, const Node& n) {
  p.expect_object(n, "a material");
  Material m;
  m.name = p.optional_string(n, "name", "the material's name");
  if (const auto pbr = p.object(n, "pbrMetallicRoughness", "the metallic-roughness parameters")) {
    if (const auto f = Parser::get(*pbr, "baseColorFactor")) m.base_color_factor = p.vec<4>(*f, kUnit, "linear RGBA, each in [0, 1]");
    m.base_color_texture = texture_ref(p, *pbr, "baseColorTexture");
    m.metallic_factor = p.number_or(*pbr, "metallicFactor", kUnit, 1.0f);
    m.roughness_factor = p.number_or(*pbr, "roughnessFactor", kUnit, 1.0f);
    m.metallic_roughness_texture = texture_ref(p, *pbr, "metallicRoughnessTexture");
  }
  m.normal_texture = texture_ref(p, n, "normalTexture", "scale", &m.normal_scale);
  m.occlusion_texture = texture_ref(p, n, "occlusionTexture", "strength", &m.occlusion_strength, kUnit);
  m.emissive_texture = texture_ref(p, n, "emissiveTexture");
  if (const auto f = Parser::get(n, "emissiveFactor")) m.emissive_factor = p.vec3(*f, kUnit, "linear RGB, each in [0, 1]");
  if (const auto ext = p.object(n, "extensions", "the material's extensions")) {
    if (const auto es = p.object(*ext, "KHR_materials_emissive_strength", "emissiveStrength")) {
      m.emissive_strength = p.number_or(*es, "emissiveStrength", kNonNegative, 1.0f);
    }
  }
  if (const auto mode = Parser::get(n, "alphaMode")) {
    const std::string s = p.string(*mode, "OPAQUE, MASK or BLEND");
    if (s == "OPAQUE") {
      m.alpha_mode = AlphaMode::Opaque;
    } else if (s == "MASK") {
      m.alpha_mode = AlphaMode::Mask;
    } else if (s == "BLEND") {
      m.alpha_mode = AlphaMode::Blend;
    } else {
      p.fail(*mode, "must be OPAQUE, MASK or BLEND");
    }
  }
  m.alpha_cutoff = p.number_or(n, "alphaCutoff", kNonNegative, 0.5f);
  if (const auto ds = Parser::get(n, "doubleSided")) m.double_sided = p.boolean(*ds);
  return m;
}

}  // namespace

void read_materials(Parser& p, const Node& root) {
  p.each(root, "samplers", [&](const Node& n) { p.asset.samplers.push_back(read_sampler(p, n)); });
  p.each(root, "textures", [&](const Node& n) { p.asset.textures.push_back(read_texture(p, n)); });
  p.each(root, "materials", [&](const Node& n) { p.asset.materials.push_back(read_material(p, n)); });
}

}  // namespace fovea::render::gltf::detail
