// SPDX-License-Identifier: Apache-2.0
// The glTF 2.0 reader (renderer/scene/gltf/): assets written here (a textured cube as .gltf + .bin,
// as .glb and with a data: URI; instancing; TRS and matrices; strips and fans; materials, cameras
// and lights) read back exactly. The hard cases are in test_gltf_reader_errors.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include "gltf_test_assets.h"
#include "scene/gltf/gltf_flatten.h"
#include "scene/gltf/gltf_reader.h"

namespace fs = std::filesystem;
using namespace fovea::render;
using namespace fovea::test;

namespace {

// Reads `doc` with `bin` as a .glb, beside an (empty) cube.png so that no image is missing.
gltf::Asset read_glb(const GltfJson& doc, const GltfBin& bin) {
  TempDir dir;
  write_file(dir.path / "cube.png", "");
  write_file(dir.path / "asset.glb", glb_bytes(doc, bin));
  return gltf::read_gltf(dir.path / "asset.glb");
}

void expect_cube(const gltf::Asset& a, const GltfCube& cube) {
  ASSERT_EQ(a.meshes.size(), 1u);
  ASSERT_EQ(a.meshes[0].primitives.size(), 1u);
  const gltf::Primitive& p = a.meshes[0].primitives[0];
  EXPECT_EQ(p.positions, cube.positions);
  EXPECT_EQ(p.normals, cube.normals);
  EXPECT_EQ(p.texcoords0, cube.uvs);
  std::vector<std::uint32_t> indices(cube.indices.begin(), cube.indices.end());
  EXPECT_EQ(p.indices, indices);
  EXPECT_TRUE(p.tangents.empty());
  EXPECT_TRUE(p.texcoords1.empty());
  EXPECT_EQ(p.material, 0u);
  ASSERT_EQ(a.textures.size(), 1u);
  EXPECT_EQ(a.textures[0].source, 0u);
  EXPECT_EQ(a.textures[0].sampler, 0u);
  ASSERT_EQ(a.samplers.size(), 1u);
  EXPECT_EQ(a.samplers[0].mag_filter, 9729u);
  EXPECT_EQ(a.samplers[0].wrap_s, 33071u);
  ASSERT_EQ(a.materials.size(), 1u);
  ASSERT_TRUE(a.materials[0].base_color_texture);
  EXPECT_EQ(a.materials[0].base_color_texture->texture, 0u);
  const auto instances = gltf::flatten(a);
  ASSERT_EQ(instances.size(), 1u);
  EXPECT_EQ(instances[0].name, "cube");
}

TEST(GltfReader, CubeGltfWithBinReadsExactly) {
  TempDir dir;
  const GltfCube cube;
  const gltf::Asset a = gltf::read_gltf(write_gltf(dir.path, "cube", cube.doc(), cube.bin()));
  expect_cube(a, cube);
  EXPECT_EQ(a.version, "2.0");
  ASSERT_EQ(a.images.size(), 1u);
  EXPECT_EQ(a.images[0].file.filename(), "cube.png");
  EXPECT_TRUE(gltf::image_bytes(a, 0).empty());
  // The image file is not there: the reference is kept (the scene builder warns when it decodes).
  EXPECT_TRUE(a.warnings.empty());
}

TEST(GltfReader, CubeGlbReadsExactly) {
  TempDir dir;
  const GltfCube cube;
  write_file(dir.path / "cube.glb", glb_bytes(cube.doc(), cube.bin()));
  expect_cube(gltf::read_gltf(dir.path / "cube.glb"), cube);
}

TEST(GltfReader, CubeDataUriReadsExactly) {
  TempDir dir;
  const GltfCube cube;
  expect_cube(gltf::read_gltf(write_gltf_data_uri(dir.path, "cube", cube.doc(), cube.bin())), cube);
}

TEST(GltfReader, ImagesInBufferViewsAndDataUris) {
  const GltfCube cube;
  GltfBin bin = cube.bin();
  const std::vector<std::uint8_t> png = {0x89, 'P', 'N', 'G', 1, 2, 3, 4};
  const std::size_t view = bin.add(png);
  GltfJson doc = cube.doc();
  doc["images"] = GltfJson::array({{{"bufferView", view}, {"mimeType", "image/png"}},
                                   {{"uri", "data:image/png;base64," + base64(png)}}});
  const gltf::Asset a = gltf::read_gltf_bytes(glb_bytes(doc, bin), "cube.glb", {});
  ASSERT_EQ(a.images.size(), 2u);
  const auto b0 = gltf::image_bytes(a, 0), b1 = gltf::image_bytes(a, 1);
  EXPECT_EQ(std::vector<std::uint8_t>(b0.begin(), b0.end()), png);
  EXPECT_EQ(std::vector<std::uint8_t>(b1.begin(), b1.end()), png);
  EXPECT_EQ(a.images[1].mime_type, "image/png");
  EXPECT_TRUE(a.warnings.empty());
}

TEST(GltfReader, InstancedMeshKeepsOneMeshAndComposesParentTransforms) {
  const GltfCube cube;
  GltfJson doc = cube.doc();
  doc["nodes"] = GltfJson::parse(R"([
    {"name": "rig", "translation": [1, 0, 0], "children": [1, 2, 3]},
    {"name": "box", "mesh": 0, "translation": [0, 2, 0]},
    {"name": "box", "mesh": 0, "scale": [2, 2, 2]},
    {"mesh": 0}
  ])");
  doc["scenes"] = GltfJson::parse(R"([{"nodes": [0]}])");
  const gltf::Asset a = read_glb(doc, cube.bin());
  const auto inst = gltf::flatten(a);
  ASSERT_EQ(inst.size(), 3u);
  EXPECT_EQ(inst[0].name, "box");
  EXPECT_EQ(inst[1].name, "box#2");
  EXPECT_EQ(inst[2].name, "node3");
  EXPECT_EQ(inst[2].node, 3u);
  for (const auto& i : inst) EXPECT_EQ(i.mesh, 0u);
  EXPECT_EQ(inst[0].world * glm::vec4(0, 0, 0, 1), glm::vec4(1, 2, 0, 1));
  EXPECT_EQ(inst[1].world * glm::vec4(1, 1, 1, 1), glm::vec4(3, 2, 2, 1));
  EXPECT_EQ(inst[2].world * glm::vec4(0, 0, 0, 1), glm::vec4(1, 0, 0, 1));
}

TEST(GltfReader, TrsAndMatrixGiveTheSameTransform) {
  const GltfCube cube;
  GltfJson doc = cube.doc();
  // 90 degrees about y, given unnormalised: the reader normalises the quaternion.
  const glm::mat4 expected = glm::translate(glm::mat4(1.0f), glm::vec3(1, 2, 3)) *
                             glm::mat4_cast(glm::angleAxis(glm::radians(90.0f), glm::vec3(0, 1, 0))) *
                             glm::scale(glm::mat4(1.0f), glm::vec3(2, 3, 4));
  GltfJson matrix = GltfJson::array();
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) matrix.push_back(expected[c][r]);
  }
  doc["nodes"] = GltfJson::array({{{"mesh", 0}, {"translation", {1, 2, 3}}, {"rotation", {0, 2, 0, 2}}, {"scale", {2, 3, 4}}},
                                  {{"mesh", 0}, {"matrix", matrix}}});
  doc["scenes"] = GltfJson::parse(R"([{"nodes": [0, 1]}])");
  const gltf::Asset a = read_glb(doc, cube.bin());
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      EXPECT_NEAR(a.nodes[0].local[c][r], expected[c][r], 1e-6f) << c << "," << r;
      EXPECT_EQ(a.nodes[1].local[c][r], expected[c][r]) << c << "," << r;
    }
  }
}

// Five vertices drawn as a strip, a fan, a non-indexed list of three, and points.
gltf::Asset strip_fan_asset(const char* primitives) {
  GltfBin bin;
  const std::vector<glm::vec3> pos = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0, 2, 0}};
  bin.add(pos);
  bin.add(std::vector<std::uint8_t>{0, 1, 2, 3, 4});
  GltfJson doc = {{"asset", {{"version", "2.0"}}},
                  {"accessors", GltfJson::parse(R"([
                     {"bufferView": 0, "componentType": 5126, "count": 5, "type": "VEC3"},
                     {"bufferView": 1, "componentType": 5121, "count": 5, "type": "SCALAR"},
                     {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}])")},
                  {"meshes", GltfJson::array({{{"primitives", GltfJson::parse(primitives)}}})}};
  return gltf::read_gltf_bytes(glb_bytes(doc, bin), "strip.glb", {});
}

TEST(GltfReader, StripsAndFansBecomeTriangleLists) {
  const gltf::Asset a = strip_fan_asset(R"([
    {"attributes": {"POSITION": 0}, "mode": 5},
    {"attributes": {"POSITION": 0}, "indices": 1, "mode": 6},
    {"attributes": {"POSITION": 2}},
    {"attributes": {"POSITION": 0}, "mode": 0}])");
  const auto& prims = a.meshes[0].primitives;
  ASSERT_EQ(prims.size(), 3u);  // the points are left out
  EXPECT_EQ(prims[0].indices, (std::vector<std::uint32_t>{0, 1, 2, 1, 3, 2, 2, 3, 4}));
  EXPECT_EQ(prims[1].indices, (std::vector<std::uint32_t>{1, 2, 0, 2, 3, 0, 3, 4, 0}));
  EXPECT_EQ(prims[2].indices, (std::vector<std::uint32_t>{0, 1, 2}));
  EXPECT_EQ(prims[2].positions.size(), 3u);
  ASSERT_EQ(a.warnings.size(), 1u);
  EXPECT_NE(a.warnings[0].find("$.meshes[0].primitives[3]: mode 0"), std::string::npos) << a.warnings[0];
}

TEST(GltfReader, MaterialWithEverySlot) {
  const GltfCube cube;
  GltfJson doc = cube.doc();
  doc["textures"] = GltfJson::parse(R"([{"source": 0}, {"source": 0}, {"source": 0}, {"source": 0}, {"source": 0}])");
  doc["extensionsUsed"] = {"KHR_materials_emissive_strength", "EXT_unknown_thing"};
  doc["materials"] = GltfJson::parse(R"([{
    "name": "everything",
    "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1, 0.75], "baseColorTexture": {"index": 0},
                             "metallicFactor": 0.2, "roughnessFactor": 0.7,
                             "metallicRoughnessTexture": {"index": 1, "texCoord": 1}},
    "normalTexture": {"index": 2, "scale": 0.5},
    "occlusionTexture": {"index": 3, "strength": 0.25, "texCoord": 1},
    "emissiveTexture": {"index": 4},
    "emissiveFactor": [1, 0.5, 0],
    "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 12}},
    "alphaMode": "MASK", "alphaCutoff": 0.3, "doubleSided": true}])");
  const gltf::Asset a = read_glb(doc, cube.bin());
  const gltf::Material& m = a.materials.at(0);
  EXPECT_EQ(m.name, "everything");
  EXPECT_EQ(m.base_color_factor, glm::vec4(0.5f, 0.25f, 1, 0.75f));
  EXPECT_FLOAT_EQ(m.metallic_factor, 0.2f);
  EXPECT_FLOAT_EQ(m.roughness_factor, 0.7f);
  EXPECT_EQ(m.base_color_texture->texture, 0u);
  EXPECT_EQ(m.metallic_roughness_texture->texture, 1u);
  EXPECT_EQ(m.metallic_roughness_texture->tex_coord, 1u);
  EXPECT_EQ(m.normal_texture->texture, 2u);
  EXPECT_FLOAT_EQ(m.normal_scale, 0.5f);
  EXPECT_EQ(m.occlusion_texture->tex_coord, 1u);
  EXPECT_FLOAT_EQ(m.occlusion_strength, 0.25f);
  EXPECT_EQ(m.emissive_texture->texture, 4u);
  EXPECT_EQ(m.emissive_factor, glm::vec3(1, 0.5f, 0));
  EXPECT_FLOAT_EQ(m.emissive_strength, 12.0f);
  EXPECT_EQ(m.alpha_mode, gltf::AlphaMode::Mask);
  EXPECT_FLOAT_EQ(m.alpha_cutoff, 0.3f);
  EXPECT_TRUE(m.double_sided);
  ASSERT_EQ(a.warnings.size(), 1u);  // the unknown extension
  EXPECT_NE(a.warnings[0].find("EXT_unknown_thing"), std::string::npos) << a.warnings[0];
}

TEST(GltfReader, CamerasAndPunctualLights) {
  const GltfCube cube;
  GltfJson doc = cube.doc();
  doc["extensionsUsed"] = {"KHR_lights_punctual"};
  doc["cameras"] = GltfJson::parse(R"([
    {"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 100, "aspectRatio": 1.5}},
    {"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.01}},
    {"type": "orthographic", "orthographic": {"xmag": 2, "ymag": 1, "znear": 0, "zfar": 10}}])");
  doc["extensions"] = GltfJson::parse(R"({"KHR_lights_punctual": {"lights": [
    {"type": "point", "color": [1, 0.5, 0.25], "intensity": 40, "range": 8},
    {"type": "spot", "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.6}},
    {"type": "directional", "intensity": 3, "name": "sun"}]}})");
  doc["nodes"] = GltfJson::parse(R"([{"mesh": 0}, {"camera": 0, "translation": [0, 1, 5]},
    {"extensions": {"KHR_lights_punctual": {"light": 1}}}])");
  doc["scenes"] = GltfJson::parse(R"([{"nodes": [0, 1, 2]}])");
  const gltf::Asset a = read_glb(doc, cube.bin());
  ASSERT_EQ(a.cameras.size(), 3u);
  EXPECT_FLOAT_EQ(a.cameras[0].yfov_rad, 0.8f);
  EXPECT_FLOAT_EQ(*a.cameras[0].zfar, 100.0f);
  EXPECT_FLOAT_EQ(*a.cameras[0].aspect_ratio, 1.5f);
  EXPECT_FALSE(a.cameras[1].zfar.has_value());
  EXPECT_EQ(a.cameras[2].type, gltf::Camera::Type::Orthographic);
  EXPECT_FLOAT_EQ(a.cameras[2].xmag, 2.0f);
  ASSERT_EQ(a.lights.size(), 3u);
  EXPECT_EQ(a.lights[0].type, gltf::Light::Type::Point);
  EXPECT_EQ(a.lights[0].color, glm::vec3(1, 0.5f, 0.25f));
  EXPECT_FLOAT_EQ(a.lights[0].intensity, 40.0f);
  EXPECT_FLOAT_EQ(*a.lights[0].range, 8.0f);
  EXPECT_EQ(a.lights[1].type, gltf::Light::Type::Spot);
  EXPECT_FLOAT_EQ(a.lights[1].inner_cone_rad, 0.2f);
  EXPECT_FLOAT_EQ(a.lights[1].outer_cone_rad, 0.6f);
  EXPECT_EQ(a.lights[2].name, "sun");
  EXPECT_EQ(a.nodes[1].camera, 0u);
  EXPECT_EQ(a.nodes[2].light, 1u);
}

// The real CC0 asset (Microsoft's BoomBox, glTF-Sample-Models), where the machine has it: one of its
// four images is missing on purpose, which a reader that keeps references must not fail on.
TEST(GltfReader, BoomBoxSampleAsset) {
  const fs::path file = "/work/shared/data/gltf/BoomBox/glTF/BoomBox.gltf";
  if (!fs::exists(file)) GTEST_SKIP() << file << " is not on this machine";
  const gltf::Asset a = gltf::read_gltf(file);
  ASSERT_EQ(a.meshes.size(), 1u);
  const gltf::Primitive& p = a.meshes[0].primitives.at(0);
  EXPECT_EQ(p.positions.size(), 3575u);
  EXPECT_EQ(p.tangents.size(), 3575u);
  EXPECT_EQ(p.indices.size(), 18108u);
  EXPECT_EQ(a.images.size(), 4u);
  EXPECT_EQ(a.textures.size(), 4u);
  // The missing image stays a reference: the scene builder warns about it (GltfScene.BoomBox...).
  EXPECT_TRUE(a.warnings.empty());
  EXPECT_EQ(a.images.at(1).file.filename(), "BoomBox_occlusionRoughnessMetallic.png");
  const auto inst = gltf::flatten(a);
  ASSERT_EQ(inst.size(), 1u);
  EXPECT_EQ(inst[0].name, "BoomBox");
}

}  // namespace
