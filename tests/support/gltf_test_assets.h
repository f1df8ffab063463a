// SPDX-License-Identifier: Apache-2.0
#pragma once
// The glTF assets the reader's tests share: a textured unit cube (24 vertices, 36 unsigned short
// indices, one material with a base colour texture) that each test changes as it needs.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "gltf_writer.h"
#include "temp_dir.h"

namespace fovea::test {

struct GltfCube {
  std::vector<glm::vec3> positions, normals;
  std::vector<glm::vec2> uvs;
  std::vector<std::uint16_t> indices;

  GltfCube() {
    const std::array<glm::vec3, 6> n = {glm::vec3(1, 0, 0), glm::vec3(-1, 0, 0), glm::vec3(0, 1, 0),
                                        glm::vec3(0, -1, 0), glm::vec3(0, 0, 1), glm::vec3(0, 0, -1)};
    for (const glm::vec3& f : n) {
      const glm::vec3 u = f.x != 0 ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
      const glm::vec3 v = glm::cross(f, u);
      const auto base = static_cast<std::uint16_t>(positions.size());
      const std::array<glm::vec2, 4> corners = {glm::vec2(0, 0), glm::vec2(1, 0), glm::vec2(1, 1), glm::vec2(0, 1)};
      for (const glm::vec2& c : corners) {
        positions.push_back(0.5f * f + (c.x - 0.5f) * u + (c.y - 0.5f) * v);
        normals.push_back(f);
        uvs.push_back(c);
      }
      for (const int i : {0, 1, 2, 0, 2, 3}) indices.push_back(static_cast<std::uint16_t>(base + i));
    }
  }

  // Views 0 positions, 1 normals, 2 uvs, 3 indices.
  GltfBin bin() const {
    GltfBin b;
    b.add(positions);
    b.add(normals);
    b.add(uvs);
    b.add(indices);
    return b;
  }

  GltfJson doc(const std::string& image_uri = "cube.png") const {
    GltfJson d = {{"asset", {{"version", "2.0"}, {"generator", "fovea tests"}}}};
    d["accessors"] = GltfJson::array({
        {{"bufferView", 0}, {"componentType", 5126}, {"count", 24}, {"type", "VEC3"}},
        {{"bufferView", 1}, {"componentType", 5126}, {"count", 24}, {"type", "VEC3"}},
        {{"bufferView", 2}, {"componentType", 5126}, {"count", 24}, {"type", "VEC2"}},
        {{"bufferView", 3}, {"componentType", 5123}, {"count", 36}, {"type", "SCALAR"}},
    });
    d["meshes"] = GltfJson::parse(R"([{"name": "cube", "primitives": [
        {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3, "material": 0}]}])");
    d["materials"] = GltfJson::parse(R"([{"name": "painted", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}])");
    d["textures"] = GltfJson::parse(R"([{"source": 0, "sampler": 0}])");
    d["samplers"] = GltfJson::parse(R"([{"magFilter": 9729, "minFilter": 9987, "wrapS": 33071}])");
    d["images"] = GltfJson::array({{{"uri", image_uri}}});
    d["nodes"] = GltfJson::parse(R"([{"name": "cube", "mesh": 0}])");
    d["scenes"] = GltfJson::parse(R"([{"nodes": [0]}])");
    d["scene"] = 0;
    return d;
  }
};

// Two unit quads facing +Z, red at x = -0.6 and green at x = +0.6, each its own mesh node with its
// own material (metallic 0: Lambertian), seen by a camera node at z = 3 (yfov 0.8 rad); no lights.
// Views 0 positions, 1 normals, 2 indices.
struct GltfTwoQuads {
  GltfBin bin() const {
    GltfBin b;
    b.add(std::vector<glm::vec3>{{-0.5f, -0.5f, 0}, {0.5f, -0.5f, 0}, {0.5f, 0.5f, 0}, {-0.5f, 0.5f, 0}});
    b.add(std::vector<glm::vec3>(4, glm::vec3(0, 0, 1)));
    b.add(std::vector<std::uint16_t>{0, 1, 2, 0, 2, 3});
    return b;
  }
  GltfJson doc() const {
    GltfJson d = {{"asset", {{"version", "2.0"}}}};
    d["accessors"] = GltfJson::parse(R"([
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-0.5, -0.5, 0], "max": [0.5, 0.5, 0]},
        {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
        {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}])");
    d["materials"] = GltfJson::parse(R"([
        {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1], "metallicFactor": 0}},
        {"name": "green", "pbrMetallicRoughness": {"baseColorFactor": [0, 1, 0, 1], "metallicFactor": 0}}])");
    d["meshes"] = GltfJson::parse(R"([
        {"name": "red quad", "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0}]},
        {"name": "green quad", "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 1}]}])");
    d["cameras"] = GltfJson::parse(R"([{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 20}}])");
    d["nodes"] = GltfJson::parse(R"([
        {"name": "left", "mesh": 0, "translation": [-0.6, 0, 0]},
        {"name": "right", "mesh": 1, "translation": [0.6, 0, 0]},
        {"name": "eye", "camera": 0, "translation": [0, 0, 3]}])");
    d["scenes"] = GltfJson::parse(R"([{"nodes": [0, 1, 2]}])");
    d["scene"] = 0;
    return d;
  }
};

}  // namespace fovea::test
