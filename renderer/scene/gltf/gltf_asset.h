// SPDX-License-Identifier: Apache-2.0
#pragma once
// A glTF 2.0 asset as read and checked by read_gltf (gltf_reader.h): typed data, every index range
// checked, every accessor decoded into per-primitive arrays. Textures and images stay references:
// decoding them is a later step (Filament gltfio's split: the asset once, resources separately).
// Nothing here knows the renderer's scene model; the builder (gltf_scene.h) converts it.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace fovea::render::gltf {

// ---- binary data ----

struct Buffer {
  std::vector<std::uint8_t> bytes;  // exactly byteLength bytes
};

struct BufferView {
  std::uint32_t buffer = 0;
  std::size_t offset = 0, length = 0;  // checked to lie inside the buffer
  std::uint32_t stride = 0;            // 0: tightly packed
};

// An image is one of: an external file (a confined path inside the asset's folder, not opened
// here and possibly missing: see Asset::warnings), the bytes of a bufferView, or the decoded bytes
// of a data: URI.
struct Image {
  std::string name;
  std::filesystem::path file;             // external file; empty otherwise
  std::optional<std::uint32_t> buffer_view;
  std::vector<std::uint8_t> data;         // a data: URI's bytes
  std::string mime_type;                  // "image/png", "image/jpeg", ... or "" when unknown
};

// Sampler filters and wraps as their glTF (OpenGL) enums, 0 where the file gives none.
struct Sampler {
  std::string name;
  std::uint32_t mag_filter = 0;  // 9728 NEAREST, 9729 LINEAR
  std::uint32_t min_filter = 0;  // 9728, 9729, 9984..9987 (mipmap variants)
  std::uint32_t wrap_s = 10497, wrap_t = 10497;  // 33071 CLAMP_TO_EDGE, 33648 MIRRORED_REPEAT, 10497 REPEAT
};

struct Texture {
  std::string name;
  std::optional<std::uint32_t> sampler;  // none: repeat wrapping, filters of the implementation's choice
  std::optional<std::uint32_t> source;   // image; none: the texture is undefined (treated as absent)
};

// ---- materials (glTF 2.0 §3.9, metallic-roughness) ----

struct TextureRef {
  std::uint32_t texture = 0;
  std::uint32_t tex_coord = 0;  // 0 or 1: TEXCOORD_0 or TEXCOORD_1
};

enum class AlphaMode { Opaque, Mask, Blend };

struct Material {
  std::string name;
  glm::vec4 base_color_factor{1.0f};
  std::optional<TextureRef> base_color_texture;
  float metallic_factor = 1.0f, roughness_factor = 1.0f;
  std::optional<TextureRef> metallic_roughness_texture;  // B: metal, G: roughness
  std::optional<TextureRef> normal_texture;
  float normal_scale = 1.0f;
  std::optional<TextureRef> occlusion_texture;  // R
  float occlusion_strength = 1.0f;
  std::optional<TextureRef> emissive_texture;
  glm::vec3 emissive_factor{0.0f};
  float emissive_strength = 1.0f;  // KHR_materials_emissive_strength
  AlphaMode alpha_mode = AlphaMode::Opaque;
  float alpha_cutoff = 0.5f;  // used by Mask only
  bool double_sided = false;
};

// ---- meshes ----

// A primitive as triangles: strips and fans are converted to lists, a primitive without indices gets
// 0, 1, 2, ...; every index is below positions.size(). The optional attributes are empty or have one
// entry per position.
struct Primitive {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<glm::vec4> tangents;  // w: handedness of the bitangent
  std::vector<glm::vec2> texcoords0, texcoords1;
  std::vector<glm::vec4> colors;    // COLOR_0; a VEC3 colour gets alpha 1
  std::vector<std::uint32_t> indices;  // triangle list
  std::optional<std::uint32_t> material;  // none: the default material
};

struct Mesh {
  std::string name;
  std::vector<Primitive> primitives;  // points and lines are left out (a warning says so)
};

// ---- cameras and lights ----

struct Camera {
  enum class Type { Perspective, Orthographic };
  std::string name;
  Type type = Type::Perspective;
  float yfov_rad = 0;                  // perspective
  std::optional<float> aspect_ratio;   // perspective; none: the viewport's
  float xmag = 0, ymag = 0;            // orthographic half extents
  float znear = 0;
  std::optional<float> zfar;           // none (perspective only): infinite
};

// KHR_lights_punctual. Units as the extension gives them: intensity in candela (point, spot) or
// lux (directional); a light shines down its node's -Z.
struct Light {
  enum class Type { Directional, Point, Spot };
  std::string name;
  Type type = Type::Point;
  glm::vec3 color{1.0f};
  float intensity = 1.0f;
  std::optional<float> range;  // none: infinite
  float inner_cone_rad = 0.0f, outer_cone_rad = 0.7853982f;  // spot
};

// ---- the node graph ----

// A node's local transform is `local` (from `matrix`, or T * R * S with the rotation normalised).
// The graph is a forest: no node has two parents and there is no cycle (both checked).
struct Node {
  std::string name;
  std::vector<std::uint32_t> children;
  glm::mat4 local{1.0f};
  std::optional<std::uint32_t> mesh, camera, light;
};

struct SceneRoots {
  std::string name;
  std::vector<std::uint32_t> nodes;  // root nodes, each at most once
};

struct Asset {
  std::string source;            // the file name as given, for messages
  std::filesystem::path folder;  // where relative URIs resolve
  std::string version, generator;
  std::vector<std::string> extensions_used;
  std::vector<Buffer> buffers;
  std::vector<BufferView> buffer_views;
  std::vector<Image> images;
  std::vector<Sampler> samplers;
  std::vector<Texture> textures;
  std::vector<Material> materials;
  std::vector<Mesh> meshes;
  std::vector<Camera> cameras;
  std::vector<Light> lights;
  std::vector<Node> nodes;
  std::vector<SceneRoots> scenes;
  std::optional<std::uint32_t> scene;  // the default scene
  // What was read but left out or could not be checked: points and lines, unsupported extensions
  // in extensionsUsed, ignored attributes, image files not found. Each names its JSON path.
  std::vector<std::string> warnings;
};

// The encoded bytes of an image held in the asset (a bufferView or a data: URI); empty for an
// external file.
std::span<const std::uint8_t> image_bytes(const Asset& asset, std::size_t image);

}  // namespace fovea::render::gltf
