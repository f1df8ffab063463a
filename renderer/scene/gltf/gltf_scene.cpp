// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf/gltf_scene.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <utility>

#include "scene/gltf/gltf_flatten.h"
#include "scene/gltf/gltf_reader.h"
#include "scene/gltf/gltf_textures.h"
#include "scene/tangents.h"

namespace fovea::render {

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

bool finite(const glm::mat4& m) {
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      if (!std::isfinite(m[c][r])) return false;
    }
  }
  return true;
}

std::string node_path(const gltf::Asset& a, std::uint32_t node) {
  std::string p = "$.nodes[" + std::to_string(node) + "]";
  if (node < a.nodes.size() && !a.nodes[node].name.empty()) p += " (\"" + a.nodes[node].name + "\")";
  return p;
}

// A node's world matrix as a transform: refused unless finite and invertible.
Transform node_transform(const gltf::Asset& a, std::uint32_t node, const glm::mat4& world) {
  if (!finite(world)) throw SceneError(a.source + ": " + node_path(a, node) + ": world matrix is not finite");
  const float det = glm::determinant(glm::mat3(world));
  if (!std::isfinite(det) || std::abs(det) < 1e-30f) {
    throw SceneError(a.source + ": " + node_path(a, node) + ": world matrix is not invertible (determinant " + std::to_string(det) +
                     "): must scale every axis by a non-zero amount");
  }
  Transform t;
  t.matrix_override = world;
  t.translation = glm::vec3(world[3]);
  t.scale = {glm::length(glm::vec3(world[0])), glm::length(glm::vec3(world[1])), glm::length(glm::vec3(world[2]))};
  return t;
}

// Area-weighted vertex normals (the cross product's length is twice the triangle's area).
std::vector<glm::vec3> area_weighted_normals(const std::vector<glm::vec3>& p, const std::vector<std::uint32_t>& idx) {
  std::vector<glm::vec3> n(p.size(), glm::vec3(0.0f));
  for (std::size_t i = 0; i + 2 < idx.size(); i += 3) {
    const glm::vec3 face = glm::cross(p[idx[i + 1]] - p[idx[i]], p[idx[i + 2]] - p[idx[i]]);
    for (std::size_t k = 0; k < 3; ++k) n[idx[i + k]] += face;
  }
  for (glm::vec3& v : n) {
    const float len = glm::length(v);
    v = len > 0 && std::isfinite(len) ? v / len : glm::vec3(0, 0, 1);  // unused or degenerate vertex
  }
  return n;
}

// The primitive as a fovea Mesh with all its attributes; tangents generated from TEXCOORD_n when
// `tangent_set` is n and the file has none.
std::shared_ptr<const Mesh> to_mesh(const gltf::Asset& a, std::uint32_t mesh, std::uint32_t prim,
                                    std::optional<std::uint32_t> tangent_set) {
  const gltf::Primitive& p = a.meshes[mesh].primitives[prim];
  Mesh m;
  m.positions = p.positions;
  m.indices = p.indices;
  m.normals = p.normals.size() == p.positions.size() ? p.normals : area_weighted_normals(p.positions, p.indices);
  m.texcoords0 = p.texcoords0;
  m.texcoords1 = p.texcoords1;
  m.colors = p.colors;
  m.tangents = p.tangents;
  if (m.tangents.empty() && tangent_set && m.texcoords(*tangent_set).size() == m.positions.size()) {
    generate_mikktspace_tangents(m, *tangent_set);  // may split vertices at mirrored UV seams
  }
  if (!all_finite(m)) {
    throw SceneError(a.source + ": $.meshes[" + std::to_string(mesh) + "].primitives[" + std::to_string(prim) +
                     "]: a position, normal, texture coordinate, colour or tangent is not finite");
  }
  return std::make_shared<const Mesh>(std::move(m));
}

struct Bounds {
  glm::vec3 lo{std::numeric_limits<float>::max()}, hi{std::numeric_limits<float>::lowest()};
  void add(const glm::vec3& p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  glm::vec3 centre() const { return 0.5f * (lo + hi); }
  float radius() const { return std::max(0.5f * glm::length(hi - lo), 1e-3f); }
};

// The camera a node gives: its origin, looking down its -Z with +Y up.
Camera node_camera(const gltf::Camera& c, const glm::mat4& world, const Bounds& b) {
  Camera cam;
  cam.position = glm::vec3(world[3]);
  cam.target = cam.position + glm::normalize(glm::vec3(world * glm::vec4(0, 0, -1, 0)));
  cam.up = glm::normalize(glm::vec3(world * glm::vec4(0, 1, 0, 0)));
  cam.vertical_fov_deg = glm::degrees(c.yfov_rad);
  cam.near_m = c.znear;
  // An infinite far plane: far enough for the whole scene seen from the camera.
  cam.far_m = c.zfar ? *c.zfar : std::max(100.0f, 4.0f * (glm::length(b.centre() - cam.position) + b.radius()));
  return cam;
}

// No camera in the file: 45° vertical field of view from +Z, the bounding sphere filling the height.
Camera framing_camera(const Bounds& b) {
  Camera cam;
  cam.vertical_fov_deg = 45;
  const float r = b.radius(), d = 1.1f * r / std::sin(glm::radians(22.5f));
  cam.target = b.centre();
  cam.position = b.centre() + glm::vec3(0, 0, d);
  cam.up = {0, 1, 0};
  cam.near_m = std::max(1e-3f, 0.5f * (d - r));
  cam.far_m = 2.0f * (d + r);
  return cam;
}

Camera pick_camera(const gltf::Asset& a, const std::vector<std::optional<glm::mat4>>& worlds, const Bounds& b,
                   const std::string& wanted, std::vector<std::string>& warn) {
  std::vector<std::string> names;
  for (std::uint32_t i = 0; i < a.nodes.size(); ++i) {
    const gltf::Node& n = a.nodes[i];
    if (!n.camera || !worlds[i]) continue;
    const std::string name = n.name.empty() ? "node" + std::to_string(i) : n.name;
    names.push_back(name);
    if (!wanted.empty() && name != wanted) continue;
    const gltf::Camera& c = a.cameras[*n.camera];
    if (c.type != gltf::Camera::Type::Perspective) {
      warn.push_back(node_path(a, i) + ": orthographic camera skipped (fovea has perspective cameras only)");
      continue;
    }
    (void)node_transform(a, i, *worlds[i]);  // finite and invertible
    return node_camera(c, *worlds[i], b);
  }
  if (!wanted.empty()) {
    std::string list;
    for (const std::string& n : names) list += (list.empty() ? "" : ", ") + ("\"" + n + "\"");
    throw SceneError(a.source + ": no perspective camera node named \"" + wanted + "\" (camera nodes: " +
                     (list.empty() ? "none" : list) + ")");
  }
  return framing_camera(b);
}

std::vector<Light> lights(const gltf::Asset& a, const std::vector<std::optional<glm::mat4>>& worlds, const Bounds& b,
                          std::vector<std::string>& warn) {
  std::vector<Light> out;
  for (std::uint32_t i = 0; i < a.nodes.size(); ++i) {
    const gltf::Node& n = a.nodes[i];
    if (!n.light || !worlds[i]) continue;
    const glm::mat4& w = *worlds[i];
    (void)node_transform(a, i, w);
    const gltf::Light& g = a.lights[*n.light];
    Light l;
    l.position = glm::vec3(w[3]);
    l.direction = glm::normalize(glm::vec3(w * glm::vec4(0, 0, -1, 0)));
    // Candela (lm/sr) taken as W/sr: the radiant power of an isotropic source of that intensity.
    l.power = 4.0f * kPi * g.intensity * g.color;
    if (g.type == gltf::Light::Type::Spot) {
      l.type = LightType::Spot;
      l.spot_cutoff_deg = glm::degrees(g.outer_cone_rad);
      l.spot_falloff_deg = glm::degrees(g.outer_cone_rad - g.inner_cone_rad);
    } else if (g.type == gltf::Light::Type::Directional) {
      // Lux taken as W/m²: a point light 10 scene radii up-beam giving that irradiance at the centre.
      const float d = 10.0f * b.radius();
      l.position = b.centre() - d * l.direction;
      l.power = 4.0f * kPi * d * d * g.intensity * g.color;
      warn.push_back(node_path(a, i) + ": directional light approximated by a distant point light");
    }
    if (g.range) warn.push_back(node_path(a, i) + ": light range ignored (inverse-square falloff everywhere)");
    out.push_back(l);
  }
  if (!out.empty()) return out;
  // The default rig: a key light above right in front, a fill light left; irradiance 4 and 1.5 W/m²
  // at the centre (Phi = 4 pi d² E).
  const glm::vec3 c = b.centre();
  const float r = b.radius();
  for (const auto& [offset, e] : {std::pair{glm::vec3(1.5f, 2.0f, 2.0f), 4.0f}, std::pair{glm::vec3(-2.0f, 1.0f, 1.5f), 1.5f}}) {
    Light l;
    l.position = c + r * offset;
    const float d2 = glm::dot(r * offset, r * offset);
    l.power = glm::vec3(4.0f * kPi * d2 * e);
    out.push_back(l);
  }
  return out;
}

}  // namespace

Material material_from_gltf(const gltf::Material& g, const std::string& name) {
  Material m;
  m.name = name;
  m.type = MaterialType::MetallicRoughness;
  PbrParameters& pbr = m.pbr;
  pbr.base_color = glm::clamp(g.base_color_factor, 0.0f, 1.0f);
  pbr.metallic = std::clamp(g.metallic_factor, 0.0f, 1.0f);
  pbr.roughness = std::clamp(g.roughness_factor, 0.0f, 1.0f);
  pbr.emissive = g.emissive_factor * g.emissive_strength;
  pbr.normal_scale = g.normal_scale;
  pbr.occlusion_strength = g.occlusion_strength;
  pbr.alpha_mode = g.alpha_mode == gltf::AlphaMode::Mask    ? AlphaMode::Mask
                   : g.alpha_mode == gltf::AlphaMode::Blend ? AlphaMode::Blend
                                                            : AlphaMode::Opaque;
  pbr.alpha_cutoff = g.alpha_mode == gltf::AlphaMode::Blend ? 0.5f : g.alpha_cutoff;
  pbr.double_sided = g.double_sided;
  // The factors' nearest Blinn-Phong, for the photon map and eye paths (renderer/gi/GI.md).
  const glm::vec3 base(pbr.base_color);
  m.kd = base * (1.0f - pbr.metallic);
  m.ks = glm::mix(glm::vec3(0.04f), base, pbr.metallic);
  const float alpha = std::max(pbr.roughness * pbr.roughness, 1e-4f);
  m.shininess = std::clamp(2.0f / (alpha * alpha) - 2.0f, 1.0f, 10000.0f);
  m.emission = pbr.emissive;
  return m;
}

namespace {

// glTF's sampler enums as fovea's sampler (minFilter is not kept: every texture is sampled trilinear,
// see scene/texture.h).
TextureSampler to_sampler(const gltf::Asset& a, const gltf::Texture& t) {
  TextureSampler s;
  if (!t.sampler) return s;
  const gltf::Sampler& g = a.samplers[*t.sampler];
  const auto wrap = [](std::uint32_t e) {
    return e == 33071 ? TextureWrap::ClampToEdge : e == 33648 ? TextureWrap::MirroredRepeat : TextureWrap::Repeat;
  };
  s.wrap_s = wrap(g.wrap_s);
  s.wrap_t = wrap(g.wrap_t);
  s.mag_nearest = g.mag_filter == 9728;
  return s;
}

// The images the materials use, one decode request per (image, colour or data), and the bindings
// that wait for them: TextureBinding::texture holds the request's index until resolve() maps it to
// the scene's texture or drops the binding.
class TextureTable {
 public:
  explicit TextureTable(const gltf::Asset& a) : a_(a) {}

  std::optional<TextureBinding> bind(const std::optional<gltf::TextureRef>& ref, bool srgb, const std::string& used_by) {
    if (!ref || ref->texture >= a_.textures.size()) return std::nullopt;  // read_gltf checked the index
    const gltf::Texture& t = a_.textures[ref->texture];
    if (!t.source || *t.source >= a_.images.size()) return std::nullopt;  // a texture without an image is undefined: treated as absent
    const auto [it, added] = index_.try_emplace({*t.source, srgb}, static_cast<std::uint32_t>(requests_.size()));
    if (added) {
      requests_.push_back({*t.source, srgb, used_by});
    } else {
      requests_[it->second].used_by += ", " + used_by;  // one warning names every slot the image fills
    }
    return TextureBinding{it->second, ref->tex_coord, to_sampler(a_, t)};
  }

  void bind_material(Material& m, const gltf::Material& g) {
    const auto slot = [&](const char* name) { return "material \"" + m.name + "\" " + name; };
    PbrParameters& p = m.pbr;
    p.base_color_texture = bind(g.base_color_texture, true, slot("baseColorTexture"));
    p.metallic_roughness_texture = bind(g.metallic_roughness_texture, false, slot("metallicRoughnessTexture"));
    p.normal_texture = bind(g.normal_texture, false, slot("normalTexture"));
    p.occlusion_texture = bind(g.occlusion_texture, false, slot("occlusionTexture"));
    p.emissive_texture = bind(g.emissive_texture, true, slot("emissiveTexture"));
  }

  // Decodes every request into scene.textures and points the materials' bindings at them; the
  // time goes to `report` as the "textures" phase.
  void resolve(Scene& scene, const gltf::TextureOptions& options, std::vector<std::string>& warn, LoadReport* report) {
    const auto start = std::chrono::steady_clock::now();
    const gltf::DecodedTextures decoded = gltf::decode_textures(a_, requests_, options);
    for (const std::string& w : decoded.warnings) warn.push_back(w);
    std::vector<std::optional<std::uint32_t>> scene_index(requests_.size());
    for (std::size_t i = 0; i < requests_.size(); ++i) {
      if (!decoded.images[i]) continue;
      scene_index[i] = static_cast<std::uint32_t>(scene.textures.size());
      scene.textures.push_back(decoded.images[i]);
    }
    for (Material& m : scene.materials) {
      if (m.type != MaterialType::MetallicRoughness) continue;
      for (std::optional<TextureBinding>* b : {&m.pbr.base_color_texture, &m.pbr.metallic_roughness_texture,
                                               &m.pbr.normal_texture, &m.pbr.occlusion_texture, &m.pbr.emissive_texture}) {
        if (!*b) continue;
        if (const auto k = scene_index.at((*b)->texture)) {
          (*b)->texture = *k;
        } else {
          b->reset();
        }
      }
    }
    if (report) {
      report->add_since("textures", start, std::to_string(scene.textures.size()) + " textures, " +
                                               std::to_string((decoded.bytes + (1u << 19)) >> 20) + " MiB");
    }
  }

 private:
  const gltf::Asset& a_;
  std::map<std::pair<std::uint32_t, bool>, std::uint32_t> index_;
  std::vector<gltf::TextureRequest> requests_;
};

// The scene's materials on first use, in the file's order of use, each with its textures bound
// (TextureTable); the default material after them.
class MaterialTable {
 public:
  MaterialTable(const gltf::Asset& a, Scene& s, TextureTable& textures, std::vector<std::string>& warn)
      : a_(a), s_(s), textures_(textures), warn_(warn) {}

  std::uint32_t index(const std::optional<std::uint32_t>& g) {
    if (!g) return default_index();
    const auto [it, added] = index_.try_emplace(*g, static_cast<std::uint32_t>(s_.materials.size()));
    if (added) {
      const gltf::Material& gm = a_.materials[*g];
      s_.materials.push_back(material_from_gltf(gm, gm.name.empty() ? "material" + std::to_string(*g) : gm.name));
      textures_.bind_material(s_.materials.back(), gm);
      if (gm.alpha_mode == gltf::AlphaMode::Blend) {
        warn_.push_back("material \"" + s_.materials.back().name +
                        "\": alphaMode BLEND drawn as MASK with cutoff 0.5 (the G-buffer holds one surface per pixel)");
      }
    }
    return it->second;
  }

 private:
  // The spec's default (white, metallic 1, roughness 1) would be a black metal here: white
  // Lambertian instead, fovea's default kd.
  std::uint32_t default_index() {
    if (!default_) {
      Material m;
      m.name = "gltf-default";
      default_ = static_cast<std::uint32_t>(s_.materials.size());
      s_.materials.push_back(m);
    }
    return *default_;
  }

  const gltf::Asset& a_;
  Scene& s_;
  TextureTable& textures_;
  std::vector<std::string>& warn_;
  std::map<std::uint32_t, std::uint32_t> index_;
  std::optional<std::uint32_t> default_;
};

}  // namespace

Scene scene_from_gltf(const gltf::Asset& a, const GltfSceneOptions& options, std::vector<std::string>* warnings,
                      LoadReport* report) {
  std::vector<std::string> warn;
  Scene s;
  s.name = std::filesystem::path(a.source).stem().string();
  s.source = a.source;

  TextureTable textures(a);
  MaterialTable materials(a, s, textures, warn);
  // The texture-coordinate set a primitive's normal map reads, for tangents the file does not give.
  const auto tangent_set = [&](const gltf::Primitive& p) -> std::optional<std::uint32_t> {
    if (!p.material || !a.materials[*p.material].normal_texture) return std::nullopt;
    return a.materials[*p.material].normal_texture->tex_coord;
  };

  // One shared fovea Mesh per glTF primitive: instances of a mesh point at the same one.
  std::vector<std::vector<std::shared_ptr<const Mesh>>> meshes(a.meshes.size());
  Bounds bounds;
  for (const gltf::MeshInstance& inst : gltf::flatten(a)) {
    const Transform t = node_transform(a, inst.node, inst.world);
    const gltf::Mesh& gm = a.meshes[inst.mesh];
    auto& shared = meshes[inst.mesh];
    shared.resize(gm.primitives.size());
    for (std::uint32_t k = 0; k < gm.primitives.size(); ++k) {
      const gltf::Primitive& p = gm.primitives[k];
      if (p.indices.empty()) continue;  // no triangles (points or lines left out by the reader)
      if (!shared[k]) shared[k] = to_mesh(a, inst.mesh, k, tangent_set(p));
      Object o;
      o.name = gm.primitives.size() == 1 ? inst.name : inst.name + "/p" + std::to_string(k);
      o.id = static_cast<std::uint32_t>(s.objects.size() + 1);
      o.mesh = shared[k];
      o.material = materials.index(p.material);
      o.transform = t;
      // A level-of-detail chain with the default settings (lod::attach_chains builds or loads it).
      LodChainRequest chain;
      chain.where = a.source + ": " + node_path(a, inst.node);
      chain.implicit = true;
      o.lod_chain = chain;
      for (const glm::vec3& v : o.mesh->positions) bounds.add(glm::vec3(inst.world * glm::vec4(v, 1.0f)));
      s.objects.push_back(std::move(o));
    }
  }
  if (s.objects.empty()) throw SceneError(a.source + ": $.nodes: no node of the scene has a mesh with triangles: nothing to render");
  textures.resolve(s, options.textures, warn, report);

  const std::vector<std::optional<glm::mat4>> worlds = gltf::node_worlds(a);
  s.camera = pick_camera(a, worlds, bounds, options.camera_name, warn);
  s.camera.width = options.width;
  s.camera.height = options.height;
  s.lights = lights(a, worlds, bounds, warn);
  if (warnings) {
    for (const std::string& w : a.warnings) warnings->push_back(w);
    for (std::string& w : warn) warnings->push_back(a.source + ": " + std::move(w));
  }
  return s;
}

bool is_gltf_file(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".gltf" || ext == ".glb";
}

Scene load_gltf_scene(const std::filesystem::path& path, const std::vector<SceneOverride>& overrides,
                      const std::string& camera, LoadReport* report) {
  GltfSceneOptions options;
  options.camera_name = camera;
  std::optional<bool> stereo;
  std::optional<float> ipd_m;
  for (const SceneOverride& o : overrides) {
    if (o.path == "camera.stereo") {
      if (o.value != "true" && o.value != "false") {
        throw SceneError(path.string() + ": --scene-set camera.stereo=" + o.value + ": must be true or false");
      }
      stereo = o.value == "true";
      continue;
    }
    if (o.path == "camera.ipd_m") {
      char* end = nullptr;
      const double v = std::strtod(o.value.c_str(), &end);
      if (o.value.empty() || *end != '\0' || !(v > 0 && v <= 1)) {
        throw SceneError(path.string() + ": --scene-set camera.ipd_m=" + o.value + ": must be a number in (0, 1] (m)");
      }
      ipd_m = static_cast<float>(v);
      continue;
    }
    if (o.path != "camera.width" && o.path != "camera.height") {
      throw SceneError(path.string() + ": --scene-set " + o.path + ": a glTF scene takes only camera.width, "
                       "camera.height, camera.stereo and camera.ipd_m overrides");
    }
    char* end = nullptr;
    const long v = std::strtol(o.value.c_str(), &end, 10);
    if (o.value.empty() || *end != '\0' || v < 1 || v > 16384) {
      throw SceneError(path.string() + ": --scene-set " + o.path + "=" + o.value + ": must be an integer in [1, 16384]");
    }
    (o.path == "camera.width" ? options.width : options.height) = static_cast<std::uint32_t>(v);
  }
  if (std::uint64_t{options.width} * options.height > std::uint64_t{7680} * 4320) {
    throw SceneError(path.string() + ": camera " + std::to_string(options.width) + "x" + std::to_string(options.height) +
                     ": at most 7680x4320 pixels");
  }
  std::vector<std::string> warnings;
  const auto start = std::chrono::steady_clock::now();
  const gltf::Asset asset = gltf::read_gltf(path);
  if (report) {
    std::size_t triangles = 0;
    for (const gltf::Mesh& m : asset.meshes) {
      for (const gltf::Primitive& p : m.primitives) triangles += p.indices.size() / 3;
    }
    report->add_since("parse", start, std::to_string(triangles) + " triangles in " + std::to_string(asset.meshes.size()) + " meshes");
  }
  Scene scene = scene_from_gltf(asset, options, &warnings, report);
  if (stereo) scene.camera.stereo = *stereo;
  if (ipd_m) scene.camera.ipd_m = *ipd_m;
  for (const std::string& w : warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  scene.source = path;
  return scene;
}

}  // namespace fovea::render
