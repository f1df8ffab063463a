// SPDX-License-Identifier: Apache-2.0
#pragma once
// A glTF asset of six textured quads (unit quads facing +Z, 1.2 apart, each its own node) that
// exercises the points of the glTF 2.0 specification fovea implements, with the pixel checks the
// Embree and OpenGL tests share. Textures are PNG data: URIs made with OpenCV.
//   top row     "checker"  base colour texture, 2x2 NEAREST: red, blue / green, grey 128 (sRGB)
//               "mask"     alphaMode MASK: the left half of its texture has alpha 0
//               "set1"     the checker on TEXCOORD_1 (TEXCOORD_0 all at the red texel), times
//                          COLOR_0 yellow
//   bottom row  "flat"     white, no texture (the lighting reference)
//               "tilt_x"   a normal map tilting the normal to +X (tangent space (0.6, 0, 0.8))
//               "tilt_y"   a normal map tilting it to +Y, up the image (generated tangents)
// One KHR_lights_punctual point light up and to the right in front; the camera node at z = 4.
// GltfMirroredSeam below: a mirrored UV seam under a normal map (generated tangents).
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <string>
#include <vector>

#include "backend/gbuffer.h"
#include "gltf_writer.h"
#include "scene/scene.h"

namespace fovea::test {

inline std::string png_data_uri(const cv::Mat& bgra) {
  std::vector<std::uint8_t> png;
  EXPECT_TRUE(cv::imencode(".png", bgra, png));
  return "data:image/png;base64," + base64(png);
}

struct GltfTexturedQuads {
  static constexpr float kSpacing = 1.2f;
  // Quad centres: index 0..2 top row left to right, 3..5 bottom row.
  static glm::vec3 centre(int quad) {
    return {kSpacing * static_cast<float>(quad % 3 - 1), quad < 3 ? 0.6f : -0.6f, 0.0f};
  }

  // Views 0 positions, 1 normals, 2 uv0, 3 uv0 at a point (for "set1"), 4 uv1, 5 colours, 6 indices.
  GltfBin bin() const {
    GltfBin b;
    b.add(std::vector<glm::vec3>{{-0.5f, -0.5f, 0}, {0.5f, -0.5f, 0}, {0.5f, 0.5f, 0}, {-0.5f, 0.5f, 0}});
    b.add(std::vector<glm::vec3>(4, glm::vec3(0, 0, 1)));
    // v down the image: the image's top row at the quad's top edge.
    const std::vector<glm::vec2> uv = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
    b.add(uv);
    b.add(std::vector<glm::vec2>(4, glm::vec2(0.25f, 0.25f)));
    b.add(uv);
    b.add(std::vector<glm::vec4>(4, glm::vec4(1, 1, 0, 1)));
    b.add(std::vector<std::uint16_t>{0, 1, 2, 0, 2, 3});
    return b;
  }

  GltfJson doc() const {
    GltfJson d = {{"asset", {{"version", "2.0"}}}};
    d["extensionsUsed"] = GltfJson::array({"KHR_lights_punctual"});
    d["extensions"] = GltfJson::parse(
        R"({"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 40, "color": [1, 1, 1]}]}})");
    d["accessors"] = GltfJson::parse(R"([
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-0.5, -0.5, 0], "max": [0.5, 0.5, 0]},
        {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
        {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
        {"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC2"},
        {"bufferView": 4, "componentType": 5126, "count": 4, "type": "VEC2"},
        {"bufferView": 5, "componentType": 5126, "count": 4, "type": "VEC4"},
        {"bufferView": 6, "componentType": 5123, "count": 6, "type": "SCALAR"}])");
    cv::Mat checker(2, 2, CV_8UC4);  // BGRA
    checker.at<cv::Vec4b>(0, 0) = {0, 0, 255, 255};
    checker.at<cv::Vec4b>(0, 1) = {255, 0, 0, 255};
    checker.at<cv::Vec4b>(1, 0) = {0, 255, 0, 255};
    checker.at<cv::Vec4b>(1, 1) = {128, 128, 128, 255};
    cv::Mat mask(1, 2, CV_8UC4, cv::Scalar(255, 255, 255, 255));
    mask.at<cv::Vec4b>(0, 0)[3] = 0;
    const auto normal = [](double x, double y, double z) {  // tangent space -> BGRA texel
      const auto b = [](double c) { return static_cast<std::uint8_t>(std::lround((c + 1) * 0.5 * 255)); };
      return cv::Mat(1, 1, CV_8UC4, cv::Scalar(b(z), b(y), b(x), 255));
    };
    d["images"] = GltfJson::array({{{"uri", png_data_uri(checker)}}, {{"uri", png_data_uri(mask)}},
                                   {{"uri", png_data_uri(normal(0.6, 0, 0.8))}},
                                   {{"uri", png_data_uri(normal(0, 0.6, 0.8))}}});
    d["samplers"] = GltfJson::parse(R"([{"magFilter": 9728, "minFilter": 9986}])");
    d["textures"] = GltfJson::parse(R"([{"source": 0, "sampler": 0}, {"source": 1, "sampler": 0},
                                       {"source": 2}, {"source": 3}])");
    d["materials"] = GltfJson::parse(R"([
        {"name": "checker", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0}},
        {"name": "mask", "alphaMode": "MASK", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1}, "metallicFactor": 0}},
        {"name": "set1", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 1}, "metallicFactor": 0}},
        {"name": "flat", "pbrMetallicRoughness": {"metallicFactor": 0}},
        {"name": "tilt_x", "normalTexture": {"index": 2}, "pbrMetallicRoughness": {"metallicFactor": 0}},
        {"name": "tilt_y", "normalTexture": {"index": 3}, "pbrMetallicRoughness": {"metallicFactor": 0}}])");
    GltfJson meshes = GltfJson::array();
    for (int k = 0; k < 6; ++k) {
      GltfJson attributes = {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 2}};
      if (k == 2) attributes = {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 3}, {"TEXCOORD_1", 4}, {"COLOR_0", 5}};
      meshes.push_back({{"primitives", GltfJson::array({{{"attributes", attributes}, {"indices", 6}, {"material", k}}})}});
    }
    d["meshes"] = meshes;
    d["cameras"] = GltfJson::parse(R"([{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 20}}])");
    const char* names[6] = {"checker", "mask", "set1", "flat", "tilt_x", "tilt_y"};
    GltfJson nodes = GltfJson::array();
    for (int k = 0; k < 6; ++k) {
      const glm::vec3 c = centre(k);
      nodes.push_back({{"name", names[k]}, {"mesh", k}, {"translation", {c.x, c.y, c.z}}});
    }
    nodes.push_back({{"name", "eye"}, {"camera", 0}, {"translation", {0, 0, 4}}});
    nodes.push_back({{"name", "lamp"}, {"translation", {3, 3, 3}}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
    d["nodes"] = nodes;
    d["scenes"] = GltfJson::parse(R"([{"nodes": [0, 1, 2, 3, 4, 5, 6, 7]}])");
    d["scene"] = 0;
    return d;
  }
};

// The pixel where a world point lands (the camera's projection, row 0 at the top).
inline std::size_t pixel_of(const render::Camera& cam, const render::GBuffer& g, glm::vec3 world) {
  const glm::vec4 clip = cam.projection() * cam.view_at(0) * glm::vec4(world, 1.0f);
  const float x = (clip.x / clip.w * 0.5f + 0.5f) * static_cast<float>(g.width);
  const float y = (0.5f - clip.y / clip.w * 0.5f) * static_cast<float>(g.height);
  return g.index(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y));
}

// `lit` rendered as loaded; `unmapped` the same scene with the normal maps removed.
inline void expect_textured_quads(const render::Camera& cam, const render::GBuffer& lit, const render::GBuffer& unmapped) {
  using Quads = GltfTexturedQuads;
  const auto at = [&](const render::GBuffer& g, int quad, float dx, float dy) {
    return pixel_of(cam, g, Quads::centre(quad) + glm::vec3(dx, dy, 0));
  };
  const auto colour = [&](int quad, float dx, float dy) { return lit.color[at(lit, quad, dx, dy)]; };
  const auto say = [](glm::vec3 c) {
    return std::to_string(c.r) + " " + std::to_string(c.g) + " " + std::to_string(c.b);
  };
  // checker: texel (0, 0) at the top left, the image's rows top down.
  const glm::vec3 tl = colour(0, -0.25f, 0.25f), tr = colour(0, 0.25f, 0.25f), bl = colour(0, -0.25f, -0.25f),
                  br = colour(0, 0.25f, -0.25f);
  EXPECT_GT(tl.r, 5 * std::max(tl.g, tl.b)) << "checker top left should be red: " << say(tl);
  EXPECT_GT(tr.b, 5 * std::max(tr.r, tr.g)) << "checker top right should be blue: " << say(tr);
  EXPECT_GT(bl.g, 5 * std::max(bl.r, bl.b)) << "checker bottom left should be green: " << say(bl);
  // Grey 128 is 0.216 in linear light: against the red texel's 1, with about the same lighting.
  const float grey = br.g / tl.r;
  EXPECT_GT(grey, 0.15f) << "sRGB texel 128 decoded to linear 0.22: " << say(br) << " against red " << say(tl);
  EXPECT_LT(grey, 0.32f) << "sRGB texel 128 decoded to linear 0.22: " << say(br) << " against red " << say(tl);
  // mask: the transparent left half shows what is behind (nothing), the right half is the quad.
  EXPECT_EQ(lit.object_id[at(lit, 1, -0.25f, 0)], 0u) << "the masked-out half must not be drawn";
  EXPECT_EQ(lit.object_id[at(lit, 1, 0.25f, 0)], 2u);
  // set1: TEXCOORD_1's checker times yellow COLOR_0 (TEXCOORD_0 would make it all red).
  const glm::vec3 s_tr = colour(2, 0.25f, 0.25f), s_br = colour(2, 0.25f, -0.25f);
  // Blue times yellow is black: what is left is the specular lobe's grey F0 = 0.04.
  EXPECT_LT(s_tr.b, 0.1f * tl.r) << "blue texel times yellow is black: " << say(s_tr);
  EXPECT_GT(s_br.r, 5 * s_br.b) << "grey times yellow is yellow: " << say(s_br);
  EXPECT_GT(s_br.g, 5 * s_br.b) << "grey times yellow is yellow: " << say(s_br);
  // Normal maps: the light is up and to the right, so tilting to +X or +Y (up the image) brightens.
  for (int quad : {4, 5}) {
    const float mapped = lit.color[at(lit, quad, 0, 0)].g, plain = unmapped.color[at(unmapped, quad, 0, 0)].g;
    EXPECT_GT(mapped, 1.1f * plain) << (quad == 4 ? "+X" : "+Y") << " normal map towards the light: " << mapped
                                    << " against " << plain << " without it";
  }
  const float flat = lit.color[at(lit, 3, 0, 0)].g, flat_unmapped = unmapped.color[at(unmapped, 3, 0, 0)].g;
  EXPECT_NEAR(flat, flat_unmapped, 1e-3f * flat) << "removing normal maps changed the quad without one";
}

// A 2 x 1 strip whose right half mirrors the left's texture (u runs 0 -> 1 -> 0) with the seam's
// vertices shared and no TANGENT: glTF asks for MikkTSpace, which splits the seam so that the +X
// normal map tilts the left half to +X and the right half to -X. A per-vertex average (Lengyel)
// gives the seam's vertices no tangent at all, and the right half near the seam tilts the wrong way.
// One point light to the right in front; the camera node at z = 3.
struct GltfMirroredSeam {
  GltfBin bin() const {
    GltfBin b;
    std::vector<glm::vec3> p;
    std::vector<glm::vec2> uv;
    for (int r = 0; r <= 1; ++r)
      for (int c = 0; c <= 2; ++c) {
        p.push_back({static_cast<float>(c - 1), static_cast<float>(r) - 0.5f, 0});
        uv.push_back({c == 1 ? 1.0f : 0.0f, 1.0f - static_cast<float>(r)});
      }
    b.add(p);
    b.add(std::vector<glm::vec3>(6, glm::vec3(0, 0, 1)));
    b.add(uv);
    b.add(std::vector<std::uint16_t>{0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4});
    return b;
  }
  GltfJson doc() const {
    GltfJson d = {{"asset", {{"version", "2.0"}}}};
    d["extensionsUsed"] = GltfJson::array({"KHR_lights_punctual"});
    d["extensions"] = GltfJson::parse(
        R"({"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 30, "color": [1, 1, 1]}]}})");
    d["accessors"] = GltfJson::parse(R"([
        {"bufferView": 0, "componentType": 5126, "count": 6, "type": "VEC3", "min": [-1, -0.5, 0], "max": [1, 0.5, 0]},
        {"bufferView": 1, "componentType": 5126, "count": 6, "type": "VEC3"},
        {"bufferView": 2, "componentType": 5126, "count": 6, "type": "VEC2"},
        {"bufferView": 3, "componentType": 5123, "count": 12, "type": "SCALAR"}])");
    cv::Mat tilt(1, 1, CV_8UC4, cv::Scalar(230, 128, 204, 255));  // BGRA of tangent-space (0.6, 0, 0.8)
    d["images"] = GltfJson::array({{{"uri", png_data_uri(tilt)}}});
    d["textures"] = GltfJson::parse(R"([{"source": 0}])");
    d["materials"] = GltfJson::parse(
        R"([{"name": "mirrored", "normalTexture": {"index": 0}, "pbrMetallicRoughness": {"metallicFactor": 0}}])");
    d["meshes"] = GltfJson::parse(
        R"([{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3, "material": 0}]}])");
    d["cameras"] = GltfJson::parse(R"([{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 20}}])");
    d["nodes"] = GltfJson::parse(R"([{"name": "strip", "mesh": 0}, {"name": "eye", "camera": 0, "translation": [0, 0, 3]},
        {"name": "lamp", "translation": [3, 0, 2], "extensions": {"KHR_lights_punctual": {"light": 0}}}])");
    d["scenes"] = GltfJson::parse(R"([{"nodes": [0, 1, 2]}])");
    d["scene"] = 0;
    return d;
  }
};

// `lit` as loaded, `unmapped` without its normal map: beside the seam, the left half turns towards
// the light on the right (brighter), the mirrored right half away from it (darker).
inline void expect_mirrored_seam(const render::Camera& cam, const render::GBuffer& lit, const render::GBuffer& unmapped) {
  for (const float x : {-0.15f, 0.15f, -0.6f, 0.6f}) {
    const std::size_t i = pixel_of(cam, lit, {x, 0.1f, 0});
    const float ratio = lit.color[i].g / unmapped.color[i].g;
    if (x < 0) EXPECT_GT(ratio, 1.1f) << "left of the seam (x = " << x << ") the +X map tilts towards the light";
    else EXPECT_LT(ratio, 0.9f) << "right of the seam (x = " << x << ") the mirrored map tilts away from the light";
  }
}

// Single- and double-sided materials (glTF 2.0 §3.9.6: a single-sided material's back faces are
// culled; a node whose world matrix has a negative determinant turns the winding round). Unit quads
// 1.2 apart, the camera node at z = 4 looking down -Z:
//   top row     "front"        counter-clockwise towards the camera, single-sided: drawn
//               "back"         clockwise towards the camera (its back), single-sided: culled
//               "back_double"  the same back, double-sided: drawn
//   bottom row  "mirrored"     "front" under scale (-1, 1, 1): clockwise on screen, yet its front
struct GltfSidedQuads {
  static glm::vec3 centre(int quad) {
    return {1.2f * static_cast<float>(quad % 3 - 1), quad < 3 ? 0.6f : -0.6f, 0.0f};
  }
  GltfBin bin() const {
    GltfBin b;
    b.add(std::vector<glm::vec3>{{-0.5f, -0.5f, 0}, {0.5f, -0.5f, 0}, {0.5f, 0.5f, 0}, {-0.5f, 0.5f, 0}});
    b.add(std::vector<glm::vec3>(4, glm::vec3(0, 0, 1)));
    b.add(std::vector<glm::vec3>(4, glm::vec3(0, 0, -1)));
    b.add(std::vector<std::uint16_t>{0, 1, 2, 0, 2, 3});
    b.add(std::vector<std::uint16_t>{0, 2, 1, 0, 3, 2});
    return b;
  }
  GltfJson doc() const {
    GltfJson d = {{"asset", {{"version", "2.0"}}}};
    d["extensionsUsed"] = GltfJson::array({"KHR_lights_punctual"});
    d["extensions"] = GltfJson::parse(
        R"({"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 40, "color": [1, 1, 1]}]}})");
    d["accessors"] = GltfJson::parse(R"([
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-0.5, -0.5, 0], "max": [0.5, 0.5, 0]},
        {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
        {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC3"},
        {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"},
        {"bufferView": 4, "componentType": 5123, "count": 6, "type": "SCALAR"}])");
    d["materials"] = GltfJson::parse(R"([{"name": "single", "pbrMetallicRoughness": {"metallicFactor": 0}},
        {"name": "double", "doubleSided": true, "pbrMetallicRoughness": {"metallicFactor": 0}}])");
    d["meshes"] = GltfJson::parse(R"([
        {"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 3, "material": 0}]},
        {"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 2}, "indices": 4, "material": 0}]},
        {"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 2}, "indices": 4, "material": 1}]}])");
    d["cameras"] = GltfJson::parse(R"([{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 20}}])");
    GltfJson nodes = GltfJson::array();
    const char* names[4] = {"front", "back", "back_double", "mirrored"};
    const int meshes[4] = {0, 1, 2, 0};
    for (int k = 0; k < 4; ++k) {
      const glm::vec3 c = centre(k == 3 ? 3 : k);
      nodes.push_back({{"name", names[k]}, {"mesh", meshes[k]}, {"translation", {c.x, c.y, c.z}}});
    }
    nodes[3]["scale"] = {-1, 1, 1};
    nodes.push_back({{"name", "eye"}, {"camera", 0}, {"translation", {0, 0, 4}}});
    nodes.push_back({{"name", "lamp"}, {"translation", {0, 0, 3}}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
    d["nodes"] = nodes;
    d["scenes"] = GltfJson::parse(R"([{"nodes": [0, 1, 2, 3, 4, 5]}])");
    d["scene"] = 0;
    return d;
  }
};

// What each quad of GltfSidedQuads shows: the culled back none, every other quad itself.
inline void expect_sided_quads(const render::Camera& cam, const render::GBuffer& g) {
  const char* names[4] = {"front (single-sided)", "back (single-sided)", "back (double-sided)", "mirrored front"};
  for (int k = 0; k < 4; ++k) {
    const std::uint32_t id = g.object_id[pixel_of(cam, g, GltfSidedQuads::centre(k))];
    if (k == 1) EXPECT_EQ(id, 0u) << names[k] << ": a single-sided material's back face is culled";
    else EXPECT_NE(id, 0u) << names[k] << " must be drawn";
  }
}

// The scene with every normal map removed.
inline render::Scene without_normal_maps(render::Scene s) {
  for (render::Material& m : s.materials) m.pbr.normal_texture.reset();
  return s;
}

}  // namespace fovea::test
