// SPDX-License-Identifier: Apache-2.0
#pragma once
// The scene model shared by every backend and pass. Units: metres, seconds, watts; colours are
// linear RGB. Loaded from JSON or glTF 2.0 by scene_loader.h (formats in renderer/SCENES.md).
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fovea/protocol/display_geometry.h"
#include "scene/texture.h"

namespace fovea::render {

// Indexed triangle mesh in object space. normals has one entry per position (smooth shading); the
// other attributes are empty or have one entry per position too.
struct Mesh {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<std::uint32_t> indices;  // 3 per triangle
  std::vector<glm::vec2> texcoords0, texcoords1;  // TEXCOORD_0 and _1 (glTF: v down the image)
  std::vector<glm::vec4> colors;                  // linear RGBA, multiplies the base colour
  std::vector<glm::vec4> tangents;                // xyz unit tangent, w the bitangent's sign (normal maps)
  const std::vector<glm::vec2>& texcoords(std::uint32_t set) const { return set == 0 ? texcoords0 : texcoords1; }
  std::size_t triangle_count() const { return indices.size() / 3; }
};

// No NaN or Inf in any component: what the scene's readers promise of all they hand on.
inline bool all_finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool all_finite(const Mesh& m);  // positions and normals

struct Transform {
  glm::vec3 translation{0.0f};
  glm::vec3 rotation_deg{0.0f};  // Euler angles in degrees: X first, then Y, then Z (R = Rz * Ry * Rx)
  glm::vec3 scale{1.0f};
  // An imported node's exact world matrix (glTF: shear and any affine matrix stay exact). When set,
  // matrix() returns its upper 3x4 with `translation` as the last column (the builder sets it to the
  // matrix's, so an animation's translation still moves it); scale holds its column lengths (for LOD
  // error), rotation_deg stays 0 and is ignored. JSON scenes never set it.
  std::optional<glm::mat4> matrix_override;
  glm::mat4 matrix() const;      // T * R * S, or matrix_override when set
};

// Piecewise-linear keyframes of translation and rotation; time in seconds. Scale is not animated.
struct AnimationKey {
  double time_s = 0;
  glm::vec3 translation{0.0f};
  glm::vec3 rotation_deg{0.0f};
};
struct Animation {
  std::vector<AnimationKey> keys;  // strictly increasing time
  bool loop = true;
  // The transform at time t: keys interpolated, added to the object's base transform.
  Transform apply(const Transform& base, double t) const;
};

enum class MaterialType { Lambertian, BlinnPhong, Mirror, Glass, Emissive, MetallicRoughness };
const char* to_string(MaterialType t);

enum class AlphaMode { Opaque, Mask, Blend };
const char* to_string(AlphaMode m);

// glTF 2.0's metallic-roughness material (§3.9), shaded with its appendix B BRDF by
// scene/shading.h shade_pbr. Each texture multiplies its factor.
struct PbrParameters {
  glm::vec4 base_color{1.0f};     // linear RGBA
  float metallic = 1.0f, roughness = 1.0f;
  glm::vec3 emissive{0.0f};       // emissiveFactor times KHR_materials_emissive_strength (W / (sr m^2))
  float normal_scale = 1.0f, occlusion_strength = 1.0f;
  std::optional<TextureBinding> base_color_texture;          // sRGB
  std::optional<TextureBinding> metallic_roughness_texture;  // B metallic, G roughness
  std::optional<TextureBinding> normal_texture;              // tangent space, +Y up the image's v decreasing
  std::optional<TextureBinding> occlusion_texture;           // R
  std::optional<TextureBinding> emissive_texture;            // sRGB
  AlphaMode alpha_mode = AlphaMode::Opaque;
  float alpha_cutoff = 0.5f;      // MASK (and BLEND, drawn as MASK: one surface per pixel)
  bool double_sided = false;
  bool has_textures() const {
    return base_color_texture || metallic_roughness_texture || normal_texture || occlusion_texture || emissive_texture;
  }
  bool alpha_tested() const { return alpha_mode != AlphaMode::Opaque; }
};

struct Material {
  std::string name;
  MaterialType type = MaterialType::Lambertian;
  glm::vec3 kd{0.8f};          // diffuse coefficient (Jensen & Pedersen 2009, eq. 5.22)
  glm::vec3 ks{0.0f};          // specular coefficient
  float shininess = 1.0f;      // n in (n.h)^n
  glm::vec3 reflectance{1.0f}; // mirror and glass: tint of reflected/transmitted light
  float ior = 1.5f;            // glass
  glm::vec3 emission{0.0f};    // emissive: radiance leaving the surface, W / (sr m^2)
  // MetallicRoughness only. kd, ks and shininess then hold the factors' nearest Blinn-Phong (what
  // the photon map and eye paths use: renderer/gi/GI.md).
  PbrParameters pbr;
  bool is_specular_or_refractive() const { return type == MaterialType::Mirror || type == MaterialType::Glass; }
  // What the GI pass stores photons on and scatters with kd and ks (Lambertian, Blinn-Phong, PBR).
  bool is_diffuse_or_glossy() const {
    return type == MaterialType::Lambertian || type == MaterialType::BlinnPhong || type == MaterialType::MetallicRoughness;
  }
  bool is_glossy() const { return type == MaterialType::BlinnPhong || type == MaterialType::MetallicRoughness; }
};

// A level of detail: the mesh to use when the object's projected size or importance calls for it.
struct LodLevel {
  std::shared_ptr<const Mesh> mesh;
  float max_error_m = 0;  // geometric error of this level against the full mesh (metres, object space)
};

// A level-of-detail chain a scene file asks for ("lod": {"chain": {...}}, Lee 2009 eq. 7.4). The
// loader keeps the request; lod::attach_chains (lod/lod_chain.h) builds or loads the chain and fills
// Object::lods. Unset fields take lod::ChainSettings' defaults.
struct LodChainRequest {
  std::optional<int> levels;
  std::optional<double> base;
  std::optional<bool> weld_attributes;  // "attributes": "weld" (true) or "seams" (false)
  std::string where;                    // "scene.json: $.objects[2].lod.chain", for messages
  // A chain the scene did not ask for by name (every glTF object gets one): a mesh the simplifier
  // cannot reduce then keeps no levels instead of being an error.
  bool implicit = false;
};

struct Object {
  std::string name;
  std::uint32_t id = 0;  // 1-based, unique; 0 in a G-buffer means "no object"
  std::shared_ptr<const Mesh> mesh;
  std::vector<LodLevel> lods;  // optional, coarser levels after the full mesh
  std::optional<LodChainRequest> lod_chain;  // until lod::attach_chains has filled `lods`
  std::uint32_t material = 0;  // index into Scene::materials
  Transform transform;
  std::optional<Animation> animation;
  float task_importance = 0;   // T_i of Lee 2009, eq. 3.7, in [0, 1]
  Transform transform_at(double t) const { return animation ? animation->apply(transform, t) : transform; }
};

enum class LightType { Point, Spot, Area };
const char* to_string(LightType t);

struct Light {
  LightType type = LightType::Point;
  glm::vec3 position{0.0f};
  glm::vec3 power{100.0f};         // radiant power Phi_s per channel, W
  glm::vec3 direction{0, -1, 0};   // spot axis, or area light normal (unit)
  float spot_cutoff_deg = 30;      // half-angle of the spot cone
  float spot_falloff_deg = 5;      // soft edge inside the cutoff
  glm::vec2 area_size{0.5f};       // area light: extent along its two tangents (metres)
  int area_samples = 4;            // area light: samples per side for local illumination (n x n)
};

struct Lens {
  // Pinhole when aperture_m == 0. Otherwise a thin lens of focal length F and aperture diameter E
  // focused at focus_distance_m (Lee 2009, eq. 4.2-4.3).
  double focal_length_m = 0.05;
  double aperture_m = 0;
  double focus_distance_m = 2.0;
  // Distance from lens to image plane (d_r of Lee eq. 4.4); 0 = derived from F and focus distance.
  double image_distance_m = 0;
  bool is_pinhole() const { return aperture_m <= 0; }
  // The human eye: F = 16.7 mm, E = 4 mm, d_r = 24 mm (Lee 2009, §4.1.2 and §4.6).
  static Lens human_eye(double focus_distance_m);
};

struct Camera {
  glm::vec3 position{0, 1, 5};
  glm::vec3 target{0, 1, 0};
  glm::vec3 up{0, 1, 0};
  float vertical_fov_deg = 45;
  std::uint32_t width = 640, height = 480;
  float near_m = 0.05f, far_m = 100.0f;
  Lens lens;
  std::optional<Animation> animation;  // moves position and target together (rotation ignored)
  // Stereo (camera.stereo, fovea-render --stereo): two views whose eyes lie ipd_m apart along the
  // camera's right axis with parallel view axes, as a headset's. eye_offset_m is the view rendered
  // now, along that axis: 0 the cyclopean camera (the scene's), -ipd/2 the left eye, +ipd/2 the
  // right. The frame pipeline sets it; scene files do not.
  bool stereo = false;
  float ipd_m = 0.063f;
  float eye_offset_m = 0;
  glm::vec3 right() const;  // unit right axis of the view (target - position) x up
  // Where a point of the cyclopean camera's image at view depth depth_m lies in this eye's image:
  // its normalised x moves by -P00 eye_offset_m / (2 depth_m) (P00 the projection's x scale), its y
  // not at all. 0 at infinite depth (parallel eyes) and for the cyclopean camera.
  double eye_shift_x(double depth_m) const;
  glm::mat4 view_at(double t) const;
  glm::mat4 projection() const;  // OpenGL convention (clip z in [-1, 1]), y up
  glm::vec3 position_at(double t) const;
};

struct Scene {
  std::string name;
  std::filesystem::path source;  // the JSON file, for messages
  Camera camera;
  std::vector<Material> materials;
  std::vector<std::shared_ptr<const TextureImage>> textures;  // TextureBinding::texture indexes here
  std::vector<Object> objects;
  std::vector<Light> lights;
  glm::vec3 ambient{0.02f};      // ambient radiance for local illumination (times kd)
  glm::vec3 background{0.0f};    // radiance where no object is hit
  protocol::DisplayGeometry display;  // the screen the frames are shown on: pixels -> visual angle

  bool has_specular_or_refractive() const;
  bool has_textures() const;  // a material samples a texture
  bool has_animation() const;
  bool has_lods() const;
  const Object* object_by_id(std::uint32_t id) const;
};

}  // namespace fovea::render
